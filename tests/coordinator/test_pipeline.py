"""Pipelined fixtures: the next part of a fixture is given out before the fixture is ready for it, and its
arm is held at the fixture's edge until it is (the assembly line's base, top and ship; the handover pad)."""

import numpy as np

from coordinator.allocation import PartView
from coordinator.dispatcher import Dispatcher
from coordinator.guard import TimedPath
from coordinator.ledger import Ledger
from coordinator.orders import GrantOrder
from coordinator.tasks import TaskState
from robots.registry import get_robot
from scenes import load_scene

BASE_H, FIXTURE_TOP = 0.03, 0.04


def only(tasks):
    assert len(tasks) == 1, tasks
    return tasks[0]


def by_part(tasks) -> dict:
    return {t.part_id: t for t in tasks}


def line() -> Ledger:
    lg = Ledger(load_scene("assembly_line"), pipeline=True)
    lg.arrived(0, "bases", 0, 1.0)
    lg.arrived(1, "tops", 0, 2.0)
    lg.at_station(1, "tops_bin", 2.5)
    return lg


def base_and_top_given_out(lg: Ledger):
    """The base's and the top's tasks, given to arm_0 and arm_1 (the top's while its base travels)."""
    base = only(lg.refresh(2.5))
    lg.assign(base.task_id, "arm_0", 3.0)
    top = only(lg.refresh(3.0))
    lg.assign(top.task_id, "arm_1", 3.0)
    return base, top


def test_a_top_is_given_out_while_its_base_is_on_the_way_and_waits_for_it_at_the_fixture():
    lg = line()
    base = only(lg.refresh(2.5))  # no top yet: its base waits for an arm, maybe the one the top would go to
    lg.assign(base.task_id, "arm_0", 3.0)
    top = only(lg.refresh(3.0))  # an arm brings the base: the top may come, and wait at the edge
    assert (top.source, top.target) == ("tops_bin", "fixture_0")
    assert lg.place_height_m("fixture_0", top.part_id) == FIXTURE_TOP + BASE_H, "on the base to come"
    lg.assign(top.task_id, "arm_1", 3.0)
    assert lg.may_enter(base, "fixture_0") and not lg.may_enter(top, "fixture_0")
    lg.at_station(0, "fixture_0", 9.0)
    assert lg.may_enter(top, "fixture_0")


def test_the_next_base_waits_until_the_assembly_is_whole_and_sent_away_then_until_it_is_lifted():
    lg = line()
    base, top = base_and_top_given_out(lg)
    lg.at_station(0, "fixture_0", 9.0)
    ship = only(lg.refresh(9.0))  # the top is on its way: the ship may be planned
    assert (ship.part_id, ship.source) == (0, "fixture_0")
    lg.assign(ship.task_id, "arm_2", 9.0)
    assert not lg.may_enter(ship, "fixture_0"), "no ship of half an assembly"
    lg.arrived(2, "bases", 0, 10.0)
    assert lg.refresh(10.0) == [], "a second base waits while the assembly is not whole"
    lg.at_station(1, "fixture_0", 14.0)
    assert lg.may_enter(ship, "fixture_0")
    second = only(lg.refresh(14.0))
    assert (second.part_id, second.target) == (2, "fixture_0")
    assert lg.place_height_m("fixture_0", second.part_id) == FIXTURE_TOP, (
        "on the bare fixture, not on the leaving assembly"
    )
    lg.assign(second.task_id, "arm_0", 14.0)
    assert not lg.may_enter(second, "fixture_0")
    lg.arm_report("arm_2", ship.task_id, "lift", 15.0)
    assert lg.may_enter(second, "fixture_0")


def test_a_top_whose_base_was_lost_does_not_keep_the_next_base_out():
    lg = line()
    base, top = base_and_top_given_out(lg)
    lg.arm_report("arm_1", top.task_id, "lift", 4.0)
    lg.lost(0, "fell to the floor", 5.0)
    lg.arrived(2, "bases", 0, 6.0)
    nxt = only(lg.refresh(6.0))
    lg.assign(nxt.task_id, "arm_0", 6.0)
    assert lg.may_enter(nxt, "fixture_0") and not lg.may_enter(top, "fixture_0")


def test_without_pipelining_a_top_waits_for_its_base_to_be_placed():
    lg = Ledger(load_scene("assembly_line"), pipeline=False)
    lg.arrived(0, "bases", 0, 1.0)
    lg.arrived(1, "tops", 0, 2.0)
    lg.at_station(1, "tops_bin", 2.5)
    lg.assign(only(lg.refresh(2.5)).task_id, "arm_0", 3.0)
    assert lg.refresh(3.0) == []


def test_a_handover_pad_takes_the_next_part_once_the_one_on_it_is_lifted():
    lg = Ledger(load_scene("handover"), pipeline=True)
    lg.arrived(0, "parts", 0, 1.0)
    first = only(lg.refresh(1.0))
    lg.assign(first.task_id, "arm_0", 1.0)
    lg.arrived(1, "parts", 0, 2.0)
    assert lg.refresh(2.0) == [], "one part on its way to the pad at a time"
    lg.at_station(0, "handover_pad", 8.0)
    onward = only(lg.refresh(8.0))
    lg.assign(onward.task_id, "arm_1", 8.0)
    second = only(lg.refresh(8.0))
    assert second.part_id == 1
    lg.assign(second.task_id, "arm_0", 8.0)
    assert not lg.may_enter(second, "handover_pad")
    lg.arm_report("arm_1", onward.task_id, "lift", 10.0)
    assert lg.may_enter(second, "handover_pad")


def test_the_dispatcher_holds_a_transfer_to_a_fixture_that_is_not_ready_and_counts_the_wait():
    scene = load_scene("assembly_line")
    d = Dispatcher(scene, pipeline=True)
    home = {a.name: np.asarray(get_robot(a.model).home_q, float) for a in scene.arms}
    d.on_event("arrived", 0, "bases", 0, 1.0)
    d.on_event("arrived", 1, "tops", 0, 2.0)
    d.on_event("at_station", 1, "tops_bin", 0, 2.5)
    d.on_parts(
        {
            0: PartView(np.array([-1.2, 0.0, 0.1]), np.array([0.05, 0.0, 0.0])),
            1: PartView(np.array([0.58, -0.62, 0.03]), np.zeros(3)),
        },
        3.0,
    )
    d.ledger.assign(only(d.ledger.refresh(3.0)).task_id, "arm_0", 3.0)  # the base; then its top
    top = only(d.ledger.refresh(3.0))
    d.ledger.assign(top.task_id, "arm_1", 3.0)
    for arm, q in home.items():
        d.on_arm(arm, q, "idle", 3.0)
    move = TimedPath("arm_1", tuple(home["arm_1"]), tuple(home["arm_1"] + 0.1), 3.0, 5.0)
    d.on_arm("arm_1", home["arm_1"], "transfer", 3.0, task_id=top.task_id, request_seq=1, request=move)
    told = [o for o in d.decide(300).orders if isinstance(o, GrantOrder)]
    assert [(o.arm, o.decision) for o in told] == [("arm_1", "standby")], (
        "the base is not on the fixture: wait beside it"
    )
    d.on_arm("arm_1", home["arm_1"], "transfer", 3.1, task_id=top.task_id, request_seq=2, request=move)
    assert not [o for o in d.decide(310).orders if isinstance(o, GrantOrder)], "asked again: held, without a word"
    assert d.grants.held_now == {"arm_1": "fixture_0"} and d.grants.held_at_station_s["arm_1"] > 0
    d.on_event("at_station", 0, "fixture_0", 0, 9.0)
    grants = [o for o in d.decide(320).orders if isinstance(o, GrantOrder)]
    assert [(g.arm, g.decision) for g in grants] == [("arm_1", "grant")]
    assert d.ledger.tasks[top.task_id].state in (TaskState.ASSIGNED, TaskState.ACTIVE)


def test_one_arm_at_a_fixture_at_a_time_whatever_the_ledger_holds():
    scene = load_scene("assembly_line")
    d = Dispatcher(scene, pipeline=True)
    home = {a.name: np.asarray(get_robot(a.model).home_q, float) for a in scene.arms}
    for arm, q in home.items():
        d.on_arm(arm, q, "idle", 1.0)
    d.on_event("arrived", 0, "bases", 0, 1.0)
    d.on_event("arrived", 1, "tops", 0, 1.0)
    for part, station in ((1, "tops_bin"), (0, "fixture_0"), (1, "fixture_0")):
        d.on_event("at_station", part, station, 0, 2.0)
    ship = only(d.ledger.refresh(2.0))
    d.ledger.assign(ship.task_id, "arm_2", 2.0)
    d.on_event("arrived", 2, "bases", 0, 3.0)
    base = only(d.ledger.refresh(3.0))  # the assembly is whole and sent for: the next base may come
    d.ledger.assign(base.task_id, "arm_0", 3.0)
    d.on_arm("arm_0", home["arm_0"], "transfer", 4.0, task_id=base.task_id)  # its move in was granted: no request
    d.on_arm(
        "arm_2",
        home["arm_2"],
        "approach",
        4.0,
        task_id=ship.task_id,
        request_seq=1,
        request=TimedPath("arm_2", tuple(home["arm_2"]), tuple(home["arm_2"] + 0.1), 4.0, 5.0),
    )
    assert d.ledger.may_enter(ship, "fixture_0"), "the ledger would let the ship in"
    assert d.grants.station_ahead("arm_2") == "fixture_0", "but the base arm is on its way in"
    d.on_arm("arm_0", home["arm_0"], "home", 6.0, task_id=base.task_id)
    assert d.grants.station_ahead("arm_2") is None


def test_an_arm_on_its_way_home_from_a_fixture_takes_no_task_until_home():
    scene = load_scene("assembly_line")
    d = Dispatcher(scene, pipeline=True)
    q = np.asarray(get_robot("openclaw").home_q, float)
    d.on_arm("arm_0", q, "home", 5.0)
    d.arms.last_stations["arm_0"] = ("fixture_0",)
    d.arms.last_stations["arm_1"] = ("tops_bin",)
    d.on_arm("arm_1", q, "home", 5.0)
    free = {v.name: v.free for v in d.arm_views()}
    assert not free["arm_0"] and free["arm_1"], (
        "from a fixture: home first; from a bin it may take the next task on the way"
    )
    d.on_arm("arm_0", q, "done", 6.0)
    assert {v.name: v.free for v in d.arm_views()}["arm_0"]


def test_an_arm_that_took_a_part_off_a_fixture_to_a_bin_goes_on_from_the_bin_but_not_after_a_failed_grasp():
    """handover: arm_1 lifts each part off the pad and sets it in the bin. On its way home from the bin it is far from
    the pad and may take the next part on the way; had its grasp at the pad failed, it is leaving the pad itself."""
    scene = load_scene("handover")
    d = Dispatcher(scene, pipeline=True)
    q = np.asarray(get_robot("openclaw").home_q, float)
    d.on_event("arrived", 0, "parts", 0, 1.0)
    d.on_event("at_station", 0, "handover_pad", 0, 2.0)
    lift = only(d.ledger.refresh(2.0))
    d.ledger.assign(lift.task_id, "arm_1", 2.0)
    # as `Dispatcher.assignment` sets them
    d.arms.last_stations["arm_1"], d.arms.last_task["arm_1"] = lift.stations, lift.task_id
    d.on_event("at_station", 0, "output_bin", 0, 8.0)
    assert lift.state == TaskState.DONE
    d.on_arm("arm_1", q, "home", 8.5)
    assert d.views.leaving_from("arm_1") == ("output_bin",)
    assert {v.name: v.free for v in d.arm_views()}["arm_1"], "from the bin: the next task on the way"
    lift.state = TaskState.FAILED  # the same task, had it failed at the pad
    assert d.views.leaving_from("arm_1") == ("handover_pad", "output_bin")
    assert not {v.name: v.free for v in d.arm_views()}["arm_1"], "maybe at the pad: home first"


def test_a_top_waits_until_an_arm_takes_its_base_for_one_arm_may_have_to_bring_both():
    lg = line()
    lg.at_station(0, "base_buffer", 2.0)  # the base set down on arm_1's buffer; arm_1 also fetches the tops
    base = only(lg.refresh(2.5))
    assert (base.source, base.target) == ("base_buffer", "fixture_0")
    assert only(lg.refresh(2.6)) is base, "no top yet: given to arm_1 first, it would hold it at the edge for ever"
    lg.assign(base.task_id, "arm_1", 3.0)
    top = only(lg.refresh(3.0))
    assert (top.part_id, top.target) == (1, "fixture_0")


def test_a_top_not_yet_taken_is_withdrawn_when_the_base_it_waited_for_is_lost():
    lg = line()
    base = only(lg.refresh(2.5))
    lg.assign(base.task_id, "arm_1", 3.0)  # arm_1 reaches the belt's end, and fetches the tops
    top = only(lg.refresh(3.0))
    lg.lost(0, "fell to the floor", 4.0)  # the base rode off before arm_1 had it
    assert lg.refresh(4.0) == [] and top.task_id not in lg.tasks, "held at the edge, it would wait for ever"
    lg.arrived(2, "bases", 0, 5.0)
    assert only(lg.refresh(5.0)).part_id == 2, "the next base comes first, then its top"
