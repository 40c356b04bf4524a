"""The coordinator's decisions as one pure class: events, arm states and requests in, orders out.

The coordinator node and the env's allocate mode both drive a `Dispatcher`; these tests drive it by hand,
with no bus and no clock, as either front end does.
"""

import numpy as np
import pytest

from coordinator.allocation import PartView, make_allocator
from coordinator.cadence import decision_period_ticks
from coordinator.dispatcher import Dispatcher
from coordinator.guard import TimedPath
from coordinator.orders import AssignOrder, CancelOrder, GrantOrder
from robots.registry import get_robot
from scenes import load_scene

SCENE = load_scene("sorting_line")
HOME = np.array(get_robot("openclaw").home_q)
PERIOD = decision_period_ticks(SCENE)


def at_home(d: Dispatcher, t: float) -> None:
    for arm in d.arm_names:
        d.on_arm(arm, HOME, "idle", t)


def part_on_belt(d: Dispatcher, part_id: int, along_m: float) -> PartView:
    belt = SCENE.conveyor
    x, y, z = belt.point_at(along_m)
    return PartView(np.array([x, y, z + 0.03]), np.array(d.belt_velocity()))


def arrive(d: Dispatcher, along_m: float = 0.4, t: float = 1.0) -> AssignOrder:
    """One part arrives on the belt; the next decision gives it to an arm."""
    d.on_event("arrived", 0, SCENE.feeders[0].name, 0, t)
    d.on_parts({0: part_on_belt(d, 0, along_m)}, t)
    at_home(d, t)
    decision = d.decide(round(t * SCENE.control_hz / PERIOD) * PERIOD)
    orders = [o for o in decision.orders if isinstance(o, AssignOrder)]
    assert len(orders) == 1, decision.orders
    return orders[0]


def test_a_part_on_the_belt_is_given_to_an_arm_with_the_belt_velocity_and_a_deadline():
    d = Dispatcher(SCENE)
    order = arrive(d)
    task = d.ledger.tasks[order.task_id]
    assert task.arm == order.arm and task.deadline_s is not None and task.deadline_s > 1.0
    assert order.surface_velocity == d.belt_velocity() and np.linalg.norm(order.surface_velocity) > 0
    assert d.arms.busy_until_s[order.arm] > 1.0, "the allocator's estimate of when the arm is free again"


def test_a_motion_request_is_granted_from_when_the_arm_acts_and_a_restarted_controllers_is_heard():
    d = Dispatcher(SCENE)
    reach_out = tuple(HOME + [0.3, 0.4, -0.3, 0, 0.2, 0])
    at_home(d, 0.0)
    d.on_arm(
        "arm_0",
        HOME,
        "approach",
        0.9,
        request_seq=5,
        acts_at_tick=95,
        request=TimedPath("arm_0", tuple(HOME), reach_out, 0.9, 1.9),
    )
    (grant,) = d.decide(90).orders
    assert grant == GrantOrder("arm_0", 5, "grant", "", grant.min_separation_m, 0.95)
    d.on_arm(
        "arm_0",
        HOME,
        "approach",
        1.0,
        request_seq=5,
        acts_at_tick=105,
        request=TimedPath("arm_0", tuple(HOME), reach_out, 1.0, 2.0),
    )
    assert d.decide(100).orders == [], "the same request is answered once"
    d.on_arm(
        "arm_0",
        HOME,
        "home",
        1.1,
        request_seq=1,
        acts_at_tick=115,  # a new controller counts from 1 again
        request=TimedPath("arm_0", tuple(HOME), tuple(HOME), 1.1, 1.5),
    )
    assert [o.request_seq for o in d.decide(110).orders] == [1]


def test_a_lost_arms_task_goes_to_another_arm():
    d = Dispatcher(SCENE)
    first = arrive(d)
    assert d.arm_lost(first.arm, "no heartbeat", 0.8) == [first.task_id]
    orders, tick = [], 100
    while not orders and tick < 3000:  # the part rides on into the next arm's stretch of the belt
        tick += PERIOD
        t = tick / SCENE.control_hz
        d.on_parts({0: part_on_belt(d, 0, 0.4 + SCENE.conveyor.speed_m_per_s * (t - 1.0))}, t)
        orders = d.decide(tick).orders
    assert [(type(o), o.part_id) for o in orders] == [(AssignOrder, 0)] and orders[0].arm != first.arm
    assert d.report()["arm_events"][0]["tasks_returned"] == [first.task_id]


def test_a_belt_task_its_arm_can_no_longer_meet_is_taken_back():
    d = Dispatcher(SCENE)
    order = arrive(d, along_m=0.4)
    d.on_parts({0: part_on_belt(d, 0, SCENE.conveyor.length_m - 0.01)}, 30.0)  # the part rode on while the arm waited
    cancels = [o for o in d.reassign_late_tasks() if isinstance(o, CancelOrder)]
    assert cancels == [CancelOrder(order.arm, 0)] and d.reassigned == 1


def test_the_same_inputs_give_the_same_decisions():
    def run() -> list:
        d = Dispatcher(SCENE)
        order = arrive(d)
        d.on_arm(
            order.arm,
            HOME,
            "approach",
            1.1,
            task_id=order.task_id,
            request_seq=1,
            acts_at_tick=115,
            request=TimedPath(order.arm, tuple(HOME), tuple(HOME + 0.2), 1.1, 2.0),
        )
        return [order, *d.decide(110).orders, d.report()["tasks"]]

    assert run() == run()


def test_a_sorted_part_goes_to_the_bin_of_its_colour_that_the_arm_taking_it_reaches():
    """On the 4-arm sorting line bin_0 and bin_3 both take the first colour: a part riding past arm_3 goes to bin_3."""
    d = Dispatcher(SCENE)
    base_3 = SCENE.arm("arm_3").base.xyz
    along = base_3[0] - SCENE.conveyor.pose.xyz[0]  # the belt runs along x from its pose
    d.on_event("arrived", 0, SCENE.feeders[0].name, 0, 1.0)
    d.on_parts({0: part_on_belt(d, 0, along)}, 1.0)
    at_home(d, 1.0)
    (order,) = [o for o in d.decide(100).orders if isinstance(o, AssignOrder)]
    bin_3 = SCENE.station("bin_3").pose.xyz
    assert order.arm == "arm_3" and order.place_xyz[:2] == bin_3[:2]
    task = d.ledger.tasks[order.task_id]
    assert (task.target, task.alternatives) == ("bin_3", ("bin_0",)) and d.ledger.parts[0].route == ["bin_3"]


def test_a_dispatcher_that_takes_over_adopts_the_arms_tasks_and_grants_nothing_until_the_arms_settle():
    """A crashed coordinator's successor: the events replayed, the task an arm says it works on adopted (the part
    gets no second task), and no grant while another arm may still move under a grant it never saw."""
    first = Dispatcher(SCENE)
    order = arrive(first)
    place = first.assignment(first.ledger.tasks[order.task_id], order.arm).place_xyz

    d = Dispatcher(SCENE, first_task_id=1 + (1 << 20))
    d.on_event("arrived", 0, SCENE.feeders[0].name, 0, 1.0)
    d.on_parts({0: part_on_belt(d, 0, 0.5)}, 2.0)
    d.take_over(2.0)
    assert d.adopt(order.arm, order.task_id, 0, place, 2.0) == ""
    assert d.ledger.tasks[order.task_id].arm == order.arm and d.ledger.busy_stations() >= set(
        d.ledger.tasks[order.task_id].stations
    )
    assert d.adopt("arm_1", 99, 0, place, 2.0) == "part 0 has a task already", "a part is never adopted twice"
    assert d.adopt(order.arm, 7, 0, (9.0, 9.0, 0.0), 2.0).startswith("no station at")

    other = next(a for a in d.arm_names if a != order.arm)
    reach_out = tuple(HOME + [0.3, 0.4, -0.3, 0, 0.2, 0])
    for arm in d.arm_names:  # the adopted arm is mid-task and not asking: it may move under an old grant
        d.on_arm(arm, HOME, "transfer" if arm == order.arm else "idle", 2.0)
    d.on_arm(
        other,
        HOME,
        "approach",
        2.0,
        request_seq=1,
        acts_at_tick=205,
        request=TimedPath(other, tuple(HOME), reach_out, 2.0, 3.0),
    )
    tick = round(2.0 * SCENE.control_hz / PERIOD) * PERIOD
    assert not [o for o in d.decide(tick).orders if isinstance(o, (GrantOrder, AssignOrder))], (
        "no grant, no second task for part 0"
    )
    d.on_arm(order.arm, HOME, "idle", 2.1)  # the adopted arm settled: grants go on
    grants = [o for o in d.decide(tick + PERIOD).orders if isinstance(o, GrantOrder)]
    assert [g.arm for g in grants] == [other]
    new = d.ledger.refresh(2.2)
    assert all(t.task_id > 1 << 20 for t in new), "a new incarnation's ids never repeat its predecessor's"


def test_a_sorted_part_resting_in_another_bin_of_its_colour_has_done_its_hop():
    d = Dispatcher(SCENE)
    feeder = SCENE.feeders[0]
    bins = SCENE.stations_for_colour(feeder.name, 0)
    assert len(bins) >= 2, "the sorting line has two bins per colour"
    d.on_event("arrived", 0, feeder.name, 0, 1.0)
    d.on_event("at_station", 0, bins[1], 0, 5.0)
    assert d.ledger.totals()["parts_completed"] == 1


def test_an_arm_on_its_way_home_from_a_bin_may_go_straight_back_to_it_and_only_it():
    """mixed_infeed: arm_0 has put a red part in bin_red and is on its way home when the next red part is in its reach
    for a few seconds only. It is given that part at once (it used to wait until home: bin_red counted as busy while
    its own arm moved away, and a red part close behind the last one rode off). For another arm that bin stays busy."""
    scene = load_scene("mixed_infeed")
    d = Dispatcher(scene)
    belt = scene.conveyor
    red = [t for t, p in enumerate(scene.feeder("belt_parts").parts) if p.colour == "#d04030"][0]

    def on_belt(along_m: float) -> PartView:
        x, y, z = belt.point_at(along_m)
        return PartView(np.array([x, y, z + 0.015]), np.array(d.belt_velocity()))

    d.on_event("arrived", 0, "belt_parts", red, 1.0)
    d.on_parts({0: on_belt(0.25)}, 1.0)
    for arm in d.arm_names:
        d.on_arm(arm, HOME, "idle", 1.0)
    [first] = [o for o in d.decide(100).orders if isinstance(o, AssignOrder)]
    assert first.arm == "arm_0"
    d.on_arm("arm_0", HOME, "transfer", 3.0, task_id=first.task_id)
    d.on_event("arrived", 1, "belt_parts", red, 3.0)
    d.on_event("at_station", 0, "bin_red", red, 4.0)
    d.on_arm("arm_0", HOME, "home", 4.1, task_id=first.task_id)
    d.on_parts({1: on_belt(0.30)}, 4.1)
    assert d.ledger.tasks[first.task_id].state.value == "done"
    assert "bin_red" in d.busy_stations("arm_1") and "bin_red" not in d.busy_stations("arm_0")
    orders = [o for o in d.decide(410).orders if isinstance(o, AssignOrder)]
    assert [(o.arm, o.part_id) for o in orders] == [("arm_0", 1)]


def overlap_sort_decision(allocator: str) -> tuple[Dispatcher, list[tuple[str, int]]]:
    """overlap_sort: a blue part (0) in front of arm_0 and a red one (1) just behind it, both arms free. Blue goes to
    either arm's blue bin, red only to arm_0's red bin."""
    scene = load_scene("overlap_sort")
    d = Dispatcher(scene, allocator=make_allocator(allocator, scene))
    red, blue = (next(t for t, p in enumerate(scene.feeders[0].parts) if p.colour == c) for c in ("#d04030", "#3070d0"))

    def on_belt(along_m: float) -> PartView:
        x, y, z = scene.conveyor.point_at(along_m)
        return PartView(np.array([x, y, z + 0.015]), np.array(d.belt_velocity()))

    d.on_event("arrived", 0, "belt_parts", blue, 1.0)
    d.on_event("arrived", 1, "belt_parts", red, 1.0)
    d.on_parts({0: on_belt(0.60), 1: on_belt(0.45)}, 1.0)
    for arm in d.arm_names:
        d.on_arm(arm, HOME, "idle", 1.0)
    return d, [(o.arm, o.part_id) for o in d.decide(100).orders if isinstance(o, AssignOrder)]


def test_an_upstream_arm_takes_the_part_only_it_can_and_leaves_the_other_to_the_arm_downstream():
    """The decision overlap_sort is made of. Optimal: arm_0 takes the red part and the blue one rides on to arm_1 (the
    red part's deadline is where it leaves arm_0's reach, the blue one's where it leaves arm_1's). Greedy, oldest
    first: arm_0 takes the blue part, and the red one is lost if arm_0 is not free again before it rides past."""
    d, optimal = overlap_sort_decision("optimal")
    blue, red = (d.ledger.tasks[t] for t in sorted(d.ledger.tasks))
    assert red.deadline_s < blue.deadline_s
    assert optimal == [("arm_0", 1)]
    assert overlap_sort_decision("greedy")[1] == [("arm_0", 0)]


SHARED_TRAY = """
name: shared_tray
description: Two arms reach one tray; each has a bin that takes the tray's parts.
physics_hz: 200
control_hz: 100
feeders:
  - name: kits
    into: parts_tray
    arrival: {rate_per_min: 6}
    parts: [{kind: box, size_m: [0.04, 0.04, 0.03], mass_kg: 0.1, colour: "#e0c020"}]
stations:
  - {name: parts_tray, kind: tray, pose: {xyz: [0.0, 0.3, 0.0]}, size_m: [0.14, 0.14, 0.02]}
"""
BINS = {
    "arm_0": '  - {name: bin_0, kind: bin, pose: {xyz: [-0.55, 0.1, 0.0]}, accepts_colour: "#e0c020"}\n',
    "arm_1": '  - {name: bin_1, kind: bin, pose: {xyz: [0.65, 0.1, 0.0]}, accepts_colour: "#e0c020"}\n',
}
ARMS = """arms:
  - {name: arm_0, base: {xyz: [-0.25, 0.0, 0.0], yaw_deg: 90}}
  - {name: arm_1, base: {xyz: [0.35, 0.0, 0.0], yaw_deg: 90}}
"""


@pytest.mark.parametrize("first_bin", ["arm_0", "arm_1"])
def test_greedy_gives_a_part_with_a_bin_for_each_arm_to_the_nearest_arm_whichever_bin_comes_first(tmp_path, first_bin):
    """A tray part either arm can take to a bin of its own: greedy gives it to arm_0, nearer the tray, whichever
    bin the scene lists first. It used to go to the arm whose bin came last (that candidate's id sorted first)."""
    second_bin = "arm_1" if first_bin == "arm_0" else "arm_0"
    path = tmp_path / "shared_tray.yaml"
    path.write_text(SHARED_TRAY + BINS[first_bin] + BINS[second_bin] + ARMS)
    scene = load_scene(str(path))
    d = Dispatcher(scene, allocator=make_allocator("greedy", scene))
    tray = scene.station("parts_tray")
    d.on_event("arrived", 0, "kits", 0, 1.0)
    d.on_event("at_station", 0, "parts_tray", 0, 1.2)
    d.on_parts({0: PartView(np.array([*tray.pose.xyz[:2], tray.surface_z_m + 0.015]), np.zeros(3))}, 1.2)
    at_home(d, 1.2)
    orders = [o for o in d.decide(120).orders if isinstance(o, AssignOrder)]
    assert [(o.arm, o.part_id, o.place_xyz[0] < 0) for o in orders] == [("arm_0", 0, True)]
