"""A user's own arm: `fleet robots --check` on robot files, robots from another package's entry point, and a scene
whose arms are declared in a file running as the built-in line it copies."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).parents[3]
EXAMPLE = ROOT / "examples" / "robots" / "my_claw.yaml"
QUICK_LINE = ROOT / "tests" / "fleet" / "scenes_data" / "quick_line.yaml"


def fleet(*argv: str, env: dict | None = None, timeout: float = 300) -> subprocess.CompletedProcess:
    wide = {**os.environ, "COLUMNS": "300", **(env or {})}
    return subprocess.run(
        [sys.executable, "-m", "fleet", *argv], capture_output=True, text=True, timeout=timeout, env=wide
    )


def robot_file(tmp_path: Path, name: str, **change) -> Path:
    data = yaml.safe_load(EXAMPLE.read_text())
    data["urdf"] = str((EXAMPLE.parent / data["urdf"]).resolve())
    data.update(change)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_check_of_a_sound_robot_file_says_ok_for_kinematics_home_gripper_and_picks():
    done = fleet("robots", "--check", str(EXAMPLE), "--trials", "2")
    lines = done.stdout.strip().splitlines()
    assert done.returncode == 0, done.stdout + done.stderr
    assert lines[0].startswith("my_claw: 6-DoF arm, 2 gripper joint(s), declared in ")
    assert [line.split(":")[0] for line in lines[1:-1]] == ["ok"] * 5, lines
    assert "Pinocchio and SAPIEN agree on every link" in lines[1] and "2/2 seeded pick trials placed" in lines[5]
    assert "reaches 0.53 m out from its base (measured -10 to 40 cm above its base" in lines[4]
    assert lines[-1] == "my_claw: no problems found"


def test_check_says_what_does_not_work_in_plain_lines(tmp_path):
    sunk = robot_file(tmp_path, "sunk", uid="sunk_claw", home_q=[0, 1.5, 1.5, 0, 1.0, 0])
    done = fleet("robots", "--check", str(sunk), "--trials", "1")
    assert done.returncode == 1 and "problem: home puts the tool 0.146 m below its base" in done.stdout, done.stdout
    assert "pick trials" not in done.stdout  # not tried at picking with a broken home
    far = robot_file(tmp_path, "far", uid="far_claw", reach_m=1.2)  # a reach is measured, not declared
    done = fleet("robots", "--check", str(far), "--trials", "0")
    said = done.stdout + done.stderr
    assert done.returncode == 2 and "reach_m: the reach is measured from the arm's kinematics" in said, said
    assert len(said.strip().splitlines()) == 1, said
    weak = robot_file(
        tmp_path, "weak", uid="weak_claw", gripper_gains={"stiffness": 1500, "damping": 40, "force_limit": 1e-5}
    )
    done = fleet("robots", "--check", str(weak), "--trials", "0")
    assert done.returncode == 1 and "problem: the gripper does not close: finger_left stays at" in done.stdout, (
        done.stdout
    )
    assert done.stdout.strip().splitlines()[-1] == "weak_claw: 1 problem(s)"


def test_a_robot_file_mistake_is_one_line_and_exit_2(tmp_path):
    bad = robot_file(tmp_path, "bad", tool_frame="tool")
    for argv in (["robots", "--check", str(bad)], ["trials", "--robot", str(bad), "--trials", "1"]):
        done = fleet(*argv)
        assert (
            done.returncode == 2
            and done.stderr.strip()
            == f"fleet: error: {bad}: tool_frame: no frame 'tool' in the URDF; did you mean tool_link"
        ), done.stderr


def tiny_package(folder: Path) -> Path:
    """A package installed only as far as Python's entry points need: its module and a dist-info folder."""
    pkg = folder / "tiny_robots"
    pkg.mkdir()
    robot_file(pkg, "tiny_claw", uid="tiny_claw", summary="a robot from another package's file")
    (pkg / "__init__.py").write_text(
        "import dataclasses\nfrom pathlib import Path\n\n"
        "def tiny_claw():\n    return Path(__file__).parent / 'tiny_claw.yaml'\n\n"
        "def tiny_spec():\n    from robots.registry import OPENCLAW\n"
        "    return dataclasses.replace(OPENCLAW, uid='tiny_spec', summary='a RobotSpec from another package')\n\n"
        "def broken():\n    raise RuntimeError('its description is not installed')\n"
    )
    info = folder / "tiny_robots-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: tiny-robots\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[clawfleet.robots]\ntiny_claw = tiny_robots:tiny_claw\ntiny_spec = tiny_robots:tiny_spec\n"
        "broken = tiny_robots:broken\n"
    )
    return folder


def test_robots_of_another_package_are_listed_and_usable_and_a_broken_one_is_reported(tmp_path):
    env = {"PYTHONPATH": str(tiny_package(tmp_path))}
    listed = fleet("robots", env=env)
    assert listed.returncode == 0, listed.stderr
    rows = {line.split("│")[1].strip(): line for line in listed.stdout.splitlines() if line.startswith("│")}
    assert {"openclaw", "tiny_claw", "tiny_spec"} <= set(rows), listed.stdout
    assert "entry point 'tiny_spec' of tiny-robots" in rows["tiny_spec"]
    assert "tiny_claw.yaml" in rows["tiny_claw"]
    assert (
        "problem: entry point 'broken' of tiny-robots (tiny_robots:broken): RuntimeError: its description is not "
        "installed" in listed.stderr
    )
    tried = fleet("trials", "--robot", "tiny_claw", "--trials", "1", "--json", env=env)
    assert tried.returncode == 0 and json.loads(tried.stdout.strip().splitlines()[-1])["successes"] == 1, (
        tried.stdout + tried.stderr
    )


def summary_of(scene: Path) -> dict:
    done = fleet("run", str(scene), "--duration", "20", "--json")
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow  # two whole runs: not in the quick set
def test_a_scene_whose_arms_are_declared_in_a_file_runs_as_the_line_it_copies(tmp_path):
    """examples/robots/my_claw_line.yaml is the quick line with its arms declared in a robot file: same parts, same
    moves."""
    own, builtin = summary_of(ROOT / "examples" / "robots" / "my_claw_line.yaml"), summary_of(QUICK_LINE)
    keys = (
        "status",
        "parts_spawned",
        "parts_completed",
        "parts_missed",
        "inter_arm_contacts",
        "arm_time",
        "goal_results",
    )
    assert {k: own[k] for k in keys} == {k: builtin[k] for k in keys}
    assert own["parts_completed"] >= 1 and own["inter_arm_contacts"] == 0


def test_a_scene_naming_a_bad_robot_file_is_one_line_naming_both_files(tmp_path):
    robot_file(tmp_path, "arm", uid="scene_claw", home_q=[0, 0])
    scene = yaml.safe_load(QUICK_LINE.read_text())
    scene.update(robot_files=["arm.yaml"], arm_row={**scene["arm_row"], "model": "scene_claw"})
    (tmp_path / "line.yaml").write_text(yaml.safe_dump(scene))
    done = fleet("check", str(tmp_path / "line.yaml"))
    expected = (
        f"fleet: error: {tmp_path / 'line.yaml'}: robot_files.0: {tmp_path / 'arm.yaml'}: home_q: 2 values for 6 joints"
    )
    assert done.returncode == 2 and done.stderr.strip().startswith(expected), done.stderr
