"""The monitor's bus side with a real sim server and Zenoh on loopback: the scene is served, status and
separations arrive, the page's controls pause, resume and re-speed the sim, and bad payloads are counted."""

import socket
import threading
import time

import pytest

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.messages import Assignment, MotionGrant, Progress, SimStatus
from fleet.bus.scene_query import SceneUnavailable, fetch_scene, serve_scene
from fleet.bus.session import BusEndpoints, open_session
from fleet.monitor.app import Monitor
from fleet.monitor.controls import LineControls
from fleet.monitor.feed import LiveFeed
from fleet.monitor.options import exposure_warning
from fleet.nodes.sim_server import SimServer
from fleet.sim.world import World
from scenes import load_scene


def wait_for(condition, timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.02)
    return False


@pytest.fixture
def realtime_sim():
    """A realtime sim server of the handover cell (no controllers: arms held) ticking in a thread."""
    keys = Keys("mon")
    with open_session(BusEndpoints()) as session:
        server = SimServer(
            World(load_scene("handover")), session, keys, mode="realtime", first_command_timeout_s=0.2, speed=1.0
        )
        stop = threading.Event()

        class Stop:
            reason = ""

            def should_stop(self) -> bool:
                return stop.is_set()

        thread = threading.Thread(target=server.run_ticks, args=(10**6,), kwargs={"stop": Stop()}, daemon=True)
        thread.start()
        try:
            yield server, session, keys
        finally:
            stop.set()
            thread.join(timeout=5)
            server.close()


def test_the_sim_serves_its_scene_and_status_and_obeys_pause_resume_and_speed(realtime_sim):
    server, session, keys = realtime_sim
    assert fetch_scene(session, keys).name == "handover"
    with LiveFeed(session, keys, ["arm_0", "arm_1"]) as feed:
        controls = LineControls(session, keys, source="test")
        try:
            assert wait_for(lambda: feed.take().status is not None and len(feed.sight.arms) == 2)
            assert feed.sight.status.mode == "realtime" and not feed.sight.status.paused
            controls.pause(True)
            assert wait_for(lambda: feed.take().status.paused)
            tick = server.world.tick
            time.sleep(0.3)
            assert server.world.tick == tick, "paused: the clock stands still"
            controls.set_speed(3.0)
            controls.pause(False)
            assert wait_for(lambda: not feed.take().status.paused and feed.sight.status.speed == 3.0)
            t0, w0 = server.world.sim_time_s, time.monotonic()
            time.sleep(0.6)
            rate = (server.world.sim_time_s - t0) / (time.monotonic() - w0)
            assert 2.0 < rate < 3.6, f"sim seconds per wall second at speed 3: {rate:.2f}"
            with pytest.raises(ValueError, match="outside"):
                controls.set_speed(0.0)
            controls.emergency_stop(True)
            assert wait_for(lambda: feed.take().status.estop)
            assert controls.sent == ["pause", "speed 3", "resume", "estop"]
        finally:
            controls.close()


def test_garbage_on_the_monitor_keys_is_dropped_and_counted(realtime_sim):
    _, session, keys = realtime_sim
    with LiveFeed(session, keys, ["arm_0", "arm_1"]) as feed:
        time.sleep(0.1)
        session.put(keys.sim_status, b"\x93garbage")
        session.put(keys.coord("separation"), b"")
        assert wait_for(lambda: feed.take() is not None and feed.drops.total >= 2)
        session.put(keys.sim_status, encode(SimStatus(1, 0.01, "lockstep", False, False, 1.0, (0.0, 0.0), 0.0, 0)))
        assert wait_for(lambda: feed.take().status is not None)


def test_progress_and_sim_status_no_line_could_send_are_dropped_and_counted(realtime_sim):
    """Well-formed lies on the monitor's figures (an insecure bus lets anyone put them): refused, counted, not
    shown; the true ones after them are. (A sim status is checked alike: `sim_status_problem`; here the sim's own
    statuses would overwrite a lie in the feed's one-deep queue.)"""
    _, session, keys = realtime_sim
    with LiveFeed(session, keys, ["arm_0", "arm_1"]) as feed:
        time.sleep(0.1)
        lies = [
            (keys.coord("progress"), Progress(float("nan"), 5, 1, 0, 1)),
            (keys.coord("progress"), Progress(3.0, 2, 5, 0, 1)),  # more done than spawned
            (keys.coord("progress"), Progress(3.0, 5, 2, 0, 3)),  # three arms busy on a line of two
        ]
        for key, lie in lies:
            session.put(key, encode(lie))
            assert wait_for(lambda: feed.take() is not None and feed.taken >= 1)
        assert wait_for(lambda: feed.take() is not None and feed.drops.total == len(lies)), feed.drops.kinds()
        assert feed.sight.progress is None
        session.put(keys.coord("progress"), encode(Progress(3.0, 5, 2, 0, 1)))
        assert wait_for(lambda: feed.take().progress is not None)


def test_motion_grants_on_an_arms_order_key_are_orders_not_garbage(realtime_sim):
    """The coordinator sends assignments and motion grants on one key: the monitor takes both as well-formed."""
    _, session, keys = realtime_sim
    with LiveFeed(session, keys, ["arm_0", "arm_1"]) as feed:
        time.sleep(0.1)
        session.put(keys.arm_assign("arm_0"), encode(MotionGrant("arm_0", 1, 1, "grant")))
        assert wait_for(lambda: feed.take() is not None and feed.taken >= 1)
        session.put(
            keys.arm_assign("arm_0"), encode(Assignment("arm_0", 2, 7, 3, 0.1, (0.2, 0.0, 0.1), (0.0, 0.0, 0.0)))
        )
        assert wait_for(lambda: "arm_0" in feed.take().assignments)
        assert feed.drops.total == 0


def test_no_sim_means_a_clear_error_not_a_hang():
    with open_session(BusEndpoints()) as session:
        with pytest.raises(SceneUnavailable, match="no sim of run 'nobody'"):
            fetch_scene(session, Keys("nobody"), timeout_s=0.5)


def test_a_scene_whose_robot_file_is_not_here_is_a_clear_error(tmp_path):
    scene = load_scene("assembly_line").model_copy(update={"robot_files": [str(tmp_path / "elsewhere.yaml")]})
    with open_session(BusEndpoints()) as session:
        queryable = serve_scene(session, Keys("far"), scene.model_dump_json())
        try:
            with pytest.raises(
                SceneUnavailable, match=r"names a robot file that cannot be used here: .*elsewhere.yaml: no such file"
            ):
                fetch_scene(session, Keys("far"), timeout_s=2.0)
        finally:
            queryable.undeclare()


def test_the_monitor_frees_its_port():
    with open_session(BusEndpoints()) as session:
        with Monitor(session, Keys("mon"), load_scene("assembly_line"), port=0) as monitor:
            port = monitor.port
            monitor.frame()
            with socket.create_connection(("127.0.0.1", port), timeout=2):
                pass
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("127.0.0.1", port))


def test_only_loopback_is_quiet():
    assert exposure_warning("127.0.0.1") is None and exposure_warning("localhost") is None
    assert "whoever can reach" in exposure_warning("0.0.0.0")
