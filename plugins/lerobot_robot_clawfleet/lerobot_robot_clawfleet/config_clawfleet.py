"""`ClawfleetConfig`: which line, which arm, which of the line's cameras (LeRobot's `--robot.*` flags)."""

from __future__ import annotations

from dataclasses import dataclass, field

from lerobot.robots.config import RobotConfig


@RobotConfig.register_subclass("clawfleet")
@dataclass
class ClawfleetConfig(RobotConfig):
    """An arm of a running clawfleet line. `zenoh_config` is the line's login file for an outside driver
    (`RUN/bus/twin.json5` on a secure line); `connect` an endpoint of an insecure one (`tcp/127.0.0.1:7447`).
    `line_cameras` are the line's cameras by name (it renders them with `fleet run --cameras`), each an image in the
    observations."""

    arm: str = "arm_1"
    zenoh_config: str | None = None
    connect: str | None = None
    run_id: str = "line"
    line_cameras: list[str] = field(default_factory=list)
    wait_s: float = 30.0  # how long `connect()` waits for the line's scene, the arm's state and the first images
