"""Where a pick-and-place claw goes: the grasp yaw across a part's narrow side, the least tilt that reaches a spot,
IK along a path of Cartesian knots, timed joint segments (`ClawGeometry`, one per skill)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from robots.frames import rotation_from_wxyz, wrap_angle
from robots.kinematics import KinematicModel
from robots.skills.interface import PartObservation
from robots.spec import RobotSpec
from robots.top_down import TopDownIK
from robots.trajectory import JointSegment

# a Cartesian path's knot that would turn a joint further than this from the one before is not kept
MAX_KNOT_JUMP_RAD = 0.5


def rise(up: np.ndarray, up_m: float, below_m: float = 0.0) -> np.ndarray:
    """From a spot to the claw `up_m` above it: `below_m` straight up, then `up_m` along `up` (the way it rises)."""
    return np.array([up[0] * up_m, up[1] * up_m, below_m + up[2] * up_m])


class ClawGeometry:
    """Where one robot's claw goes for a pick or a place, through its `top_down` IK and its model `km`. It keeps no
    state of a task: the skill hands it the joints to start from, where the part sits between the jaws
    (`grasp_centre`, tool frame) and the yaws that missed."""

    def __init__(self, spec: RobotSpec, top_down: TopDownIK, km: KinematicModel) -> None:
        self.spec, self.top_down, self.km = spec, top_down, km

    def ik(
        self,
        position_world: np.ndarray,
        yaw_world: float,
        q_start: np.ndarray,
        tilt_rad: float,
        grasp_centre: tuple[float, float, float],
    ) -> tuple[np.ndarray, bool]:
        return self.top_down.solve(position_world, yaw_world, q_start, tilt_rad, grasp_centre)

    def least_tilt(
        self,
        spot_world: np.ndarray,
        yaw_world: float,
        up_m: float,
        q_seed: np.ndarray,
        grasp_centre: tuple[float, float, float],
        below_m: float = 0.0,
        from_rad: float = 0.0,
    ) -> tuple[float, np.ndarray, np.ndarray] | None:
        """The most vertical claw (straight down where it can; leaning `from_rad` at least) that reaches `up_m`
        above a spot (and `below_m` straight above it first): its tilt, its joints and the way it rises there."""

        def rise_at(tilt: float) -> np.ndarray:
            return rise(self.top_down.up_between_jaws(spot_world, yaw_world, tilt), up_m, below_m)

        found = self.top_down.least_tilt(spot_world, yaw_world, q_seed, grasp_centre, rise_at, from_rad)
        if found is None:
            return None
        tilt, q = found
        return tilt, q, self.top_down.up_between_jaws(spot_world, yaw_world, tilt)

    def natural_yaw(self, position_world: np.ndarray) -> float:
        return self.top_down.natural_yaw(position_world)

    def grasp_yaw(self, part: PartObservation, missed: Sequence[float] = ()) -> float:
        """A yaw that closes the fingers across the part's narrow side, nearest the natural yaw (a round part: the
        natural yaw itself); for a part whose grasp closed on nothing at the yaws `missed` (a jaw on a bin's wall
        or on a neighbour), across its other side where it has one as narrow (a round or square part): the same
        grasp again would miss again."""
        natural = self.natural_yaw(part.position)
        if part.size_m is None:
            return natural
        square = abs(part.size_m[0] - part.size_m[1]) < 1e-6
        # a round part closes across at any yaw: the arm's own, least wrist roll (measured: fewer grasps miss)
        base = natural if part.round else self.across_yaw(part)
        step = math.pi / 2 if part.round or square else math.pi
        candidates = [wrap_angle(base + k * step) for k in range(int(round(2 * math.pi / step)))]
        untried = [c for c in candidates if all(abs(math.remainder(c - m, math.pi)) > 0.3 for m in missed)]
        return min(untried or candidates, key=lambda c: abs(wrap_angle(c - natural)))

    def across_yaw(self, part: PartObservation) -> float:
        """The yaw that closes the fingers across the part's narrower side (one of its two)."""
        sx, sy, _ = part.size_m
        axes = rotation_from_wxyz(part.quaternion_wxyz)
        across = axes[:, 0] if sx <= sy else axes[:, 1]
        cx, cy, _ = self.spec.closing_axis_tool  # pointing down, the tool's closing axis lies at yaw + atan2(-cy, cx)
        if (cx, cy) == (0.0, 1.0):  # the usual claw, closing along tool y = (sin yaw, -cos yaw)
            return math.atan2(across[0], -across[1])
        return math.atan2(across[1], across[0]) - math.atan2(-cy, cx)

    def segment(self, q_from: np.ndarray, q_to: np.ndarray, t0_s: float, speed: float) -> JointSegment:
        """A rest-to-rest joint move at `speed` (a fraction of each joint's velocity limit)."""
        return JointSegment.timed(q_from, q_to, t0_s, self.km.arm_velocity_limit, speed)

    def solve_path(
        self,
        points: list[np.ndarray],
        yaw: float,
        tilt_rad: float,
        q_seed: np.ndarray,
        grasp_centre: tuple[float, float, float],
    ) -> tuple[np.ndarray, int]:
        """Joints through Cartesian tool positions at one claw tilt, each IK seeded by the one before (the first by
        `q_seed`), and how many of the solves failed."""
        qs, q, failed = [], q_seed, 0
        for p in points:
            solved, ok = self.ik(p, yaw, q, tilt_rad, grasp_centre)
            if not ok:
                failed += 1
            if ok or np.max(np.abs(solved - q)) <= MAX_KNOT_JUMP_RAD:
                q = solved  # a failed solve's best attempt that stays near the path is kept (the tracker follows it)
            qs.append(q)  # else the knot before is held: such an attempt can be anywhere (a wrist turned half round)
        return np.asarray(qs), failed
