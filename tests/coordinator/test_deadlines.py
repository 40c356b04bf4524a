"""Belt deadlines and reassignment: a riding part's deadline is when it leaves the last arm's reach, and an
assigned task whose arm has fallen behind the part is spotted while a downstream arm can still take it."""

import numpy as np
import pytest

from coordinator.allocation import ArmView, CachedReach, Eligibility, PartView
from coordinator.deadlines import belt_deadline_s, cannot_make_it, last_reach_along_belt_m
from coordinator.ledger import Ledger
from coordinator.tasks import TaskState
from robots.frames import yaw_transform
from robots.registry import get_robot
from robots.top_down import TopDownIK
from scenes import load_scene

BELT = np.array([0.06, 0.0, 0.0])


@pytest.fixture(scope="module")
def cell():
    scene = load_scene("sorting_line", arms=3)
    home = tuple(get_robot("openclaw").home_q)
    arms = [
        ArmView(
            a.name,
            a.base.xyz,
            True,
            CachedReach(TopDownIK(get_robot(a.model), yaw_transform(a.base.xyz, a.base.yaw_rad))),
            home,
        )
        for a in scene.arms
    ]
    return scene, arms


def test_the_deadline_is_when_the_part_rides_past_the_last_point_an_arm_reaches(cell):
    scene, arms = cell
    belt, z = scene.conveyor, scene.conveyor.pose.xyz[2] + 0.015
    last = last_reach_along_belt_m(belt, arms, z)
    assert last is not None and 0 < last < belt.length_m
    end = np.array(belt.point_at(last + 0.05))
    end[2] = z
    assert not any(Eligibility.in_reach(a, end) for a in arms), "5 cm further nobody reaches the belt"
    start = PartView(np.array([*belt.point_at(0.1)[:2], z]), BELT)
    deadline = belt_deadline_s(belt, last, start, now_s=10.0)
    assert deadline == pytest.approx(10.0 + (last - 0.1) / belt.speed_m_per_s)
    assert belt_deadline_s(belt, None, start, 10.0) is None, "a belt no arm reaches gives no deadline"


def test_a_task_whose_arm_fell_behind_the_part_can_be_taken_by_the_next_arm(cell):
    scene, arms = cell
    ledger = Ledger(scene)
    ledger.arrived(1, "mixed", 1, 0.0)  # colour 1 goes to bin_1, beside arm_1
    (task,) = ledger.refresh(0.0)
    rules = Eligibility(scene, arms)
    downstream = PartView(np.array([scene.arms[1].base.xyz[0] - 0.09, 0.0, 0.095]), BELT)
    assert not cannot_make_it(rules, arms[1], task, downstream)
    assert cannot_make_it(rules, arms[1], task, PartView(downstream.position + BELT * 10, BELT)), "long gone past arm_1"
    ledger.assign(task.task_id, "arm_1", 1.0)
    requeued = ledger.requeue(task.task_id, "arm_1 could no longer meet the part")
    assert requeued.state == TaskState.PENDING and requeued.arm is None and requeued.reassignments == 1
    assert ledger.parts[1].attempts == 0, "a reassignment is not a failed attempt"
