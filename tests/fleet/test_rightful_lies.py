"""Lies from a rightful sender: a process logged in with a role (an arm's controller, the coordinator) says what
that role may say, but what cannot be true. Each is refused by the receiver's plausibility checks and counted by
kind in the summary, and the lockstep run comes out exactly as a clean run of the same seed."""

import math

import pytest

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmStatus, Assignment, ControllerStep, MotionGrant
from fleet.bus.session import open_session
from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.sim_time_trigger import SimTimeTrigger
from tests.fleet.test_bus_lies import COUNTED
from tests.fleet.test_run import QUICK_LINE, assert_nothing_left

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

LIAR_ARM = "arm_0"


def controller_lies(keys: Keys, arm: str, other: str) -> list[tuple[str, bytes]]:
    """From `arm`'s own login, on its own keys: a restart the launcher never did, a heartbeat in another arm's
    name, answers to states the sim never sent."""
    return [
        (keys.arm_status(arm), encode(ArmStatus(arm, 1, 1.0, "idle", None, 0.0, incarnation=77))),
        (keys.arm_status(arm), encode(ArmStatus(other, 1, 1.0, "idle", None, 0.0, incarnation=1))),
        (keys.arm_step(arm), encode(ControllerStep(arm, 10**6, 10**6 + 5))),
        (keys.arm_step(arm), encode(ControllerStep(arm, 0, 5))),
    ]


def coordinator_lies(keys: Keys, arm: str) -> list[tuple[str, bytes]]:
    """From the coordinator's login: orders from coordinators that do not hold the line (a start the launcher
    never did, none said)."""
    return [
        (keys.arm_assign(arm), encode(Assignment(arm, 1, 99, 0, 0.1, (0.3, 0.0, 0.1), (0.0,) * 3, holder=2))),
        (keys.arm_assign(arm), encode(Assignment(arm, 1, 99, 0, 0.1, (0.3, 0.0, 0.1), (0.0,) * 3, holder=0))),
        (keys.arm_assign(arm), encode(MotionGrant(arm, 1, 1, "grant", holder=5))),
    ]


def run(lie: bool) -> dict:
    options = RunOptions(scene=QUICK_LINE, duration_s=12.0, seed=5)
    poured: list[int] = []
    with Launcher(options) as launcher:
        keys, arms = Keys(options.run_id), [a.name for a in launcher.scene.arms]
        with (
            open_session(launcher.client_endpoints(LIAR_ARM)) as as_arm,
            open_session(launcher.client_endpoints("coordinator")) as as_coordinator,
        ):

            def pour() -> None:
                for key, payload in controller_lies(keys, LIAR_ARM, arms[1]):
                    as_arm.put(key, payload)
                for arm in arms:
                    for key, payload in coordinator_lies(keys, arm):
                        as_coordinator.put(key, payload)
                poured.append(launcher.supervision.last_sim_time_s)

            with SimTimeTrigger(as_arm, keys, [1.0, 3.0, 5.0, 7.0, 9.0] if lie else [], pour):
                summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert not lie or poured, "the lies went out while the line ran"
    return summary


def test_lies_from_a_rightful_sender_are_refused_counted_by_kind_and_change_nothing():
    clean, lied = run(False), run(True)
    assert lied["status"] == "ok" and math.isclose(lied["sim_seconds"], 12.0)
    assert clean["refused_messages"] == {}, "a clean run refuses nothing"
    refused = lied["refused_messages"]
    coordinator = " ".join(refused["coordinator"])
    assert "which the launcher started as _" in coordinator, refused
    assert "a heartbeat of arm__ on another arm's key" in coordinator, refused
    assert any("an answer to no state" in kind for kind in refused["sim"]), refused
    for arm in [a for a in refused if a.startswith("arm_")]:
        assert any("the launcher started as _" in kind for kind in refused[arm]), refused
    assert {a for a in refused if a.startswith("arm_")} == {"arm_0", "arm_1"}, "every arm refused the ghost orders"
    assert lied["arms_lost"] == clean["arms_lost"] == []
    strip = lambda s: {k: v for k, v in s.items() if k not in COUNTED}  # noqa: E731
    assert strip(lied) == strip(clean), "the line ran exactly as without them"
