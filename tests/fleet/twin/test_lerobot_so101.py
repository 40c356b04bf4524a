"""LeRobot's own SO-101 driver, unmodified, in LeRobot's own virtualenv, drives the SO-101 of a running mixed_fleet
line through `fleet twin serve-bus`: it connects without a calibration prompt (serve-bus wrote the sim arm's
calibration file and the servos hold it), reads the joints in its degrees, and its goals move the sim arm."""

import json
import math
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState
from fleet.bus.session import BusEndpoints, open_session
from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.line_beside import run_beside

# a realtime line: LeRobot's driver gives each servo about 34 ms to answer, as a real bus would (a lockstep line
# takes both cores, and a servo answer may then wait longer)
pytestmark = pytest.mark.slow

DRIVER = Path(__file__).with_name("lerobot_so101_driver.py")
JOINTS = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")


def serve_and_drive(launcher: Launcher, lerobot: Path, calibration_dir: Path, seen: dict) -> None:
    """`fleet twin serve-bus --calibration` on arm_1, then LeRobot's driver on its port; the line stopped after."""
    serve = None
    try:
        config = launcher.bus.config_for("twin")
        calibration = calibration_dir / "arm_1.json"
        serve = subprocess.Popen(
            [sys.executable, "-m", "fleet", "twin", "serve-bus", "--arm", "arm_1", "--zenoh-config", str(config)]
            + ["--calibration", str(calibration)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        lines = [serve.stdout.readline() for _ in range(2)]
        seen["serve_lines"] = lines
        port = lines[1].rsplit(" on ", 1)[1].strip()
        with open_session(BusEndpoints(config_file=config)) as session:
            decoder, states = Decoder(ArmState, DropCounter()), []
            sub = session.declare_subscriber(
                Keys(launcher.options.run_id).arm_state("arm_1"),
                lambda sample: states.append(decoder.decode("state", sample.payload.to_bytes())),
            )
            driver = subprocess.run(
                [str(lerobot), str(DRIVER), port, str(calibration_dir), "arm_1"],
                stdin=subprocess.DEVNULL,
                capture_output=True,
                text=True,
                timeout=180,
            )
            sub.undeclare()
        seen["line_q_deg"] = [[math.degrees(q) for q in (*m.q, m.gripper_q[0])] for m in states if m is not None]
        seen["driver_rc"], seen["driver_err"] = driver.returncode, driver.stderr[-3000:]
        seen["driver"] = json.loads(driver.stdout.strip().splitlines()[-1]) if driver.returncode == 0 else {}
        seen["calibration"] = json.loads(calibration.read_text())
    finally:
        if serve is not None:
            serve.send_signal(signal.SIGINT)
            try:
                _, seen["serve_err"] = serve.communicate(timeout=20)
            except subprocess.TimeoutExpired:
                serve.kill()
                _, seen["serve_err"] = serve.communicate()
            seen["serve_rc"] = serve.returncode


def test_lerobots_so101_follower_drives_a_line_s_so_101_through_its_servo_bus(lerobot, tmp_path):
    options = RunOptions(scene="mixed_fleet", duration_s=120.0, seed=0, mode="realtime")
    summary, seen, _ = run_beside(options, serve_and_drive, lerobot, tmp_path)
    assert "error" not in seen, (seen["error"], seen.get("serve_lines"), seen.get("serve_err"))
    assert seen["driver_rc"] == 0, seen["driver_err"]
    assert seen["serve_rc"] == 0, seen["serve_err"]
    assert summary["inter_arm_contacts"] == 0, summary["error"]
    assert "wrote the sim so101's calibration" in seen["serve_lines"][0]
    assert seen["calibration"]["gripper"]["id"] == 6
    driven = seen["driver"]
    assert driven["calibrated"] is True, "LeRobot reads back the calibration its file names"
    sent, after = driven["sent"], driven["after"]
    # the goals reached within a degree once the arm settled; the gripper half open (0 closed, 100 open)
    for joint in JOINTS:
        assert abs(after[f"{joint}.pos"] - sent[f"{joint}.pos"]) < 1.0, (joint, sent, after)
    assert abs(after["gripper.pos"] - 50.0) < 5.0, after
    # the driver's degrees are the joints' own: while the servos held the goal, the line's states (rad) read
    # through them within 0.2 degree (a tick is 0.09), for half a sim second at least (10 states)
    read = np.array([after[f"{joint}.pos"] for joint in JOINTS])
    line = np.array(seen["line_q_deg"])[:, : len(JOINTS)]
    off = np.abs(line - read).max(axis=1)
    assert (off < 0.2).sum() >= 10, (read, line[off.argmin()], driven["settled_after_s"])
    events = [(e["arm"], e["event"]) for e in summary["arm_events"]]
    assert ("arm_1", "taken") in events, events
    assert "0 with a wrong checksum" in seen["serve_err"], seen["serve_err"]
