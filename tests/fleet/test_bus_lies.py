"""Well-formed lies on a running line's bus: each is refused, dropped and counted, and the lockstep run comes out
exactly as a clean run of the same seed (an unknown feeder, messages from the far future, NaN fields, a fake
assignment, a fake coordinator tick).

An insecure bus (`--insecure`): by default the router refuses lies from a process without the role before any node
hears them (`tests/fleet/test_secure_bus.py`); here every node must stand on its own."""

import math

import pytest

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, Assignment, ControllerStep, CoordTick, LineEvent, LineView, PartsState
from fleet.bus.session import BusEndpoints, open_session
from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.sim_time_trigger import SimTimeTrigger
from tests.fleet.test_run import QUICK_LINE, WALL_FIGURES, assert_nothing_left

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

FAR = 10**18
COUNTED = WALL_FIGURES + ("dropped_messages", "refused_messages", "bus_refused", "bus_messages_per_arm_per_s")


def lies(keys: Keys, arms: list[str]) -> list[tuple[str, bytes]]:
    nan = math.nan
    # noqa: E731
    state = lambda arm: ArmState(
        arm, FAR, 1e16, (nan,) * 6, (nan,) * 6, (0.0, 0.0), (0.0,) * 3, (1.0, 0.0, 0.0, 0.0), lost=True
    )
    parts = PartsState(FAR, 1e16, (), (), (), (), (), (), ())
    out = [
        (keys.events, encode(LineEvent("arrived", 1_000_000_000, 0, "feeder_nope", -5))),
        (keys.events, encode(LineEvent("at_station", 0, FAR, "bin_0"))),
        (keys.events, encode(LineEvent("lost", 424242, 1, "gone"))),
        (keys.frame, encode(LineView(FAR, 1e16, tuple(state(a) for a in arms), parts))),
        (keys.coord("tick"), encode(CoordTick(FAR, tuple(2**62 for _ in arms)))),
    ]
    for arm in arms:
        out.append((keys.arm_state(arm), encode(state(arm))))
        out.append(
            (
                keys.arm_step(arm),
                encode(ControllerStep(arm, 0, 5, (), None, "approach", 0.1, "", "", 1, (nan,) * 6, 1.0)),
            )
        )
        out.append(
            (keys.arm_assign(arm), encode(Assignment(arm, 2**63 - 1, 7, 0, 0.1, (nan, 0.0, 0.0), (0.0, 0.0, 0.0))))
        )
        out.append((keys.arm_assign(arm), encode(Assignment(arm, 3, 7, 0, 0.1, (math.inf, 0.0, 0.0), (0.0, 0.0, 0.0)))))
    return out


def run(with_lies: bool) -> tuple[dict, int]:
    keys = Keys("line")
    told: list[int] = []
    options = RunOptions(scene=QUICK_LINE, duration_s=18.0, seed=5, insecure=True)
    with Launcher(options) as launcher:
        arms = [a.name for a in launcher.scene.arms]
        with open_session(BusEndpoints(connect=(launcher.endpoint,))) as session:

            def tell() -> None:
                for key, payload in lies(keys, arms):
                    session.put(key, payload)
                told.append(len(lies(keys, arms)))

            with SimTimeTrigger(session, keys, [1.0, 4.0, 7.0, 10.0, 13.0] if with_lies else [], tell):
                summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    return summary, sum(told)


def test_well_formed_lies_are_dropped_and_counted_and_change_nothing():
    clean, _ = run(with_lies=False)
    lied, told = run(with_lies=True)
    assert told >= 13, "at least one round of lies went out while parts were worked"
    assert lied["status"] == "ok" and lied["parts_completed"] >= 2
    assert lied["dropped_messages"] >= told, "each lie was dropped and counted"
    strip = lambda s: {k: v for k, v in s.items() if k not in COUNTED}  # noqa: E731
    assert strip(lied) == strip(clean), "the line ran exactly as without them"


def test_heartbeats_of_a_dead_controller_and_reports_no_node_sends_are_refused_and_counted():
    """arm_0's controller is killed (no respawn); a liar then beats for it with its own incarnation, beats with NaN
    sim times for every arm, and sends progress and sim status no line could: the arm stays lost (no "rejoined"),
    and the coordinator and the launcher count each kind of lie."""
    import os
    import signal

    import msgspec

    from fleet.bus.codec import Decoder, DropCounter
    from fleet.bus.messages import ArmStatus, Progress, SimStatus

    keys, killed, heard, told = Keys("line"), [], [], []
    options = RunOptions(scene=QUICK_LINE, duration_s=16.0, seed=5, insecure=True)

    with Launcher(options) as launcher:
        arms = [a.name for a in launcher.scene.arms]
        with open_session(BusEndpoints(connect=(launcher.endpoint,))) as session:
            decoder = Decoder(ArmStatus, DropCounter())

            def kill_arm_0(sample) -> None:
                """On the first heartbeat of arm_0 heard from 3 s of sim time on (its own sim time: heartbeats come
                every 0.2 s of wall time, and a lockstep line on an idle machine passes seconds of sim between two;
                on a loaded one, a trigger on the line's sim time had fired before any was heard), the liar beats
                on from it."""
                beat = decoder.decode(str(sample.key_expr), sample.payload.to_bytes())
                heard.append(beat)
                if not killed and beat is not None and beat.sim_time_s >= 3.0:
                    node = next(n for n in launcher.nodes if n.name == "arm_0")
                    killed.append(node.proc.pid)
                    os.kill(node.proc.pid, signal.SIGKILL)

            sub = session.declare_subscriber(keys.arm_status("arm_0"), kill_arm_0)

            def lie() -> None:
                if not killed or not heard:
                    return
                beat = heard[-1]
                for k in range(5):  # its own incarnation, its next numbers: only the sim knows it is dead
                    ghost = msgspec.structs.replace(beat, seq=beat.seq + 10 + k, sim_time_s=9.0)
                    session.put(keys.arm_status("arm_0"), encode(ghost))
                for arm in arms[1:]:
                    session.put(keys.arm_status(arm), encode(ArmStatus(arm, 5, math.nan, "idle", None, 0.0)))
                session.put(keys.coord("progress"), encode(Progress(1e9, 5, 9, 0, 1)))
                session.put(keys.sim_status, encode(SimStatus(FAR, 3.0, "lockstep", False, False, 1.0, (), 0.0, 0)))
                told.append(1)

            with SimTimeTrigger(session, keys, [7.0, 8.0, 9.0, 10.0, 11.0, 12.0, 13.0], lie):
                summary = launcher.run()
            sub.undeclare()
    assert_nothing_left(summary, launcher.endpoint)
    assert summary["status"] == "ok" and summary["sim_seconds"] >= 15.9, (summary["error"], summary["sim_seconds"])
    assert killed and len(told) >= 3, (killed, told, len(heard))
    events = [e["event"] for e in summary["arm_events"] if e["arm"] == "arm_0"]
    assert events == ["lost"], summary["arm_events"]
    refused = summary["refused_messages"]
    coordinator = {k: n for k, n in refused.get("coordinator", {}).items() if k.startswith("status")}
    assert sum(n for k, n in coordinator.items() if "lost controller" in k) >= 5 * len(told), refused
    assert sum(n for k, n in coordinator.items() if "NaN" in k) >= len(told) * (len(arms) - 1), refused
    launcher_refused = refused.get("launcher", {})
    assert sum(n for k, n in launcher_refused.items() if k.startswith("progress")) >= len(told), refused
    assert sum(n for k, n in launcher_refused.items() if k.startswith("status")) >= len(told), refused
