"""Top-down tool poses for one arm standing in the world: the IK every pick and place (and reach check) uses.

The claw points straight down (tool z along world -z); its yaw is either
given or the arm's natural yaw for that spot, facing away from its base, which
needs least wrist roll. Where an arm cannot point straight down (a short arm
over a high belt), it approaches tilted: the approach axis leans outwards,
away from its base, by the least angle it reaches, up to the robot's
`max_approach_tilt_deg`, in `TILT_STEP_DEG` steps. The claw's closing axis
stays horizontal, across the part.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from robots.built_once import BuiltOnce
from robots.chain_span import ChainSpan
from robots.frames import top_down_rotation, transform, wrap_angle
from robots.ik import IKOptions, IKResult, solve_ik
from robots.kinematics import KinematicModel
from robots.spec import RobotSpec

TILT_STEP_DEG = 5.0
REACH_TILT_STEP_DEG = 15.0  # a reach check needs only to know that some tilt reaches: it tries every third
YAW_TOLERANCE_RAD = 0.05  # a short arm's claw turned to within this of the asked yaw counts as turned
TURNED_TOLERANCE_M = 0.001
TURNED_TOLERANCE_RAD = 0.1


def tilted_rotation(yaw_rad: float, tilt_rad: float, outward_xy: np.ndarray) -> np.ndarray:
    """The top-down tool orientation with `yaw_rad`, its approach axis leaned by `tilt_rad` towards `outward_xy`."""
    down = top_down_rotation(yaw_rad)
    if tilt_rad == 0.0:
        return down
    u = np.array([outward_xy[0], outward_xy[1], 0.0])
    tangent = np.cross(u / np.linalg.norm(u), [0.0, 0.0, 1.0])  # turning -z about it leans the axis towards u
    return pin.AngleAxis(tilt_rad, tangent).toRotationMatrix() @ down


class TopDownIK(BuiltOnce):
    """IK for top-down tool poses of an arm whose base stands at `transform_base_to_world` (pickled as what it was
    built from: `robots.built_once`)."""

    def __init__(
        self,
        spec: RobotSpec,
        transform_base_to_world: np.ndarray,
        model: KinematicModel | None = None,
        options: IKOptions = IKOptions(restarts=2),
        reach_m: float = math.inf,
    ) -> None:
        self.spec = spec
        self.reach_m = reach_m  # spots farther from the base are "no" without IK (the coordinator's: the measured)
        self.km = model or KinematicModel(spec)
        self.base_to_world = np.asarray(transform_base_to_world, float)
        self.world_to_base = np.linalg.inv(self.base_to_world)
        self.approach_axis_only = spec.arm_dof < 6
        self.options = options
        # with its roll joint set, a short arm meets position and axis only nearly (the roll axis misses the tool point)
        # `solve(quick=True)`: one attempt from the start given
        self._quick_options = dataclasses.replace(options, restarts=0)
        self._turn_options = dataclasses.replace(
            options, tolerance_m=TURNED_TOLERANCE_M, tolerance_rad=TURNED_TOLERANCE_RAD, restarts=0, rotation_weight=0.1
        )
        # where the arm turns, and which way (SO-101: about -z)
        pan_origin_base, self.pan_sign = self.km.first_joint_axis()
        self.pan_origin_world = (self.base_to_world @ np.append(pan_origin_base, 1.0))[:3]
        self.yaw_offset = self._home_yaw_offset()
        step = math.radians(TILT_STEP_DEG)
        self.tilts_rad = [0.0] + [
            step * k for k in range(1, int(spec.max_approach_tilt_deg / TILT_STEP_DEG + 1e-9) + 1)
        ]
        every = round(REACH_TILT_STEP_DEG / TILT_STEP_DEG)  # reach checks try fewer tilts, each one the skill tries too
        self.reach_tilts_rad = self.tilts_rad[::every] + (
            [self.tilts_rad[-1]] if (len(self.tilts_rad) - 1) % every else []
        )
        self.chain_span = ChainSpan.of(self.km)  # where straight down cannot reach, told without IK
        self._shoulder_world = (
            (self.base_to_world @ np.append(self.chain_span.shoulder_base, 1.0))[:3] if self.chain_span else None
        )
        args = (spec, self.base_to_world.copy(), self.km, options, reach_m)
        self._built_from(args, self.built_key(*args))

    @classmethod
    def built_key(
        cls, spec: RobotSpec, base_to_world: np.ndarray, _model: object, options: IKOptions, reach_m: float = math.inf
    ) -> tuple:
        """The robot by id (the instance holds it), where it stands, the options and cut; its model is the robot's."""
        return (id(spec), np.asarray(base_to_world, float).tobytes(), options, reach_m)

    def outward(self, position_world: np.ndarray) -> np.ndarray:
        """Horizontal direction from the arm's turning axis to the spot (world frame): where a tilted approach leans,
        in the plane the arm moves in."""
        d = np.asarray(position_world, float)[:2] - self.pan_origin_world[:2]
        n = float(np.hypot(d[0], d[1]))
        return d / n if n > 1e-9 else np.array([1.0, 0.0])

    def natural_yaw(self, position_world: np.ndarray) -> float:
        """The tool yaw the arm reaches with least wrist roll: facing along the line from its base."""
        p_base = self.world_to_base @ np.append(np.asarray(position_world, float)[:3], 1.0)
        base_yaw = math.atan2(self.base_to_world[1, 0], self.base_to_world[0, 0])
        return wrap_angle(base_yaw + self._bearing(p_base) + self.yaw_offset)

    def _home_yaw_offset(self) -> float:
        """How the tool's x axis turns from the spot's bearing at the home pose, to the nearest quarter turn: the
        natural yaw keeps it so (the OpenClaw's x points back at its base, a Panda hand's away), so the wrist need
        not turn half round to point down."""
        home = self.km.frame_pose(self.km.full_q(np.asarray(self.spec.home_q, float)))
        heading = math.atan2(home[1, 0], home[0, 0])
        quarter = round(wrap_angle(heading - self._bearing(home[:3, 3])) / (math.pi / 2)) % 4
        return (0.0, math.pi / 2, math.pi, -math.pi / 2)[quarter]

    def _bearing(self, p_base: np.ndarray) -> float:
        """The spot's direction seen from the arm's turning axis, in the base frame (radians about +z)."""
        o = self.km.first_joint_axis()[0]
        return math.atan2(p_base[1] - o[1], p_base[0] - o[0])

    def solve(
        self,
        position_world: np.ndarray,
        yaw_world: float | None,
        q_start: np.ndarray,
        tilt_rad: float = 0.0,
        centre_tool: tuple[float, float, float] = (0.0, 0.0, 0.0),
        quick: bool = False,
    ) -> tuple[np.ndarray, bool]:
        """Arm joints putting the tool at `position_world` pointing down with `yaw_world` (natural if None), its
        approach axis leaned outwards by `tilt_rad`; with `centre_tool` (a point in the tool frame, e.g. between
        one-sided jaws) that point goes to `position_world` instead of the tool frame's origin.

        Starts from `q_start`; if that fails, once more from the home pose with the base joint
        turned towards the spot (far turns trap a local solver); `quick`: one attempt from `q_start` only (no
        restarts, no retry: a start next to the answer converges or the spot needs the full search). An arm of fewer
        than six joints
        matches the approach axis first, then the yaw too where it can (its closing axis across the part).
        """
        yaw = self.natural_yaw(position_world) if yaw_world is None else yaw_world
        tool_at = np.asarray(position_world, float)[:3]
        rotation = tilted_rotation(yaw, tilt_rad, self.outward(tool_at))
        if any(centre_tool):  # the tool stands off the spot; a tilt leans in the arm's plane through the tool
            for _ in range(1 if tilt_rad == 0.0 else 3):
                tool_at = np.asarray(position_world, float)[:3] - rotation @ np.asarray(centre_tool, float)
                rotation = tilted_rotation(yaw, tilt_rad, self.outward(tool_at))
        target = self.world_to_base @ transform(tool_at, rotation)
        options = self._quick_options if quick else self.options
        result = solve_ik(
            self.km, target, self.km.full_q(q_start), approach_axis_only=self.approach_axis_only, options=options
        )
        aimed = self.aimed_home(position_world)
        if not quick and not result.success and not np.array_equal(np.asarray(q_start, float), aimed):
            retry = solve_ik(
                self.km, target, self.km.full_q(aimed), approach_axis_only=self.approach_axis_only, options=self.options
            )
            if retry.success:
                result = retry
        if result.success and self.approach_axis_only and self.spec.match_yaw:
            result = self._turned_to(target, result)
        return result.q[self.km.arm_q_index], result.success

    def _turned_to(self, target: np.ndarray, reached: IKResult) -> IKResult:
        """A short arm's claw turned about its approach axis to the target's yaw: its last joint (the wrist roll)
        set to the turn, the others solved again for position and axis (the roll axis need not pass through the
        tool point, so turning it moves the tool). The axis-only answer if that fails."""
        km, last = self.km, self.km.arm_q_index[-1]
        have = km.frame_pose(reached.q)[:3, :3]
        want = target[:3, :3]
        axis = have @ np.asarray(self.spec.approach_axis_tool, float)
        x_have, x_want = have[:, 0], want[:, 0]
        turn = math.atan2(float(np.dot(np.cross(x_have, x_want), axis)), float(np.dot(x_have, x_want)))
        for sign in (1.0, -1.0):  # which way the roll joint turns the claw about its approach axis
            q = reached.q.copy()
            q[last] = wrap_angle(q[last] + sign * turn)
            if not km.lower[last] <= q[last] <= km.upper[last]:
                continue
            again = solve_ik(
                km, target, q, approach_axis_only=True, options=self._turn_options, locked=(self.spec.arm_dof - 1,)
            )
            turned = km.frame_pose(again.q)[:3, :3][:, 0]
            if again.success and float(np.dot(turned, x_want)) > math.cos(YAW_TOLERANCE_RAD):
                return again
        return reached

    def up_between_jaws(self, position_world: np.ndarray, yaw_world: float, tilt_rad: float) -> np.ndarray:
        """The way up that keeps the jaws where they are across the part: straight up, less its part along the
        closing axis (a tilted claw turned across a part would otherwise slide a jaw onto the part's top)."""
        closing = tilted_rotation(yaw_world, tilt_rad, self.outward(position_world)) @ np.asarray(
            self.spec.closing_axis_tool, float
        )
        up = np.array([0.0, 0.0, 1.0]) - closing[2] * closing
        return up / np.linalg.norm(up)

    def least_tilt(
        self,
        position_world: np.ndarray,
        yaw_world: float | None,
        q_start: np.ndarray,
        centre_tool: tuple[float, float, float] = (0.0, 0.0, 0.0),
        offset: Callable[[float], np.ndarray] | None = None,
        from_rad: float = 0.0,
        tilts_rad: list[float] | None = None,
    ) -> tuple[float, np.ndarray] | None:
        """The most vertical approach (leaning `from_rad` at least) that reaches the position (moved by
        `offset(tilt)` if given: a hover above the part along the way it rises), and its joints; None if no
        allowed tilt does."""
        for tilt in [t for t in (self.tilts_rad if tilts_rad is None else tilts_rad) if t >= from_rad - 1e-9]:
            point = position_world if offset is None else position_world + offset(tilt)
            q, ok = self.solve(point, yaw_world, q_start, tilt, centre_tool)
            if ok:
                return tilt, q
        return None

    def aimed_home(self, position_world: np.ndarray) -> np.ndarray:
        """The home pose with the base joint (the first arm joint) turned towards a spot, within its limits."""
        p = self.world_to_base @ np.append(np.asarray(position_world, float)[:3], 1.0)
        q = np.asarray(self.spec.home_q, float).copy()
        j = self.km.arm_q_index[0]
        q[0] = np.clip(self.pan_sign * self._bearing(p), self.km.lower[j], self.km.upper[j])
        return q

    def reachable(self, position_world: np.ndarray) -> bool:
        """True when the tool can point straight down at this spot (past `reach_m`: no IK needed)."""
        return self.joints_for(position_world) is not None

    def joints_for(self, position_world: np.ndarray, within_m: float | None = None) -> np.ndarray | None:
        """Arm joints pointing the claw at this spot as the skill would (straight down, else the least tilt the
        robot allows), or None if it is out of reach; spots farther from the base than `within_m` (`reach_m` unless
        given) are out of reach without IK."""
        found = self.reach_pose(position_world, within_m)
        return None if found is None else found[1]

    def reach_pose(self, position_world: np.ndarray, within_m: float | None = None) -> tuple[float, np.ndarray] | None:
        """`joints_for`'s answer with the tilt it leans by: (tilt_rad, arm joints), or None. Straight down is not
        searched where the chain cannot stretch that far (`ChainSpan`: a certain no, the search's own answer)."""
        if self.beyond(position_world, within_m):
            return None
        spot, centre = np.asarray(position_world, float)[:3], self._middling_centre()
        tilts = self.reach_tilts_rad
        if self.chain_span is not None and self.chain_span.beyond_straight_down(spot, centre, self._shoulder_world):
            tilts = [t for t in tilts if t != 0.0]
            if not tilts:
                return None
        return self.least_tilt(spot, None, self.aimed_home(position_world), centre, tilts_rad=tilts)

    def joints_near(self, position_world: np.ndarray, tilt_rad: float, q_near: np.ndarray) -> np.ndarray | None:
        """The joints reaching a spot next to one `reach_pose` answered (`tilt_rad`, `q_near`): one solve at that
        tilt from those joints, no restarts; None if it does not converge (then only the full search can tell).
        An answer is a real reach, though maybe not at the least tilt; a few ms where the search takes 100+."""
        if self.beyond(position_world):
            return None
        q, ok = self.solve(
            np.asarray(position_world, float)[:3], None, q_near, tilt_rad, self._middling_centre(), quick=True
        )
        return q if ok else None

    def beyond(self, position_world: np.ndarray, within_m: float | None = None) -> bool:
        """Whether a spot is farther from the base, horizontally, than `within_m` (`reach_m` unless given)."""
        p = self.world_to_base @ np.append(np.asarray(position_world, float)[:3], 1.0)
        return math.hypot(p[0], p[1]) > (self.reach_m if within_m is None else within_m)

    def _middling_centre(self) -> tuple[float, float, float]:
        return self.spec.grasp_centre_tool(sum(self.spec.grasp_width_m) / 2)  # a part of middling width
