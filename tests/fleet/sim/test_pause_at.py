"""`--pause-at`: the line pauses once its tick at a sim second it was given has run, says so in its status, stands
there until a user resumes it, and pauses there once (a resume goes on)."""

import threading
import time

import pytest

from fleet.bus.keys import Keys
from fleet.bus.session import BusEndpoints, open_session
from fleet.cli import main
from fleet.monitor.controls import LineControls
from fleet.monitor.feed import LiveFeed
from fleet.nodes.sim_server import SimServer
from fleet.sim.world import World
from scenes import load_scene
from tests.fleet.monitor.test_bus_side import wait_for


class Stop:
    def __init__(self) -> None:
        self.event = threading.Event()
        self.reason = ""

    def should_stop(self) -> bool:
        return self.event.is_set()


def test_a_lockstep_line_pauses_at_the_tick_it_was_given_until_resumed():
    keys = Keys("pause_at")
    with open_session(BusEndpoints()) as session:
        server = SimServer(World(load_scene("handover")), session, keys, mode="lockstep", controllers=False)
        hz = server.world.scene_model.control_hz
        server.controls.pause_at_ticks = {round(0.5 * hz)}
        stop = Stop()
        thread = threading.Thread(target=server.run_ticks, args=(round(1.0 * hz),), kwargs={"stop": stop})
        with LiveFeed(session, keys, ["arm_0", "arm_1"]) as feed:
            controls = LineControls(session, keys, source="test")
            try:
                thread.start()
                assert wait_for(lambda: feed.take().status is not None and feed.sight.status.paused)
                after = round(0.5 * hz) + 1  # the tick at 0.5 s has run
                assert server.world.tick == after and feed.sight.status.tick == after
                time.sleep(0.3)
                assert server.world.tick == after, "paused: the clock stands still"
                controls.pause(False)
                thread.join(10)
                assert not thread.is_alive() and server.world.tick == round(1.0 * hz), "resumed, and not paused again"
            finally:
                stop.event.set()
                thread.join(5)
                controls.close()
                server.close()


@pytest.mark.parametrize("value", ["0", "-3", "ten", "5,,nan"])
def test_a_pause_at_no_clock_reaches_is_refused_in_one_line(value, capsys):
    with pytest.raises(SystemExit) as exited:
        main(["run", "pick_cell", "--pause-at", value])
    assert exited.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--pause-at" in err, err
