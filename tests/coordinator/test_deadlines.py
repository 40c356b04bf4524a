"""Belt deadlines and reassignment: a riding part's deadline is when it leaves the last arm's reach, and an
assigned task whose arm has fallen behind the part is spotted while a downstream arm can still take it."""

import numpy as np
import pytest

from coordinator.allocation import ArmView, CachedReach, Eligibility, PartView
from coordinator.capacity import arm_views
from coordinator.deadlines import belt_deadline_s, cannot_make_it, last_reach_along_belt_m, layout_belt_reach
from coordinator.ledger import Ledger
from coordinator.tasks import PartRecord, TaskState
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


def test_a_sorted_parts_deadline_is_where_it_leaves_the_last_arm_with_a_bin_of_its_colour():
    """overlap_sort: red goes only to arm_0's bin, blue to arm_0's or arm_1's. A red part is lost once past arm_0;
    counting it due at the end of the belt (as any sorted part was) let arm_0 take a blue part first."""
    scene = load_scene("overlap_sort")
    reach = layout_belt_reach(scene, arm_views(scene))
    red_bin, blue_bins = reach.by_station_m["bin_red"], [reach.by_station_m[b] for b in ("bin_blue_0", "bin_blue_1")]
    arm_0_only = last_reach_along_belt_m(scene.conveyor, arm_views(scene)[:1], scene.conveyor.pose.xyz[2] + 0.015)
    assert red_bin == blue_bins[0] == arm_0_only < blue_bins[1] == reach.any_m


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


def test_in_a_row_of_bays_a_part_bound_for_its_bay_can_be_taken_until_it_leaves_that_bay():
    from coordinator.capacity import arm_views
    from coordinator.deadlines import layout_belt_reach

    one = load_scene("assembly_line")
    alone = layout_belt_reach(one, arm_views(one))
    assert alone.for_station("fixture_0") == alone.any_m  # one bay: as it always was
    row = load_scene("assembly_line", arms=9)
    reach = layout_belt_reach(row, arm_views(row))
    bays = [reach.for_station(f) for f in ("fixture_0", "fixture_0_b1", "fixture_0_b2")]
    assert bays[0] >= alone.any_m  # a belt that goes on: bay 0's arms take parts past where the one bay's ended
    assert bays[1] == pytest.approx(bays[0] + 1.6, abs=0.05)  # each bay 1.6 m further down
    assert bays[2] == pytest.approx(row.conveyor.length_m)  # the last bay: to the belt's end, as one bay's
    assert reach.for_station("base_buffer_b1") == reach.for_station("fixture_0_b1")
    assert reach.any_m == bays[2] and reach.for_station(None) == reach.any_m  # the whole row: its last bay
    sorting = load_scene("sorting_line", arms=3)
    bins = layout_belt_reach(sorting, arm_views(sorting))  # a sorted part: until past the arms with a bin of its colour
    assert bins.for_station("bin_0") < bins.for_station("bin_2") == bins.any_m


def test_a_part_gets_its_last_chance_at_each_buffer_from_that_buffers_own_arms():
    """The main job: infeed_buffer is arm_0's, upstream; base_buffer arm_1's, at the belt's end. A base 6 s before
    the end of arm_0's stretch is at its last chance for infeed_buffer (8 s: an approach and a grasp), not yet for
    base_buffer; past arm_0, never again for infeed_buffer. (Asked by the belt's end alone, a base got its task for
    infeed_buffer 2.7 s before it left arm_0, too late: three bases in a row rode off on seed 3, arm_0 idle.)"""
    scene = load_scene("assembly_line")
    reach = layout_belt_reach(scene, arm_views(scene))
    belt, z = scene.conveyor, scene.conveyor.pose.xyz[2] + 0.015
    upstream, downstream = reach.by_station_m["infeed_buffer"], reach.by_station_m["base_buffer"]
    assert upstream < downstream == reach.by_station_m["fixture_0"], "arm_0's stretch ends before arm_1's"

    def riding_at(along_m: float) -> dict[int, PartView]:
        return {7: PartView(np.array([*belt.point_at(along_m)[:2], z]), np.array(belt.direction) * belt.speed_m_per_s)}

    base = PartRecord(7, "bases", 0, 0.03, ["fixture_0", "output_tray"], 0.0)
    six_s_before = upstream - 6.0 * belt.speed_m_per_s
    near_arm_0 = reach.riding_off(belt, riding_at(six_s_before), 8.0)
    assert near_arm_0(base, "infeed_buffer") and not near_arm_0(base, "base_buffer")
    assert not reach.riding_off(belt, riding_at(upstream + 0.02), 8.0)(base, "infeed_buffer"), "past arm_0"
    assert reach.riding_off(belt, riding_at(downstream - 0.1), 8.0)(base, "base_buffer")
