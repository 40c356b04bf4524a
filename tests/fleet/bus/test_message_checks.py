"""Messages that decode but cannot be true are refused with their reason: a motion request the guard could not
check, a heartbeat, progress report or sim status with numbers no node sends."""

import math

import msgspec

from fleet.bus.message_checks import heartbeat_problem, progress_problem, request_problem, sim_status_problem
from fleet.bus.messages import ArmStatus, ControllerStep, Progress, SimStatus

Q = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5)


def step(**request) -> ControllerStep:
    return ControllerStep("arm_0", 10, 20, request_seq=3, request_q_to=Q, request_duration_s=1.0, **request)


def test_a_request_with_its_local_stage_is_believed():
    assert request_problem(step(), 6) == ""
    assert request_problem(step(request_then_q=Q + Q, request_then_after_s=(0.5, 0.9)), 6) == ""


def test_a_local_stage_that_does_not_fit_or_goes_back_in_time_is_refused():
    assert "joint values" in request_problem(step(request_then_q=Q, request_then_after_s=(0.5, 0.9)), 6)
    assert "joint values" in request_problem(step(request_then_q=Q[:5], request_then_after_s=(0.5,)), 6)
    assert "non-finite" in request_problem(step(request_then_q=(float("nan"),) + Q[1:], request_then_after_s=(0.5,)), 6)
    assert "increase" in request_problem(step(request_then_q=Q + Q, request_then_after_s=(0.9, 0.5)), 6)
    assert "increase" in request_problem(step(request_then_q=Q, request_then_after_s=(0.0,)), 6)
    assert "increase" in request_problem(step(request_then_q=Q, request_then_after_s=(1e9,)), 6)


def test_a_sim_status_or_progress_no_line_could_send_says_why():
    arms = ["arm_0", "arm_1"]
    status = SimStatus(600, 6.0, "lockstep", False, False, 1.0, (0.5, 0.1), 2.0, 0)
    assert sim_status_problem(status, arms, "lockstep", 100.0, 30.0) == ""
    lies = {
        "NaN": msgspec.structs.replace(status, speed=math.nan),
        "ends at": msgspec.structs.replace(status, tick=10**18, sim_time_s=1e16),
        "is not its sim time": msgspec.structs.replace(status, tick=900),
        "another line": msgspec.structs.replace(status, utilisation=(0.1,) * 5),
    }
    for says, lie in lies.items():
        assert says in sim_status_problem(lie, arms, "lockstep", 100.0, 30.0), says
    assert "another line" in sim_status_problem(status, arms, "realtime", 100.0, 30.0)
    assert "another line" in sim_status_problem(msgspec.structs.replace(status, arms_lost=("arm_9",)), arms)
    progress = Progress(6.0, 5, 2, 1, 1)
    assert progress_problem(progress, 2, 30.0) == ""
    assert "NaN" in progress_problem(msgspec.structs.replace(progress, min_separation_m=math.inf), 2)
    assert "negative" in progress_problem(msgspec.structs.replace(progress, parts_missed=-1), 2)
    assert "more parts done" in progress_problem(msgspec.structs.replace(progress, parts_completed=9), 2)
    assert "ends at" in progress_problem(msgspec.structs.replace(progress, sim_time_s=99.0), 2, 30.0)


def test_a_heartbeat_with_numbers_no_controller_sends_says_why():
    beat = ArmStatus("arm_0", 3, -1.0, "idle", None, 0.0)  # before its first state: sim time -1
    assert heartbeat_problem(beat) == ""
    for lie in (
        msgspec.structs.replace(beat, sim_time_s=math.nan),
        msgspec.structs.replace(beat, sim_time_s=-5.0),
        msgspec.structs.replace(beat, busy_s=math.inf),
        msgspec.structs.replace(beat, seq=-1),
        msgspec.structs.replace(beat, place_xyz=(0.0, math.nan, 0.0)),
    ):
        assert "heartbeat with NaN" in heartbeat_problem(lie), lie
