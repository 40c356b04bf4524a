"""The local stages of a pick and place planned: the approach above the part's predicted spot, the grasp (descend,
close, lift) and the place (lower, release, retreat), each one goal through Cartesian knots."""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from robots.failures import FailureCode
from robots.phase import Phase
from robots.skills.interface import ArmObservation, PartObservation
from robots.trajectory import quintic, within_velocity_limits

KNOT_S = 0.05  # spacing of the Cartesian knots of the grasp and place goals

# the words of a skill's refusal of a part it cannot grasp as it lies (`FailureCode.UNREACHABLE`)
UNREACHABLE = "cannot be reached from above"


class PickPlans:
    """Planning the local stages: one concern of `PickPlaceSkill`, kept apart (it reads and writes the skill's plan)."""

    def _plan_approach(self, obs: ArmObservation, part: PartObservation) -> None:
        """The move above where the part will be when the claw gets there (two passes refine the travel time)."""
        t = self.timing
        lead = t.descend_s
        seg = None
        for _ in range(2):
            at = part.position + self.velocity * lead
            grasp = np.array([at[0], at[1], self.grasp_z])
            found = self.geometry.least_tilt(grasp, self.grasp_yaw, t.hover_m, self.q_cmd, self.grasp_centre)
            if found is None:
                hover = grasp + [0.0, 0.0, t.hover_m]
                self._fail(
                    FailureCode.UNREACHABLE, f"part {part.part_id} {UNREACHABLE} at {np.round(hover, 3).tolist()}"
                )
                return
            self.pick_tilt_rad, q_hover, self._pick_up = found
            seg = self.geometry.segment(self.q_cmd, q_hover, obs.time_s, t.approach_speed)
            lead = seg.duration_s + t.descend_s * 0.5
        self._grasp_world = grasp
        self._begin_segment(seg, Phase.APPROACH, obs.time_s)

    def _plan_grasp(self, part: PartObservation | None, now: float) -> None:
        """Descend onto the part following it, close, lift: one goal from the approach's end, and the close."""
        t = self.timing
        if part is None:
            self._fail(FailureCode.PART_VANISHED, f"part {self.job.part_id} vanished before the grasp")
            return
        start = self._earliest(self.plan_end_s)
        seen_at = now
        d, c, lift = t.descend_s, t.close_s, t.lift_s
        times = np.arange(KNOT_S, d + c + lift + 1e-9, KNOT_S)

        def aim(tt: float) -> np.ndarray:
            return part.position + self.velocity * (start + tt - seen_at + t.track_lead_s)

        lift_xy = aim(d + c)[:2]
        up = self._pick_up
        points = []
        for tt in times:
            if tt <= d + c:
                xy = aim(tt)[:2]
                rise = t.hover_m * (1 - quintic(tt / d)) if tt <= d else 0.0
            else:
                e = tt - d - c
                xy = lift_xy + self.velocity[:2] * min(e, 0.15)
                rise = t.lift_m * quintic(e / lift)
            points.append(np.array([xy[0] + up[0] * rise, xy[1] + up[1] * rise, self.grasp_z + up[2] * rise]))
        qs = self._solve_path(points, self.grasp_yaw, self.pick_tilt_rad)
        at = self._send_knots(start, times, qs)
        self._send_gripper(0.0, start + at(d))
        self.q_cmd, self.plan_end_s = qs[-1].copy(), start + at(times[-1])
        self._timeline = [(start, Phase.DESCEND), (start + at(d), Phase.CLOSE), (start + at(d + c), Phase.LIFT)]

    def _after_lift(self, obs: ArmObservation) -> None:
        """The part must be in the claw (the fingers stopped apart); then the transfer above the place."""
        t, now = self.timing, obs.time_s
        if self._gripper_opening(obs) < 0.03:
            self._send_gripper(1.0, None)
            self.missed_yaws.setdefault(self.job.part_id, []).append(self.grasp_yaw)  # not that way again
            self._fail(FailureCode.GRASP_MISSED, f"grasp of part {self.job.part_id} missed: the claw closed on nothing")
            return
        place = np.asarray(self.job.place_xyz, float)
        self.place_yaw = self.geometry.natural_yaw(place)
        above_place = functools.partial(
            self.geometry.least_tilt, place, self.place_yaw, t.hover_m, self.q_cmd, self.grasp_centre
        )
        found = None
        if self.spec.carry_tilted:  # the part is carried as it was picked, not turned in the jaws on the way
            found = above_place(below_m=self.tool_above_bottom_m, from_rad=self.pick_tilt_rad)
        found = found or above_place(below_m=self.tool_above_bottom_m)
        if found is None:
            self._fail(FailureCode.PLACE_UNREACHABLE, f"place position {np.round(place, 3).tolist()} cannot be reached")
            return
        self.place_tilt_rad, q_above, self._place_up = found
        self._begin_segment(self.geometry.segment(self.q_cmd, q_above, now, t.transfer_speed), Phase.TRANSFER, now)

    def _plan_place(self) -> None:
        """Lower, release, retreat: one goal from the transfer's end, and the claw opening at the release."""
        t = self.timing
        start = self._earliest(self.plan_end_s)
        place = np.asarray(self.job.place_xyz, float)
        release_z = place[2] + self.tool_above_bottom_m + t.place_drop_m
        lo, rel, back = t.lower_s, t.release_s, t.retreat_s
        times = np.arange(KNOT_S, lo + rel + back + 1e-9, KNOT_S)
        up = self._place_up
        points = []
        for tt in times:
            if tt <= lo:
                rise = t.hover_m * (1 - quintic(tt / lo))
            elif tt <= lo + rel:
                rise = 0.0
            else:
                rise = t.hover_m * quintic((tt - lo - rel) / back)
            points.append(np.array([place[0] + up[0] * rise, place[1] + up[1] * rise, release_z + up[2] * rise]))
        qs = self._solve_path(points, self.place_yaw, self.place_tilt_rad)
        at = self._send_knots(start, times, qs)
        self._send_gripper(self.pregrasp_opening, start + at(lo))
        self.q_cmd, self.plan_end_s = qs[-1].copy(), start + at(times[-1])
        self._timeline = [(start, Phase.LOWER), (start + at(lo), Phase.RELEASE), (start + at(lo + rel), Phase.RETREAT)]

    def _solve_path(self, points: list[np.ndarray], yaw: float, tilt_rad: float) -> np.ndarray:
        """Joints through Cartesian tool positions from the joints last commanded (`ClawGeometry.solve_path`),
        the failed solves counted."""
        qs, failed = self.geometry.solve_path(points, yaw, tilt_rad, self.q_cmd, self.grasp_centre)
        self.ik_failures += failed
        return qs

    def _send_knots(self, start_s: float, times_s: np.ndarray, qs: np.ndarray) -> Callable[[float], float]:
        """Send a knot path, stretched where it would break a joint's velocity limit; returns the map from a
        planned time to when the stretched path gets there."""
        sent = within_velocity_limits(self.q_cmd, times_s, qs, self.km.arm_velocity_limit)
        self.outbox.knots(start_s, sent, qs)
        planned = np.concatenate([[0.0], np.asarray(times_s, float)])
        stretched = np.concatenate([[0.0], sent])
        return lambda t_s: float(np.interp(t_s, planned, stretched))
