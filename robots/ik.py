"""Damped-least-squares inverse kinematics with joint limits (Pinocchio), for full poses or position + approach axis.

IK never returns a silent wrong answer: the result says whether it converged
and carries the residual position and angle errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robots.kinematics import KinematicModel


@dataclass(frozen=True)
class IKResult:
    """Outcome of an IK solve: full configuration, success flag and residuals (metres, radians)."""

    q: np.ndarray
    success: bool
    position_error_m: float
    angle_error_rad: float
    iterations: int


@dataclass(frozen=True)
class IKOptions:
    """Tolerances and step control of the solver."""

    tolerance_m: float = 1e-4
    tolerance_rad: float = 1e-3
    max_iterations: int = 150
    damping: float = 1e-2
    max_step_rad: float = 0.3
    restarts: int = 4
    seed: int = 0
    stall_iterations: int = 25  # give an attempt up when its error has not dropped by 1% for this many iterations
    rotation_weight: float = 1.0  # below 1: position matters more than orientation where both cannot be met


def _axis_error(current_axis: np.ndarray, target_axis: np.ndarray) -> np.ndarray:
    """Rotation vector turning `current_axis` onto `target_axis` (both unit vectors, base frame).

    Plain floats: on 3-vectors numpy's cross and norm cost more in call overhead than the arithmetic (the solver
    calls this every iteration)."""
    (ax, ay, az), (bx, by, bz) = current_axis.tolist(), target_axis.tolist()
    wx, wy, wz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    s, c = math.sqrt(wx * wx + wy * wy + wz * wz), ax * bx + ay * by + az * bz
    if s < 1e-12:
        if c > 0:
            return np.zeros(3)
        perp = np.cross(current_axis, [1.0, 0.0, 0.0])
        if np.linalg.norm(perp) < 1e-6:
            perp = np.cross(current_axis, [0.0, 1.0, 0.0])
        return perp / np.linalg.norm(perp) * np.pi
    k = math.atan2(s, c) / s
    return np.array([wx * k, wy * k, wz * k])


def _norm(v: np.ndarray) -> float:
    return math.sqrt(float(v @ v))


def _solve_once(
    km: KinematicModel,
    target: np.ndarray,
    q0: np.ndarray,
    axis_tool: np.ndarray | None,
    opts: IKOptions,
    cols: np.ndarray,
) -> IKResult:
    q = km.clamp(q0.copy())  # cols: the joints moved (revolute/prismatic joints: idx_v == idx_q)
    p_t, r_t = target[:3, 3], target[:3, :3]
    axis_target = None if axis_tool is None else r_t @ axis_tool
    model, data, frame = km.model, km.data, km.tool_frame_id
    damping = (opts.damping**2) * np.eye(6)
    lower, upper, step = km.lower, km.upper, opts.max_step_rad
    pos_err = ang_err = np.inf
    best_err, best_at = np.inf, 0
    for it in range(1, opts.max_iterations + 1):
        # forward kinematics too
        jac = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)[:, cols]
        pose = pin.updateFramePlacement(model, data, frame)  # the tool's pose at q, from that pass
        p, r = pose.translation, pose.rotation
        e_pos = p_t - p
        if axis_target is None:
            e_rot = pin.log3(r_t @ r.T)
            j = jac
        else:
            a = r @ axis_tool
            e_rot = _axis_error(a, axis_target)
            e_rot = e_rot - a * float(a @ e_rot)  # rotation about the approach axis is free: (I - a a^T) e
            j = jac.copy()
            j[3:] -= np.outer(a, a @ jac[3:])
        pos_err, ang_err = _norm(e_pos), _norm(e_rot)
        if pos_err < opts.tolerance_m and ang_err < opts.tolerance_rad:
            return IKResult(q, True, pos_err, ang_err, it)
        err = pos_err + 0.1 * ang_err
        if err < 0.99 * best_err:
            best_err, best_at = err, it
        elif it - best_at >= opts.stall_iterations:  # stuck (a joint limit, out of reach): a restart does better
            return IKResult(q, False, pos_err, ang_err, it)
        if opts.rotation_weight != 1.0:
            e_rot, j = e_rot * opts.rotation_weight, np.vstack([j[:3], j[3:] * opts.rotation_weight])
        e = np.concatenate([e_pos, e_rot])
        dq = j.T @ np.linalg.solve(j @ j.T + damping, e)
        q[cols] += np.minimum(np.maximum(dq, -step), step)
        q = np.minimum(np.maximum(q, lower), upper)  # np.clip's own overhead is twice these two ufuncs'
    return IKResult(q, False, pos_err, ang_err, opts.max_iterations)


def solve_ik(
    km: KinematicModel,
    transform_target_to_base: np.ndarray,
    q_start: np.ndarray,
    *,
    approach_axis_only: bool = False,
    options: IKOptions = IKOptions(),
    locked: tuple[int, ...] = (),
) -> IKResult:
    """Joint configuration putting the tool at a target pose in the base frame.

    With `approach_axis_only`, only the target's position and the direction of
    the tool's approach axis are matched (rotation about that axis is free), as
    a 5-DoF arm needs. Arm joints listed in `locked` (indices into the arm's joints) stay as
    `q_start` has them. Starts from `q_start`, then from seeded random configurations; returns
    the best attempt, flagged unsuccessful if none converged.
    """
    axis = np.asarray(km.spec.approach_axis_tool, dtype=float) if approach_axis_only else None
    cols = np.delete(km.arm_q_index, list(locked)) if locked else km.arm_q_index
    best = _solve_once(km, transform_target_to_base, q_start, axis, options, cols)
    rng = np.random.default_rng(options.seed)
    for _ in range(options.restarts):
        if best.success:
            break
        q_seed = q_start.copy()
        q_seed[cols] = rng.uniform(km.lower[cols], km.upper[cols])
        attempt = _solve_once(km, transform_target_to_base, q_seed, axis, options, cols)
        if attempt.success or attempt.position_error_m < best.position_error_m:
            best = attempt
    return best
