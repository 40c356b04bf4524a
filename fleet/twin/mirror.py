"""Mirror mode: a LeRobot robot (a real arm, or one served by `fleet twin serve-bus`) runs the goals one arm of a
running line runs, beside it. At the mirror's rate it reads the robot's joints, pairs them with the line arm's newest
state (`MirrorSample`), and sends the robot where the line's tracker wants its arm now (the trajectory goal's
desired joints; where the arm stands when no goal drives it). The goals it streams are ones the plant's safety layer
accepted for the sim arm; while the line holds its arm (an e-stop, a watchdog, a lost controller) the robot holds
where it stood when the hold began."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from typing import Protocol

from fleet.bus.messages import ArmState
from fleet.twin.deviation import MirrorSample
from fleet.twin.lerobot_units import arm_q_rad, positions
from fleet.twin.line_arm import ArmFeed
from robots.spec import RobotSpec


class LeRobotRobot(Protocol):
    """What mirror mode asks of a LeRobot `Robot` (connected)."""

    def get_observation(self) -> dict: ...

    def send_action(self, action: dict) -> dict: ...


def command(spec: RobotSpec, state: ArmState, offsets_deg: Mapping[str, float] | None = None) -> dict[str, float]:
    """Where the robot goes for the line arm's `state`: its tracker's desired joints while a goal drives it, where
    it stands otherwise; the gripper as the sim claw stands (in the robot's degrees: `offsets_deg` added)."""
    driven = state.goal_id != 0 and len(state.desired_q) == len(state.q)
    q = state.desired_q if driven else state.q
    return positions(spec, q, state.gripper_q[0] if state.gripper_q else 0.0, offsets_deg)


class Mirror:
    """The line arm read off `feed` mirrored onto `robot`, whose degrees read `offsets_deg` more than the joints'
    own (by joint; none: the same); `samples` gathered as it goes (`step`), in the joints' own radians."""

    def __init__(
        self, feed: ArmFeed, robot: LeRobotRobot, spec: RobotSpec, offsets_deg: Mapping[str, float] | None = None
    ) -> None:
        self.feed, self.robot, self.spec = feed, robot, spec
        self.offsets_deg = dict(offsets_deg or {})
        self.samples: list[MirrorSample] = []
        self.hold: dict[str, float] | None = None  # the robot's joints when the line's hold began
        self.holds = 0  # holds begun
        self.sent = 0
        self._tick = -1

    def step(self) -> MirrorSample | None:
        """Read the robot, pair it with the line arm's newest state, send the robot its next goal; the sample (None
        until the line arm's first state, and while no new state came since the last step)."""
        state = self.feed.take()
        if state is None or state.tick == self._tick:
            return None
        self._tick = state.tick
        present = self.robot.get_observation()
        action = self._action(state, present)
        commanded = arm_q_rad(self.spec, action, self.offsets_deg)
        real = arm_q_rad(self.spec, present, self.offsets_deg)
        sample = MirrorSample(state.sim_time_s, state.goal_id, tuple(state.q), real, commanded, state.held)
        self.samples.append(sample)
        self.robot.send_action(action)
        self.sent += 1
        return sample

    def _action(self, state: ArmState, present: Mapping[str, object]) -> dict[str, float]:
        if not state.held:
            self.hold = None
            return command(self.spec, state, self.offsets_deg)
        if self.hold is None:  # the line holds its arm: the robot holds where it stands now
            self.hold = {k: float(v) for k, v in present.items() if k.endswith(".pos")}
            self.holds += 1
        return dict(self.hold)

    def run(self, rate_hz: float, until: Callable[[MirrorSample | None], bool]) -> None:
        """Step at `rate_hz` (wall) until `until(last sample)` says so."""
        period, next_at = 1.0 / rate_hz, time.monotonic()
        while True:
            sample = self.step()
            if until(sample):
                return
            next_at += period
            time.sleep(max(0.0, next_at - time.monotonic()))
            next_at = max(next_at, time.monotonic() - period)  # late: no burst of steps to catch up
