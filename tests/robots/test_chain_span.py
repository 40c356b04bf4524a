"""The chain's span tells "out of reach" without IK only where the IK search itself answers no: spots around each
registered robot, every one the span rules out searched straight down as before, and none of them reached."""

import numpy as np
import pytest

from coordinator.allocation import REACH_IK
from robots.frames import yaw_transform
from robots.measured_reach import reach_m_of
from robots.registry import get_robot
from robots.top_down import TopDownIK


def spots(robot: str, n: int, seed: int) -> np.ndarray:
    """Spots about an arm at the origin, from inside its reach to well past it, floor to above the shoulder."""
    rng = np.random.default_rng(seed)
    reach = reach_m_of(get_robot(robot))
    r, bearing = rng.uniform(0.5 * reach, 1.25 * reach, n), rng.uniform(-np.pi, np.pi, n)
    return np.column_stack([r * np.cos(bearing), r * np.sin(bearing), rng.uniform(-0.05, 0.45, n)])


@pytest.mark.parametrize("robot", ["openclaw", "so101", "panda"])
def test_every_spot_the_span_rules_out_is_one_the_search_cannot_reach_straight_down(robot):
    # searched with the reach checks' own options (restarts), at a turned base
    ik = TopDownIK(get_robot(robot), yaw_transform((0.3, -0.2, 0.0), 0.7), options=REACH_IK)
    assert ik.chain_span is not None, "every registered arm is a serial chain of revolute joints"
    centre, ruled_out = ik._middling_centre(), 0
    for spot in spots(robot, 120, seed=1) + [0.3, -0.2, 0.0]:
        if ik.chain_span.beyond_straight_down(spot, centre, ik._shoulder_world):
            ruled_out += 1
            _, ok = ik.solve(spot, None, ik.aimed_home(spot), 0.0, centre)
            assert not ok, f"{robot}: {spot} is reached straight down, yet the span ruled it out"
    assert ruled_out >= 10, f"{robot}: the span ruled out only {ruled_out} of 120 spots"
