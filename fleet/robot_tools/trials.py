"""Seeded pick-and-place trials: one arm picks a part off the moving conveyor and drops it in a bin.

Each trial builds a fresh world from the `pick_cell` scene with its own seed
(part type, lateral offset and yaw come from the feeder's seeded stream), runs
the pick skill in process and judges success by where the part comes to rest.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from fleet.common.scene_loading import load_checked_scene
from fleet.sim.observe import arm_observation, base_transform, part_observations
from fleet.sim.tracking import TrackedArms
from fleet.sim.world import World
from robots.frames import wrap_angle
from robots.kinematics import KinematicModel
from robots.measured_reach import reach_m_of
from robots.registry import get_robot
from robots.skills.interface import PickPlaceJob
from robots.skills.pick_place import DEFAULT_DECISION_HZ, Phase, PickPlaceSkill
from scenes.schema import Arrival, Scene
from scenes.shapes import WALL_M

TRIAL_SCENE = "pick_cell"
REFERENCE_ROBOT = "openclaw"  # the trial cell is laid out for its reach; a shorter arm's is scaled in
SETTLE_S = 0.3
TIME_LIMIT_S = 15.0
FACING_MARGIN = 0.85  # of the first joint's range: the cell's yaw is kept while belt and bin are this well inside it


@dataclass(frozen=True)
class TrialResult:
    """One trial: success, the skill's last phase, and why it failed if it did."""

    seed: int
    success: bool
    phase: str
    reason: str
    sim_seconds: float


def trial_scene(robot: str, seed: int, physics_hz: float | None = None, solver_iterations: int | None = None) -> Scene:
    """The pick cell for `robot`, scaled in to a shorter arm's reach, with the trial's seed (and physics settings)."""
    spec = get_robot(robot)
    scene = load_checked_scene(TRIAL_SCENE)
    k = min(1.0, reach_m_of(spec) / reach_m_of(get_robot(REFERENCE_ROBOT)))

    def scaled(pose):  # move a placement towards the arm base at the origin
        x, y, z = pose.xyz
        return pose.model_copy(update={"xyz": (x * k, y * k, z)})

    conveyor = scene.conveyor.model_copy(
        update={"pose": scaled(scene.conveyor.pose), "width_m": scene.conveyor.width_m * max(k, 0.7)}
    )
    stations = [s.model_copy(update={"pose": scaled(s.pose)}) for s in scene.stations]
    arms = [
        a.model_copy(
            update={
                "model": robot,
                "base": a.base.model_copy(update={"yaw_deg": facing_deg(spec, a, conveyor, stations[0])}),
            }
        )
        for a in scene.arms
    ]
    # one part, spawned by the trial
    feeders = [
        f.model_copy(update={"arrival": Arrival(schedule_s=[]), "parts": graspable(spec, f.parts)})
        for f in scene.feeders
    ]
    update = {"seed": seed, "conveyor": conveyor, "stations": stations, "arms": arms, "feeders": feeders}
    if physics_hz is not None:
        update["physics_hz"] = physics_hz
    if solver_iterations is not None:
        update["solver_position_iterations"] = solver_iterations
    return scene.revalidated(**update)


def graspable(spec, parts: list) -> list:
    """The part types whose narrow side fits the robot's gripper (`grasp_width_m`): the trial feeds it those."""
    low, high = spec.grasp_width_m
    fit = [p for p in parts if low <= min(p.size_m[0], p.size_m[1]) <= high]
    return fit or list(parts)


def facing_deg(spec, arm, conveyor, bin_station) -> float:
    """The arm's base yaw: the cell's own, unless the arm's first joint cannot turn from the belt to the bin that
    way (SO-101: +-110 degrees); then turned to face between them."""
    km = KinematicModel(spec)
    j = km.arm_q_index[0]
    limit = min(abs(km.lower[j]), abs(km.upper[j]))
    x0, y0 = arm.base.xyz[0], arm.base.xyz[1]
    cx, cy = conveyor.pose.xyz[0], conveyor.pose.xyz[1]
    along = (math.cos(conveyor.pose.yaw_rad), math.sin(conveyor.pose.yaw_rad))
    s_m = (x0 - cx) * along[0] + (y0 - cy) * along[1]  # the belt's nearest point to the arm
    pick = (cx + along[0] * s_m, cy + along[1] * s_m)
    bearings = [math.atan2(y - y0, x - x0) for x, y in (pick, bin_station.pose.xyz[:2])]
    relative = [wrap_angle(b - arm.base.yaw_rad) for b in bearings]
    if max(abs(r) for r in relative) <= FACING_MARGIN * limit:
        return arm.base.yaw_deg
    spread = wrap_angle(bearings[1] - bearings[0])
    return math.degrees(wrap_angle(bearings[0] + spread / 2))


def part_in_bin(world: World, part_id: int, bin_name: str) -> bool:
    """True when the part rests inside the bin's walls, on its floor."""
    station = world.scene_model.station(bin_name)
    info = world.part_info(part_id)
    sx, sy, sz = station.size_m
    dx, dy = info.position[0] - station.pose.xyz[0], info.position[1] - station.pose.xyz[1]
    inside = abs(dx) < sx / 2 - WALL_M and abs(dy) < sy / 2 - WALL_M
    low = info.position[2] < station.pose.xyz[2] + sz
    still = float(np.linalg.norm(info.velocity)) < 0.05
    return bool(inside and low and still)


def run_trial(
    robot: str, seed: int, physics_hz: float | None = None, solver_iterations: int | None = None
) -> TrialResult:
    """One seeded pick from the conveyor into the bin: the skill decides at a controller's default rate, the tracker
    follows."""
    world = World(trial_scene(robot, seed, physics_hz, solver_iterations))
    arm_name, bin_name = "arm_0", "bin_0"
    spec = world.arms[arm_name].spec
    period = max(1, round(world.scene_model.control_hz / DEFAULT_DECISION_HZ))
    skill = PickPlaceSkill(spec, base_transform(world, arm_name), decision_period_s=period * world.control_dt_s)
    tracked = TrackedArms(world)
    part_id = world.spawn_now("trial_parts")
    world.step(int(SETTLE_S / world.control_dt_s))
    station = world.scene_model.station(bin_name)
    task = PickPlaceJob(
        part_id=part_id,
        surface_z_m=world.scene_model.conveyor.pose.xyz[2],
        place_xyz=(station.pose.xyz[0], station.pose.xyz[1], station.pose.xyz[2] + WALL_M),
        surface_velocity=tuple(world.belt_velocity()),
    )
    parts = part_observations(world)
    skill.start(task, arm_observation(world, arm_name), parts[part_id])
    limit_ticks = int(TIME_LIMIT_S / world.control_dt_s)
    for k in range(limit_ticks):
        if k % period == 0:
            if not skill.active:
                break
            tracked.decide(arm_name, skill, part_observations(world))
        tracked.apply()
        world.step()
        tracked.update()
    world.step(int(0.5 / world.control_dt_s))
    success = skill.phase == Phase.DONE and part_in_bin(world, part_id, bin_name)
    reason = skill.failure_reason
    if not success and not reason:
        reason = "timed out" if skill.active else "part did not come to rest in the bin"
    return TrialResult(seed, success, skill.phase.value, reason, world.sim_time_s)


def run_trials(
    robot: str,
    trials: int,
    seed: int,
    on_result: Callable[[TrialResult], None] | None = None,
    physics_hz: float | None = None,
    solver_iterations: int | None = None,
) -> list[TrialResult]:
    """`trials` seeded trials (seeds seed, seed+1, ...); `on_result` sees each as it finishes."""
    get_robot(robot)  # unknown names and missing extras fail before any work
    results = []
    for i in range(trials):
        result = run_trial(robot, seed + i, physics_hz, solver_iterations)
        results.append(result)
        if on_result is not None:
            on_result(result)
    return results
