"""Time-parametrised joint trajectories: quintic segments timed from the joints' velocity limits."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BPoly

QUINTIC_PEAK_SPEED = 1.875  # peak / mean speed of the 10t^3 - 15t^4 + 6t^5 profile


def quintic(tau: float) -> float:
    """The rest-to-rest time law 10t^3 - 15t^4 + 6t^5 (0 to 1 as `tau` goes 0 to 1, clamped)."""
    tau = min(max(tau, 0.0), 1.0)
    return tau**3 * (10 - 15 * tau + 6 * tau**2)


@dataclass(frozen=True)
class JointSegment:
    """A rest-to-rest move from `q_start` to `q_end`, starting at `t0_s` and lasting `duration_s`."""

    q_start: np.ndarray
    q_end: np.ndarray
    t0_s: float
    duration_s: float

    @classmethod
    def timed(
        cls,
        q_start: np.ndarray,
        q_end: np.ndarray,
        t0_s: float,
        velocity_limit: np.ndarray,
        speed_fraction: float = 0.6,
        min_duration_s: float = 0.25,
    ) -> JointSegment:
        """A segment as fast as `speed_fraction` of every joint's velocity limit allows."""
        delta = np.abs(np.asarray(q_end) - np.asarray(q_start))
        needed = float(np.max(delta * QUINTIC_PEAK_SPEED / (velocity_limit * speed_fraction))) if delta.size else 0.0
        return cls(np.asarray(q_start, float), np.asarray(q_end, float), t0_s, max(min_duration_s, needed))

    @property
    def t_end_s(self) -> float:
        return self.t0_s + self.duration_s

    def sample(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity at time `t_s` (held at the ends)."""
        tau = min(max((t_s - self.t0_s) / self.duration_s, 0.0), 1.0)
        s = quintic(tau)
        ds = 30 * tau**2 * (1 - tau) ** 2 / self.duration_s
        if tau >= 1.0:
            ds = 0.0
        delta = self.q_end - self.q_start
        return self.q_start + s * delta, ds * delta

    def state_at(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at time `t_s` (at rest at the ends)."""
        q, dq = self.sample(t_s)
        tau = (t_s - self.t0_s) / self.duration_s
        dds = 0.0 if not 0.0 < tau < 1.0 else (60 * tau - 180 * tau**2 + 120 * tau**3) / self.duration_s**2
        return q, dq, dds * (self.q_end - self.q_start)

    def done(self, t_s: float) -> bool:
        return t_s >= self.t_end_s


SPLICE_SPEED_FRACTION = 0.95  # a move spliced into a moving arm keeps every joint under this share of its limit


def spliced_duration_s(
    moving: JointSegment, start_s: float, q_end: np.ndarray, duration_s: float, velocity_limit: np.ndarray
) -> float | None:
    """How long a move to rest at `q_end` must last when it starts at `start_s` while the arm follows `moving`: the
    tracker splices it in from the arm's position, velocity and acceleration there (a quintic to rest), and a
    duration timed for a start at rest may then turn a joint past its limit (the plant refuses such a goal).
    The shortest of `duration_s` stretched by up to 3x in which no joint passes `SPLICE_SPEED_FRACTION` of its
    limit (or the speed it already turns at, if faster); None if none does (a longer move overshoots further
    against the arm's way: start it once `moving` has ended). `duration_s` as it is at rest."""
    if not moving.t0_s < start_s < moving.t_end_s:
        return duration_s
    q0, dq0, ddq0 = moving.state_at(start_s)
    ends = np.stack([np.stack([q0, dq0, ddq0]), np.stack([np.asarray(q_end, float), 0 * q0, 0 * q0])])
    allowed = np.maximum(np.asarray(velocity_limit, float) * SPLICE_SPEED_FRACTION, np.abs(dq0) + 1e-6)  # (as fast)
    u = np.linspace(0.0, 1.0, 65)
    for stretch in np.arange(1.0, 3.0001, 0.05):
        duration = duration_s * stretch
        speed = BPoly.from_derivatives([0.0, duration], ends).derivative()
        if (np.abs(speed(u * duration)).max(axis=0) <= allowed).all():
            return float(duration)
    return None


def spliced(
    moving: JointSegment | None, seg: JointSegment, start_s: float, velocity_limit: np.ndarray
) -> tuple[JointSegment, float]:
    """A free move `seg` and its start as it will run from `start_s`, if the move sent before, `moving`, is still
    under way then (a task taken on the way home: the tracker splices the new move in at speed): from where that
    move has got to, stretched to keep within the joints' limits; or, where no stretch does, from that move's end,
    at rest. `seg` and `start_s` as they are otherwise."""
    if moving is None or not moving.t0_s < start_s < moving.t_end_s:
        return seg, start_s
    duration = spliced_duration_s(moving, start_s, seg.q_end, seg.duration_s, velocity_limit)
    if duration is not None:
        return JointSegment(moving.sample(start_s)[0], seg.q_end, start_s, duration), start_s
    at_rest = JointSegment.timed(moving.q_end, seg.q_end, moving.t_end_s, velocity_limit, 1.0).duration_s
    as_timed = JointSegment.timed(seg.q_start, seg.q_end, start_s, velocity_limit, 1.0).duration_s
    duration = seg.duration_s * at_rest / as_timed if as_timed > 0 else seg.duration_s
    return JointSegment(moving.q_end, seg.q_end, moving.t_end_s, duration), moving.t_end_s


def knot_velocities(times_s: np.ndarray, qs: np.ndarray) -> np.ndarray:
    """Velocities at the knots of a joint path (finite differences), at rest at the last knot."""
    dq = np.gradient(qs, times_s, axis=0) if len(times_s) > 1 else np.zeros_like(qs)
    dq[-1] = 0.0
    return dq


def _piece_peaks(q_start: np.ndarray, times_s: np.ndarray, qs: np.ndarray, samples: int = 16) -> np.ndarray:
    """Each piece's largest |joint velocity| / per joint, (pieces, joints), of the cubic a tracker builds from rest
    at `q_start` through the knots."""
    knots = np.concatenate([[0.0], times_s])
    pos = np.vstack([q_start, qs])
    vel = np.vstack([np.zeros_like(q_start), knot_velocities(times_s, qs)])
    dpoly = BPoly.from_derivatives(knots, np.stack([pos, vel], axis=1)).derivative()
    u = np.linspace(0.0, 1.0, samples)
    at = knots[:-1, None] + np.diff(knots)[:, None] * u[None]
    return np.abs(dpoly(at.ravel())).reshape(len(times_s), samples, -1).max(axis=1)


def within_velocity_limits(
    q_start: np.ndarray, times_s: np.ndarray, qs: np.ndarray, velocity_limit: np.ndarray, rounds: int = 8
) -> np.ndarray:
    """The knot times of a joint path stretched where a piece would turn a joint faster than its limit allows
    (an IK path that swings a joint: a redundant arm's null space, a wrist near its singularity); unchanged where
    none does. The path starts at rest at `q_start`; a piece too fast is stretched by how far it is over."""
    times = np.asarray(times_s, float).copy()
    q_start, qs = np.asarray(q_start, float), np.asarray(qs, float)
    allowed = np.asarray(velocity_limit, float) * 0.98
    for _ in range(rounds):
        over = (_piece_peaks(q_start, times, qs) / allowed).max(axis=1)
        if over.max() <= 1.0:
            break
        pieces = np.diff(np.concatenate([[0.0], times])) * np.maximum(over, 1.0)
        times = np.cumsum(pieces)
    return times
