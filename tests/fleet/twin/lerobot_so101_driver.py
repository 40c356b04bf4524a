"""Run by LeRobot's own Python (its virtualenv), not by pytest: LeRobot's unmodified `SO101Follower` on the port
given, as a LeRobot user runs a real one. It connects (no prompt: the servos hold its calibration file), reads the
joints, sends the arm to a pose beside its home (shoulder pan and elbow 15 degrees on, gripper half open) and
reads until it has settled there; one JSON line of what it saw.
Usage: python lerobot_so101_driver.py PORT CALIBRATION_DIR ROBOT_ID"""

import json
import sys
import time
from pathlib import Path

from lerobot.robots.so_follower import SO101Follower, SO101FollowerConfig

# the sim SO-101's home pose (robots/registry.py, in degrees) with the pan and elbow 15 degrees on
GOAL = {
    "shoulder_pan.pos": 15.0,
    "shoulder_lift.pos": -28.6,
    "elbow_flex.pos": 43.6,
    "wrist_flex.pos": 68.8,
    "wrist_roll.pos": 0.0,
    "gripper.pos": 50.0,
}
SETTLE_TIMEOUT_S = 60.0


def settled(robot: SO101Follower) -> tuple[dict, float]:
    """The joints once three reads 0.2 s apart agree within 0.1 degree, and how long that took (s)."""
    started, reads = time.monotonic(), [robot.get_observation()]
    while time.monotonic() - started < SETTLE_TIMEOUT_S:
        time.sleep(0.2)
        reads = [*reads[-2:], robot.get_observation()]
        if len(reads) == 3 and all(abs(r[k] - reads[-1][k]) < 0.1 for r in reads for k in GOAL):
            break
    return reads[-1], time.monotonic() - started


def main() -> None:
    port, calibration_dir, robot_id = sys.argv[1:4]
    robot = SO101Follower(SO101FollowerConfig(port=port, id=robot_id, calibration_dir=Path(calibration_dir)))
    robot.connect()  # as a user does; stdin is closed, so a calibration prompt fails the run (EOFError)
    try:
        seen = {"calibrated": robot.is_calibrated, "before": robot.get_observation()}
        seen["sent"] = robot.send_action(dict(GOAL))
        seen["after"], seen["settled_after_s"] = settled(robot)
    finally:
        robot.disconnect()
    print(json.dumps(seen), flush=True)


if __name__ == "__main__":
    main()
