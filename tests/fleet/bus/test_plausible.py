"""A motion request that decodes but could not be checked by the guard is refused with its reason."""

from fleet.bus.messages import ControllerStep
from fleet.bus.plausible import request_problem

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
