"""`fleet bench cameras` and `fleet run --cameras` from the command line: real frames timed, and every mistake (a
camera the scene lacks, no Vulkan device) one line naming what to do, before anything starts."""

import json
import os

import pytest

from tests.fleet.cli.test_cli import fleet
from tests.fleet.in_process import fleet_in_process


@pytest.mark.slow  # a benchmark's renders: not in the quick set
def test_the_camera_benchmark_times_real_frames():
    code, stdout, stderr = fleet_in_process(
        ["bench", "cameras", "--sizes", "16x16", "32x24", "--cameras", "1", "--frames", "2", "--json"]
    )
    assert code == 0, stderr
    rows = json.loads(stdout.strip().splitlines()[-1])
    assert [(r["width_px"], r["height_px"], r["cameras"]) for r in rows] == [(16, 16, 1), (32, 24, 1)]
    assert all(r["render_s"] > 0 and r["frames"] == 2 for r in rows)


def test_no_vulkan_device_is_one_line_naming_what_to_install():
    nowhere = os.environ | {"VK_ICD_FILENAMES": "/nonexistent.json", "VK_DRIVER_FILES": "/nonexistent.json"}
    result = fleet("bench", "cameras", "--sizes", "16x16", "--cameras", "1", "--frames", "1", env=nowhere)
    assert result.returncode == 2
    assert result.stderr.startswith("fleet: error: no Vulkan device to render cameras on")
    assert "mesa-vulkan-drivers" in result.stderr and result.stderr.count("\n") <= 1, result.stderr


def test_a_wrong_size_is_one_line():
    code, _, stderr = fleet_in_process(["bench", "cameras", "--sizes", "big"])
    assert code == 2 and "give a size as WIDTHxHEIGHT" in stderr


def test_run_with_a_camera_the_scene_lacks_is_one_line_before_anything_starts():
    code, _, stderr = fleet_in_process(["run", "sorting_line", "--duration", "1", "--cameras", "wrist"])
    assert code == 2
    assert stderr == "fleet: error: --cameras 'wrist': the scene's cameras are overhead (or all)\n"


def test_run_with_cameras_and_no_vulkan_device_is_one_line_before_anything_starts():
    nowhere = os.environ | {"VK_ICD_FILENAMES": "/nonexistent.json", "VK_DRIVER_FILES": "/nonexistent.json"}
    result = fleet("run", "pick_cell", "--duration", "1", "--cameras", env=nowhere)
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert result.stderr.startswith("fleet: error: no Vulkan device to render cameras on"), result.stderr


@pytest.mark.slow  # renders a scene's cameras: not in the quick set
def test_the_perception_benchmark_scores_detections_against_the_worlds_parts():
    code, stdout, stderr = fleet_in_process(
        ["bench", "perception", "--scenes", "pick_cell", "--seconds", "6", "--json"]
    )
    assert code == 0, stderr
    (row,) = json.loads(stdout.strip().splitlines()[-1])
    assert (row["scene"], row["camera"], row["frames"]) == ("pick_cell", "overhead", 30)
    assert row["parts_visible"] > 10 and row["recall"] >= 0.95 and row["precision"] >= 0.95, row
    assert row["error_p95_mm"] <= 10.0, row


def test_a_perception_benchmark_of_a_scene_that_does_not_exist_is_one_line():
    code, _, stderr = fleet_in_process(["bench", "perception", "--scenes", "nowhere"])
    assert code == 2 and stderr.startswith("fleet: error: nowhere: no such scene") and stderr.count("\n") == 1


def test_perception_on_a_scene_without_a_fixed_camera_is_one_line_before_anything_starts():
    from tests.fleet.test_run import QUICK_LINE

    code, _, stderr = fleet_in_process(["run", QUICK_LINE, "--duration", "1", "--perception", "cameras"])
    assert (
        code == 2
        and stderr.startswith("fleet: error: --perception cameras: the scene ")
        and "no fixed camera" in stderr
    )
