"""Observations of the physics world in the skills' terms (the narrow interface of robots.skills)."""

from __future__ import annotations

import numpy as np

from fleet.sim.world import World
from robots.skills.interface import ArmObservation, PartObservation
from robots.tracker import ArmTracker


def arm_observation(world: World, arm_name: str, tracker: ArmTracker | None = None) -> ArmObservation:
    """Joint state of one arm now, split into arm and gripper joints, with its tracker's newest result."""
    arm = world.arms[arm_name]
    q, dq, n = arm.qpos(), arm.qvel(), arm.spec.arm_dof
    last = tracker.last if tracker is not None else None
    held = tracker is not None and tracker.estop
    if last is None:
        return ArmObservation(world.sim_time_s, q[:n], dq[:n], q[n:], held=held)
    return ArmObservation(
        world.sim_time_s, q[:n], dq[:n], q[n:], last.goal_id, last.status.value, last.reason, held=held
    )


def part_observations(world: World) -> dict[int, PartObservation]:
    """Every active part's pose, velocity and size, by part id."""
    out = {}
    for info in world.active_parts():
        out[info.part_id] = PartObservation(
            info.part_id,
            info.position,
            info.quaternion_wxyz,
            info.velocity,
            info.width_m,
            info.height_m,
            info.size_m,
            info.round,
        )
    return out


def base_transform(world: World, arm_name: str) -> np.ndarray:
    """4x4 transform of an arm's base in the world."""
    return world.arms[arm_name].base_pose.to_transformation_matrix()
