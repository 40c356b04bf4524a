"""The plant's safety layer: no motion, from any source, brings two arms within the scene's separation.

The coordinator's guard plans grants well; this layer guarantees, below every planner, as an
arm's driver would. Before a tracker takes a trajectory goal (from the skill, an outside
client, a replay) its path is walked against every neighbour's committed path (python-fcl,
conservative advancement as in `coordinator.guard`) and its joint speeds against the
robot's velocity limits; a goal that breaks either is refused with a reason. While arms
move, each pair of neighbours is measured again before it could have closed the gap, and a
motion that brings an arm within the separation (pushed, or running late) is stopped and held.

Every arm is placed with its claw as it is: swept over the openings it may take until its next claw goal (its
measured opening, its claw goal's, a pending one's: `coordinator.claw_sweep`). A claw goal that would widen that
span is walked too, along the arm's committed path, and refused where the wider claw would come too close.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from coordinator.claw_sweep import ClawSpan
from coordinator.geometry import ArmGeometry, neighbours, separation_m
from fleet.sim.safety_speeds import GRID_DT_S, Closing, PathSpeeds, grid_steps
from robots.joint_trajectory import Spline
from robots.saved_state import SavedState
from robots.tracker import ArmTracker

SPEED_SLACK = 1.02  # a spline's peak between two samples may pass a sampled peak by a little
PUSH_SPEED_M_PER_S = (
    0.5  # how fast an arm off its path (pushed, lagging) is assumed to drift when pairs are rescheduled
)
MEASURE_CAP_M = 1.0  # farther than this, a pair's exact distance does not matter to the walk
ROUGH_ENOUGH_M = 0.05  # beyond the floor by this much, the covering spheres' gap (a lower bound) is measure enough

Claws = Callable[[str], ClawSpan]  # each arm's claw: the openings it may take until its next claw goal


@dataclass(frozen=True)
class Refusal:
    """Why a goal may not run: `kind` is `speed` or `separation`; `reason` the sentence the goal's result carries."""

    kind: str
    reason: str


class SafetyState(SavedState, frozen=True):
    """What `PlantSafety` saves: its counts and when each pair of neighbours is next measured (its paths' speed
    bounds are worked out again from the paths)."""

    refused: dict[str, int]
    stopped: int
    due_s: list[tuple[str, str, float]]


@dataclass
class SafetyCounts:
    """What the layer did in a run: goals refused by kind, motions stopped."""

    refused: Counter = field(default_factory=Counter)
    stopped: int = 0


def _peak_speeds(spline: Spline, samples: int = 64) -> np.ndarray:
    """Each joint's largest |velocity| along the spline (its servo grid when it has one)."""
    if spline.grid_dq is not None and len(spline.grid_dq):
        return np.abs(spline.grid_dq).max(axis=0)
    times = np.linspace(spline.t0_s, spline.moves_until_s, samples)  # over its motion: a held tail does not move
    return np.abs(spline.dpoly(times)).max(axis=0)


class PlantSafety:
    """Checks goals and watches moving arms of one cell; `geometries` place each arm's shapes in the world."""

    def __init__(
        self,
        geometries: dict[str, ArmGeometry],
        separation_m: float,
        velocity_limits: dict[str, np.ndarray],
        step_m: float = 0.01,
    ) -> None:
        self.geometries, self.separation_m, self.step_m = geometries, float(separation_m), step_m
        self.velocity_limits = velocity_limits
        self.levers_m = {name: g.joint_levers_m() for name, g in geometries.items()}
        self.path_speeds = PathSpeeds(self.levers_m)
        self.neighbours = {name: neighbours(geometries, name, self.separation_m) for name in geometries}
        self.counts = SafetyCounts()
        self._due_s: dict[tuple[str, str], float] = {}  # when each pair of neighbours is next measured

    def state(self) -> SafetyState:
        return SafetyState(
            refused=dict(self.counts.refused),
            stopped=self.counts.stopped,
            due_s=[(a, b, t) for (a, b), t in self._due_s.items()],
        )

    def restore(self, state: SafetyState) -> None:
        self.counts = SafetyCounts(Counter(state.refused), state.stopped)
        self._due_s = {(a, b): t for a, b, t in state.due_s}

    def report(self) -> dict:
        """The run summary's part: goals refused by kind, motions stopped, the separation kept."""
        return {
            "safety_refused_goals": dict(sorted(self.counts.refused.items())),
            "safety_stops": self.counts.stopped,
            "safety_separation_m": self.separation_m,
        }

    # --- goals ------------------------------------------------------------------------
    def refusal(self, arm: str, spline: Spline, trackers: dict[str, ArmTracker], claws: Claws) -> Refusal | None:
        """Why `arm` may not follow `spline` from its start (None: it may), given every arm's committed path and
        claw."""
        why = self._speed_refusal(arm, spline) or self._walk_refusal(
            arm,
            spline.t0_s,
            [spline],
            lambda k, t: spline.q_at(t) if k is None else self._q_on_grid(arm, spline, k, t),
            claws(arm),
            "its path",
            trackers,
            claws,
        )
        if why is not None:
            self.counts.refused[why.kind] += 1
        return why

    def claw_refusal(
        self, arm: str, opening: float, now_s: float, trackers: dict[str, ArmTracker], claws: Claws
    ) -> Refusal | None:
        """Why `arm`'s claw may not go to `opening` now (None: it may): only a claw that would reach past the
        openings it may already take is walked, along the arm's committed path."""
        span = claws(arm).union(opening)
        if claws(arm).holds(span):
            return None
        tracker = trackers[arm]
        why = self._walk_refusal(
            arm,
            now_s,
            [a.spline for a in (tracker.active, tracker.next) if a is not None],
            lambda k, t: tracker.path_q(t) if k is None else self._path_on_grid(arm, tracker, k, t),
            span,
            f"its claw opened to {opening:.2f}",
            trackers,
            claws,
        )
        if why is not None:
            self.counts.refused[why.kind] += 1
        return why

    def _speed_refusal(self, arm: str, spline: Spline) -> Refusal | None:
        limit = self.velocity_limits[arm]
        peak = _peak_speeds(spline)
        over = np.flatnonzero(peak > limit * SPEED_SLACK + 1e-9)
        if not over.size:
            return None
        j = int(over[0])
        name = self.geometries[arm].spec.arm_joints[j]
        return Refusal("speed", f"{name} would turn at {peak[j]:.3g} rad/s; its limit is {limit[j]:.3g} rad/s")

    def _point_speed_m_per_s(self, arm: str, spline: Spline | None) -> float:
        """An upper bound on how fast any point of `arm` moves along `spline` (0 for an arm that holds)."""
        if spline is None or spline.moves_until_s <= spline.t0_s:
            return 0.0
        return float(_peak_speeds(spline) @ self.levers_m[arm])

    def _tracker_speed_m_per_s(self, arm: str, tracker: ArmTracker, t_s: float) -> float:
        """An upper bound on how fast any point of `arm` moves along its committed path from `t_s` on."""
        return max(
            (
                self._point_speed_m_per_s(arm, a.spline)
                for a in (tracker.active, tracker.next)
                if a is not None and a.spline.moves_until_s > t_s
            ),
            default=0.0,
        )

    def _walk_refusal(
        self,
        arm: str,
        t0: float,
        my_splines: list[Spline],
        my_q: Callable[[int | None, float], np.ndarray],
        my_claw: ClawSpan,
        what: str,
        trackers: dict[str, ArmTracker],
        claws: Claws,
    ) -> Refusal | None:
        """Conservative advancement per neighbour, from `t0` along `arm`'s path (`my_q(k, t)`: its joints at grid
        step k, or exactly at t where k is None) with its claw over `my_claw`: after measuring a gap d to a
        neighbour, the two cannot close it before (d - floor) / (both speed bounds), so that neighbour is not
        measured again until then."""
        others = self.neighbours[arm]
        if not others:
            return None
        me = self.geometries[arm]
        # until everything rests: a goal holding its last point for an hour is walked no further than its motion
        t_end = max([t0] + [s.moves_until_s for s in my_splines] + [trackers[o].committed_end_s() for o in others])
        ka, kb = grid_steps(t0, t_end)
        kb = max(kb, ka + 1)
        grid = np.arange(ka, kb + 1) * GRID_DT_S
        mine = self.path_speeds.on(arm, my_splines, ka, kb)
        committed = lambda o: [a.spline for a in (trackers[o].active, trackers[o].next) if a is not None]  # noqa: E731
        closing = {o: Closing(grid, mine + self.path_speeds.on(o, committed(o), ka, kb)) for o in others}
        # an arm already within the separation (pushed there) may move, but never closer than it is with its claw
        # as it is now
        me.place(my_q(None, t0), claws(arm))
        gaps = {o: self._gap(me, o, trackers[o].path_q(t0), claws(o), math.inf) for o in others}
        floor_m = min(self.separation_m, min(gaps.values()) - 1e-4)
        if my_claw != claws(arm):
            me.place(my_q(None, t0), my_claw)
            gaps = {o: self._gap(me, o, trackers[o].path_q(t0), claws(o), math.inf) for o in others}
        due = {o: closing[o].time_to_close(t0, max(self.step_m, d - floor_m)) for o, d in gaps.items()}
        for o, d in gaps.items():
            if d < floor_m:
                return self._separation(what, o, d, t0)
        last_k = ka
        while (t := min(due.values())) <= t_end:  # past the end: every pair keeps its gap until all rest
            now = [o for o, at in due.items() if at <= t]
            k = math.floor(t / GRID_DT_S + 1e-9)
            if k > last_k and k * GRID_DT_S >= t0:  # measured at the grid step before: earlier is never late
                t, last_k = k * GRID_DT_S, k
                me.place(my_q(k, t), my_claw)
                where = lambda o, k=k, t=t: self._path_on_grid(o, trackers[o], k, t)  # noqa: E731
            else:  # no grid step left before it is due: exactly then
                me.place(my_q(None, t), my_claw)
                where = lambda o, t=t: trackers[o].path_q(t)  # noqa: E731
            for o in now:
                d = self._gap(me, o, where(o), claws(o), floor_m + ROUGH_ENOUGH_M)
                if d < floor_m:
                    return self._separation(what, o, d, t)
                due[o] = closing[o].time_to_close(t, max(self.step_m, d - floor_m)) if t < t_end else math.inf
        return None

    def _separation(self, what: str, other: str, d: float, t: float) -> Refusal:
        return Refusal(
            "separation",
            f"{what} comes within {max(d, 0.0) * 1000:.0f} mm of {other} at t={t:.2f} s "
            f"(the plant keeps {self.separation_m * 1000:.0f} mm)",
        )

    def _q_on_grid(self, arm: str, spline: Spline, k: int, t_s: float) -> np.ndarray:
        q = self.path_speeds.q_at_step(arm, spline, k) if spline.t0_s <= t_s <= spline.t_end_s else None
        return spline.q_at(t_s) if q is None else q

    def _path_on_grid(self, arm: str, tracker: ArmTracker, k: int, t_s: float) -> np.ndarray:
        """`tracker.path_q(t_s)` at grid step k (t_s = k * dt), read from the committed paths' samples."""
        if tracker.next is not None and t_s >= tracker.next.spline.t0_s:
            return self._q_on_grid(arm, tracker.next.spline, k, t_s)
        if tracker.active is not None:
            return self._q_on_grid(arm, tracker.active.spline, k, t_s)
        return tracker.hold_q

    def _gap(self, me: ArmGeometry, other: str, q_other: np.ndarray, claw: ClawSpan, rough_above_m: float) -> float:
        """The distance from `me` (placed) to `other` at joints `q_other` with its claw over `claw`; where the
        spheres covering both arms already stand `rough_above_m` apart, their gap (a lower bound, enough to step
        on)."""
        g = self.geometries[other]
        g.place(q_other, claw)
        return _distance_m(me, g, rough_above_m)

    # --- motions ----------------------------------------------------------------------
    def too_close(
        self,
        now_s: float,
        measured_q: Callable[[str], np.ndarray],
        trackers: dict[str, ArmTracker],
        claws: Claws,
    ) -> list[str]:
        """Moving arms that are within the separation of a neighbour and whose path takes them closer still: the
        caller stops them. Each pair is measured again only when it could have closed its gap."""
        stop: set[str] = set()
        for a, b in self._pairs_due(now_s, trackers):
            ga, gb = self.geometries[a], self.geometries[b]
            ga.place(measured_q(a), claws(a))
            gb.place(measured_q(b), claws(b))
            d = _distance_m(ga, gb, self.separation_m + ROUGH_ENOUGH_M)
            if d < self.separation_m:
                stop |= self._closing(a, b, d, now_s, measured_q, trackers, claws)
                self._due_s[_pair(a, b)] = now_s
            else:
                speed = sum(self._tracker_speed_m_per_s(x, trackers[x], now_s) + PUSH_SPEED_M_PER_S for x in (a, b))
                self._due_s[_pair(a, b)] = now_s + (d - self.separation_m) / speed
        self.counts.stopped += len(stop)
        return sorted(stop)

    def _pairs_due(self, now_s: float, trackers: dict[str, ArmTracker]) -> list[tuple[str, str]]:
        moving = {name for name, t in trackers.items() if t.committed_end_s() >= now_s}
        return [
            (a, b)
            for a in sorted(moving)
            for b in self.neighbours[a]
            if (b not in moving or a < b) and self._due_s.get(_pair(a, b), -math.inf) <= now_s
        ]

    def _closing(
        self,
        a: str,
        b: str,
        d: float,
        now_s: float,
        measured_q: Callable[[str], np.ndarray],
        trackers: dict[str, ArmTracker],
        claws: Claws,
    ) -> set[str]:
        """Of two arms within the separation, the moving ones whose next committed pose is closer than now."""
        out = set()
        for me, other in ((a, b), (b, a)):
            tracker = trackers[me]
            if tracker.committed_end_s() < now_s:
                continue
            g, go = self.geometries[me], self.geometries[other]
            g.place(tracker.path_q(now_s + 0.05), claws(me))
            go.place(measured_q(other), claws(other))
            if separation_m(g, go, below_m=MEASURE_CAP_M) <= d:
                out.add(me)
        return out


def _distance_m(a: ArmGeometry, b: ArmGeometry, rough_above_m: float) -> float:
    """The distance between two placed arms: the gap of the spheres covering them (a lower bound) where that is
    `rough_above_m` or more, else python-fcl's (capped at `MEASURE_CAP_M`)."""
    bound = float(a.sphere_gaps(b).min())
    return bound if bound >= rough_above_m else separation_m(a, b, below_m=MEASURE_CAP_M)


def _pair(a: str, b: str) -> tuple[str, str]:
    return (a, b) if a < b else (b, a)
