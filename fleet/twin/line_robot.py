"""An arm of a running line in a LeRobot robot's terms: observations `"<joint>.pos"` (degrees; the gripper from 0
closed to 100 open, as LeRobot's SO-101 follower reads a real one) beside the line's camera images (H x W x 3
uint8), and actions in those units, clipped to the joints' limits and sent as an outside driver's goals (`LineArm`:
the plant's safety layer checks them; the coordinator lets the arm go while they drive it). The LeRobot plug-in
(`plugins/lerobot_robot_clawfleet`) is this class behind LeRobot's `Robot` API."""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Mapping, Sequence

import numpy as np
import zenoh

from fleet.bus.codec import Decoder
from fleet.bus.images import decode_image
from fleet.bus.keys import Keys
from fleet.bus.messages import CameraImage
from fleet.bus.session import Inbox
from fleet.twin.calibration import motor_names
from fleet.twin.lerobot_units import GRIPPER_SPAN, positions
from fleet.twin.line_arm import LineArm, gripper_rad
from robots.kinematics import KinematicModel
from robots.registry import get_robot
from scenes.schema import Scene

LOG = logging.getLogger(__name__)


class LineRobotError(RuntimeError):
    """A line that cannot be driven as asked (an arm or camera it lacks, a silent arm, images never made)."""


def robot_features(scene: Scene, arm: str, cameras: Sequence[str] = ()) -> dict[str, type | tuple[int, int, int]]:
    """LeRobot's features of `arm` of `scene` with `cameras`: `"<motor>.pos"` floats, then each camera's image shape."""
    try:
        spec = get_robot(scene.arm(arm).model)
    except KeyError as exc:
        raise LineRobotError(f"arm {arm!r}: {exc.args[0]}") from None
    by_name = {c.name: c for c in scene.cameras}
    if unknown := [c for c in cameras if c not in by_name]:
        raise LineRobotError(f"camera {unknown[0]!r}: the scene has {', '.join(by_name) or 'no camera'}")
    features: dict[str, type | tuple[int, int, int]] = {f"{m}.pos": float for m in motor_names(spec)}
    for name in cameras:
        features[name] = (by_name[name].height_px, by_name[name].width_px, 3)
    return features


class LineRobot:
    """`arm` of the line `scene` runs, on `session`, with the images of `cameras` (the line renders them only when
    it runs with `--cameras`). Use `connect(wait_s)` first: it waits for the arm's state and each camera's image."""

    def __init__(self, session: zenoh.Session, keys: Keys, scene: Scene, arm: str, cameras: Sequence[str] = ()):
        self.features = robot_features(scene, arm, cameras)
        self.spec = get_robot(scene.arm(arm).model)
        self.motors = motor_names(self.spec)
        kinematics = KinematicModel(self.spec)
        arm_index = kinematics.arm_q_index
        self.lower_deg = np.degrees(kinematics.lower[arm_index])
        self.upper_deg = np.degrees(kinematics.upper[arm_index])
        self.line_arm = LineArm(session, keys, arm, self.spec)
        self.cameras = list(cameras)
        self._images = {name: Inbox() for name in self.cameras}
        self._image_subs = [session.declare_subscriber(keys.camera(n, "rgb"), self._images[n]) for n in self.cameras]
        self._image_decoder = Decoder(CameraImage, self.line_arm.feed.drops)
        self._newest: dict[str, np.ndarray] = {}

    def connect(self, wait_s: float) -> None:
        """Wait until the arm's state and every camera's first image came (`LineRobotError` after `wait_s`)."""
        deadline = time.monotonic() + wait_s
        while self.line_arm.take() is None or any(self._image(n) is None for n in self.cameras):
            if time.monotonic() > deadline:
                missing = [f"the state of {self.line_arm.arm}"] if self.line_arm.take() is None else []
                missing += [f"images of camera {n} (does the line run with --cameras?)" for n in self.cameras]
                raise LineRobotError(f"no {missing[0]} within {wait_s:.0f} s")
            time.sleep(0.02)

    def observation(self) -> dict[str, float | np.ndarray]:
        """The arm's newest state in LeRobot's units, and each camera's newest image."""
        self.line_arm.renew()
        q = self.line_arm.feed.q_rad()
        out: dict[str, float | np.ndarray] = dict(positions(self.spec, q[:-1], q[-1]))
        for name in self.cameras:
            out[name] = self._image(name)
        return out

    def act(self, action: Mapping[str, float]) -> dict[str, float]:
        """Send `action` (`"<motor>.pos"` in LeRobot's units; a motor left out keeps its goal) as the arm's goals,
        each clipped to its joint's limits; the action actually sent. A key that is no motor's, or a value that is
        not a finite number, is refused (ValueError) and nothing is sent."""
        keys = {f"{m}.pos": i for i, m in enumerate(self.motors)}
        if unknown := [k for k in action if k not in keys]:
            raise ValueError(f"action {unknown[0]!r}: the motors are {', '.join(keys)}")
        values = {}
        for key, value in action.items():
            if not isinstance(value, (int, float, np.floating, np.integer)) or not math.isfinite(value):
                raise ValueError(f"action {key!r}: {value!r} is not a finite number")
            values[key] = float(value)
        sent = {}
        arm = len(self.motors) - 1
        for key, value in values.items():
            i = keys[key]
            if i < arm:
                sent[key] = float(np.clip(value, self.lower_deg[i], self.upper_deg[i]))
                self.line_arm.goals[i] = math.radians(sent[key])
            else:
                sent[key] = float(np.clip(value, *GRIPPER_SPAN))
                self.line_arm.goals[i] = gripper_rad(self.spec, sent[key] / GRIPPER_SPAN[1])
        q = self.line_arm.feed.q_rad()
        for i in range(arm):  # a joint never given a goal holds where it stands
            if self.line_arm.goals[i] is None:
                self.line_arm.goals[i] = q[i]
        self.line_arm.send()
        self._tell_refusals()
        return sent

    def _tell_refusals(self) -> None:
        """The plant's answers come later than the action: a goal it refused or aborted since the last action is
        logged with the plant's reason (and counted in `line_arm.refused`); the arm holds its last goal meanwhile."""
        for result in self.line_arm.refusals():
            LOG.warning("%s: the line %s a goal: %s", self.line_arm.arm, result.status, result.reason)

    def let_go(self) -> None:
        """Hand the arm back to the line: every goal dropped, as servos whose torque is turned off."""
        self.line_arm.goals[:] = [None] * len(self.line_arm.goals)
        self.line_arm.send()

    def close(self) -> None:
        for sub in self._image_subs:
            sub.undeclare()
        self.line_arm.close()

    def _image(self, name: str) -> np.ndarray | None:
        """Camera `name`'s newest image (None before the first): only the newest queued is decoded."""
        for key, payload in reversed(self._images[name].drain()):
            msg = self._image_decoder.decode(key, payload)
            if msg is None or msg.camera != name or msg.kind != "rgb":
                continue
            try:
                self._newest[name] = decode_image("rgb", msg.data, msg.encoding, msg.width_px, msg.height_px)
            except ValueError:
                self.line_arm.feed.drops.drop(key, "an image that does not decode")
                continue
            break
        return self._newest.get(name)
