"""Allocation: the optimal assignment equals brute force; every allocator obeys reach and one-task-per-station."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coordinator.allocation import (
    ALLOCATORS,
    ArmView,
    CachedReach,
    Eligibility,
    PartView,
    assign_min_cost,
    make_allocator,
)
from coordinator.ledger import Ledger
from robots.frames import yaw_transform
from robots.registry import get_robot, is_available
from robots.top_down import TopDownIK
from scenes import load_scene


def brute_force(cost: np.ndarray) -> float:
    """Least total cost over every way to match rows to distinct columns, skipping infinite pairs."""
    rows, cols = cost.shape
    best = (0, 0.0)  # (pairs matched, cost): more pairs first, then less cost
    for k in range(min(rows, cols), 0, -1):
        for rs in itertools.combinations(range(rows), k):
            for cs in itertools.permutations(range(cols), k):
                c = sum(cost[r, q] for r, q in zip(rs, cs))
                if np.isfinite(c) and (k, -c) > (best[0], -best[1]):
                    best = (k, c)
        if best[0] == k:
            break
    return best[1]


@pytest.mark.parametrize("seed", range(40))
def test_optimal_assignment_equals_brute_force(seed):
    rng = np.random.default_rng(seed)
    rows, cols = rng.integers(1, 5, size=2)
    cost = rng.uniform(1, 20, size=(rows, cols))
    cost[rng.random((rows, cols)) < 0.25] = np.inf  # infeasible pairs
    pairs = assign_min_cost(cost)
    assert len({r for r, _ in pairs}) == len(pairs) == len({c for _, c in pairs})
    assert all(np.isfinite(cost[r, c]) for r, c in pairs)
    assert sum(cost[r, c] for r, c in pairs) == pytest.approx(brute_force(cost))


def test_unknown_allocator_lists_the_valid_ones():
    with pytest.raises(ValueError, match="valid allocators: optimal, auction, greedy"):
        make_allocator("fastest", load_scene("assembly_line"))


@pytest.fixture(scope="module")
def sorting_cell():
    scene = load_scene("sorting_line", arms=3)
    reach = {
        a.name: CachedReach(TopDownIK(get_robot(a.model), yaw_transform(a.base.xyz, a.base.yaw_rad)))
        for a in scene.arms
    }
    return scene, reach


@pytest.mark.parametrize("name", list(ALLOCATORS))
def test_each_allocator_gives_each_part_to_the_arm_whose_bin_takes_its_colour(name, sorting_cell):
    scene, reach = sorting_cell
    ledger = Ledger(scene)
    home = tuple(get_robot("openclaw").home_q)
    arms = [ArmView(a.name, a.base.xyz, True, reach[a.name], home) for a in scene.arms]
    parts = {}
    for pid, (i, colour) in enumerate([(0, 0), (1, 1), (2, 2)]):  # a part in front of each arm, of that arm's colour
        x = scene.arms[i].base.xyz[0] - 0.09  # 1.5 s upstream at 6 cm/s
        parts[pid] = PartView(np.array([x, 0.0, 0.095]), np.array([0.06, 0.0, 0.0]))
        ledger.arrived(pid, "mixed", colour, 1.0)
    pending = ledger.refresh(1.0)
    got = dict(make_allocator(name, scene).allocate(pending, arms, parts, set()))
    assert {ledger.tasks[t].part_id: arm for t, arm in got.items()} == {0: "arm_0", 1: "arm_1", 2: "arm_2"}
    busy = make_allocator(name, scene).allocate(pending, arms, parts, {"bin_1"})
    assert all(ledger.tasks[t].target != "bin_1" for t, _ in busy)  # a busy station takes no second task


def test_optimal_serves_the_part_due_first_when_tasks_outnumber_arms(sorting_cell):
    """One free arm, two parts of its colour: the one about to ride out of reach goes first, though the other
    would be met sooner (cheaper); the part that can wait is taken next time."""
    scene, reach = sorting_cell
    ledger = Ledger(scene)
    home = tuple(get_robot("openclaw").home_q)
    arms = [ArmView(a.name, a.base.xyz, a.name == "arm_0", reach[a.name], home) for a in scene.arms]
    x0 = scene.arms[0].base.xyz[0]
    parts = {
        0: PartView(
            np.array([x0 - 0.20, 0.0, 0.095]), np.array([0.06, 0.0, 0.0])
        ),  # farther from the bin: 5.2 s of work
        1: PartView(np.array([x0 + 0.10, 0.0, 0.095]), np.array([0.06, 0.0, 0.0])),  # nearer the bin: 4.6 s
    }
    for pid in parts:
        ledger.arrived(pid, "mixed", 0, 1.0)
    pending = ledger.refresh(1.0)
    for task in pending:  # part 0 must be met within 3 s (say, a gate closes), part 1 within 5 s
        task.deadline_s = 1.0 + (3.0 if task.part_id == 0 else 5.0)
    got = make_allocator("optimal", scene).allocate(pending, arms, parts, set())
    assert [(ledger.tasks[t].part_id, arm) for t, arm in got] == [(0, "arm_0")]


@pytest.fixture(scope="module")
def mixed_cell():
    scene = load_scene("mixed_infeed")
    reach = {
        a.name: CachedReach(TopDownIK(get_robot(a.model), yaw_transform(a.base.xyz, a.base.yaw_rad)))
        for a in scene.arms
    }
    return scene, reach


def red_belt_part_and_tray_part(scene, tray_first_s: float, belt_deadline_s: float):
    """A red part on the belt just upstream of arm_0 and a part waiting in the rework tray, as pending tasks."""
    ledger = Ledger(scene)
    tray = scene.station("rework_tray")
    parts = {
        0: PartView(np.array([*tray.pose.xyz[:2], tray.surface_z_m + 0.015]), np.zeros(3)),
        1: PartView(np.array([scene.arms[0].base.xyz[0] - 0.13, 0.38, 0.095]), np.array([0.09, 0.0, 0.0])),
    }
    ledger.arrived(0, "rework", 0, tray_first_s)
    ledger.at_station(0, "rework_tray", tray_first_s)
    ledger.arrived(1, "belt_parts", 0, 2.0)
    pending = ledger.refresh(2.0)
    next(t for t in pending if t.part_id == 1).deadline_s = belt_deadline_s
    return ledger, pending, parts


def test_optimal_takes_the_belt_part_before_an_older_tray_part_greedy_does_not(mixed_cell):
    """The contention scene's first decision: arm_0 alone is free; the tray part is older but can wait."""
    scene, reach = mixed_cell
    home = tuple(get_robot("openclaw").home_q)
    arms = [ArmView(a.name, a.base.xyz, a.name == "arm_0", reach[a.name], home) for a in scene.arms]
    ledger, pending, parts = red_belt_part_and_tray_part(scene, tray_first_s=1.0, belt_deadline_s=8.0)
    part_of = lambda got: [(ledger.tasks[t].part_id, arm) for t, arm in got]
    assert part_of(make_allocator("optimal", scene).allocate(pending, arms, parts, set())) == [(1, "arm_0")]
    assert part_of(make_allocator("greedy", scene).allocate(pending, arms, parts, set())) == [(0, "arm_0")]


def test_optimal_leaves_shared_work_to_an_arm_about_to_be_free(mixed_cell):
    """arm_1 ends its task in 0.3 s: arm_0 takes the belt part only it can serve and leaves the tray to arm_1,
    though the tray part is due first; not knowing when arm_1 is free, arm_0 takes the tray part."""
    scene, reach = mixed_cell
    home = tuple(get_robot("openclaw").home_q)
    ledger, pending, parts = red_belt_part_and_tray_part(scene, tray_first_s=1.0, belt_deadline_s=40.0)
    part_of = lambda got: [(ledger.tasks[t].part_id, arm) for t, arm in got]
    for free_in_s, expected in ((0.3, [(1, "arm_0")]), (None, [(0, "arm_0")])):
        arms = [
            ArmView(
                a.name, a.base.xyz, a.name == "arm_0", reach[a.name], home, None if a.name == "arm_0" else free_in_s
            )
            for a in scene.arms
        ]
        assert part_of(make_allocator("optimal", scene).allocate(pending, arms, parts, set())) == expected


def test_optimal_keeps_a_free_arm_for_a_belt_part_riding_into_its_reach_rather_than_start_a_tray_part(mixed_cell):
    """arm_0's stretch of belt is a few seconds long: a red part 1 s from it is worth waiting for (the tray part can
    wait, the belt part cannot); one 5 s away, beyond the look-ahead, is not, and arm_0 empties the tray meanwhile."""
    scene, reach = mixed_cell
    home = tuple(get_robot("openclaw").home_q)
    arms = [ArmView(a.name, a.base.xyz, a.name == "arm_0", reach[a.name], home) for a in scene.arms]
    ledger, pending, parts = red_belt_part_and_tray_part(scene, tray_first_s=1.0, belt_deadline_s=12.0)
    part_of = lambda got: [(ledger.tasks[t].part_id, arm) for t, arm in got]
    upstream_x = scene.arms[0].base.xyz[0] - 0.45  # not in arm_0's reach yet: it enters 0.1 m downstream
    for speed_m_per_s, expected in ((0.09, []), (0.02, [(0, "arm_0")])):
        parts[1] = PartView(np.array([upstream_x, 0.38, 0.095]), np.array([speed_m_per_s, 0.0, 0.0]))
        assert part_of(make_allocator("optimal", scene).allocate(pending, arms, parts, set())) == expected, (
            speed_m_per_s
        )


def test_time_costs_use_each_arm_robots_own_timing_on_a_mixed_line():
    from coordinator.allocation import Eligibility, TimeCost
    from robots.skills.pick_place import PickPlaceTiming

    if not is_available("so101"):
        pytest.skip("needs the models extra")
    scene = load_scene("mixed_fleet")
    so101 = scene.arm("arm_1")
    view = ArmView(so101.name, so101.base.xyz, True, CachedReach.of(so101), tuple(get_robot("so101").home_q))
    ledger = Ledger(scene)
    ledger.arrived(0, "mixed", 1, 1.0)  # green: the SO-101's bin
    task = ledger.refresh(1.0)[0]
    part = PartView(np.array([0.66, 0.0, 0.095]), np.array([0.05, 0.0, 0.0]))
    rules = Eligibility(scene, [view])
    own, openclaws = TimeCost(rules)(view, task, part), TimeCost(rules, PickPlaceTiming())(view, task, part)
    assert np.isfinite(own) and own > openclaws  # the SO-101 transfers at 0.15 of its joints' speed, not 0.45


def owner_views(bases_xy: list[tuple[float, float]], live: list[bool]) -> list[ArmView]:
    """Arms standing at `bases_xy` (no reach needed: only belt ownership is asked of them)."""
    return [ArmView(f"arm_{i}", (x, y, 0.0), True, None, live=up) for i, ((x, y), up) in enumerate(zip(bases_xy, live))]


@settings(max_examples=200, deadline=None)
@given(
    bases=st.lists(st.tuples(st.floats(-2, 2), st.floats(-1, 1)), min_size=1, max_size=8),
    live_draw=st.lists(st.booleans(), min_size=8, max_size=8),
    points=st.lists(st.tuples(st.floats(-2.5, 2.5), st.floats(-1.5, 1.5), st.just(0.1)), min_size=1, max_size=12),
)
def test_the_one_pass_belt_ownership_filter_never_rules_out_an_arm_that_owns_the_point(bases, live_draw, points):
    """The optimal allocator costs a belt task only for the arms the filter leaves; an owner it dropped would lose
    the part."""
    arms = owner_views(bases, live_draw[: len(bases)])
    rules = Eligibility(load_scene("sorting_line"), arms)
    may = rules.may_own_belt_points(arms, np.array(points))
    for p, point in enumerate(points):
        for a, arm in enumerate(arms):
            if rules.owns_belt_point(arm, point):
                assert may[p, a], (arm.name, point)


def test_the_one_pass_filter_leaves_few_arms_of_a_long_line():
    """On a 12-arm row, a belt point may belong to one arm at most: the filter's whole point."""
    arms = owner_views([(0.55 * i, -0.35) for i in range(12)], [True] * 12)
    rules = Eligibility(load_scene("sorting_line"), arms)
    points = np.column_stack([np.linspace(-0.5, 6.5, 141), np.zeros(141), np.full(141, 0.1)])
    assert rules.may_own_belt_points(arms, points).sum(axis=1).max() == 1


def test_belt_ownership_asked_of_each_arm_at_its_own_point_is_the_diagonal_of_asking_every_arm_every_point():
    """The optimal allocator asks each arm about its own wait's pick point only (`paired`): the same answers as the
    full (points x arms) pass, for a fraction of its work on a 24-arm row; lost arms included."""
    from fleet.common.scene_loading import load_checked_scene as load_with_arms

    scene = load_with_arms("sorting_line", arms=24)
    rng = np.random.default_rng(0)
    for _ in range(100):
        live = rng.random(24) > 0.1
        arms = [ArmView(a.name, a.base.xyz, True, None, live=bool(up)) for a, up in zip(scene.arms, live)]
        rules = Eligibility(scene, arms)
        asked = [arms[i] for i in rng.permutation(24)[: rng.integers(1, 25)]]
        n = int(rng.integers(1, 12))
        points = np.concatenate(
            [rng.uniform([-1.0, -0.2], [14.0, 0.2], (n, len(asked), 2)), np.full((n, len(asked), 1), 0.1)], axis=2
        )
        every = rules.may_own_belt_points(asked, points)
        own = np.arange(len(asked))
        assert np.array_equal(every[:, own, own], rules.may_own_belt_points(asked, points, paired=True))
