"""Mirror mode's report: the deviation of the real arm from its sim copy, over the whole mirror and per goal, as a
table to read and as files (`deviation.json`, `samples.csv`) under `--out`."""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fleet.twin.deviation import (
    MAX_LAG_S,
    Deviation,
    MirrorSample,
    MirrorSeries,
    series_deviation,
    series_deviation_by_goal,
)

REST_STILL_DEG = 0.2  # a sim arm that moved less than this over the lag looked for stands at rest
HOLD_SETTLE_S = 0.25  # a real arm stopped mid-move by a hold comes to rest within this (s)


@dataclass(frozen=True)
class MirrorFigures:
    """The mirror's figures while the line did not hold its arm (`whole`), those of its samples at rest
    (`resting_samples`: what calibration, backlash and noise alone make; None when there were none), each goal's, and
    the holds: how many samples the line held its arm for, and how far the real arm moved while held (the most any
    joint moved within a hold, from `HOLD_SETTLE_S` into it; deg)."""

    whole: Deviation
    at_rest: Deviation | None
    goals: list[Deviation]
    held_samples: int = 0
    held_drift_deg: float = 0.0

    def to_dict(self) -> dict:
        rest = self.at_rest.to_dict() if self.at_rest is not None else None
        return {
            "whole": self.whole.to_dict(),
            "at_rest": rest,
            "goals": [g.to_dict() for g in self.goals],
            "held_samples": self.held_samples,
            "held_drift_deg": self.held_drift_deg,
        }


def held_drift_deg(samples: Sequence[MirrorSample]) -> float:
    """The most any joint of the real arm moved within one hold of the line's, from `HOLD_SETTLE_S` into it."""
    drift, start = 0.0, None
    for i, s in enumerate([*samples, None]):
        if s is not None and s.held:
            start = i if start is None else start
            continue
        if start is not None:
            settled = [
                x.real_q_rad for x in samples[start:i] if x.sim_time_s >= samples[start].sim_time_s + HOLD_SETTLE_S
            ]
            if settled:
                drift = max(drift, float(np.degrees(np.ptp(np.array(settled), axis=0)).max()))
            start = None
    return drift


def resting_samples(samples: Sequence[MirrorSample], still_deg: float = REST_STILL_DEG) -> np.ndarray:
    """The samples at rest (indices): over the `MAX_LAG_S` before each (the real arm had time to get there) no goal
    drove the sim arm, the line did not hold it, and none of its joints moved more than `still_deg`."""
    return _resting(MirrorSeries.of(samples), still_deg)


def _resting(series: MirrorSeries, still_deg: float) -> np.ndarray:
    t, sim = series.t, np.degrees(series.sim)
    free = (series.goal_ids == 0) & ~series.held
    starts = np.searchsorted(t, t - MAX_LAG_S)  # each sample's window: the samples of the lag before it
    out = [
        i
        for i, lo in enumerate(starts)
        if t[i] - t[0] >= MAX_LAG_S and free[lo : i + 1].all() and np.abs(sim[lo : i + 1] - sim[i]).max() <= still_deg
    ]
    return np.array(out, int)


def mirror_figures(samples: Sequence[MirrorSample], joints: Sequence[str]) -> MirrorFigures:
    """Every figure of the report, from the samples made into arrays once."""
    series = MirrorSeries.of(samples)
    resting = _resting(series, REST_STILL_DEG)
    rest = series_deviation(series, joints, resting) if len(resting) else None
    free = np.flatnonzero(~series.held)
    whole = series_deviation(series, joints, free if len(free) else None)
    held = len(samples) - len(free)
    return MirrorFigures(whole, rest, series_deviation_by_goal(series, joints), held, held_drift_deg(samples))


def table(figures: MirrorFigures) -> str:
    """The figures as lines of text: each joint over the whole mirror and at rest, then the worst joint of each
    goal."""
    whole, goals = figures.whole, figures.goals
    lines = [
        f"mirror: {whole.samples} samples over {whole.end_s - whole.start_s:.1f} s of sim time, {len(goals)} goals; "
        f"the real arm lags {whole.lag_s * 1000:.0f} ms",
        "real arm against sim arm (deg): RMSE as read, RMSE lag-aligned, worst point; then each arm's RMSE off the "
        "goals both were sent",
        f"{'joint':<16}{'RMSE':>8}{'aligned':>9}{'worst':>9}{'at s':>8}{'real off':>10}{'sim off':>9}",
    ]
    for j in whole.joints:
        lines.append(
            f"{j.joint:<16}{j.rmse_deg:>8.3f}{j.aligned_rmse_deg:>9.3f}{j.worst_deg:>9.2f}{j.worst_at_s:>8.2f}"
            f"{j.real_off_goal_deg:>10.3f}{j.sim_off_goal_deg:>9.3f}"
        )
    if figures.at_rest is not None:
        rest = ", ".join(f"{j.joint} {j.aligned_rmse_deg:.3f}" for j in figures.at_rest.joints)
        lines.append(f"at rest ({figures.at_rest.samples} samples), RMSE deg: {rest}")
    if figures.held_samples:
        lines.append(
            f"held by the line for {figures.held_samples} samples: the real arm moved at most "
            f"{figures.held_drift_deg:.2f} deg while held"
        )
    for g in goals:
        w = g.worst_joint()
        lines.append(
            f"goal {g.goal_id}: {g.start_s:.2f}-{g.end_s:.2f} s, lag {g.lag_s * 1000:.0f} ms, worst joint {w.joint} "
            f"{w.rmse_deg:.3f} deg RMSE ({w.aligned_rmse_deg:.3f} lag-aligned)"
        )
    return "\n".join(lines)


def write_mirror_files(
    out: Path, samples: Sequence[MirrorSample], joints: Sequence[str], figures: MirrorFigures
) -> list[Path]:
    """`deviation.json` (the figures) and `samples.csv` (every sample, degrees) in `out`; their paths."""
    out.mkdir(parents=True, exist_ok=True)
    written = out / "deviation.json"
    written.write_text(json.dumps(figures.to_dict(), indent=1))
    rows = out / "samples.csv"
    with rows.open("w", newline="") as f:
        writer = csv.writer(f)
        columns = [f"{side}_{j}_deg" for side in ("sim", "real", "commanded") for j in joints]
        writer.writerow(["sim_time_s", "goal_id", "held", *columns])
        for s in samples:
            degrees = [round(math.degrees(v), 4) for v in (*s.sim_q_rad, *s.real_q_rad, *s.commanded_q_rad)]
            writer.writerow([round(s.sim_time_s, 4), s.goal_id, int(s.held), *degrees])
    return [written, rows]
