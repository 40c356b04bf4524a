"""How far a real arm strays from its sim copy in mirror mode: per goal and joint, the RMSE of their joint angles
as read, the lag that best lines the real arm up behind the sim's (a servo bus and its driver take time), the RMSE
once lined up, and the worst point; and, to tell which side strayed, each arm's RMSE off the goal both were sent.
Plain numbers over plain samples: `fleet twin mirror` gathers the samples."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np

MAX_LAG_S = 0.5  # the longest lag looked for
LAG_STEP_S = 0.005


@dataclass(frozen=True)
class MirrorSample:
    """One read of both arms: the sim arm's state (its sim time, the goal driving it: 0 none, whether the line held
    it), the real arm's joints read just after, and the goal then sent to the real arm (rad, the arm's joints in
    order; the gripper is left out: a sim claw stops on a part)."""

    sim_time_s: float
    goal_id: int
    sim_q_rad: tuple[float, ...]
    real_q_rad: tuple[float, ...]
    commanded_q_rad: tuple[float, ...]
    held: bool = False


@dataclass(frozen=True)
class JointDeviation:
    joint: str
    rmse_deg: float  # real against sim, as read at the same moment
    aligned_rmse_deg: float  # ... with the real arm's reads set back by the lag
    worst_deg: float  # the largest deviation as read (signed: real - sim)
    worst_at_s: float  # its sim time
    real_off_goal_deg: float  # the real arm's RMSE off the goals it was sent (set back by the lag)
    sim_off_goal_deg: float  # the sim arm's RMSE off the same goals (its tracker's desired joints)


@dataclass(frozen=True)
class Deviation:
    """One stretch of samples (a goal, or the whole mirror): its lag and each joint's figures."""

    goal_id: int  # 0: the whole mirror (every sample, goals or not)
    start_s: float
    end_s: float
    samples: int
    lag_s: float
    joints: tuple[JointDeviation, ...]

    def worst_joint(self) -> JointDeviation:
        return max(self.joints, key=lambda j: j.aligned_rmse_deg)

    def to_dict(self) -> dict:
        return asdict(self)


def _rmse_behind(t: np.ndarray, ref: np.ndarray, real: np.ndarray, pick: np.ndarray, lag_s: float) -> np.ndarray:
    """Each joint's RMSE (rad) of `real` at the samples `pick` against `ref` `lag_s` earlier (interpolated over the
    whole series; a sample read sooner than `lag_s` after the first has nothing to line up with and is left out)."""
    lined_up = pick[t[pick] - lag_s >= t[0]]
    pick = lined_up if len(lined_up) else pick
    shifted = np.column_stack([np.interp(t[pick] - lag_s, t, ref[:, j]) for j in range(ref.shape[1])])
    return np.sqrt(np.mean((real[pick] - shifted) ** 2, axis=0))


def best_lag_s(t: np.ndarray, ref: np.ndarray, real: np.ndarray, pick: np.ndarray, max_lag_s: float) -> float:
    """The lag (s, 0..`max_lag_s`) at which `real` at the samples `pick` best matches `ref` that much earlier."""
    lags = np.arange(0.0, max_lag_s + LAG_STEP_S / 2, LAG_STEP_S)
    errors = [_rmse_behind(t, ref, real, pick, lag).mean() for lag in lags]
    return float(lags[int(np.argmin(errors))])


@dataclass(frozen=True)
class MirrorSeries:
    """Samples as arrays, built once for all the figures judged on them: sim times, the sim arm's, the real arm's
    and the commanded joints (rad, one row a sample), each sample's goal and whether the line held its arm."""

    t: np.ndarray
    sim: np.ndarray
    real: np.ndarray
    sent: np.ndarray
    goal_ids: np.ndarray
    held: np.ndarray

    @classmethod
    def of(cls, samples: Sequence[MirrorSample]) -> MirrorSeries:
        if not samples:
            raise ValueError("no samples to judge")
        rows = lambda field: np.array([getattr(s, field) for s in samples], float)  # noqa: E731
        return cls(
            t=rows("sim_time_s"),
            sim=rows("sim_q_rad"),
            real=rows("real_q_rad"),
            sent=rows("commanded_q_rad"),
            goal_ids=np.array([s.goal_id for s in samples]),
            held=np.array([s.held for s in samples], bool),
        )


def deviation(
    samples: Sequence[MirrorSample], joints: Sequence[str], pick: np.ndarray | None = None, goal_id: int = 0
) -> Deviation:
    """The figures of the samples `pick` (indices; default all), the lag looked for against the whole series."""
    return series_deviation(MirrorSeries.of(samples), joints, pick, goal_id)


def series_deviation(
    series: MirrorSeries, joints: Sequence[str], pick: np.ndarray | None = None, goal_id: int = 0
) -> Deviation:
    """`deviation` of samples already as arrays."""
    t, sim, real, sent = series.t, series.sim, series.real, series.sent
    pick = np.arange(len(t)) if pick is None else np.asarray(pick)
    if len(pick) == 0:
        raise ValueError("no samples to judge")
    lag = best_lag_s(t, sim, real, pick, MAX_LAG_S) if len(t) > 1 else 0.0
    aligned = np.degrees(_rmse_behind(t, sim, real, pick, lag))
    real_off = np.degrees(_rmse_behind(t, sent, real, pick, lag))
    sim_off = np.degrees(np.sqrt(np.mean((sim[pick] - sent[pick]) ** 2, axis=0)))
    off = np.degrees(real[pick] - sim[pick])
    worst = np.argmax(np.abs(off), axis=0)
    figures = tuple(
        JointDeviation(
            joint=name,
            rmse_deg=float(np.sqrt(np.mean(off[:, j] ** 2))),
            aligned_rmse_deg=float(aligned[j]),
            worst_deg=float(off[worst[j], j]),
            worst_at_s=float(t[pick][worst[j]]),
            real_off_goal_deg=float(real_off[j]),
            sim_off_goal_deg=float(sim_off[j]),
        )
        for j, name in enumerate(joints)
    )
    return Deviation(goal_id, float(t[pick][0]), float(t[pick][-1]), len(pick), lag, figures)


def deviation_by_goal(samples: Sequence[MirrorSample], joints: Sequence[str], min_samples: int = 3) -> list[Deviation]:
    """One `Deviation` for each goal that drove the sim arm over at least `min_samples` samples, in order."""
    return series_deviation_by_goal(MirrorSeries.of(samples), joints, min_samples)


def series_deviation_by_goal(series: MirrorSeries, joints: Sequence[str], min_samples: int = 3) -> list[Deviation]:
    """`deviation_by_goal` of samples already as arrays."""
    goals = series.goal_ids
    ordered = list(dict.fromkeys(int(g) for g in goals if g != 0))
    picks = [(g, np.flatnonzero(goals == g)) for g in ordered]
    return [series_deviation(series, joints, pick, g) for g, pick in picks if len(pick) >= min_samples]
