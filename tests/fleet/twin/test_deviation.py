"""Mirror mode's figures on series whose truth is known: a real arm that runs 0.15 s behind its sim copy with 0.5
degree of encoder noise is reported so, per goal and joint; at rest only calibration, backlash and noise count."""

import csv
import json
import math

import msgspec
import numpy as np
import pytest

from fleet.bus.messages import ArmState
from fleet.twin.deviation import MirrorSample, deviation, deviation_by_goal
from fleet.twin.lerobot_units import arm_q_rad
from fleet.twin.mirror import command
from fleet.twin.mirror_report import mirror_figures, resting_samples, table, write_mirror_files
from robots.registry import get_robot

JOINTS = ("a", "b", "c")
RATE_HZ = 20.0


def moves(t: np.ndarray) -> np.ndarray:
    """Three joints swinging at different speeds (rad)."""
    return np.column_stack([0.8 * np.sin(1.3 * t), 0.5 * np.sin(0.7 * t + 1.0), 0.3 * np.cos(2.1 * t)])


def mirrored(lag_s: float, noise_deg: float, seconds: float = 20.0, goal_every_s: float = 5.0) -> list[MirrorSample]:
    """Samples of a real arm `lag_s` behind the sim arm, read with `noise_deg` of noise; a new goal id every
    `goal_every_s` (the sim arm's commands lead it by nothing: its tracker is ideal here)."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, seconds, 1.0 / RATE_HZ)
    sim, real = moves(t), moves(t - lag_s) + rng.normal(0.0, math.radians(noise_deg), (len(t), 3))
    goal = (t // goal_every_s).astype(int) + 1
    return [
        MirrorSample(float(t[i]), int(goal[i]), tuple(sim[i]), tuple(real[i]), tuple(sim[i])) for i in range(len(t))
    ]


def test_the_lag_is_found_and_lining_up_leaves_the_noise():
    figures = deviation(mirrored(0.15, 0.5), JOINTS)
    assert figures.lag_s == pytest.approx(0.15, abs=0.01)
    for joint in figures.joints:
        assert joint.aligned_rmse_deg == pytest.approx(0.5, rel=0.2), joint
        assert joint.rmse_deg > 2 * joint.aligned_rmse_deg, "read at the same moment, the lag counts"
        assert joint.real_off_goal_deg == pytest.approx(joint.aligned_rmse_deg, rel=0.01), "its goals are the sim's"
        assert joint.sim_off_goal_deg == 0.0
        assert abs(joint.worst_deg) >= joint.rmse_deg


def test_each_goal_is_judged_on_its_own_and_stretches_without_a_goal_are_not_goals():
    samples = mirrored(0.1, 0.0)
    samples[:10] = [MirrorSample(s.sim_time_s, 0, s.sim_q_rad, s.real_q_rad, s.commanded_q_rad) for s in samples[:10]]
    goals = deviation_by_goal(samples, JOINTS)
    assert [g.goal_id for g in goals] == [1, 2, 3, 4]
    assert goals[0].samples == 100 - 10 and goals[0].start_s == pytest.approx(0.5)
    assert all(g.lag_s == pytest.approx(0.1, abs=0.01) for g in goals)


def test_at_rest_only_still_samples_without_a_goal_count_and_they_show_an_offset():
    t = np.arange(0.0, 4.0, 1.0 / RATE_HZ)
    q = np.where(t[:, None] < 2.0, 0.5 * t[:, None], 1.0) * np.ones((1, 3))  # moves for 2 s, then stands
    off = math.radians(0.3)  # a real arm calibrated 0.3 degree off
    samples = [
        MirrorSample(float(t[i]), 0, tuple(q[i]), tuple(q[i] + off), tuple(q[i]), held=bool(3.5 <= t[i] < 3.7))
        for i in range(len(t))
    ]
    resting = resting_samples(samples)
    times = t[resting]
    assert times.min() >= 2.5 - 1e-9, "still for the whole lag looked for before it"
    assert not any(3.5 <= x < 3.7 for x in times), "the line held it: not at rest"
    rest = mirror_figures(samples, JOINTS).at_rest
    assert rest is not None and rest.samples == len(resting)
    assert all(j.rmse_deg == pytest.approx(0.3, abs=1e-6) for j in rest.joints)


def test_the_report_reads_and_its_files_hold_every_sample(tmp_path):
    samples = mirrored(0.15, 0.5)
    figures = mirror_figures(samples, JOINTS)
    text = table(figures)
    assert "lags 150 ms" in text and text.count("goal ") == 4
    written = write_mirror_files(tmp_path, samples, JOINTS, figures)
    assert [p.name for p in written] == ["deviation.json", "samples.csv"]
    saved = json.loads(written[0].read_text())
    assert saved["whole"]["lag_s"] == figures.whole.lag_s and len(saved["goals"]) == 4
    rows = list(csv.DictReader(written[1].open()))
    assert len(rows) == len(samples)
    assert float(rows[7]["real_b_deg"]) == pytest.approx(math.degrees(samples[7].real_q_rad[1]), abs=1e-3)


def test_the_robot_is_sent_the_trackers_desired_joints_while_a_goal_drives_the_arm_and_its_joints_otherwise():
    spec = get_robot("so101")
    q, desired = (0.1, -0.5, 0.8, 1.2, 0.0), (0.2, -0.4, 0.7, 1.1, 0.3)
    state = ArmState("arm_1", 10, 0.5, q, (0.0,) * 5, spec.gripper_open, (0.0,) * 3, (1.0, 0.0, 0.0, 0.0))
    driven = msgspec.structs.replace(state, goal_id=7, desired_q=desired)
    assert command(spec, state)["elbow_flex.pos"] == pytest.approx(math.degrees(0.8))
    assert command(spec, driven)["elbow_flex.pos"] == pytest.approx(math.degrees(0.7))
    assert command(spec, driven)["gripper.pos"] == pytest.approx(100.0), "the claw open, as LeRobot reads one"


def test_a_hold_is_left_out_of_the_figures_and_how_far_the_real_arm_crept_in_it_is_said():
    t = np.arange(0.0, 3.0, 1.0 / RATE_HZ)
    held = (t >= 1.0) & (t < 2.0)
    creep = np.where(held, np.clip(t - 1.0, 0.0, None) * math.radians(0.4), 0.0)  # 0.4 degree a second
    samples = [
        MirrorSample(float(t[i]), 0, (0.0,) * 3, (creep[i],) * 3, (0.0,) * 3, held=bool(held[i])) for i in range(len(t))
    ]
    figures = mirror_figures(samples, JOINTS)
    assert figures.held_samples == held.sum() and figures.whole.samples == len(t) - held.sum()
    assert figures.whole.joints[0].rmse_deg == 0.0, "what the real arm did while held is no deviation"
    assert figures.held_drift_deg == pytest.approx(0.4 * (0.95 - 0.25), abs=1e-6), "from 0.25 s into the hold"
    assert "moved at most 0.28 deg while held" in table(figures)


def test_a_robot_calibrated_off_is_sent_and_read_in_its_own_degrees():
    spec = get_robot("so101")
    q = (0.1, -0.5, 0.8, 1.2, 0.0)
    state = ArmState("arm_1", 10, 0.5, q, (0.0,) * 5, spec.gripper_open, (0.0,) * 3, (1.0, 0.0, 0.0, 0.0))
    offsets = {"shoulder_pan": 5.0}  # this robot's pan reads 5 degrees more than the joint's own
    sent = command(spec, state, offsets)
    assert sent["shoulder_pan.pos"] == pytest.approx(math.degrees(0.1) + 5.0)
    assert sent["elbow_flex.pos"] == pytest.approx(math.degrees(0.8)), "the other joints as they are"
    assert arm_q_rad(spec, sent, offsets) == pytest.approx(q), "read back through the same offsets: the joints"
