"""The narrow interface between a skill and the world: observations in, commands out.

The same dataclasses travel over the bus later, so a skill runs unchanged in
process or behind Zenoh. World frame, metres, seconds, quaternions wxyz.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ArmObservation:
    """What an arm reports at each decision: its joints and gripper joints at a sim time, the newest
    trajectory result of its tracker (goal id, status, reason; 0 and "" before any) and, over a bus that
    can lose messages, the goal driving it (so the skill sees which of its goals arrived)."""

    time_s: float
    q: np.ndarray
    dq: np.ndarray
    gripper_q: np.ndarray
    result_goal_id: int = 0
    result_status: str = ""
    result_reason: str = ""
    goal_id: int | None = None  # the trajectory goal driving the arm (0: none); None where goals cannot be lost
    held: bool = False  # the arm is held (e-stop): goals are refused until it is released


@dataclass(frozen=True)
class PartObservation:
    """One part as the line sees it: pose, velocity and its size across and up; `round`: round about its up axis (a
    cylinder), so a grasp at any yaw closes across it."""

    part_id: int
    position: np.ndarray
    quaternion_wxyz: np.ndarray
    velocity: np.ndarray
    width_m: float
    height_m: float
    size_m: tuple[float, float, float] | None = None
    round: bool = False


@dataclass(frozen=True)
class PickPlaceJob:
    """Pick part `part_id` from a surface at `surface_z_m` and set it down with its bottom at `place_xyz`."""

    part_id: int
    surface_z_m: float
    place_xyz: tuple[float, float, float]
    surface_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class MotionRequest:
    """A joint-space move the skill wants to make: from `q_from` to `q_to` in `duration_s`, asked at `asked_at_s`;
    then the local stage it will follow without asking (`then_q`, reached `then_after_s` after the move's end)."""

    seq: int
    q_from: tuple[float, ...]
    q_to: tuple[float, ...]
    duration_s: float
    asked_at_s: float
    then_q: tuple[tuple[float, ...], ...] = ()
    then_after_s: tuple[float, ...] = ()
