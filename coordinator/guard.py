"""The collision guard: motion grants checked with python-fcl, and the cell's minimum separation.

An arm asks for a grant before a motion segment, with its joint path and time
window. The guard walks the path by conservative advancement: a joint turning by
dq moves no point of the arm more than lever * |dq| (its lever: how far its
shapes can be from it, `ArmGeometry.joint_levers_m`), so after measuring a
clearance d (with FCL, every other arm placed where its own granted path or its
current state puts it at that time) it may skip ahead until the arms could have
closed d - margin (`coordinator.gap_closing`: their travel along their timed paths),
never less than `step_m`. No link can pass through another
between two samples. The answer:

- `grant`: clear by the margin everywhere; the path is recorded for later checks;
- `wait`: it would come too close to another arm's granted motion; ask again later;
- `deny`: it would come too close to an arm that is not going to move (no grant):
  waiting does not help, the asker must plan something else.

Grants never wait on anything, and every granted path ends at a known time, so
waits cannot form a cycle: the classic crossing case resolves in request order.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from coordinator.claw_sweep import ClawSpan
from coordinator.denied_arms import DeniedArms
from coordinator.gap_closing import GapClosing, PathTravel
from coordinator.geometry import ArmGeometry, CellBounds, closest_points_below, neighbours, separation_m
from coordinator.pair_measurements import PairMeasurements
from robots.trajectory import quintic

DEFAULT_MARGIN_M = 0.02
OUT_TOLERANCE_M = 0.001  # a way out of another arm's margin may come this much nearer than it starts (FCL's noise)
OUT_FLOOR_M = 0.005  # no way out comes nearer than this, wherever it starts
YIELD_M = 0.75  # of the margin: how near a path may pass an arm that waits for it in turn (`CollisionGuard._way_out`)
TIE_M = 1e-9  # two distances this close are one (each arm's nearest pairs include every pair at its distance)


@dataclass(frozen=True)
class TimedPath:
    """A joint-space segment: `q_from` at `t_start_s` to `q_to` at `t_end_s`, straight in joint space, timed as the
    skills move (rest to rest, quintic), so the guard places each arm where it really is at each instant.

    `then_q` are the poses of the local stage that follows the move without a grant of its own (the grasp's
    descent and lift, a place's lowering and retreat), reached `then_after_s` seconds after `t_end_s` (joint-space
    straight lines between them): a grant covers that stage too, until `t_done_s`.
    """

    arm: str
    q_from: tuple[float, ...]
    q_to: tuple[float, ...]
    t_start_s: float
    t_end_s: float
    then_q: tuple[tuple[float, ...], ...] = ()
    then_after_s: tuple[float, ...] = ()

    @property
    def t_done_s(self) -> float:
        """When the move and the local stage after it are over."""
        return self.t_end_s + (self.then_after_s[-1] if self.then_after_s else 0.0)

    def at(self, t_s: float) -> np.ndarray:
        """Where the arm is at `t_s`: the skills' rest-to-rest quintic time law along the joint-space line, then
        the local stage's poses."""
        if t_s > self.t_end_s and self.then_q:
            times = np.concatenate([[self.t_end_s], self.t_end_s + np.asarray(self.then_after_s)])
            poses = np.vstack([self.q_to, self.then_q])
            return np.array([np.interp(t_s, times, poses[:, j]) for j in range(poses.shape[1])])
        span = self.t_end_s - self.t_start_s
        u = 1.0 if span <= 0 else quintic((t_s - self.t_start_s) / span)
        return (1 - u) * np.asarray(self.q_from) + u * np.asarray(self.q_to)

    def travel_m(self, levers_m: np.ndarray) -> float:
        """The most any point of the arm moves along the move (`ArmGeometry.joint_levers_m`: sum_j lever_j |dq_j|)."""
        return float(np.abs(np.asarray(self.q_to) - np.asarray(self.q_from)) @ levers_m)


@dataclass(frozen=True)
class NearestPair:
    """Two arms, their distance and closest points (world frame): `a`'s nearest other arm is `b` or the reverse."""

    a: str
    b: str
    distance_m: float
    point_a: np.ndarray
    point_b: np.ndarray


@dataclass(frozen=True)
class Verdict:
    decision: str  # grant | wait | deny
    conflict_arm: str | None
    min_separation_m: float
    at_time_s: float | None = None

    @property
    def granted(self) -> bool:
        return self.decision == "grant"


class CollisionGuard:
    """Grants motion to arms of one cell; `set_state` keeps each arm's current joints up to date."""

    def __init__(
        self, arms: dict[str, ArmGeometry], margin_m: float = DEFAULT_MARGIN_M, step_m: float | None = None
    ) -> None:
        self.arms = arms
        self._upper = np.triu_indices(len(arms), k=1)  # every pair of arms once, as (row, column) indices
        self._bounds = CellBounds(list(arms.values()))
        self.margin_m = margin_m
        self.step_m = step_m if step_m is not None else margin_m / 2
        self.state = {name: np.asarray(g.spec.home_q, float) for name, g in arms.items()}
        self.grants: dict[str, TimedPath] = {}
        self.denied = 0
        self.waits = 0
        self.ways_out = 0  # grants nearer than the margin, out of two arms' deadlock (`_way_out`)
        self.last_check_samples = 0
        self._claws: dict[str, ClawSpan] = {}  # each arm's claw as last measured
        self._watch_memo = PairMeasurements()
        self._levers_m: dict[str, np.ndarray] = {}
        self._denials = DeniedArms()

    def set_state(self, arm: str, q: np.ndarray, gripper_q: np.ndarray | None = None) -> None:
        """An arm's measured joints, and its claw's where known: the cell's separations place the claw as measured
        (else over its whole travel). Grants always sweep every claw over its whole travel: a skill opens and
        closes its claw along a granted path without asking again."""
        self.state[arm] = np.asarray(q, float)
        if gripper_q is not None and len(gripper_q):
            self.claw_state()[arm] = ClawSpan.at(self.arms[arm].spec.opening_of(gripper_q))

    def claw_state(self) -> dict[str, ClawSpan]:
        """Each arm's claw as last measured (arms never measured: none)."""
        return self._claws

    def release(self, arm: str) -> None:
        self.grants.pop(arm, None)

    def expire(self, now_s: float) -> None:
        """Forget grants whose time window has passed."""
        for arm in [a for a, p in self.grants.items() if p.t_done_s < now_s]:
            del self.grants[arm]

    # --- queries --------------------------------------------------------------------
    def min_separation(
        self, configurations: dict[str, np.ndarray] | None = None
    ) -> tuple[float, tuple[str, str] | None]:
        """The smallest distance between any two arms (at their current states unless given).

        Pairs are measured nearest first by their shapes' bounding spheres; a pair whose spheres stand
        farther apart than the best distance so far is skipped, and within a pair only shapes that can
        still beat it are measured (python-fcl).
        """
        claws = self.claw_state() if configurations is None else {}
        configurations = configurations or self.state
        for name, q in configurations.items():
            self.arms[name].place(q, claws.get(name))
        best, pair = math.inf, None
        for gap, a, b in self._pairs_by_bound():
            if a not in configurations or b not in configurations:
                continue
            if gap >= best:
                break
            d = separation_m(self.arms[a], self.arms[b], below_m=best)
            if d < best:
                best, pair = d, (a, b)
        return best, pair

    def nearest_other_m(self, cap_m: float = math.inf) -> dict[str, float]:
        """Each arm's distance to its nearest other arm, at the current states; a pair is measured only if it
        could beat what one of its two arms already has. With `cap_m`, distances at or beyond it read `cap_m`
        (a pair whose bound is past the cap is not measured at all)."""

        def distance(a: ArmGeometry, b: ArmGeometry, below_m: float) -> tuple[float] | None:
            d = separation_m(a, b, below_m=below_m)
            return None if math.isinf(d) else (d,)

        return self._nearest_pass(distance, cap_m)[0]

    def nearest_pairs(self) -> list[NearestPair]:
        """For each arm its nearest other arm at the current states, each pair once; the cell's closest pair is among
        them. The pass of `nearest_other_m`, with the nearest points of each pair it measures."""
        nearest, measured = self._nearest_pass(closest_points_below, math.inf, TIE_M, self._watch_memo)
        out = [
            NearestPair(a, b, d, p_a, p_b)
            for (a, b), (d, p_a, p_b) in measured.items()
            if abs(d - nearest[a]) < TIE_M or abs(d - nearest[b]) < TIE_M
        ]
        return sorted(out, key=lambda p: p.distance_m)

    def _nearest_pass(
        self,
        measure: Callable[[ArmGeometry, ArmGeometry, float], tuple | None],
        cap_m: float,
        tie_m: float = 0.0,
        memo: PairMeasurements | None = None,
    ) -> tuple[dict[str, float], dict[tuple[str, str], tuple]]:
        """Each arm's nearest distance (at most `cap_m`) and what `measure(a, b, below_m)` said of each pair it was
        asked about (its first item the distance; None: not below): pairs nearest first by their bound, a pair asked
        only if it could come within `tie_m` of what one of its two arms already has (`memo`: a pair whose arms stood
        still since it was last asked is answered as then)."""
        claws = self.claw_state()
        for name, q in self.state.items():
            self.arms[name].place(q, claws.get(name))
        nearest = {name: cap_m for name in self.arms}
        measured: dict[tuple[str, str], tuple] = {}
        gaps = self._bounds.gaps_m()
        rows, cols = self._upper
        if rows.size == 0 or gaps[rows, cols].min() >= cap_m:
            return nearest, measured  # every pair is beyond the cap: nothing to measure
        for gap, a, b in self._pairs_by_bound(gaps):
            worse = max(nearest[a], nearest[b]) + tie_m
            if gap >= worse:
                continue  # cannot be nearer than what both already have
            pair = self.arms[a], self.arms[b]
            found = measure(*pair, worse) if memo is None else memo.measured(*pair, worse, measure)
            if found is not None:
                measured[(a, b)] = found
                nearest[a], nearest[b] = min(nearest[a], found[0]), min(nearest[b], found[0])
        return nearest, measured

    def _pairs_by_bound(self, gaps: np.ndarray | None = None) -> list[tuple[float, str, str]]:
        """Every pair of arms as placed now, nearest first by a lower bound on their distance (their shapes'
        bounding spheres; `gaps` if already computed for this placement)."""
        names = list(self.arms)
        gaps = self._bounds.gaps_m() if gaps is None else gaps
        rows, cols = self._upper
        order = np.argsort(gaps[rows, cols], kind="stable")
        return [(float(gaps[rows[k], cols[k]]), names[rows[k]], names[cols[k]]) for k in order]

    def _where(self, arm: str, t_s: float) -> np.ndarray:
        path = self.grants.get(arm)
        return path.at(t_s) if path is not None and path.t_start_s <= t_s + 1e-9 else self.state[arm]

    def _closing(self, path: TimedPath, among: list[str]) -> GapClosing:
        """How far the asking arm and the arms moving with it (`among` these: its neighbours, the only arms it is
        measured against) can close on each other over any stretch of the path's time."""
        others = {
            a: PathTravel(p, self.levers_m(a), self.state[a])  # placed where it stands until its path starts
            for a, p in self.grants.items()
            if a != path.arm and a in among and p.t_done_s > path.t_start_s and p.t_start_s < path.t_done_s
        }
        return GapClosing(PathTravel(path, self.levers_m(path.arm)), others)

    def levers_m(self, arm: str) -> np.ndarray:
        """How far from each of the arm's joints its shapes can be (a point moves at most lever * the turn)."""
        if arm not in self._levers_m:
            self._levers_m[arm] = self.arms[arm].joint_levers_m()
        return self._levers_m[arm]

    def _neighbours(self, arm: str) -> list[str]:
        """Other arms whose bases stand close enough that their links could meet this arm's."""
        return neighbours(self.arms, arm, self.margin_m)

    def check(self, path: TimedPath) -> Verdict:
        """Would this path keep `margin_m` from every other arm? (Does not record anything.) One refused because of
        an arm it stands too close to already, or one that waits for it in turn, is judged again by `_way_out`."""
        neighbours = self._neighbours(path.arm)
        if not neighbours:
            return Verdict("grant", None, math.inf)
        verdict = self._walk(path, neighbours, dict.fromkeys(neighbours, self.margin_m))
        if verdict.decision != "deny":
            return verdict
        return self._way_out(path, neighbours) or verdict

    def _way_out(self, path: TimedPath, neighbours: list[str]) -> Verdict | None:
        """Two arms left close together (by an outside driver) could otherwise never move again, each denied
        because of the other. So a path may come nearer to an arm than the margin where (None: neither holds):
        - it starts within the margin of that arm: never nearer than it starts (less `OUT_TOLERANCE_M`);
        - that arm's own request was denied because of this one (`DeniedArms`): down to `YIELD_M` of the margin.
        The first of the two to ask again moves; the walk's step keeps the clearance every grant keeps."""
        me, thresholds = self.arms[path.arm], {}
        me.place(path.at(path.t_start_s))
        for other in neighbours:
            self.arms[other].place(self._where(other, path.t_start_s))
            start_m = separation_m(me, self.arms[other], below_m=self.margin_m)
            out_m = max(OUT_FLOOR_M, start_m - OUT_TOLERANCE_M) if start_m < self.margin_m else self.margin_m
            yield_m = self.margin_m * (YIELD_M if self.denials().blocks(other, path.arm, path.t_start_s) else 1.0)
            thresholds[other] = min(out_m, yield_m)
        if min(thresholds.values()) >= self.margin_m:
            return None
        return self._walk(path, neighbours, thresholds)

    def denials(self) -> DeniedArms:
        """The arms whose last request was denied, and because of whom."""
        return self._denials

    def _walk(self, path: TimedPath, neighbours: list[str], thresholds: dict[str, float]) -> Verdict:
        """Walk the path by conservative advancement: a grant if it keeps each neighbour's threshold; else wait
        (the nearest arm moves under a grant) or deny."""
        me, closing = self.arms[path.arm], self._closing(path, neighbours)
        lowest, highest = min(thresholds.values()), max(thresholds.values())
        # between two samples the arms close by at most the step: keep what the margin's step keeps (or half)
        kept_m = self.margin_m - self.step_m
        step_m = self.step_m if lowest >= self.margin_m else (lowest - kept_m if lowest > kept_m else lowest / 2)
        closest, closest_arm, when, short = math.inf, None, None, False
        t = path.t_start_s
        self.last_check_samples = 0
        seen: dict[str, tuple[float, float]] = {}  # neighbour -> (when, no nearer than): its last measurement
        while True:
            self.last_check_samples += 1
            me.place(path.at(t))
            here = math.inf
            bounds = {
                o: (seen[o][1] - closing.pair_closed_m(o, seen[o][0], t) if o in seen else -1.0) for o in neighbours
            }
            for other in sorted(neighbours, key=bounds.__getitem__):  # likely nearest first: the rest skip soonest
                if bounds[other] >= here:
                    continue  # it cannot have come nearer than the nearest so far: no need to measure it
                geometry = self.arms[other]
                geometry.place(self._where(other, t))
                d = separation_m(me, geometry, below_m=here)  # no nearer than the nearest so far: not measured
                seen[other] = (t, min(d, here))
                here = min(here, d)
                if d < closest:
                    closest, closest_arm, when = d, other, float(t)
                short = short or d < thresholds[other]
            if short or t >= path.t_done_s:
                break
            t = closing.next_sample_s(t, max(step_m, here - highest), path.t_done_s)
        if not short:
            return Verdict("grant", None, closest)
        other_moves = closest_arm in self.grants and self.grants[closest_arm].t_done_s >= (when or 0.0)
        return Verdict("wait" if other_moves else "deny", closest_arm, closest, when)

    def request(self, path: TimedPath) -> Verdict:
        """Check a path and, if it is clear, grant it (replacing the arm's earlier grant)."""
        verdict = self.check(path)
        if verdict.granted:
            self.grants[path.arm] = path
            self.denials().granted(path.arm)
            if verdict.min_separation_m < self.margin_m:
                self.ways_out = getattr(self, "ways_out", 0) + 1  # (a guard of an older snapshot has none)
        elif verdict.decision == "deny":
            self.denied += 1
            self.denials().denied(path.arm, verdict.conflict_arm, path.t_start_s)
        else:
            self.waits += 1
        return verdict
