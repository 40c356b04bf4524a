"""A servo joint read as a worn real one: the play of its backlash shows when it turns back, its encoder's noise
has the spread asked for, and a perfect one reads exactly."""

import numpy as np
import pytest

from robots.feetech.imperfect_joint import TICKS_PER_DEG, ImperfectJoint
from tests.robots.feetech.joints import StiffJoint


def test_a_perfect_joint_reads_its_shaft_and_passes_goals_on():
    shaft = StiffJoint(2048)
    joint = ImperfectJoint(shaft, 0.0, 0.0, np.random.default_rng(0))
    for ticks in (2048, 2100, 1900, 4095, 3):
        shaft.ticks = ticks
        assert joint.position_ticks() == ticks
    joint.drive(2222)
    assert shaft.goal == 2222


def test_backlash_shows_the_play_when_the_joint_turns_back():
    shaft = StiffJoint(2000)
    joint = ImperfectJoint(shaft, 2.0, 0.0, np.random.default_rng(0))  # 2 degrees of play: 22.8 ticks
    half = 1.0 * TICKS_PER_DEG
    joint.position_ticks()
    shaft.ticks = 2200  # forward: the output trails the motor by half the play
    assert joint.position_ticks() == round(2200 - half)
    shaft.ticks = 2190  # back by less than the play: the output stays
    assert joint.position_ticks() == round(2200 - half)
    shaft.ticks = 2000  # back past it: the output leads by half the play
    assert joint.position_ticks() == round(2000 + half)
    shaft.ticks = 4095  # on through the turn's end, the play kept
    joint.position_ticks()
    shaft.ticks = 100
    assert joint.position_ticks() == round(100 - half)


def test_noise_has_the_spread_asked_for():
    shaft = StiffJoint(2048)
    joint = ImperfectJoint(shaft, 0.0, 0.5, np.random.default_rng(1))
    reads = np.array([joint.position_ticks() for _ in range(4000)], float)
    assert abs(reads.mean() - 2048) < 0.2
    assert reads.std() / TICKS_PER_DEG == pytest.approx(0.5, rel=0.05)


@pytest.mark.parametrize(("backlash", "noise"), [(-1.0, 0.0), (0.0, float("nan")), (float("inf"), 0.0)])
def test_an_impossible_backlash_or_noise_is_refused(backlash, noise):
    with pytest.raises(ValueError, match="give a finite number, 0 or more"):
        ImperfectJoint(StiffJoint(0), backlash, noise, np.random.default_rng(0))
