"""The plant's safety layer places every claw as it is: for two arms of every pair of robot models standing within
reach of each other, random goals near the other arm, with each claw open, closed or moving, run in the physics:
whatever the plant accepts brings the arms into contact not once."""

from __future__ import annotations

import fcl
import numpy as np
import pytest

from coordinator.claw_sweep import ClawSpan
from coordinator.geometry import ArmGeometry, separation_m
from coordinator.guard import CollisionGuard
from fleet.sim.tracking import TrackedArms
from fleet.sim.world import World
from robots.joint_trajectory import GoalStatus, GripperGoal, rest_to_rest
from robots.registry import is_available
from scenes import load_scene
from scenes.schema import Pose2D as Pose

# model pairs and the distance between their bases: each reaches into the other's space
PAIRS = [
    ("openclaw", "openclaw", 0.45),
    ("openclaw", "so101", 0.42),
    ("openclaw", "panda", 0.6),
    ("so101", "panda", 0.55),
    ("panda", "panda", 0.7),
    ("so101", "so101", 0.3),
]


def two_arm_cell(model_a: str, model_b: str, apart_m: float):
    """mixed_fleet with only two arms, `apart_m` apart facing the same way, on a bare floor."""
    scene = load_scene("mixed_fleet")
    arm_a, arm_b = scene.arms[0], scene.arms[1]
    arms = [
        arm_a.model_copy(update={"model": model_a, "base": Pose(xyz=(0.0, -0.35, 0.0), yaw_deg=90.0)}),
        arm_b.model_copy(update={"model": model_b, "base": Pose(xyz=(apart_m, -0.35, 0.0), yaw_deg=90.0)}),
    ]
    return scene.model_copy(update={"arms": arms, "feeders": [], "stations": [], "conveyor": None})


FLOOR = fcl.CollisionObject(fcl.Box(20.0, 20.0, 1.0), fcl.Transform(np.array([0.0, 0.0, -0.5])))


def _floor_gaps(geometry: ArmGeometry) -> np.ndarray:
    """How far each of the arm's shapes (as placed) stands above the floor."""
    out = []
    for i in range(len(geometry.shapes)):
        result = fcl.DistanceResult()
        out.append(fcl.distance(geometry.object(i), FLOOR, fcl.DistanceRequest(), result))
    return np.array(out)


def _near(tracked: TrackedArms, arm: str, other: str, rng: np.random.Generator) -> np.ndarray | None:
    """Joints for `arm` within its limits that put it near `other` as `other` stands (within 3 cm of it, or a
    little into it, claws anywhere), clear of the floor (a reachable pose: an arm pressed into the floor leaves its
    path, which no goal check can foresee)."""
    safety, tracker = tracked.safety, tracked.trackers[arm]
    me, them = safety.geometries[arm], safety.geometries[other]
    me.place(tracker.hold_q)
    at_home = _floor_gaps(me)
    clear = np.minimum(at_home, 0.02) - 1e-6  # 2 cm above it, or no lower than at home (the base's shapes)
    them.place(tracked.trackers[other].hold_q)
    for _ in range(20000):
        q = rng.uniform(tracker.lower, tracker.upper)
        me.place(q)
        if -0.02 < separation_m(me, them, below_m=0.03) < 0.03 and (_floor_gaps(me) >= clear).all():
            return q
    return None  # `other` stands where `arm` cannot come near it


def _within_speed(tracked: TrackedArms, arm: str, q: np.ndarray, rng: np.random.Generator) -> float:
    """A duration for a rest-to-rest move of `arm` to `q` that keeps every joint within its velocity limit (a
    quintic peaks at 1.875 times its mean speed), so that the goal is judged on where it goes."""
    travel = np.abs(q - tracked.trackers[arm].hold_q) / tracked.safety.velocity_limits[arm]
    return max(0.5, 2.0 * float(travel.max())) * float(rng.uniform(1.0, 1.5))


def _claw_goal(goal_id: int, rng: np.random.Generator, start_s: float | None = None) -> GripperGoal:
    return GripperGoal(goal_id, float(rng.choice([0.0, 1.0, rng.uniform(0.0, 1.0)])), start_time_s=start_s)


def _run(world: World, tracked: TrackedArms, seconds: float) -> int:
    """Step the world; the number of ticks with a contact between two arms."""
    ticks = 0
    for _ in range(int(round(seconds / world.control_dt_s))):
        tracked.apply()
        world.step()
        tracked.update()
        ticks += bool(world.inter_arm_contacts())
    return ticks


@pytest.mark.slow
@pytest.mark.parametrize(("model_a", "model_b", "apart_m"), PAIRS, ids=[f"{a}-{b}" for a, b, _ in PAIRS])
def test_no_goal_the_plant_accepts_brings_two_arms_into_contact_whatever_their_claws_do(model_a, model_b, apart_m):
    if not (is_available(model_a) and is_available(model_b)):
        pytest.skip("needs the models extra")
    world = World(two_arm_cell(model_a, model_b, apart_m))
    tracked = TrackedArms(world)
    rng = np.random.default_rng(sum(map(ord, model_a + model_b)))
    accepted = refused = contact_ticks = 0
    for trial in range(6):
        arm, other = ("arm_0", "arm_1") if trial % 2 == 0 else ("arm_1", "arm_0")
        for name in (arm, other):  # each claw open, closed or half way, and moving when the goal starts
            tracked.submit(name, _claw_goal(1000 + trial, rng))
        q = _near(tracked, arm, other, rng)
        if q is None:  # the other arm stands out of this one's way: it goes home (a goal like any other)
            arm, other, q = other, arm, np.asarray(world.arms[other].spec.home_q, float)
        duration = _within_speed(tracked, arm, q, rng)
        goal = rest_to_rest(trial + 1, tuple(world.arms[arm].spec.arm_joints), q, duration, None)
        results = tracked.submit(arm, goal)
        if any(r.status == GoalStatus.REJECTED for r in results):
            refused += 1
        else:
            accepted += 1
        contact_ticks += _run(world, tracked, duration * float(rng.uniform(0.2, 0.8)))
        for name in (arm, other):  # and a claw goal on the way
            tracked.submit(name, _claw_goal(2000 + trial, rng))
        contact_ticks += _run(world, tracked, duration + 0.4)
    assert accepted >= 1, "some goals near the other arm ran in the physics"
    assert contact_ticks == 0, f"{contact_ticks} contact ticks; {accepted} goals accepted, {refused} refused"


def test_a_goal_that_clears_a_closed_claw_but_not_an_open_one_is_refused_and_touches_nothing():
    """The issue's case: on the sorting line, arm_1 stands at home with its claw open; goals for arm_0 to poses
    that a closed claw would keep 11-16 mm from it. The plant refuses those its open fingers would come too close
    to, and what it accepts runs without a contact."""
    world = World(load_scene("sorting_line"))
    tracked = TrackedArms(world)
    me, them = tracked.safety.geometries["arm_0"], tracked.safety.geometries["arm_1"]
    rng, tracker, names = (
        np.random.default_rng(3),
        tracked.trackers["arm_0"],
        tuple(world.arms["arm_0"].spec.arm_joints),
    )
    them.place(tracked.trackers["arm_1"].hold_q, ClawSpan.at(1.0))
    targets = []
    while len(targets) < 6:
        q = rng.uniform(tracker.lower, tracker.upper)
        me.place(q, ClawSpan.at(0.0))
        closed = separation_m(me, them, below_m=0.02)
        me.place(q, ClawSpan.at(1.0))
        if 0.011 < closed < 0.016 and separation_m(me, them, below_m=0.01) <= 0.0:
            targets.append(q)
    refused = 0
    for k, q in enumerate(targets):
        results = tracked.submit("arm_0", rest_to_rest(k + 1, names, q, 1.5, None))
        refused += any(r.status == GoalStatus.REJECTED and "safety" in r.reason for r in results)
        assert _run(world, tracked, 2.0) == 0
        tracked.submit(
            "arm_0", rest_to_rest(100 + k, names, tracker.lower * 0 + world.arms["arm_0"].spec.home_q, 1.5, None)
        )
        assert _run(world, tracked, 2.0) == 0
    assert refused == len(targets)


@pytest.mark.parametrize(("model_a", "model_b", "apart_m"), PAIRS[:3], ids=[f"{a}-{b}" for a, b, _ in PAIRS[:3]])
def test_the_coordinator_s_separation_is_never_positive_while_the_physics_has_two_arms_touching(
    model_a, model_b, apart_m
):
    """The guard measures each claw as the arm state gives it (the coordinator's `min_separation_m`): over random
    poses near contact, with claws at random openings, every pose the physics finds touching measures <= 0 (to
    0.5 mm: PhysX's contact offset)."""
    if not (is_available(model_a) and is_available(model_b)):
        pytest.skip("needs the models extra")
    world = World(two_arm_cell(model_a, model_b, apart_m))
    tracked = TrackedArms(world)
    guard = CollisionGuard(tracked.safety.geometries)
    rng = np.random.default_rng(7)
    floor = {a: np.minimum(_floor_gaps(g), 0.005) - 1e-6 for a, g in guard.arms.items()}  # as placed at home
    touching = apart = 0
    while touching < 15 or apart < 15:
        q = {}
        for name, arm in world.arms.items():
            n, spec = arm.spec.arm_dof, arm.spec
            lower, upper = arm.joint_limits()
            q[name] = rng.uniform(lower, upper)
            q[name][n:] = spec.gripper_targets(float(rng.uniform(0.0, 1.0)))
        for name, arm in world.arms.items():
            guard.set_state(name, q[name][: arm.spec.arm_dof], q[name][arm.spec.arm_dof :])
        measured, _ = guard.min_separation()
        if measured > 0.01 or not all((_floor_gaps(g) >= floor[a]).all() for a, g in guard.arms.items()):
            continue  # far apart (nothing to compare), or into the floor (which would throw the arms about)
        for name, arm in world.arms.items():
            arm.set_qpos(q[name])
            arm.set_targets(q[name][: arm.spec.arm_dof], np.zeros(arm.spec.arm_dof), q[name][arm.spec.arm_dof :])
        world.step()
        if world.inter_arm_contacts():  # found at the step's start, where the arms were set
            touching += 1
            assert measured <= 0.0005, (model_a, model_b, q, measured)
        else:
            apart += 1
