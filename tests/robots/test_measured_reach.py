"""An arm's reach is measured from its kinematics, not declared: past it the reach search finds nothing, within
it the farthest spot found is reached, and the number is measured once per declaration and kept on disk."""

import dataclasses
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from robots import measured_reach
from robots.disk_cache import cache_dir
from robots.measured_reach import HEIGHTS_M, MARGIN_M, measure_reach_m, reach_m_of
from robots.registry import get_robot, is_available
from robots.spec import DriveGains
from robots.top_down import TopDownIK


@pytest.mark.parametrize("robot", ["openclaw", "so101", "panda"])
def test_past_the_measured_reach_the_search_reaches_nothing_and_just_within_it_something(robot):
    if not is_available(robot):
        pytest.skip("needs the models extra")
    spec = get_robot(robot)
    ik = TopDownIK(spec, np.eye(4))
    rng = np.random.default_rng(7)
    reach = reach_m_of(spec)
    past = 0
    for _ in range(12):  # any bearing, any height measured at, up to 10 cm past the reach
        r, bearing = reach + rng.uniform(0.0, 0.1), rng.uniform(-math.pi, math.pi)
        spot = np.array([r * math.cos(bearing), r * math.sin(bearing), rng.uniform(HEIGHTS_M[0], HEIGHTS_M[-1])])
        assert ik.reach_pose(spot, math.inf) is None, f"{robot} reaches {spot}, past its measured {reach} m"
        past += 1
    axis = ik.pan_origin_world[:2]
    inner = reach - MARGIN_M - float(np.hypot(*axis))  # the farthest spot found, out from the turning axis
    found = [ik.reach_pose(np.array([axis[0] + inner, axis[1], z]), math.inf) is not None for z in HEIGHTS_M]
    assert past == 12 and any(found), f"{robot}: nothing reached {inner:.3f} m out at any height"


def test_the_reach_is_kept_on_disk_and_read_again_and_a_tuned_robot_is_not_measured_anew(monkeypatch, tmp_path):
    monkeypatch.setenv("CLAWFLEET_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(measured_reach, "_MEASURED", {})
    spec = get_robot("openclaw")
    reach = reach_m_of(spec)
    (kept,) = (cache_dir("robots")).glob("openclaw-*.json")
    assert json.loads(kept.read_text())["reach_m"] == reach == measure_reach_m(spec)
    kept.write_text(json.dumps({"robot": "openclaw", "reach_m": 0.4242}))  # a kept number is read, not measured
    monkeypatch.setattr(measured_reach, "_MEASURED", {})
    assert reach_m_of(spec) == 0.4242
    tuned = dataclasses.replace(spec, arm_gains=DriveGains(1.0, 1.0, 1.0), finger_friction=0.3)
    assert reach_m_of(tuned) == 0.4242  # gains and friction move no reach: the same file
    leaning = dataclasses.replace(spec, max_approach_tilt_deg=30.0)
    assert reach_m_of(leaning) >= reach  # a new declaration of what it reaches: measured, in a file of its own
    assert len(list(cache_dir("robots").glob("openclaw-*.json"))) == 2


def test_a_broken_or_unwritable_kept_reach_is_measured_again(monkeypatch, tmp_path):
    monkeypatch.setenv("CLAWFLEET_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(measured_reach, "_MEASURED", {})
    spec = get_robot("openclaw")
    reach = reach_m_of(spec)
    (kept,) = cache_dir("robots").glob("openclaw-*.json")
    kept.write_text("{not json")
    monkeypatch.setattr(measured_reach, "_MEASURED", {})
    assert reach_m_of(spec) == reach
    monkeypatch.setenv("CLAWFLEET_CACHE_DIR", "off")
    monkeypatch.setattr(measured_reach, "_MEASURED", {})
    assert reach_m_of(spec) == reach


def test_loading_a_scene_measures_only_the_robots_its_arms_are(tmp_path):
    code = (
        "from fleet.common.scene_loading import load_checked_scene\n"
        "from robots import measured_reach\n"
        "load_checked_scene('sorting_line')\n"
        "print(sorted({spec.uid for spec, _ in measured_reach._MEASURED.values()}))\n"
    )
    env = {"CLAWFLEET_CACHE_DIR": str(tmp_path), "PATH": "/usr/bin:/bin"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "['openclaw']"
