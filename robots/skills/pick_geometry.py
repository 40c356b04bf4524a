"""Where a pick-and-place claw goes: the grasp yaw across a part's narrow side, the least tilt that reaches a spot,
IK along a path of Cartesian knots, timed joint segments."""

from __future__ import annotations

import math

import numpy as np

from robots.frames import rotation_from_wxyz, wrap_angle
from robots.phase import Phase
from robots.skills.interface import PartObservation
from robots.trajectory import JointSegment

# a Cartesian path's knot that would turn a joint further than this from the one before is not kept
MAX_KNOT_JUMP_RAD = 0.5


def rise(up: np.ndarray, up_m: float, below_m: float = 0.0) -> np.ndarray:
    """From a spot to the claw `up_m` above it: `below_m` straight up, then `up_m` along `up` (the way it rises)."""
    return np.array([up[0] * up_m, up[1] * up_m, below_m + up[2] * up_m])


class PickGeometry:
    """The claw geometry of `PickPlaceSkill`, kept apart (it reads the skill's spec, IK and joints)."""

    missed_yaws: dict[int, list[float]]  # part id -> the grasp yaws that closed on nothing (the skill's)

    def _ik(
        self, position_world: np.ndarray, yaw_world: float, q_start: np.ndarray, tilt_rad: float
    ) -> tuple[np.ndarray, bool]:
        return self.top_down.solve(position_world, yaw_world, q_start, tilt_rad, self.grasp_centre)

    def _least_tilt(
        self, spot_world: np.ndarray, yaw_world: float, up_m: float, below_m: float = 0.0, from_rad: float = 0.0
    ) -> tuple[float, np.ndarray, np.ndarray] | None:
        """The most vertical claw (straight down where it can; leaning `from_rad` at least) that reaches `up_m`
        above a spot (and `below_m` straight above it first): its tilt, its joints and the way it rises there."""

        def rise_at(tilt: float) -> np.ndarray:
            return rise(self.top_down.up_between_jaws(spot_world, yaw_world, tilt), up_m, below_m)

        found = self.top_down.least_tilt(spot_world, yaw_world, self.q_cmd, self.grasp_centre, rise_at, from_rad)
        if found is None:
            return None
        tilt, q = found
        return tilt, q, self.top_down.up_between_jaws(spot_world, yaw_world, tilt)

    def _natural_yaw(self, position_world: np.ndarray) -> float:
        return self.top_down.natural_yaw(position_world)

    def _grasp_yaw(self, part: PartObservation) -> float:
        """A yaw that closes the fingers across the part's narrow side, nearest the natural yaw (a round part: the
        natural yaw itself); for a part whose grasp closed on nothing before (a jaw on a bin's wall or on a
        neighbour), across its other side where it has one as narrow (a round or square part): the same grasp
        again would miss again."""
        natural = self._natural_yaw(part.position)
        if part.size_m is None:
            return natural
        square = abs(part.size_m[0] - part.size_m[1]) < 1e-6
        # a round part closes across at any yaw: the arm's own, least wrist roll (measured: fewer grasps miss)
        base = natural if part.round else self._across_yaw(part)
        step = math.pi / 2 if part.round or square else math.pi
        candidates = [wrap_angle(base + k * step) for k in range(int(round(2 * math.pi / step)))]
        missed = self.missed_yaws.get(part.part_id, ())
        untried = [c for c in candidates if all(abs(math.remainder(c - m, math.pi)) > 0.3 for m in missed)]
        return min(untried or candidates, key=lambda c: abs(wrap_angle(c - natural)))

    def _across_yaw(self, part: PartObservation) -> float:
        """The yaw that closes the fingers across the part's narrower side (one of its two)."""
        sx, sy, _ = part.size_m
        axes = rotation_from_wxyz(part.quaternion_wxyz)
        across = axes[:, 0] if sx <= sy else axes[:, 1]
        cx, cy, _ = self.spec.closing_axis_tool  # pointing down, the tool's closing axis lies at yaw + atan2(-cy, cx)
        if (cx, cy) == (0.0, 1.0):  # the usual claw, closing along tool y = (sin yaw, -cos yaw)
            return math.atan2(across[0], -across[1])
        return math.atan2(across[1], across[0]) - math.atan2(-cy, cx)

    def _segment(self, q_from: np.ndarray, q_to: np.ndarray, t0_s: float, speed: float) -> JointSegment:
        return JointSegment.timed(q_from, q_to, t0_s, self.km.arm_velocity_limit, speed)

    def _head_home(self, time_s: float) -> None:
        """The free move home from where the arm was last sent, at the approach's speed."""
        home = np.asarray(self.spec.home_q, float)
        self._begin_segment(self._segment(self.q_cmd, home, time_s, self.timing.approach_speed), Phase.HOME, time_s)

    def _solve_path(self, points: list[np.ndarray], yaw: float, tilt_rad: float) -> np.ndarray:
        """Joints through Cartesian tool positions at one claw tilt, each IK seeded by the one before."""
        qs, q = [], self.q_cmd
        for p in points:
            solved, ok = self._ik(p, yaw, q, tilt_rad)
            if not ok:
                self.ik_failures += 1
            if ok or np.max(np.abs(solved - q)) <= MAX_KNOT_JUMP_RAD:
                q = solved  # a failed solve's best attempt that stays near the path is kept (the tracker follows it)
            qs.append(q)  # else the knot before is held: such an attempt can be anywhere (a wrist turned half round)
        return np.asarray(qs)
