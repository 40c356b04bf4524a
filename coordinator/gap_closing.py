"""How far an arm asking for a move and its neighbours can close on each other over a stretch of time: the bound
the guard's walk steps by (`CollisionGuard.check`).

A point of an arm moves at most sum_j lever_j |dq_j| (`ArmGeometry.joint_levers_m`). Along a granted path that is
exact to integrate: the move follows the rest-to-rest quintic, so by time t a point has travelled at most the
move's levered travel times quintic(tau); the local stage after it is straight pieces at a steady pace. A walk
that steps by this cumulative travel takes long steps where the arms move slowly (near the ends of a move, where
two arms at a shared station are close) and short ones only where they are fast.
"""

from __future__ import annotations

import bisect

import numpy as np

from robots.trajectory import QUINTIC_PEAK_SPEED, quintic

REFINE_STEPS = 4  # halvings of the last doubling of the step (its length to within a sixteenth)


class PathTravel:
    """How far any point of one arm can have moved along a timed path (`coordinator.guard.TimedPath`) since its
    start, as a function of time (metres, non-decreasing)."""

    def __init__(self, path, levers_m: np.ndarray, standing_at: np.ndarray | None = None) -> None:
        self.t_start_s, self.t_end_s = path.t_start_s, path.t_end_s
        self.move_m = path.travel_m(levers_m)
        # an arm placed where it stands until its path starts: the step to the path's first pose, at its start
        self.jump_m = 0.0 if standing_at is None else float(np.abs(np.asarray(path.q_from) - standing_at) @ levers_m)
        span = self.t_end_s - self.t_start_s
        self.span_s = span
        self.times_s: list[float] = []
        self.cumulative_m: list[float] = []
        if path.then_q:
            poses = np.vstack([path.q_to, path.then_q])
            pieces = np.abs(np.diff(poses, axis=0)) @ levers_m
            self.times_s = [path.t_end_s, *(path.t_end_s + np.asarray(path.then_after_s, float)).tolist()]
            self.cumulative_m = [0.0, *np.cumsum(pieces).tolist()]
        move_peak = QUINTIC_PEAK_SPEED * self.move_m / span if span > 0 else 0.0
        local_peak = max(
            (
                (b - a) / max(tb - ta, 1e-9)
                for a, b, ta, tb in zip(self.cumulative_m, self.cumulative_m[1:], self.times_s, self.times_s[1:])
            ),
            default=0.0,
        )
        self.peak_m_per_s = max(move_peak, local_peak)

    def at(self, t_s: float) -> float:
        """The most any point has moved from the path's start until `t_s` (from where the arm stood before it)."""
        if t_s < self.t_start_s - 1e-9:
            return 0.0
        return self.jump_m + self._along(t_s)

    def _along(self, t_s: float) -> float:
        if t_s <= self.t_start_s:
            return 0.0
        if t_s < self.t_end_s:
            return self.move_m * quintic((t_s - self.t_start_s) / self.span_s)
        if not self.times_s or t_s <= self.t_end_s:
            return self.move_m
        k = bisect.bisect_right(self.times_s, t_s)
        if k >= len(self.times_s):
            return self.move_m + self.cumulative_m[-1]
        ta, tb = self.times_s[k - 1], self.times_s[k]
        ca, cb = self.cumulative_m[k - 1], self.cumulative_m[k]
        return self.move_m + ca + (cb - ca) * (t_s - ta) / max(tb - ta, 1e-12)


class GapClosing:
    """How far the asking arm and any one of its moving neighbours can close their gap between two times: the
    asker's travel plus the most any one neighbour travels (each pair is measured apart)."""

    def __init__(self, mine: PathTravel, others: dict[str, PathTravel]) -> None:
        self.mine, self.others = mine, others
        self.peak_m_per_s = mine.peak_m_per_s + max((o.peak_m_per_s for o in others.values()), default=0.0)

    def closed_m(self, t0_s: float, t1_s: float) -> float:
        own = self.mine.at(t1_s) - self.mine.at(t0_s)
        return own + max((o.at(t1_s) - o.at(t0_s) for o in self.others.values()), default=0.0)

    def pair_closed_m(self, other: str, t0_s: float, t1_s: float) -> float:
        """How far the asker and `other` (a still arm if it has no path here) can close their gap in between."""
        own = self.mine.at(t1_s) - self.mine.at(t0_s)
        theirs = self.others.get(other)
        return own if theirs is None else own + theirs.at(t1_s) - theirs.at(t0_s)

    def next_sample_s(self, t_s: float, gap_m: float, last_s: float) -> float:
        """The latest time up to `last_s` by which the arms cannot have closed `gap_m` from `t_s` on: from the step
        at their peak speeds (always safe) doubled while it stays safe, then refined by `REFINE_STEPS` halvings."""
        if self.closed_m(t_s, last_s) <= gap_m:
            return last_s
        lo = gap_m / self.peak_m_per_s  # short of last_s: at the peak speeds they would close no more than gap_m
        while True:
            hi = min(2.0 * lo, last_s - t_s)
            if self.closed_m(t_s, t_s + hi) > gap_m:
                break
            lo = hi
        for _ in range(REFINE_STEPS):
            mid = 0.5 * (lo + hi)
            if self.closed_m(t_s, t_s + mid) <= gap_m:
                lo = mid
            else:
                hi = mid
        return t_s + lo
