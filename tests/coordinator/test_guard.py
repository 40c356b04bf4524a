"""The FCL collision guard on two OpenClaw arms facing each other across a gap."""

import numpy as np
import pytest

from coordinator.geometry import ArmGeometry, closest_points, separation_m
from coordinator.guard import CollisionGuard, TimedPath
from robots.frames import yaw_transform
from robots.registry import get_robot

HOME = np.array(get_robot("openclaw").home_q)
REACH_OUT = np.array([0.0, 1.0, 0.6, 0.0, 0.5, 0.0])  # shoulder forward: the claw far out in front


def two_arms(gap_m: float = 0.7) -> dict[str, ArmGeometry]:
    spec = get_robot("openclaw")
    return {
        "arm_0": ArmGeometry("arm_0", spec, yaw_transform((0.0, 0.0, 0.0), 0.0)),
        "arm_1": ArmGeometry("arm_1", spec, yaw_transform((gap_m, 0.0, 0.0), np.pi)),  # facing arm_0
    }


def test_folded_arms_are_clear_and_two_reaching_arms_touch():
    arms = two_arms()
    arms["arm_0"].place(HOME)
    arms["arm_1"].place(HOME)
    assert separation_m(arms["arm_0"], arms["arm_1"]) > 0.1
    arms["arm_0"].place(REACH_OUT)
    arms["arm_1"].place(REACH_OUT)
    assert separation_m(arms["arm_0"], arms["arm_1"]) <= 0.0


def test_the_margin_is_respected():
    guard = CollisionGuard(two_arms(), margin_m=0.02)
    d, pair = guard.min_separation({"arm_0": HOME, "arm_1": HOME})
    assert pair == ("arm_0", "arm_1")
    wide = CollisionGuard(two_arms(), margin_m=d + 0.01)  # a margin wider than the gap: home is within it
    verdict = wide.check(TimedPath("arm_0", tuple(HOME), tuple(REACH_OUT), 0.0, 1.0))
    assert verdict.decision == "deny" and verdict.conflict_arm == "arm_1"
    assert guard.check(TimedPath("arm_0", tuple(HOME), tuple(HOME), 0.0, 1.0)).granted


def test_two_arms_left_within_the_margin_may_move_apart_but_not_nearer():
    """An outside driver left arm_0 reaching towards arm_1, inside the guard's margin but clear of the plant's
    separation: arm_1 standing still, arm_0 may go home (farther), never reach farther in (nearer)."""
    guard = CollisionGuard(two_arms(gap_m=0.75), margin_m=0.02)
    there = 0.4 * REACH_OUT + 0.6 * HOME  # arm_1 reaching a little
    inside = next(
        q
        for q in (f * REACH_OUT + (1 - f) * HOME for f in np.linspace(1.0, 0.0, 201))
        if 0.008 < guard.min_separation({"arm_0": q, "arm_1": there})[0] < 0.015
    )
    guard.set_state("arm_1", there)
    home = guard.request(TimedPath("arm_0", tuple(inside), tuple(HOME), 0.0, 1.0))
    assert home.granted and home.min_separation_m < guard.margin_m and guard.ways_out == 1
    guard.release("arm_0")
    deeper = guard.request(TimedPath("arm_0", tuple(inside), tuple(REACH_OUT), 0.0, 1.0))
    assert deeper.decision == "deny" and deeper.conflict_arm == "arm_1"
    guard.set_state("arm_0", inside)
    assert guard.request(TimedPath("arm_1", tuple(there), tuple(HOME), 0.0, 1.0)).granted, "arm_1 backs off too"


def test_a_thin_link_passing_through_between_two_coarse_samples_is_caught():
    """arm_0 swings its base round through arm_1's outstretched claw: both ends are clear, the middle is not."""
    arms = two_arms(gap_m=0.75)
    guard = CollisionGuard(arms)
    reach = np.array([0.0, 1.1, 0.3, 0.0, 0.4, 0.0])
    guard.set_state("arm_1", reach)
    start, end = reach.copy(), reach.copy()
    start[0], end[0] = -1.2, 1.2  # sweeping through the line between the bases
    for q in (start, end):
        assert guard.min_separation({"arm_0": q, "arm_1": reach})[0] > 0.02, "both ends alone are clear"
    coarse = CollisionGuard(arms, step_m=10.0)  # two samples: start and end
    assert coarse.check(TimedPath("arm_0", tuple(start), tuple(end), 0.0, 2.0)).granted, "coarse sampling misses it"
    verdict = guard.check(TimedPath("arm_0", tuple(start), tuple(end), 0.0, 2.0))
    assert verdict.decision == "deny" and verdict.conflict_arm == "arm_1"


def test_the_crossing_case_resolves_without_deadlock():
    """Both arms want to reach into the shared middle at once: one is granted, the other waits, then goes."""
    # one arm reaching out is clear of the other folded; both reaching touch
    guard = CollisionGuard(two_arms(gap_m=1.0))
    out_0 = TimedPath("arm_0", tuple(HOME), tuple(REACH_OUT), 0.0, 1.0)
    back_0 = TimedPath("arm_0", tuple(REACH_OUT), tuple(HOME), 1.0, 2.0)
    out_1 = TimedPath("arm_1", tuple(HOME), tuple(REACH_OUT), 0.0, 1.0)
    assert guard.request(out_0).granted
    verdict = guard.request(out_1)
    assert verdict.decision == "wait" and verdict.conflict_arm == "arm_0"
    assert guard.request(back_0).granted  # arm_0 does its work and leaves the middle by t = 2 s
    guard.set_state("arm_0", HOME)
    later = TimedPath("arm_1", tuple(HOME), tuple(REACH_OUT), 2.5, 3.5)
    guard.expire(2.5)
    assert guard.request(later).granted  # arm_1 goes once arm_0's grant is over
    assert guard.waits == 1 and guard.denied == 0


def test_free_paths_of_both_arms_are_granted_at_once():
    guard = CollisionGuard(two_arms(gap_m=2.0))  # too far apart to meet
    assert guard.request(TimedPath("arm_0", tuple(HOME), tuple(REACH_OUT), 0.0, 1.0)).granted
    assert guard.request(TimedPath("arm_1", tuple(HOME), tuple(REACH_OUT), 0.0, 1.0)).granted


POSE_RANGE = (np.array([-1.5, -0.3, -0.3, -1.0, -0.8, -1.0]), np.array([1.5, 1.2, 1.2, 1.0, 0.8, 1.0]))


def row_of_arms(xs_m: list[float]) -> dict[str, ArmGeometry]:
    """OpenClaw arms along x, every other one turned to face the one before."""
    spec = get_robot("openclaw")
    return {
        f"arm_{i}": ArmGeometry(f"arm_{i}", spec, yaw_transform((x, 0.0, 0.0), np.pi * (i % 2)))
        for i, x in enumerate(xs_m)
    }


def test_nearest_other_with_a_cap_is_the_exact_distance_or_the_cap():
    """The capped query skips what cannot come under the cap; what it returns is min(exact distance, cap)."""
    arms = row_of_arms([0.0, 0.55, 1.1, 3.0])  # the last one stands far from the rest
    guard = CollisionGuard(arms)
    rng = np.random.default_rng(3)
    capped_somewhere = measured_somewhere = False
    for _ in range(30):
        for name in arms:
            guard.set_state(name, rng.uniform(*POSE_RANGE))
        for cap in (0.05, 0.2):
            got = guard.nearest_other_m(cap_m=cap)  # places every arm at its state, as the exact distances below need
            for name in arms:
                exact = min(separation_m(arms[name], arms[o]) for o in arms if o != name)
                assert got[name] == pytest.approx(min(exact, cap), abs=1e-9)
                capped_somewhere |= exact >= cap
                measured_somewhere |= exact < cap
    assert capped_somewhere and measured_somewhere, "both branches must be exercised"


def test_the_local_stage_after_a_move_is_checked_and_held_by_its_grant():
    """arm_0 moves to a pose clear of arm_1, then (without a grant of its own) reaches out: the grant covers both."""
    guard = CollisionGuard(two_arms(gap_m=1.0))
    guard.set_state("arm_1", REACH_OUT)  # arm_1 stands reaching into the middle
    halfway = (HOME + REACH_OUT) / 2
    move_only = TimedPath("arm_0", tuple(HOME), tuple(HOME), 0.0, 1.0)
    assert guard.check(move_only).granted
    with_stage = TimedPath(
        "arm_0", tuple(HOME), tuple(HOME), 0.0, 1.0, then_q=(tuple(halfway), tuple(REACH_OUT)), then_after_s=(0.5, 1.0)
    )
    assert (
        with_stage.t_done_s == 2.0
        and np.allclose(with_stage.at(1.5), halfway)
        and np.allclose(with_stage.at(9.0), REACH_OUT)
    )
    verdict = guard.check(with_stage)
    assert verdict.decision == "deny" and verdict.at_time_s > 1.0, "the clash is in the local stage, after the move"
    guard.set_state("arm_1", HOME)
    assert guard.request(with_stage).granted
    reach_1 = TimedPath("arm_1", tuple(HOME), tuple(REACH_OUT), 1.2, 1.8)
    assert guard.request(reach_1).decision == "wait", "arm_0 is reaching out in its local stage by then"
    guard.expire(1.9)
    assert "arm_0" in guard.grants, "the grant lasts until the local stage is over"
    guard.expire(2.1)
    assert "arm_0" not in guard.grants


def test_each_arms_nearest_pair_comes_with_its_nearest_points_as_measured_pair_by_pair():
    """`nearest_pairs` measures in one bounded pass; every arm's nearest other arm (ties included), once, nearest
    first, is what measuring every pair exactly gives, with the same distance and nearest points."""
    arms = row_of_arms([0.0, 0.55, 1.1, 1.65, 3.0])
    guard = CollisionGuard(arms)
    rng = np.random.default_rng(5)
    states = [{name: HOME for name in arms}]  # every arm at home: neighbours equally near (ties)
    states += [{name: rng.uniform(*POSE_RANGE) for name in arms} for _ in range(25)]
    for state in states:
        for name, q in state.items():
            guard.set_state(name, q)
        got = guard.nearest_pairs()
        exact = {(a, b): closest_points(arms[a], arms[b]) for a in arms for b in arms if a < b}
        nearest = {n: min(d for pair, (d, _, _) in exact.items() if n in pair) for n in arms}
        want = {pair for pair, (d, _, _) in exact.items() if any(abs(d - nearest[n]) < 1e-9 for n in pair)}
        assert {(p.a, p.b) for p in got} == want
        assert [p.distance_m for p in got] == sorted(p.distance_m for p in got)
        for p in got:
            d, p_a, p_b = exact[(p.a, p.b)]
            assert p.distance_m == pytest.approx(d, abs=1e-9)
            np.testing.assert_allclose(p.point_a, p_a, atol=1e-9)
            np.testing.assert_allclose(p.point_b, p_b, atol=1e-9)


def test_the_separation_watch_reuses_what_it_measured_of_still_arms_and_answers_as_a_fresh_guard():
    """Most arms of a line stand still from one decision to the next: the watch answers a pair whose arms have not
    moved as it measured it, and its answers are a fresh guard's, pair for pair and point for point."""
    spec = get_robot("openclaw")

    def row() -> dict[str, ArmGeometry]:
        return {f"arm_{i}": ArmGeometry(f"arm_{i}", spec, yaw_transform((0.5 * i, 0.0, 0.0), 0.0)) for i in range(4)}

    watch, rng = CollisionGuard(row()), np.random.default_rng(3)
    state = {name: HOME.copy() for name in watch.arms}
    for _ in range(25):
        mover = f"arm_{rng.integers(4)}"
        state[mover] = HOME + rng.normal(0.0, 0.5, HOME.size) * [1, 1, 1, 1, 1, 0]
        fresh = CollisionGuard(row())
        for name, q in state.items():
            watch.set_state(name, q)
            fresh.set_state(name, q)
        seen, expected = watch.nearest_pairs(), fresh.nearest_pairs()
        assert [(p.a, p.b, p.distance_m) for p in seen] == [(p.a, p.b, p.distance_m) for p in expected]
        for p, e in zip(seen, expected):
            assert np.array_equal(p.point_a, e.point_a) and np.array_equal(p.point_b, e.point_b)
    assert watch._watch_memo.reused >= 25, "pairs of still arms were not measured again"


class MeasuresEveryNeighbour(CollisionGuard):
    """The guard as it was: every neighbour measured at every sample (no lower bound lets one be skipped)."""

    def _closing(self, path, among):
        closing = super()._closing(path, among)
        closing.pair_closed_m = lambda *_: float("inf")
        return closing


def test_a_neighbour_skipped_for_its_lower_bound_leaves_every_verdict_as_measuring_them_all(monkeypatch):
    """A neighbour whose last distance, less what the pair can close since, is past the nearest so far is not
    measured at a sample: the verdicts, distances, times and samples are those of measuring every neighbour, with
    neighbours moving on granted paths that start mid-check away from where they stand."""
    spec = get_robot("openclaw")
    lower, upper = np.array(spec.home_q) - 1.0, np.array(spec.home_q) + 1.0

    def row() -> dict[str, ArmGeometry]:
        return {f"arm_{i}": ArmGeometry(f"arm_{i}", spec, yaw_transform((0.45 * i, 0.0, 0.0), 0.0)) for i in range(4)}

    import coordinator.guard as guard_module

    measured = {"now": 0}
    measure = guard_module.separation_m
    monkeypatch.setattr(
        guard_module,
        "separation_m",
        lambda *a, **k: measured.__setitem__("now", measured["now"] + 1) or measure(*a, **k),
    )
    rng, counts = np.random.default_rng(7), [0, 0]
    for _ in range(40):
        guards = CollisionGuard(row()), MeasuresEveryNeighbour(row())
        states = {f"arm_{i}": rng.uniform(lower, upper) for i in range(4)}
        grants = {
            f"arm_{i}": TimedPath(
                f"arm_{i}",
                tuple(rng.uniform(lower, upper)),
                tuple(rng.uniform(lower, upper)),
                t0 := float(rng.uniform(0.0, 2.0)),
                t0 + float(rng.uniform(0.5, 2.0)),
            )
            for i in (0, 2, 3)
            if rng.random() < 0.6
        }
        asked = TimedPath("arm_1", tuple(states["arm_1"]), tuple(rng.uniform(lower, upper)), 0.5, 2.5)
        verdicts = []
        for k, guard in enumerate(guards):
            for name, q in states.items():
                guard.set_state(name, q)
            guard.grants.update(grants)
            measured["now"] = 0
            verdicts.append((guard.check(asked), guard.last_check_samples))
            counts[k] += measured["now"]
        assert verdicts[0] == verdicts[1]
    assert counts[0] < 0.8 * counts[1], counts
