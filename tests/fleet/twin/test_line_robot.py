"""An arm of a running line in a LeRobot robot's terms (`LineRobot`, what the LeRobot plug-in drives): mixed_fleet's
SO-101 reads in degrees with its gripper 0-100 and the overhead camera's images; an action moves it, clipped to its
joints' limits; a wrong action is refused whole; let go, the line has the arm back."""

import math
import time

import numpy as np
import pytest

from fleet.bus.keys import Keys
from fleet.bus.scene_query import fetch_scene
from fleet.bus.session import BusEndpoints, open_session
from fleet.run.launcher import Launcher, RunOptions
from fleet.twin.line_robot import LineRobot, LineRobotError, robot_features
from tests.fleet.line_beside import run_beside

pytestmark = [pytest.mark.slow, pytest.mark.heavy]  # a lockstep line that renders a camera

GOAL = {"shoulder_pan.pos": 15.0, "shoulder_lift.pos": -28.6, "elbow_flex.pos": 43.6, "wrist_flex.pos": 68.8}


def drive(launcher: Launcher, seen: dict) -> None:
    keys = Keys(launcher.options.run_id)
    with open_session(BusEndpoints(config_file=launcher.bus.config_for("twin"))) as session:
        scene = fetch_scene(session, keys, 30.0)
        seen["features"] = robot_features(scene, "arm_1", ["overhead"])
        with pytest.raises(LineRobotError, match="camera 'wrist'"):
            robot_features(scene, "arm_1", ["wrist"])
        robot = LineRobot(session, keys, scene, "arm_1", ["overhead"])
        try:
            robot.connect(60.0)
            seen["first"] = robot.observation()
            state = robot.line_arm.take()
            seen["state_deg"] = [math.degrees(q) for q in state.q]
            with pytest.raises(ValueError, match="'elbow.pos'"):
                robot.act({"elbow.pos": 1.0})
            with pytest.raises(ValueError, match="not a finite number"):
                robot.act({"elbow_flex.pos": float("nan")})
            assert robot.line_arm.sent == 0, "a refused action sends nothing"
            seen["sent"] = robot.act(GOAL | {"wrist_roll.pos": 400.0, "gripper.pos": 50.0})
            sent_at = robot.line_arm.take().sim_time_s
            while robot.line_arm.take().sim_time_s < sent_at + 10.0:  # past a hold and a release: renewed
                seen["last"] = robot.observation()
                time.sleep(0.01)
            robot.let_go()
            let_go_at = robot.line_arm.take().sim_time_s
            while robot.line_arm.take().sim_time_s < let_go_at + 12.0:
                time.sleep(0.01)
            seen["back"] = robot.observation()
        finally:
            robot.close()


def test_a_line_s_so101_reads_and_moves_in_lerobot_units():
    options = RunOptions(scene="mixed_fleet", duration_s=120.0, seed=0, cameras="overhead")
    summary, seen, _ = run_beside(options, drive)
    assert "error" not in seen, seen["error"]
    assert summary["inter_arm_contacts"] == 0
    motors = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]
    assert list(seen["features"]) == [f"{m}.pos" for m in motors] + ["overhead"]
    first = seen["first"]
    assert seen["features"]["overhead"] == first["overhead"].shape and first["overhead"].dtype == np.uint8
    assert first["overhead"].std() > 5, "the overhead image shows something"
    # degrees are the joints' own; the open gripper reads 100
    assert np.allclose([first[f"{m}.pos"] for m in motors[:5]], seen["state_deg"], atol=1e-6)
    assert 0.0 <= first["gripper.pos"] <= 100.0
    # the wrist roll asked past its limit (+161 degrees) is clipped there; the rest sent as asked
    sent = seen["sent"]
    assert sent["wrist_roll.pos"] == pytest.approx(math.degrees(2.84121), abs=1e-3)
    assert {k: sent[k] for k in GOAL} == GOAL and sent["gripper.pos"] == 50.0
    last = seen["last"]
    for key, value in sent.items():
        assert abs(last[key] - value) < (5.0 if key == "gripper.pos" else 1.0), (key, sent, last)
    # let go: the line takes the arm back (its home pose, or a task's)
    back = seen["back"]
    assert max(abs(back[k] - last[k]) for k in GOAL) > 5.0, (last, back)
    events = [(e["arm"], e["event"]) for e in summary["arm_events"]]
    assert ("arm_1", "taken") in events and ("arm_1", "let go") in events, events
