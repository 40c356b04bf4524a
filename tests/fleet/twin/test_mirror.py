"""Mirror mode end to end, in LeRobot's own Python: LeRobot's `SO101Follower` on the servo bus `fleet twin serve-bus`
makes of a second SO-101 (the "real" arm, out of everyone's reach) runs the goals of the line's working SO-101
beside it. Served clean, the real arm follows its goals within a degree or two, a fixed lag behind, and stands on
the sim arm's joints at rest; an e-stop holds it where it stands. Served worn (and calibrated off on one joint, which
the mirror is told), the deviation at rest is the noise and backlash that were set."""

import json
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, EStop
from fleet.bus.session import BusEndpoints, open_session
from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.line_beside import run_beside

pytestmark = pytest.mark.slow  # a realtime line: LeRobot's driver gives each servo about 34 ms to answer

SCENE = Path(__file__).with_name("twin_cell.yaml")
NOISE_DEG, BACKLASH_DEG = 2.0, 1.0
# a homing offset of -57 ticks: the servo reads 57 ticks more, LeRobot 57 * 360 / 4095 degrees more than the joint
PAN_OFFSET_TICKS, PAN_OFFSET_DEG = 57, 5.011


def serve(launcher: Launcher, calibration: Path, *wear: str) -> tuple[subprocess.Popen, str]:
    """`fleet twin serve-bus` on the real arm; its port."""
    config = launcher.bus.config_for("twin")
    served = subprocess.Popen(
        [sys.executable, "-m", "fleet", "twin", "serve-bus", "--arm", "real_so101", "--zenoh-config", config]
        + ["--calibration", str(calibration), *wear],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    lines = [served.stdout.readline() for _ in range(2)]
    assert " on /dev/" in lines[1], (lines, served.stderr.read() if served.poll() is not None else "")
    return served, lines[1].rsplit(" on ", 1)[1].strip()


def stop(served: subprocess.Popen) -> str:
    served.send_signal(signal.SIGINT)
    try:
        return served.communicate(timeout=20)[1]
    except subprocess.TimeoutExpired:
        served.kill()
        return served.communicate()[1]


def mirror(lerobot: Path, launcher: Launcher, port: str, calibration_dir: Path, seconds: float, out: Path, *more: str):
    """`fleet twin mirror` of arm_1 onto LeRobot's SO-101 follower on `port`, started (stdin closed: a calibration
    prompt would fail it)."""
    return subprocess.Popen(
        [str(lerobot), "-m", "fleet", "twin", "mirror", "--arm", "arm_1", "--robot-type", "so101_follower"]
        + ["--robot", f"port={port}", "--robot", "id=real_so101", "--robot", f"calibration_dir={calibration_dir}"]
        + ["--zenoh-config", launcher.bus.config_for("twin"), "--duration", str(seconds), "--out", str(out), *more],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def estop_while_it_moves(launcher: Launcher, seen: dict, hold_s: float = 1.5) -> None:
    """Engage the e-stop 0.3 s after a goal first drives arm_1, release it `hold_s` later (the monitor's login)."""
    keys = Keys(launcher.options.run_id)
    with open_session(BusEndpoints(config_file=launcher.bus.config_for("monitor"))) as session:
        decoder, moving = Decoder(ArmState, DropCounter()), threading.Event()

        def heard(sample) -> None:
            state = decoder.decode("state", sample.payload.to_bytes())
            if state is not None and state.goal_id != 0:
                moving.set()

        sub = session.declare_subscriber(keys.arm_state("arm_1"), heard)
        if moving.wait(60):
            time.sleep(0.3)
            session.put(keys.estop, encode(EStop(True, "test")))
            time.sleep(hold_s)
            session.put(keys.estop, encode(EStop(False, "test")))
            seen["estop"] = True
        sub.undeclare()


def calibrated_off(calibration: Path, joint: str, homing_offset: int) -> None:
    """The real arm's calibration file, `joint`'s homing offset set: LeRobot's degrees then read off the joint's."""
    entries = json.loads(calibration.read_text())
    entries[joint]["homing_offset"] = homing_offset
    calibration.write_text(json.dumps(entries))


def mirror_clean_then_worn(launcher: Launcher, lerobot: Path, tmp_path: Path, seen: dict) -> None:
    calibration_dir = tmp_path / "calibration"
    calibration = calibration_dir / "real_so101.json"
    wear = ("--noise-deg", str(NOISE_DEG), "--backlash-deg", str(BACKLASH_DEG))
    for name, serve_flags, seconds, mirror_flags in (
        ("clean", (), 14.0, ()),
        # 10 s: the at-rest figures need the sim arm still for 0.5 s before; 6 s of a busy arm once had none
        ("worn", wear, 10.0, ("--offset-deg", f"shoulder_pan={PAN_OFFSET_DEG}")),
    ):
        if name == "worn":  # the worn arm is calibrated off too, and the mirror told by how much
            calibrated_off(calibration, "shoulder_pan", -PAN_OFFSET_TICKS)
        served, port = serve(launcher, calibration, *serve_flags)
        try:
            run = mirror(lerobot, launcher, port, calibration_dir, seconds, tmp_path / name, *mirror_flags)
            started = run.stdout.readline()  # "mirroring ...": the robot is connected, the mirror on
            if name == "clean" and "mirroring" in started:
                estop_while_it_moves(launcher, seen)
            out, err = run.communicate(timeout=120)
            seen[name] = {"rc": run.returncode, "out": started + out, "err": err[-3000:]}
        finally:
            seen[name + "_serve_err"] = stop(served)


def test_a_lerobot_so101_mirrors_a_line_arm_and_its_deviation_is_what_its_servos_make(lerobot, tmp_path):
    options = RunOptions(scene=str(SCENE), duration_s=150.0, seed=0, mode="realtime")
    summary, seen, _ = run_beside(options, mirror_clean_then_worn, lerobot, tmp_path)
    assert "error" not in seen, (seen["error"], seen)
    for name in ("clean", "worn"):
        assert seen[name]["rc"] == 0, (name, seen[name]["err"], seen[name + "_serve_err"])
    assert summary["inter_arm_contacts"] == 0, summary["error"]
    clean = json.loads((tmp_path / "clean" / "deviation.json").read_text())
    worn = json.loads((tmp_path / "worn" / "deviation.json").read_text())
    print(seen["clean"]["out"], seen["worn"]["out"], sep="\n")  # the figures, for the record
    # clean: a fixed lag (the mirror's rate, the bus, a servo's 0.1 s move), the goals followed within a degree or
    # two (a swing faster than an STS3215 turns is the servo's own), the sim arm's joints at rest to a tick or two
    assert 0.05 <= clean["whole"]["lag_s"] <= 0.35, clean["whole"]["lag_s"]
    assert len(clean["goals"]) >= 2, "the arm worked while mirrored"
    # (one lag for the whole mirror: a goal whose own lag is twice it, on a machine running the suite 1.4x slower
    # than usual, left the pan 2.9 deg off in one clean-clone CI run; 1-2 deg on an idle one)
    for joint in clean["whole"]["joints"]:
        assert joint["real_off_goal_deg"] <= 4.0, joint
    assert all(j["aligned_rmse_deg"] <= 0.3 for j in clean["at_rest"]["joints"]), clean["at_rest"]
    # the e-stop: the line held its arm, and the robot stood where it was when the hold began
    assert seen.get("estop") and "1 holds" in seen["clean"]["err"], seen["clean"]["err"]
    assert clean["held_samples"] >= 20 and clean["held_drift_deg"] <= 0.5, clean["held_drift_deg"]
    # worn and calibrated 5 degrees off on the pan, told so: at rest, what noise (a standard deviation of NOISE_DEG)
    # and backlash (up to half of it either way) make, and no more on the pan
    assert worn["at_rest"] is not None, "the sim arm stood still for a while in 10 s of the line"
    for joint in worn["at_rest"]["joints"]:
        assert 0.7 * NOISE_DEG <= joint["aligned_rmse_deg"] <= NOISE_DEG + BACKLASH_DEG / 2 + 0.3, joint
