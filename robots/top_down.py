"""Top-down tool poses for one arm standing in the world: the IK every pick and place (and reach check) uses.

The claw points straight down (tool z along world -z); its yaw is either
given or the arm's natural yaw for that spot, facing away from its base, which
needs least wrist roll.
"""

from __future__ import annotations

import math

import numpy as np

from robots.frames import top_down_rotation, transform, wrap_angle
from robots.ik import IKOptions, solve_ik
from robots.kinematics import KinematicModel
from robots.spec import RobotSpec


class TopDownIK:
    """IK for top-down tool poses of an arm whose base stands at `transform_base_to_world`."""

    def __init__(self, spec: RobotSpec, transform_base_to_world: np.ndarray, model: KinematicModel | None = None, options: IKOptions = IKOptions(restarts=2)) -> None:
        self.spec = spec
        self.km = model or KinematicModel(spec)
        self.base_to_world = np.asarray(transform_base_to_world, float)
        self.world_to_base = np.linalg.inv(self.base_to_world)
        self.approach_axis_only = spec.arm_dof < 6
        self.options = options

    def natural_yaw(self, position_world: np.ndarray) -> float:
        """The tool yaw the arm reaches with least wrist roll: facing along the line from its base."""
        p_base = self.world_to_base @ np.append(np.asarray(position_world, float)[:3], 1.0)
        base_yaw = math.atan2(self.base_to_world[1, 0], self.base_to_world[0, 0])
        return wrap_angle(base_yaw + math.atan2(p_base[1], p_base[0]) + math.pi)

    def solve(self, position_world: np.ndarray, yaw_world: float | None, q_start: np.ndarray) -> tuple[np.ndarray, bool]:
        """Arm joints putting the tool at `position_world` pointing down with `yaw_world` (natural if None).

        Starts from `q_start`; if that fails, once more from the home pose with the base joint
        turned towards the spot (far turns trap a local solver).
        """
        yaw = self.natural_yaw(position_world) if yaw_world is None else yaw_world
        target = self.world_to_base @ transform(np.asarray(position_world, float), top_down_rotation(yaw))
        result = solve_ik(self.km, target, self.km.full_q(q_start), approach_axis_only=self.approach_axis_only, options=self.options)
        aimed = self.aimed_home(position_world)
        if not result.success and not np.array_equal(np.asarray(q_start, float), aimed):
            retry = solve_ik(self.km, target, self.km.full_q(aimed), approach_axis_only=self.approach_axis_only, options=self.options)
            if retry.success:
                result = retry
        return result.q[self.km.arm_q_index], result.success

    def aimed_home(self, position_world: np.ndarray) -> np.ndarray:
        """The home pose with the base joint (the first arm joint) turned towards a spot, within its limits."""
        p = self.world_to_base @ np.append(np.asarray(position_world, float)[:3], 1.0)
        q = np.asarray(self.spec.home_q, float).copy()
        j = self.km.arm_q_index[0]
        q[0] = np.clip(math.atan2(p[1], p[0]), self.km.lower[j], self.km.upper[j])
        return q

    def reachable(self, position_world: np.ndarray) -> bool:
        """True when the tool can point straight down at this spot (beyond the spec's reach: no IK needed)."""
        return self.joints_for(position_world) is not None

    def joints_for(self, position_world: np.ndarray) -> np.ndarray | None:
        """Arm joints pointing the claw straight down at this spot, or None if it is out of reach."""
        p = self.world_to_base @ np.append(np.asarray(position_world, float)[:3], 1.0)
        if math.hypot(p[0], p[1]) > self.spec.reach_m:
            return None
        q, ok = self.solve(position_world, None, self.aimed_home(position_world))
        return q if ok else None
