"""The local stages of a pick and place planned: the approach above the part's predicted spot, the grasp (descend,
close, lift) and the place (lower, release, retreat), each one goal through Cartesian knots; and the free moves
between them (the transfer, a stand-by, home), which are returned to be asked for or sent."""

from __future__ import annotations

import functools

import numpy as np

from robots.failures import FailureCode
from robots.phase import Phase
from robots.skills.interface import ArmObservation, PartObservation, PickPlaceJob
from robots.skills.pick_geometry import ClawGeometry, rise
from robots.skills.skill_plan import SkillPlan
from robots.spec import RobotSpec
from robots.trajectory import JointSegment, quintic

KNOT_S = 0.05  # spacing of the Cartesian knots of the grasp and place goals

# the words of a skill's refusal of a part it cannot grasp as it lies (`FailureCode.UNREACHABLE`)
UNREACHABLE = "cannot be reached from above"


class PickPlans:
    """Where the claw goes for one task and how it gets there: the grasp worked out when the task starts, the
    stages planned into `plan`. `timing` is a `PickPlaceTiming`."""

    def __init__(self, plan: SkillPlan, spec: RobotSpec, geometry: ClawGeometry, timing) -> None:
        self.plan, self.spec, self.geometry, self.timing = plan, spec, geometry, timing
        self.missed_yaws: dict[int, list[float]] = {}  # part id -> the grasp yaws that closed on nothing
        self.ik_failures = 0
        self.grasp_yaw = self.grasp_z = self.tool_above_bottom_m = self.pregrasp_opening = self.part_height = 0.0
        self.velocity = np.zeros(3)  # the surface's, and the grasp on the line above: set when a task starts
        self.grasp_centre = (0.0, 0.0, 0.0)  # the part between the jaws, tool frame (one fixed jaw: off centre)
        self.grasp_world = np.zeros(3)
        self.pick_up = self.place_up = np.array([0.0, 0.0, 1.0])  # the way the claw rises from the part, the place
        self.place_yaw = 0.0
        self.pick_tilt_rad = self.place_tilt_rad = 0.0  # how far the claw leans from straight down at each end

    def begin(self, job: PickPlaceJob, part: PartObservation) -> None:
        """Work out the grasp of `part` for `job`, and open the claw for it."""
        t, spec = self.timing, self.spec
        self.grasp_yaw = self.geometry.grasp_yaw(part, self.missed_yaws.get(part.part_id, ()))
        self.grasp_centre = spec.grasp_centre_tool(part.width_m, t.fixed_jaw_gap_m)
        tip = spec.fingertip_below_tool_m
        self.grasp_z = max(job.surface_z_m + part.height_m / 2, job.surface_z_m + tip + 0.004)
        self.grasp_z = min(self.grasp_z, job.surface_z_m + part.height_m + tip - 0.010)
        self.tool_above_bottom_m = self.grasp_z - job.surface_z_m
        self.velocity = np.asarray(job.surface_velocity, float)
        self.pregrasp_opening = min(1.0, spec.opening_for_width(part.width_m + t.pregrasp_clearance_m))
        self.part_height = part.height_m
        self.plan.send_gripper(self.pregrasp_opening, None)

    def approach(self, obs: ArmObservation, part: PartObservation) -> JointSegment | None:
        """The move above where the part will be when the claw gets there (two passes refine the travel time);
        None when it cannot be reached (the task failed)."""
        t = self.timing
        lead = t.descend_s
        seg = None
        for _ in range(2):
            at = part.position + self.velocity * lead
            grasp = np.array([at[0], at[1], self.grasp_z])
            found = self.geometry.least_tilt(grasp, self.grasp_yaw, t.hover_m, self.plan.q_cmd, self.grasp_centre)
            if found is None:
                hover = np.round(grasp + [0.0, 0.0, t.hover_m], 3).tolist()
                self.plan.fail(FailureCode.UNREACHABLE, f"part {part.part_id} {UNREACHABLE} at {hover}")
                return None
            self.pick_tilt_rad, q_hover, self.pick_up = found
            seg = self.geometry.segment(self.plan.q_cmd, q_hover, obs.time_s, t.approach_speed)
            lead = seg.duration_s + t.descend_s * 0.5
        self.grasp_world = grasp
        return seg

    def grasp(self, part: PartObservation | None, now: float) -> None:
        """Descend onto the part following it, close, lift: one goal from the approach's end, and the close."""
        t, plan = self.timing, self.plan
        if part is None:
            plan.fail(FailureCode.PART_VANISHED, f"part {plan.job.part_id} vanished before the grasp")
            return
        start = plan.earliest(plan.plan_end_s)
        d, c, lift = t.descend_s, t.close_s, t.lift_s
        times = np.arange(KNOT_S, d + c + lift + 1e-9, KNOT_S)

        def aim(tt: float) -> np.ndarray:
            return part.position + self.velocity * (start + tt - now + t.track_lead_s)

        lift_xy = aim(d + c)[:2]
        up = self.pick_up
        points = []
        for tt in times:
            if tt <= d + c:
                xy = aim(tt)[:2]
                height = t.hover_m * (1 - quintic(tt / d)) if tt <= d else 0.0
            else:
                e = tt - d - c
                xy = lift_xy + self.velocity[:2] * min(e, 0.15)
                height = t.lift_m * quintic(e / lift)
            points.append(np.array([xy[0] + up[0] * height, xy[1] + up[1] * height, self.grasp_z + up[2] * height]))
        qs = self._solve_path(points, self.grasp_yaw, self.pick_tilt_rad)
        at = plan.send_knots(start, times, qs)
        plan.send_gripper(0.0, start + at(d))
        plan.q_cmd, plan.plan_end_s = qs[-1].copy(), start + at(times[-1])
        plan.timeline = [(start, Phase.DESCEND), (start + at(d), Phase.CLOSE), (start + at(d + c), Phase.LIFT)]

    def transfer_after_lift(self, obs: ArmObservation) -> JointSegment | None:
        """The part must be in the claw (the fingers stopped apart); then the move above the place. None when the
        task failed (the grasp missed, the place cannot be reached)."""
        t, plan = self.timing, self.plan
        if self._gripper_opening(obs) < 0.03:
            plan.send_gripper(1.0, None)
            self.missed_yaws.setdefault(plan.job.part_id, []).append(self.grasp_yaw)  # not that way again
            plan.fail(FailureCode.GRASP_MISSED, f"grasp of part {plan.job.part_id} missed: the claw closed on nothing")
            return None
        place = np.asarray(plan.job.place_xyz, float)
        self.place_yaw = self.geometry.natural_yaw(place)
        above_place = functools.partial(
            self.geometry.least_tilt, place, self.place_yaw, t.hover_m, plan.q_cmd, self.grasp_centre
        )
        found = None
        if self.spec.carry_tilted:  # the part is carried as it was picked, not turned in the jaws on the way
            found = above_place(below_m=self.tool_above_bottom_m, from_rad=self.pick_tilt_rad)
        found = found or above_place(below_m=self.tool_above_bottom_m)
        if found is None:
            plan.fail(FailureCode.PLACE_UNREACHABLE, f"place position {np.round(place, 3).tolist()} cannot be reached")
            return None
        self.place_tilt_rad, q_above, self.place_up = found
        return self.geometry.segment(plan.q_cmd, q_above, obs.time_s, t.transfer_speed)

    def place(self) -> None:
        """Lower, release, retreat: one goal from the transfer's end, and the claw opening at the release."""
        t, plan = self.timing, self.plan
        start = plan.earliest(plan.plan_end_s)
        place = np.asarray(plan.job.place_xyz, float)
        release_z = place[2] + self.tool_above_bottom_m + t.place_drop_m
        lo, rel, back = t.lower_s, t.release_s, t.retreat_s
        times = np.arange(KNOT_S, lo + rel + back + 1e-9, KNOT_S)
        up = self.place_up
        points = []
        for tt in times:
            if tt <= lo:
                height = t.hover_m * (1 - quintic(tt / lo))
            elif tt <= lo + rel:
                height = 0.0
            else:
                height = t.hover_m * quintic((tt - lo - rel) / back)
            points.append(np.array([place[0] + up[0] * height, place[1] + up[1] * height, release_z + up[2] * height]))
        qs = self._solve_path(points, self.place_yaw, self.place_tilt_rad)
        at = plan.send_knots(start, times, qs)
        plan.send_gripper(self.pregrasp_opening, start + at(lo))
        plan.q_cmd, plan.plan_end_s = qs[-1].copy(), start + at(times[-1])
        plan.timeline = [(start, Phase.LOWER), (start + at(lo), Phase.RELEASE), (start + at(lo + rel), Phase.RETREAT)]

    def local_stage_after(self, q_end: np.ndarray, detouring: bool) -> tuple[list[float], list[np.ndarray]]:
        """Where the stage that follows this phase's free move without a grant will take the arm, and when (seconds
        after the move's end), padded by the latency it may start late: the descent, grasp and lift after an
        approach (the part carried on by its surface meanwhile); the lowering, release and retreat after a
        transfer. The guard keeps the other arms clear of these too, so an arm never moves where no check has
        looked."""
        t, plan = self.timing, self.plan
        late = plan.decision_period_s + plan.latency_s  # the stage may begin this much after the move ends
        if plan.phase == Phase.APPROACH and plan.job is not None:
            d, c, lift = t.descend_s, t.close_s, t.lift_s
            v, down = self.velocity, self.grasp_world
            points = [down + v * d, down + v * (d + c), down + v * (d + c + 0.15) + self.pick_up * t.lift_m]
            times = [d, d + c, d + c + lift]
            yaw, tilt = self.grasp_yaw, self.pick_tilt_rad
        elif plan.phase == Phase.TRANSFER and not detouring and plan.job is not None:
            place = np.asarray(plan.job.place_xyz, float)
            release = place + [0, 0, self.tool_above_bottom_m + t.place_drop_m]
            above = place + rise(self.place_up, t.hover_m, self.tool_above_bottom_m)
            points, yaw, tilt = [release, release, above], self.place_yaw, self.place_tilt_rad
            times = [t.lower_s, t.lower_s + t.release_s, t.lower_s + t.release_s + t.retreat_s]
        else:
            return [], []
        qs, q = [], np.asarray(q_end, float)
        for point in points:
            q, ok = self.geometry.ik(point, yaw, q, tilt, self.grasp_centre)
            if not ok:
                return [], []  # the stage's own planning will fail the task; the move alone is still checked
            qs.append(q)
        return [*times, times[-1] + late], [*qs, qs[-1]]

    def standby(self, q_transfer_end: np.ndarray, time_s: float) -> JointSegment | None:
        """The move to a spot `standby_back` of the way from the place's hover point to the arm's base and
        `standby_up_m` higher, the part in the claw; None where that spot cannot be reached."""
        t = self.timing
        place = np.asarray(self.plan.job.place_xyz, float)
        above = place + rise(self.place_up, t.hover_m, self.tool_above_bottom_m)
        back = (self.geometry.top_down.base_to_world[:2, 3] - above[:2]) * t.standby_back
        spot = above + [back[0], back[1], t.standby_up_m]
        q, ok = self.geometry.ik(spot, self.place_yaw, q_transfer_end, self.place_tilt_rad, self.grasp_centre)
        return self.geometry.segment(self.plan.q_cmd, q, time_s, t.transfer_speed) if ok else None

    def home(self, time_s: float) -> JointSegment:
        """The free move home from where the arm was last sent, at the approach's speed."""
        home = np.asarray(self.spec.home_q, float)
        return self.geometry.segment(self.plan.q_cmd, home, time_s, self.timing.approach_speed)

    def _gripper_opening(self, obs: ArmObservation) -> float:
        c, o = self.spec.gripper_closed[0], self.spec.gripper_open[0]
        return float((np.mean(obs.gripper_q) - c) / (o - c))

    def _solve_path(self, points: list[np.ndarray], yaw: float, tilt_rad: float) -> np.ndarray:
        """Joints through Cartesian tool positions from the joints last commanded (`ClawGeometry.solve_path`),
        the failed solves counted."""
        qs, failed = self.geometry.solve_path(points, yaw, tilt_rad, self.plan.q_cmd, self.grasp_centre)
        self.ik_failures += failed
        return qs
