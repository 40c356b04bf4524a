"""A default run's bus is its own: TLS, a login per node and access control, made for the run. A process without
the run's credentials cannot reach it, and one logged in with a role cannot speak beyond that role: the lockstep run
comes out exactly as a clean run of the same seed."""

import contextlib
import math

import pytest

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.messages import Assignment, EStop, LineEvent, SimControl
from fleet.bus.session import BusEndpoints, open_session
from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.sim_time_trigger import SimTimeTrigger
from tests.fleet.test_bus_lies import COUNTED
from tests.fleet.test_run import QUICK_LINE, assert_nothing_left

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out


def intrusions(keys: Keys, arms: list[str]) -> list[tuple[str, bytes]]:
    """What would change the line if anyone heard it: an e-stop, a pause, a fake order, a phantom part."""
    out = [
        (keys.estop, encode(EStop(True, "intruder"))),
        (keys.control, encode(SimControl("intruder", True, None))),
        (keys.events, encode(LineEvent("arrived", 7, 1, "feeder_nope", 0))),
    ]
    for arm in arms:
        out.append((keys.arm_assign(arm), encode(Assignment(arm, 1, 99, 0, 0.1, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))))
    return out


INTRUDERS = ("outsider", "monitor", "arm_0")  # no credentials at all; the monitor's login; an arm's own login


def run(intruders: tuple[str, ...]) -> dict:
    """The quick line, seed 5, with each of `intruders` pouring everything it is not allowed to say while the line
    runs: `outsider` has no credentials (plain TCP to the sim's port), the others are a node's login."""
    options = RunOptions(scene=QUICK_LINE, duration_s=12.0, seed=5)
    poured: list[int] = []
    with Launcher(options) as launcher, contextlib.ExitStack() as sessions:
        keys, arms = Keys(options.run_id), [a.name for a in launcher.scene.arms]
        private = [f for f in (launcher.dir / "bus").iterdir() if f.suffix in (".json5", ".key", ".txt")]
        assert private and all(f.stat().st_mode & 0o077 == 0 for f in private), "keys and passwords: the owner's"
        assert launcher.endpoint.startswith("tls/127.0.0.1:")
        speakers = {}
        for who in intruders:
            if who == "outsider":
                endpoints = BusEndpoints(connect=(launcher.endpoint.replace("tls/", "tcp/"),))
            else:
                endpoints = launcher.client_endpoints(who)
            speakers[who] = sessions.enter_context(open_session(endpoints))

        def pour() -> None:
            for who, session in speakers.items():
                for key, payload in intrusions(keys, arms):
                    if not (who == "monitor" and key in (keys.estop, keys.control)):  # the monitor's own role
                        session.put(key, payload)
            poured.append(1)

        listener = sessions.enter_context(open_session(launcher.client_endpoints("monitor")))
        with SimTimeTrigger(listener, keys, [1.0, 3.0, 5.0, 7.0, 9.0] if intruders else [], pour):
            summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert not intruders or poured, "the intrusions went out while the line ran"
    return summary


def test_no_process_without_the_runs_credentials_or_role_can_change_the_line():
    clean = run(())
    lied = run(INTRUDERS)
    assert clean["bus"] == lied["bus"] == "secure"
    assert lied["status"] == "ok" and math.isclose(lied["sim_seconds"], 12.0)
    strip = lambda s: {k: v for k, v in s.items() if k not in COUNTED}  # noqa: E731
    assert strip(lied) == strip(clean), "the line ran exactly as without them"
    assert clean["bus_refused"] == {}, "a clean run's router refuses nothing"
    refused = lied["bus_refused"]
    assert refused.get("connections refused at the TLS handshake", 0) >= 1, refused
    for who, key in (("monitor", "arm/arm_0/assign"), ("arm_0", "estop"), ("arm_0", "arm/arm_1/assign")):
        assert refused.get(f"{who}: put on clawfleet/line/{key}", 0) >= 1, (who, key, refused)


def forbidden_to(arm: str, keys: Keys, arms: list[str]) -> list[str]:
    """Every key of the run an arm's own login may not put on: the line's, the other nodes' (perception's too),
    every arm's but its own four (step, goal, status, its snapshot part)."""
    line = [keys.estop, keys.control, keys.events, keys.parts, keys.sim_status, keys.frame, keys.view, keys.history]
    line += [keys.respawn, keys.roster, keys.snapshot_ask, keys.recorder_ready, keys.coord("progress")]
    line += [keys.snapshot_part("sim"), keys.snapshot_part("coordinator")]
    line += [keys.seen_parts, keys.detections("overhead")]  # perception's: the line's parts as seen are its alone
    for other in arms:
        line += [keys.arm_state(other), keys.arm_drive(other), keys.arm_result(other), keys.arm_assign(other)]
        if other != arm:
            line += [keys.arm_step(other), keys.arm_goal(other), keys.arm_status(other), keys.snapshot_part(other)]
    return line


def test_every_refusal_of_the_router_is_counted_however_long_the_run():
    """arm_0's login probes every key it may not put on, three times, at 1, 6 and 11 s of a realtime run: the
    router's audit (its log files switch every 5 s) counts each of those puts in the summary, none lost."""
    options = RunOptions(scene=QUICK_LINE, duration_s=12.0, seed=5, mode="realtime")
    with Launcher(options) as launcher, contextlib.ExitStack() as sessions:
        keys, arms = Keys(options.run_id), [a.name for a in launcher.scene.arms]
        probe = sessions.enter_context(open_session(launcher.client_endpoints("arm_0")))
        listener = sessions.enter_context(open_session(launcher.client_endpoints("monitor")))
        forbidden = forbidden_to("arm_0", keys, arms)

        def pour() -> None:
            for key in forbidden:
                probe.put(key, b"\x93probe")

        with SimTimeTrigger(listener, keys, [1.0, 6.0, 11.0], pour) as trigger:
            summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert trigger.times == 3 and summary["status"] == "ok", summary.get("error")
    counted = {key: summary["bus_refused"].get(f"arm_0: put on {key}", 0) for key in forbidden}
    assert counted == dict.fromkeys(forbidden, 3), counted
    assert sum(summary["bus_refused"].values()) == 3 * len(forbidden), summary["bus_refused"]
