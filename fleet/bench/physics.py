"""`fleet bench physics`: raw physics steps per second of the sorting line, the ceiling of every later figure.

No controllers run: the arms hold their home pose under their drives while
parts ride the conveyor. PhysX runs on one thread (no worker threads).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from fleet.common.scene_loading import load_checked_scene
from fleet.sim.world import World


@dataclass(frozen=True)
class PhysicsBenchRow:
    arms: int
    parts_active: int
    physics_steps: int
    wall_seconds: float
    physics_hz: float = 200.0

    @property
    def steps_per_s(self) -> float:
        return self.physics_steps / self.wall_seconds

    @property
    def sim_s_per_wall_s(self) -> float:
        return self.steps_per_s / self.physics_hz


def populated_sorting_world(arms: int, warmup_s: float = 2.0) -> World:
    """The sorting line with `arms` arms and parts already on the belt."""
    world = World(load_checked_scene("sorting_line", arms=arms))
    for _ in range(4):
        world.spawn_now("mixed")
        world.step(int(0.5 / world.control_dt_s))
    world.step(int(max(0.0, warmup_s - 2.0) / world.control_dt_s) + 1)
    return world


def bench_physics(arms: int, sim_seconds: float = 4.0) -> PhysicsBenchRow:
    """Time `sim_seconds` of physics for a sorting line with `arms` arms."""
    world = populated_sorting_world(arms)
    ticks = int(sim_seconds / world.control_dt_s)
    start = time.perf_counter()
    world.step(ticks)
    wall = time.perf_counter() - start
    return PhysicsBenchRow(arms, len(world.active_parts()), ticks * world.substeps, wall, world.scene_model.physics_hz)
