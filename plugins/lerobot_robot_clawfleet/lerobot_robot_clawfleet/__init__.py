"""An arm of a running clawfleet line as a LeRobot robot: `--robot.type=clawfleet`."""

from lerobot_robot_clawfleet.clawfleet import Clawfleet
from lerobot_robot_clawfleet.config_clawfleet import ClawfleetConfig

__all__ = ["Clawfleet", "ClawfleetConfig"]
