"""LeRobot's own record loop writes a `LeRobotDataset` from a line's SO-101 as the `clawfleet` robot (the plug-in in
`plugins/lerobot_robot_clawfleet`, found as LeRobot finds third-party robots), driven by a scripted teleoperator,
with the overhead camera's frames; LeRobot's loader reads it back. Its states and actions are the line's own: every
state one the line's recording of the same run holds, every action a goal the recording shows sent to the arm."""

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmGoalMsg, ArmState, GripperGoalMsg, TrajectoryGoalMsg
from fleet.record.mcap_file import Recording
from fleet.run.launcher import Launcher, RunOptions
from robots.registry import get_robot
from tests.fleet.line_beside import run_beside

pytestmark = [pytest.mark.slow, pytest.mark.heavy]  # a lockstep line that renders a camera

DRIVER = Path(__file__).with_name("lerobot_record_driver.py")
SECONDS = 4.0
TOLERANCE_DEG = 1e-3  # the dataset keeps float32: a degree value to about 1e-5


def record(launcher: Launcher, lerobot: Path, root: Path, seen: dict) -> None:
    driver = subprocess.run(
        [str(lerobot), str(DRIVER), str(launcher.bus.config_for("twin")), str(root), str(SECONDS)],
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=300,
    )
    seen["rc"], seen["err"] = driver.returncode, driver.stderr[-4000:]
    if driver.returncode == 0:
        seen["dataset"] = json.loads(driver.stdout.strip().splitlines()[-1])
    seen["overhead"] = next(c for c in launcher.scene.cameras if c.name == "overhead")


def line_said(path: Path, arm: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """From the line's recording: the arm's states in LeRobot's units (degrees, the gripper 0-100), the targets
    of the trajectories sent on its drive key (degrees) and the openings of its claw goals (0-100)."""
    spec, drops, keys = get_robot("so101"), DropCounter(), Keys("line")
    closed, opened = spec.gripper_closed[0], spec.gripper_open[0]
    states, goals = Decoder(ArmState, drops), Decoder(ArmGoalMsg, drops)
    q, targets, openings = [], [], []
    for msg in Recording(path).raw_messages([keys.arm_state(arm), keys.arm_drive(arm)]):
        if msg.key.endswith("/state"):
            s = states.decode(msg.key, msg.payload)
            gripper = min(100.0, max(0.0, 100.0 * (s.gripper_q[0] - closed) / (opened - closed)))
            q.append([*np.degrees(s.q), gripper])
        elif isinstance(g := goals.decode(msg.key, msg.payload), TrajectoryGoalMsg):
            targets.append(np.degrees(g.positions[: len(g.joint_names)]))
        elif isinstance(g, GripperGoalMsg):
            openings.append(100.0 * g.opening)
    assert drops.total == 0, drops.kinds()
    return np.array(q), np.array(targets), np.array(openings)


def test_lerobots_record_loop_writes_a_dataset_of_the_line_s_own_states_and_goals(lerobot, tmp_path):
    options = RunOptions(
        scene="mixed_fleet", duration_s=600.0, seed=0, cameras="overhead", record=str(tmp_path / "line.mcap")
    )
    summary, seen, _ = run_beside(options, record, lerobot, tmp_path)
    assert "error" not in seen, seen["error"]
    assert seen["rc"] == 0, seen["err"]
    overhead = seen["overhead"]
    assert summary["inter_arm_contacts"] == 0
    dataset = seen["dataset"]
    motors = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]
    assert dataset["names"] == [f"{m}.pos" for m in motors]
    assert dataset["episodes"] == 1 and dataset["frames"] >= 0.75 * SECONDS * 10  # 10 fps, a loaded machine lags
    assert "observation.images.overhead" in dataset["features"]
    assert dataset["image_shape"] == [3, overhead.height_px, overhead.width_px] and dataset["image_std"] > 0.01
    state, action = np.array(dataset["state"]), np.array(dataset["action"])
    assert np.ptp(state[:, 0]) > 15.0, "the scripted pan swing moved the arm"
    line_q, targets, openings = line_said(tmp_path / "line.mcap", "arm_1")
    # every frame's state is a state the line recorded (the plug-in reads the line's newest)
    nearest = np.abs(state[:, None, :] - line_q[None, :, :]).max(axis=2).min(axis=1)
    assert nearest.max() < TOLERANCE_DEG, nearest
    # every frame's action went to the arm: a trajectory to its joints, a goal to its claw
    arm_off = np.abs(action[:, None, :5] - targets[None, :, :]).max(axis=2).min(axis=1)
    assert arm_off.max() < TOLERANCE_DEG, arm_off
    claw_off = np.abs(action[:, 5:6] - openings[None, :]).min(axis=1)
    assert claw_off.max() < TOLERANCE_DEG, claw_off
    assert math.isfinite(summary["sim_seconds"])
    events = [(e["arm"], e["event"]) for e in summary["arm_events"]]
    assert ("arm_1", "taken") in events, events
