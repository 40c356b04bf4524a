"""How far an arm's chain can stretch: a test that tells, without IK, that a straight-down tool pose is out of reach.

Two points of a serial arm keep their distance whatever the joints: the shoulder (the last joint origin on the first
joint's axis: it never moves) and the wrist (the first joint origin from which on every joint turns about an axis
through the next origin: it rides fixed in the tool frame). Between them each link keeps its length, and a link
whose far end lies on the joint's axis (or whose near end does) keeps the distance across that joint, so the wrist
stays within the chain's span of the shoulder. For a tool pointing straight down the wrist lies at a known height
in a ring about the spot (its offset turned by any yaw), so a spot whose ring is farther than the span from the
shoulder cannot be reached at any yaw: the reach search (15-20 ms where it tries everything before it answers no)
is skipped. Only a certain "no" is given; anything else goes to the search as before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from robots.kinematics import KinematicModel

ON_AXIS_M = 1e-4  # a joint origin this close to an axis is taken to lie on it (each such step adds its error back)
SLACK_M = 0.005  # beyond the IK's own tolerances: a spot this close to the span is left to the search


@dataclass(frozen=True)
class ChainSpan:
    """The shoulder (base frame, fixed), the most the wrist can be from it, and the wrist in the tool frame."""

    shoulder_base: np.ndarray
    span_m: float
    wrist_in_tool: np.ndarray

    @classmethod
    def of(cls, km: KinematicModel) -> ChainSpan | None:
        """The span of a serial arm of revolute joints whose tool frame rides on its last arm joint; None for any
        other (no test)."""
        model, data = km.model, km.data
        ids = [model.getJointId(name) for name in km.spec.arm_joints]
        if any(model.parents[ids[k]] != ids[k - 1] for k in range(1, len(ids))):
            return None
        if model.frames[km.tool_frame_id].parentJoint != ids[-1]:
            return None
        if any("R" not in model.joints[j].shortname().replace("JointModel", "")[:2] for j in ids):
            return None  # a prismatic (or other) joint: no span worked out
        q = km.full_q(np.asarray(km.spec.home_q, float))
        pin.computeJointJacobians(model, data, q)
        origins = [data.oMi[j].translation.copy() for j in ids]
        axes = [pin.getJointJacobian(model, data, j, pin.ReferenceFrame.WORLD)[3:, model.joints[j].idx_v] for j in ids]

        def on_axis(point: np.ndarray, k: int) -> bool:
            d = point - origins[k]
            return float(np.linalg.norm(np.cross(d, axes[k] / np.linalg.norm(axes[k])))) < ON_AXIS_M

        s = 0
        while s + 1 < len(ids) and on_axis(origins[s + 1], 0):
            s += 1  # the shoulder: on the first axis, it never moves
        e = len(ids) - 1
        while e - 1 > s and on_axis(origins[e - 1], e):
            e -= 1  # the wrist: every joint after it turns about an axis through the origin before
        kept, skipped = [origins[s]], 0
        for k in range(s + 1, e):
            just_skipped = kept[-1] is not origins[k - 1]
            if not just_skipped and (on_axis(origins[k + 1], k) or on_axis(origins[k - 1], k)):
                skipped += 1  # the distance from the origin before joint k to the one after it stays what it is
            else:
                kept.append(origins[k])
        kept.append(origins[e])
        span = sum(float(np.linalg.norm(b - a)) for a, b in zip(kept, kept[1:])) + 2 * ON_AXIS_M * (s + skipped + 1)
        tool = km.frame_pose(q)
        wrist = np.linalg.inv(tool) @ np.append(origins[e], 1.0)
        return cls(origins[s], span, wrist[:3])

    def beyond_straight_down(self, spot: np.ndarray, centre_tool: np.ndarray, shoulder: np.ndarray) -> bool:
        """Whether no configuration puts `centre_tool` (a point in the tool frame) at `spot` with the tool pointing
        straight down (along -z of the frame `spot` and `shoulder` are given in), at any yaw. The tool's origin
        lies in a ring about the spot (the centre's horizontal offset turned by the yaw) and the wrist in a ring
        about that (its own offset turned by the roll about the approach axis): at a known height, in an annulus."""
        c, w = np.asarray(centre_tool, float), self.wrist_in_tool
        rho_c, rho_w = math.hypot(c[0], c[1]), math.hypot(w[0], w[1])
        height = spot[2] + c[2] - w[2]  # the tool's z points down: a tool-frame z offset is a drop in height
        d = np.asarray(shoulder, float) - np.array([spot[0], spot[1], height])
        across = math.hypot(d[0], d[1])
        gap = max(0.0, abs(rho_c - rho_w) - across, across - (rho_c + rho_w))
        slack = SLACK_M + float(np.linalg.norm(w - c)) * 0.01  # the IK's angle tolerance, tenfold
        return math.hypot(d[2], gap) > self.span_m + slack
