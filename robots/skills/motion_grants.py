"""A pick-and-place skill's free moves asked for and answered: the request it holds still for (with the local stage
after it), a grant, a denial (a detour home, a wait), a stand-by beside a place that is not ready."""

from __future__ import annotations

import numpy as np

from robots.failures import FailureCode
from robots.phase import Phase
from robots.skills.interface import MotionRequest
from robots.skills.pick_geometry import rise


class MotionGrants:
    """The motion grants of `PickPlaceSkill`, one concern of it kept apart (it reads and moves the skill's plan)."""

    def _ask(self, time_s: float) -> None:
        self._request_seq += 1
        seg = self.segment
        key = (self.phase, tuple(np.round(seg.q_end, 9)))
        if self._then_cache[0] != key:
            self._then_cache = (key, self._local_stage_after(seg.q_end))
        then_after_s, then_q = self._then_cache[1]
        self.request = MotionRequest(
            self._request_seq,
            tuple(map(float, self.q_cmd)),
            tuple(map(float, seg.q_end)),
            float(seg.duration_s),
            time_s,
            tuple(tuple(map(float, q)) for q in then_q),
            tuple(then_after_s),
        )

    def _local_stage_after(self, q_end: np.ndarray) -> tuple[list[float], list[np.ndarray]]:
        """Where the stage that follows this move without a grant will take the arm, and when (seconds after the
        move's end), padded by the latency it may start late: the descent, grasp and lift after an approach (the
        part carried on by its surface meanwhile); the lowering, release and retreat after a transfer. The guard
        keeps the other arms clear of these too, so an arm never moves where no check has looked."""
        t = self.timing
        late = self.decision_period_s + self.latency_s  # the stage may begin this much after the move ends
        if self.phase == Phase.APPROACH and self.job is not None:
            d, c, lift = t.descend_s, t.close_s, t.lift_s
            v = self.velocity
            down = self._grasp_world
            points = [down + v * d, down + v * (d + c), down + v * (d + c + 0.15) + self._pick_up * t.lift_m]
            times = [d, d + c, d + c + lift]
            yaw, tilt = self.grasp_yaw, self.pick_tilt_rad
        elif self.phase == Phase.TRANSFER and self._detour_to is None and self.job is not None:
            place = np.asarray(self.job.place_xyz, float)
            release = place + [0, 0, self.tool_above_bottom_m + t.place_drop_m]
            above = place + rise(self._place_up, t.hover_m, self.tool_above_bottom_m)
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

    def on_grant(
        self, request_seq: int, decision: str, conflict_arm: str, time_s: float, start_time_s: float | None = None
    ) -> None:
        """The coordinator's answer to request `request_seq` (stale answers are ignored): grant (from `start_time_s`,
        else now), or deny naming the arm in the way."""
        if self.request is None or request_seq != self.request.seq or not self.active:
            return
        self._now = time_s
        if decision == "grant":
            self.request = None
            self._go(max(time_s, start_time_s if start_time_s is not None else time_s))
            return
        if decision == "standby":  # the place is not ready: wait beside it, then ask to place from there
            self.request = None
            self._stand_by(time_s)
            return
        self.denials += 1
        if self._denied_since_s is None:
            self._denied_since_s = time_s
        if self.phase == Phase.APPROACH:  # nothing in hand: give the task back, the coordinator decides again
            self.request = None
            self._fail(
                FailureCode.MOTION_DENIED,
                f"motion denied: the approach would pass within the margin of {conflict_arm or 'another arm'}",
            )
        elif self.phase == Phase.STANDBY:  # the spot beside the place is in another arm's way: wait where it is
            self._transfer_from_here(time_s)
        elif self._should_detour(time_s):  # the way stays blocked: make room by going home, then transfer from there
            self._detour_home(time_s)
        else:  # a part in the claw, or on the way home: ask again
            self._ask(time_s)

    def _stand_by(self, time_s: float) -> None:
        """Told to stand by (once a task, a transfer only): move to a spot `standby_back` of the way from the place's
        hover point to the arm's base and `standby_up_m` higher, the part in the claw; from there the transfer
        is asked for again. Where that spot cannot be reached, the transfer is asked for again from here."""
        if self.phase != Phase.TRANSFER or self._detour_to is not None or self._stood_by or self.job is None:
            self._ask(time_s)
            return
        self._stood_by, self._transfer_to = True, self.segment.q_end.copy()
        t = self.timing
        place = np.asarray(self.job.place_xyz, float)
        above = place + rise(self._place_up, t.hover_m, self.tool_above_bottom_m)
        back = (self.top_down.base_to_world[:2, 3] - above[:2]) * t.standby_back
        spot = above + [back[0], back[1], t.standby_up_m]
        q, ok = self.geometry.ik(spot, self.place_yaw, self._transfer_to, self.place_tilt_rad, self.grasp_centre)
        if not ok:
            self._transfer_from_here(time_s)
            return
        self.standbys += 1
        self._begin_segment(self.geometry.segment(self.q_cmd, q, time_s, t.transfer_speed), Phase.STANDBY, time_s)

    def _transfer_from_here(self, time_s: float) -> None:
        """The transfer to above the place, from where the arm is (after standing by, or instead of it)."""
        q_to, self._transfer_to = self._transfer_to, None
        self._transfer(q_to, time_s)

    def _transfer(self, q_to: np.ndarray, time_s: float) -> None:
        """A transfer-phase free move from where the arm is to `q_to`, part in hand."""
        segment = self.geometry.segment(self.q_cmd, q_to, time_s, self.timing.transfer_speed)
        self._begin_segment(segment, Phase.TRANSFER, time_s)

    def _should_detour(self, time_s: float) -> bool:
        """Two arms each standing in the other's way (one waiting to transfer, one to go home or transfer) would
        wait for ever; the transfer that has waited `detour_after_s` gives way."""
        return (
            self.phase == Phase.TRANSFER
            and self._detour_to is None
            and not self._at_home(self.q_cmd)
            and time_s - self._denied_since_s >= self.timing.detour_after_s - 1e-9
        )

    def _detour_home(self, time_s: float) -> None:
        self._detour_to = self.segment.q_end.copy()
        self.detours += 1
        self._transfer(np.asarray(self.spec.home_q, float), time_s)
