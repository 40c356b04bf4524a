"""Allocator plug-ins in whole lines: the example package, installed as a user installs it, is listed by
`fleet allocators` and runs a line by its entry point name; a plug-in with a bug on some decisions costs the line
only those decisions (greedy's instead), counted in the summary."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.test_run import assert_nothing_left

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "allocator_plugin"


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """The example plug-in installed into a folder of its own (its dist-info and entry point with it), on the path
    of the commands that follow."""
    target = tmp_path_factory.mktemp("plugins")
    source = tmp_path_factory.mktemp("plugin_source") / EXAMPLE.name  # a build writes beside its sources: not here
    shutil.copytree(EXAMPLE, source, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    pip = [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--target", str(target)]
    done = subprocess.run([*pip, str(source)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(target), os.environ.get("PYTHONPATH", "")])}


def fleet_run(env: dict, line: list[str], summary_file: Path) -> dict:
    """`fleet run LINE...` where the plug-ins are installed; its summary."""
    done = subprocess.run(
        [sys.executable, "-m", "fleet", "run", *line, "--summary", str(summary_file)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(summary_file.read_text())


def test_an_installed_plug_in_is_listed_and_runs_a_line(installed, tmp_path):
    listed = subprocess.run(
        [sys.executable, "-m", "fleet", "allocators"], env=installed, capture_output=True, text=True, timeout=60
    )
    assert listed.returncode == 0 and "deadline_first" in listed.stdout and "clawfleet-deadline-first" in listed.stdout
    line = ["sorting_line", "--arms", "2", "--duration", "30", "--allocator", "deadline_first"]
    summary = fleet_run(installed, line, tmp_path / "summary.json")
    assert summary["allocator"] == "deadline_first" and summary["allocator_faults"] == {}
    assert summary["parts_completed"] > 0 and summary["inter_arm_contacts"] == 0


def test_a_plug_in_that_raises_on_some_decisions_costs_only_those():
    options = RunOptions(
        "sorting_line", arms=2, duration_s=30.0, allocator="tests.coordinator.faulty_allocators:RaisesEveryThird"
    )
    said: list[str] = []
    with Launcher(options, on_message=said.append) as launcher:
        summary = launcher.run()
    assert summary["status"] == "ok" and summary["allocator"] == "raises_every_third"
    faults = [line for line in said if line.startswith("allocator raises_every_third: raised")]
    assert len(faults) == 1 and "greedy decides instead" in faults[0], said  # on the terminal, once
    assert summary["allocator_faults"]["raised"] > 0, "every faulty decision counted"
    assert summary["parts_completed"] > 0, "greedy decided those, the line went on"
    assert_nothing_left(summary, launcher.endpoint)


@pytest.mark.lockstep
def test_an_allocator_that_sees_gets_the_overhead_frames_at_its_rate_and_its_line_repeats(installed, tmp_path):
    line = ["pick_cell", "--duration", "12", "--seed", "1", "--allocator", "overhead_eyes"]
    first, second = (fleet_run(installed, line, tmp_path / f"{name}.json") for name in ("first", "second"))
    eyes = first["allocator_eyes"]
    # 2 looks a sim second, the first once a frame is 50 ms old: 24 in 12 s, each of the overhead's one frame
    assert eyes == {"looks": 24, "frames_handed": 24, "looks_without_all_frames": 0}, eyes
    assert first["allocator"] == "overhead_eyes" and "see_raised" not in first["allocator_faults"]
    assert first["parts_completed"] > 0 and first["inter_arm_contacts"] == 0
    same = ("parts_completed", "parts_missed", "throughput_per_min", "arm_time", "goal_results", "allocator_faults")
    assert {k: first[k] for k in same} == {k: second[k] for k in same}
    assert second["allocator_eyes"] == eyes
