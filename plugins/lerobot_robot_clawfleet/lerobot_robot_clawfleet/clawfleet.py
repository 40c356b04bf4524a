"""`Clawfleet`: LeRobot's `Robot` API over `fleet.twin.line_robot.LineRobot` (the arm of a running line in LeRobot's
units). An SO-101 of the line reads as a real SO-101 follower does (`"<joint>.pos"` in degrees, the gripper 0-100);
`send_action` drives it as an outside driver, through the plant's safety layer, and returns what it sent."""

from __future__ import annotations

import contextlib
from functools import cached_property
from typing import Any

from lerobot.robots.robot import Robot

from fleet.bus.keys import Keys
from fleet.bus.scene_query import fetch_scene
from fleet.bus.session import BusEndpoints, open_session
from fleet.twin.line_robot import LineRobot, robot_features
from lerobot_robot_clawfleet.config_clawfleet import ClawfleetConfig
from scenes.schema import Scene


class Clawfleet(Robot):
    """An arm of a running clawfleet line, as LeRobot drives a robot."""

    config_class = ClawfleetConfig
    name = "clawfleet"

    def __init__(self, config: ClawfleetConfig) -> None:
        super().__init__(config)
        self.config = config
        self._keys = Keys(config.run_id)
        self._session_cm: contextlib.AbstractContextManager | None = None
        self._robot: LineRobot | None = None
        self._scene: Scene | None = None

    def _endpoints(self) -> BusEndpoints:
        if not (self.config.zenoh_config or self.config.connect):
            raise ValueError(
                "clawfleet robot: give --robot.zenoh_config=RUN/bus/twin.json5 or --robot.connect=ENDPOINT"
            )
        if self.config.zenoh_config:
            return BusEndpoints(config_file=self.config.zenoh_config)
        return BusEndpoints(connect=(self.config.connect,))

    def _line_scene(self) -> Scene:
        """The line's scene, asked of its sim once (the features need it before `connect`)."""
        if self._scene is None:
            with open_session(self._endpoints()) as session:
                self._scene = fetch_scene(session, self._keys, self.config.wait_s)
        return self._scene

    @cached_property
    def observation_features(self) -> dict[str, Any]:
        return robot_features(self._line_scene(), self.config.arm, self.config.line_cameras)

    @cached_property
    def action_features(self) -> dict[str, Any]:
        return {k: v for k, v in self.observation_features.items() if k.endswith(".pos")}

    @property
    def is_connected(self) -> bool:
        return self._robot is not None

    def connect(self, calibrate: bool = True) -> None:
        """Join the line's bus and wait for the arm's state and each camera's first image (a sim arm needs no
        calibration: `calibrate` is taken and ignored)."""
        if self._robot is not None:
            raise RuntimeError(f"{self} is already connected")
        self._session_cm = open_session(self._endpoints())
        session = self._session_cm.__enter__()
        try:
            if self._scene is None:  # else asked already, for the features
                self._scene = fetch_scene(session, self._keys, self.config.wait_s)
            self._robot = LineRobot(session, self._keys, self._scene, self.config.arm, self.config.line_cameras)
            self._robot.connect(self.config.wait_s)
        except BaseException:
            if self._robot is not None:
                self._robot.close()
                self._robot = None
            self._session_cm.__exit__(None, None, None)
            raise

    @property
    def is_calibrated(self) -> bool:
        return True

    def calibrate(self) -> None:
        """A sim arm's joints are where its state says: nothing to calibrate."""

    def configure(self) -> None:
        """Nothing to set: the line's plant has its own gains."""

    def get_observation(self) -> dict[str, Any]:
        return self._connected().observation()

    def send_action(self, action: dict[str, Any]) -> dict[str, Any]:
        """The action's `"<motor>.pos"` entries as the arm's goals (other keys, such as a policy's extras, are left
        out); what was sent, each clipped to its joint's limits."""
        return self._connected().act({k: v for k, v in action.items() if k.endswith(".pos")})

    def disconnect(self) -> None:
        """Hand the arm back to the line and leave its bus."""
        robot = self._connected()
        try:
            robot.let_go()
        finally:
            robot.close()
            self._robot = None
            self._session_cm.__exit__(None, None, None)

    def _connected(self) -> LineRobot:
        if self._robot is None:
            raise ConnectionError(f"{self} is not connected: call connect() first")
        return self._robot
