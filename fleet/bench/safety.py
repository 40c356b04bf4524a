"""`fleet bench safety`: what the plant's safety layer costs per trajectory goal, against the tracker's own planning.

Goals to random in-limit poses near home go to every arm of the sorting line in turn while the others are moving
along goals accepted before; each goal's check (swept path against every neighbour's committed path, python-fcl,
and the joints' speeds) is timed, and so is the tracker's splining of the same goal, the work a goal costs anyway.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from fleet.common.scene_loading import load_checked_scene
from fleet.sim.tracking import TrackedArms
from fleet.sim.world import World
from robots.joint_trajectory import rest_to_rest


@dataclass(frozen=True)
class SafetyBenchRow:
    arms: int
    goals: int
    refused: int
    check_p50_ms: float
    check_p99_ms: float
    plan_p50_ms: float

    @property
    def check_over_plan(self) -> float:
        return self.check_p50_ms / self.plan_p50_ms


def bench_safety(arms: int, goals: int = 400, seed: int = 0, reach_rad: float = 0.6) -> SafetyBenchRow:
    """`goals` goals over the arms of a sorting line of `arms`, a few ticks apart."""
    world = World(load_checked_scene("sorting_line", arms=arms))
    tracked = TrackedArms(world)
    rng = np.random.default_rng(seed)
    names = list(tracked.trackers)
    checks, plans, refused = [], [], 0
    for k in range(goals):
        arm = names[k % len(names)]
        tracker = tracked.trackers[arm]
        home = np.asarray(world.arms[arm].spec.home_q, float)
        q = np.clip(home + rng.uniform(-reach_rad, reach_rad, home.size), tracker.lower, tracker.upper)
        goal = rest_to_rest(k + 1, tracker.joint_names, q, float(rng.uniform(1.0, 2.0)), None)
        t0 = time.perf_counter()
        planned = tracker.plan(goal, world.sim_time_s)
        t1 = time.perf_counter()
        why = tracked.safety.refusal(arm, planned.spline, tracked.trackers, tracked.claws())
        t2 = time.perf_counter()
        plans.append(t1 - t0)
        checks.append(t2 - t1)
        if why is None:
            tracker.commit(planned, world.sim_time_s)
        else:
            refused += 1
        for _ in range(5):
            tracked.apply()
            world.step()
            tracked.update()
    ms = np.array(checks) * 1e3
    return SafetyBenchRow(
        arms, goals, refused, float(np.median(ms)), float(np.percentile(ms, 99)), float(np.median(plans) * 1e3)
    )
