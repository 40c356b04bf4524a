"""One arm of a running line behind servo joints (`LineArm.joints`): each joint's shaft is where the arm's
newest state puts it, and the goals servos are given go to the sim as an outside driver's (on the arm's `drive`
key: the plant's safety layer checks them, and the coordinator lets go of the arm while they come).

A servo tick is 1/4096 of a turn, tick 2048 the joint's zero; the gripper's servo turns the gripper joint, and
its goal is sent as the claw's opening between the robot's closed and open gripper positions."""

from __future__ import annotations

import itertools
import math
import os

import numpy as np
import zenoh

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, GoalResultMsg, GripperGoalMsg, TrajectoryGoalMsg
from fleet.bus.session import Inbox
from robots.feetech.control_table import TICKS_PER_TURN
from robots.spec import RobotSpec

ZERO_TICKS = TICKS_PER_TURN // 2
TICKS_PER_RAD = TICKS_PER_TURN / (2.0 * math.pi)
JOINT_SPEED_RAD_S = 4.7  # a servo goal is reached at this speed: an STS3215 unloaded at 7.4 V (0.222 s per 60 deg)
MIN_MOVE_S = 0.1  # the shortest trajectory a goal becomes
SERVO_HOLD_S = 5.0  # a goal's trajectory holds it this long (sim s), renewed while the servos' torque is on
RENEW_BEFORE_S = 2.0  # ... this long before its hold ends (the plant checks a goal over its whole length)


def ticks_of(q_rad: float) -> int:
    return int(round(ZERO_TICKS + q_rad * TICKS_PER_RAD)) % TICKS_PER_TURN


def rad_of(ticks: int) -> float:
    return (ticks - ZERO_TICKS) / TICKS_PER_RAD


def gripper_opening(spec: RobotSpec, q_rad: float) -> float:
    """The claw's opening (0 closed, 1 open) its gripper joint at `q_rad` stands for, bounded there."""
    closed, opened = spec.gripper_closed[0], spec.gripper_open[0]
    return float(np.clip((q_rad - closed) / (opened - closed), 0.0, 1.0))


def gripper_rad(spec: RobotSpec, opening: float) -> float:
    """The gripper joint's position (rad) for the claw's `opening` (0 closed, 1 open)."""
    closed, opened = spec.gripper_closed[0], spec.gripper_open[0]
    return closed + (opened - closed) * opening


class ArmFeed:
    """The newest state of one arm of the line (`take`), its joints as the servos count them: the arm's, then the
    gripper's."""

    def __init__(self, session: zenoh.Session, keys: Keys, arm: str, joints: int) -> None:
        self.joints = joints
        self.drops = DropCounter()
        self._decoder = Decoder(ArmState, self.drops)
        self._inbox = Inbox()
        self._sub = session.declare_subscriber(keys.arm_state(arm), self._inbox)
        self.state: ArmState | None = None

    def take(self) -> ArmState | None:
        """The newest state heard (None before the first). Only the newest of those queued is decoded (each is
        the whole arm): a servo answers within the driver's timeout, a few ms a packet, however fast the line runs."""
        for key, payload in reversed(self._inbox.drain()):
            state = self._decoder.decode(key, payload)
            if state is not None:
                if self.state is None or state.tick >= self.state.tick:
                    self.state = state
                break
        return self.state

    def q_rad(self) -> list[float]:
        state = self.take()
        if state is None:
            return [0.0] * self.joints
        return [*state.q, state.gripper_q[0] if state.gripper_q else 0.0]

    def dq_rad_s(self) -> list[float]:
        state = self.take()
        return [*state.dq, 0.0] if state is not None else [0.0] * self.joints

    def close(self) -> None:
        self._sub.undeclare()


class LineArmJoint:
    """One servo's joint (`index` into the arm's joints, the gripper last): read off `feed`, its goal (rad) put
    in `goals` for the arm to send."""

    def __init__(self, feed: ArmFeed, goals: list[float | None], index: int) -> None:
        self.feed, self.goals, self.index = feed, goals, index

    def position_ticks(self) -> int:
        return ticks_of(self.feed.q_rad()[self.index])

    def velocity_ticks_per_s(self) -> int:
        return int(round(self.feed.dq_rad_s()[self.index] * TICKS_PER_RAD))

    def drive(self, goal_ticks: int | None) -> None:
        self.goals[self.index] = None if goal_ticks is None else rad_of(goal_ticks)


class LineArm:
    """Arm `arm` of the line on `session`: its states taken as they come (`feed`), its servo goals sent together
    once a packet's worth was written (`send`), as one trajectory from where the arm stands and a claw goal. The
    trajectory then holds the goal, as a servo does while its torque is on, so the arm stays the driver's (the
    plant lets an outside driver's arm go 2 s after its last goal); torque off on every joint hands it back."""

    def __init__(self, session: zenoh.Session, keys: Keys, arm: str, spec: RobotSpec) -> None:
        self.arm, self.spec = arm, spec
        n = len(spec.arm_joints) + 1
        self.feed = ArmFeed(session, keys, arm, n)
        self._pub = session.declare_publisher(keys.arm_drive(arm))
        self.goals: list[float | None] = [None] * n  # rad, by joint; the gripper last
        self._sent: list[float | None] = [None] * n
        self._ids = itertools.count((1 << 53) + (int.from_bytes(os.urandom(2), "little") << 32))
        self.sent = 0
        self._target: np.ndarray | None = None  # the arm's joints' goal while the servos hold one (rad)
        self._renew_at_s = 0.0  # when (sim s) that goal's hold is renewed
        self._mine: set[int] = set()  # the goals this arm sent, whose results are its own
        self._results = Inbox()
        self._result_sub = session.declare_subscriber(keys.arm_result(arm), self._results)
        self._result_decoder = Decoder(GoalResultMsg, self.feed.drops)
        self.refused: list[GoalResultMsg] = []  # its goals the plant refused or aborted, with their reasons

    def joints(self) -> list[LineArmJoint]:
        return [LineArmJoint(self.feed, self.goals, i) for i in range(len(self.goals))]

    def take(self) -> ArmState | None:
        return self.feed.take()

    def send(self) -> None:
        """The goals written since the last send, to the sim: one trajectory for the arm's joints (from where the
        arm stands, at `JOINT_SPEED_RAD_S`), one goal for the claw; else the held goal renewed when due."""
        if self.goals == self._sent or self.feed.take() is None:
            self.renew()
            return
        q = np.asarray(self.feed.q_rad())
        arm = len(self.spec.arm_joints)
        if self.goals[:arm] != self._sent[:arm]:
            if any(g is not None for g in self.goals[:arm]):
                self._target = np.array([g if g is not None else q[i] for i, g in enumerate(self.goals[:arm])])
                self._hold(q[:arm])
            else:  # torque off everywhere: a short hold where the arm stands, and the line has it back after
                self._target = None
                self._put(
                    TrajectoryGoalMsg(self.arm, next(self._ids), self.spec.arm_joints, (MIN_MOVE_S,), tuple(q[:arm]))
                )
        if self.goals[arm] != self._sent[arm] and self.goals[arm] is not None:
            self._put(GripperGoalMsg(self.arm, next(self._ids), gripper_opening(self.spec, self.goals[arm])))
        self._sent = list(self.goals)

    def renew(self) -> None:
        """While the servos hold a goal, a fresh hold of it before the last one ends: a servo with its torque on
        holds its goal however long, so the arm stays the driver's."""
        state = self.feed.take()
        if self._target is not None and state is not None and state.sim_time_s >= self._renew_at_s:
            self._hold(np.asarray(state.q))

    def _hold(self, q: np.ndarray) -> None:
        """The arm's goal (`_target`) from `q`: there at `JOINT_SPEED_RAD_S`, then held for `SERVO_HOLD_S`."""
        move_s = max(MIN_MOVE_S, float(np.max(np.abs(self._target - q))) / JOINT_SPEED_RAD_S)
        times, points = (move_s, move_s + SERVO_HOLD_S), tuple(self._target) * 2
        self._put(TrajectoryGoalMsg(self.arm, next(self._ids), self.spec.arm_joints, times, points))
        self._renew_at_s = self.feed.state.sim_time_s + move_s + SERVO_HOLD_S - RENEW_BEFORE_S

    def refusals(self) -> list[GoalResultMsg]:
        """This arm's own goals the plant refused or aborted, heard since the last call (all of them are kept in
        `refused`); the other results are let pass."""
        out = []
        for key, payload in self._results.drain():
            result = self._result_decoder.decode(key, payload)
            if result is not None and result.goal_id in self._mine and result.status in ("rejected", "aborted"):
                out.append(result)
        self.refused += out
        return out

    def _put(self, msg: TrajectoryGoalMsg | GripperGoalMsg) -> None:
        self._mine.add(msg.goal_id)
        self._pub.put(encode(msg))
        self.sent += 1

    def close(self) -> None:
        self.feed.close()
        self._result_sub.undeclare()
        self._pub.undeclare()
