"""Pairing two sets of things on the line's floor plan: each of one set with at most one of the other, of the same
kind and within a gate, the pairs chosen together for the least total distance (scipy's `linear_sum_assignment`)."""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment


def nearest_pairs(
    a_xy_m: np.ndarray, a_kinds: list[int], b_xy_m: np.ndarray, b_kinds: list[int], gate_m: float
) -> list[tuple[int, int, float]]:
    """(index in a, index in b, distance in metres) for each pair: same kind, x-y distance within `gate_m`."""
    if not len(a_kinds) or not len(b_kinds):
        return []
    a, b = np.asarray(a_xy_m, float)[:, :2], np.asarray(b_xy_m, float)[:, :2]
    gaps = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    allowed = (np.asarray(a_kinds)[:, None] == np.asarray(b_kinds)[None, :]) & (gaps <= gate_m)
    far = 1e6
    rows, cols = linear_sum_assignment(np.where(allowed, gaps, far))
    return [(int(i), int(j), float(gaps[i, j])) for i, j in zip(rows, cols) if allowed[i, j]]
