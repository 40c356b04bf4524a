"""How far out an arm reaches, measured by the reach rule the coordinator decides by, not declared.

`reach_m` is the farthest a spot can lie from the arm's base, horizontally, and still be reached as the skill
reaches (`TopDownIK.reach_pose`: the claw straight down, else leaning as far as the robot allows), at any of the
heights arms work at. The coordinator answers a spot past it "no" without IK, scenes check their stations against
it and the pick trials scale their cell by it, so a number that a person wrote down and the arm cannot honour (the
OpenClaw's 0.62 m against 0.51 reached; the SO-101's 0.36 m against 0.45) misled all three. Measured once per
declaration and kept on disk (`robots.disk_cache`); a declaration, URDF or IK code that changes is measured anew.
"""

from __future__ import annotations

import contextlib
import json
import math
from typing import TYPE_CHECKING

import numpy as np

from robots.disk_cache import cache_dir, declaration_key, replace_atomically

if TYPE_CHECKING:
    from robots.spec import RobotSpec

HEIGHTS_M = tuple(round(-0.1 + 0.05 * k, 2) for k in range(11))
"""Spot heights above the base the reach is measured at (-0.1 to 0.4 m): where belts and stations put parts."""
STEP_M = 0.01
COARSE_STEPS = 4  # spots are tried inwards this many steps apart until one is reached, then the gap is halved
MARGIN_M = 0.02
"""Added to the farthest spot reached: the next step out was not reached (so the arm's reach at that height is
less than a step more), and a height between the measured ones may reach up to about a step farther."""
MEASURED_BY = (
    "robots.measured_reach",
    "robots.top_down",
    "robots.ik",
    "robots.chain_span",
    "robots.kinematics",
    "robots.frames",
)
MOVES_NO_REACH = ("summary", "arm_gains", "gripper_gains", "finger_friction", "pick_timing", "declared_in")
"""Declaration fields no reach answer depends on: a robot tuned in these is not measured again."""

_MEASURED: dict[int, tuple[RobotSpec, float]] = {}  # by the declaration object (kept, so its id is not reused)


def reach_m_of(spec: RobotSpec) -> float:
    """The robot's measured reach: this process's, else the one kept on disk, else measured now (a few tenths of a
    second for a 6-joint arm, ~3 s for one that leans: once per declaration) and kept."""
    known = _MEASURED.get(id(spec))
    if known is None:
        known = _MEASURED[id(spec)] = (spec, _kept_or_measured(spec))
    return known[1]


def _kept_or_measured(spec: RobotSpec) -> float:
    folder = cache_dir("robots")
    path = (
        None
        if folder is None
        else folder / f"{spec.uid}-{declaration_key(spec, MEASURED_BY, HEIGHTS_M, ignoring=MOVES_NO_REACH)}.json"
    )
    if path is not None:
        with contextlib.suppress(OSError, ValueError, KeyError, TypeError):
            return float(json.loads(path.read_text())["reach_m"])
    reach = measure_reach_m(spec)
    if path is not None:
        with contextlib.suppress(OSError):
            replace_atomically(path, lambda f: f.write(json.dumps({"robot": spec.uid, "reach_m": reach}).encode()))
    return reach


def measure_reach_m(spec: RobotSpec) -> float:
    """Measure it: at each height, spots straight out from the turning axis are tried inwards from the farthest the
    chain could stretch, coarsely until one is reached, then to within a step; the farthest over the heights, plus
    how far the turning axis stands from the base's origin (the worst bearing) and `MARGIN_M`."""
    from robots.top_down import TopDownIK

    ik = TopDownIK(spec, np.eye(4))
    axis = np.asarray(ik.pan_origin_world[:2], float)
    farthest = max((_farthest_at(ik, axis, z) for z in HEIGHTS_M), default=0.0)
    return round(farthest + float(np.hypot(*axis)) + MARGIN_M, 3)


def _farthest_at(ik, axis: np.ndarray, z_m: float) -> float:
    """The farthest spot reached at one height, to within `STEP_M`, out from the turning axis (0 if none is)."""

    def reached(r_m: float) -> bool:
        return ik.reach_pose(np.array([axis[0] + r_m, axis[1], z_m]), math.inf) is not None

    top = _stretch_bound_m(ik, axis, z_m)
    steps = int(top / STEP_M)
    k = steps
    while k * STEP_M > STEP_M and not reached(k * STEP_M):
        k -= COARSE_STEPS
    if k * STEP_M <= STEP_M:
        return 0.0
    lo, hi = k, min(k + COARSE_STEPS, steps + 1)  # lo reached; hi not (or past the bound)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if reached(mid * STEP_M) else (lo, mid)
    return lo * STEP_M


def _stretch_bound_m(ik, axis: np.ndarray, z_m: float) -> float:
    """The farthest out from the turning axis a claw can be at this height, whatever its tilt: the wrist within the
    chain's span of the shoulder and the claw's centre within its own distance of the wrist (no chain worked out:
    twice the home pose's stretch)."""
    span = ik.chain_span
    if span is None:
        return 2.0 * float(np.linalg.norm(ik.km.frame_pose(ik.km.full_q(np.asarray(ik.spec.home_q)))[:3, 3]))
    centre = np.asarray(ik.spec.grasp_centre_tool(sum(ik.spec.grasp_width_m) / 2), float)
    radius = span.span_m + float(np.linalg.norm(span.wrist_in_tool - centre))
    shoulder = np.asarray(span.shoulder_base, float)
    rise = z_m - shoulder[2]
    if abs(rise) >= radius:
        return 0.0
    return float(np.hypot(*(shoulder[:2] - axis))) + math.sqrt(radius**2 - rise**2)
