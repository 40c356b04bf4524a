"""The task ledger on the assembly line: precedence, retries, lost arms and parts, every part accounted for."""

import numpy as np
import pytest
import yaml

from coordinator.allocation import Eligibility, PartView
from coordinator.capacity import arm_views
from coordinator.ledger import DENIAL_HOLD_S, MAX_ATTEMPTS, MAX_DENIALS, Ledger
from coordinator.tasks import TaskState
from robots.failures import FailureCode
from robots.skills.pick_plans import UNREACHABLE
from scenes import load_scene
from scenes.loader import BUNDLED_DIR, SceneError


def ledger() -> Ledger:
    return Ledger(load_scene("assembly_line"), pipeline=False)


def only(tasks):
    assert len(tasks) == 1, tasks
    return tasks[0]


def test_a_top_waits_for_its_base_and_the_base_ships_only_with_its_top():
    lg = ledger()
    lg.arrived(0, "bases", 0, 1.0)
    lg.arrived(1, "tops", 0, 2.0)
    base_task = only(lg.refresh(2.0))  # the top is still falling into its bin: no task yet
    assert (base_task.part_id, base_task.source, base_task.target) == (0, "conveyor", "fixture_0")
    lg.at_station(1, "tops_bin", 2.5)
    assert only(lg.refresh(2.5)) is base_task  # no top before the base sits on the fixture
    lg.assign(base_task.task_id, "arm_0", 3.0)
    lg.arm_report("arm_0", base_task.task_id, "approach", 3.1)
    lg.at_station(0, "fixture_0", 9.0)
    assert base_task.state == TaskState.DONE
    top_task = only(lg.refresh(9.0))
    assert (top_task.part_id, top_task.source, top_task.target) == (1, "tops_bin", "fixture_0")
    assert lg.place_height_m("fixture_0") == 0.04 + 0.03  # on top of the base
    lg.assign(top_task.task_id, "arm_1", 9.0)
    lg.at_station(1, "fixture_0", 14.0)
    ship = only(lg.refresh(14.0))
    assert (ship.part_id, ship.source, ship.target) == (0, "fixture_0", "output_tray")
    lg.assign(ship.task_id, "arm_2", 14.0)
    lg.arm_report("arm_2", ship.task_id, "lift", 15.0)
    lg.at_station(0, "output_tray", 19.0)
    lg.at_station(1, "output_tray", 19.0)  # the top rode along
    totals = lg.totals()
    assert totals["parts_completed"] == 2 and totals["parts_in_progress"] == 0
    assert lg.stacks["fixture_0"] == []


def test_a_failed_grasp_is_retried_then_given_up_with_the_reason():
    lg = ledger()
    lg.arrived(0, "bases", 0, 1.0)
    for attempt in range(MAX_ATTEMPTS):
        task = only(lg.refresh(2.0 + attempt))
        lg.assign(task.task_id, "arm_0", 2.0 + attempt)
        lg.arm_report("arm_0", task.task_id, "failed", 2.5 + attempt, "the claw closed on nothing")
        assert task.state == TaskState.FAILED
    assert lg.refresh(10.0) == []
    assert lg.unfinished() == [
        {
            "part_id": 0,
            "fate": "failed",
            "location": "conveyor",
            "reason": f"{MAX_ATTEMPTS} attempts failed; last: the claw closed on nothing",
        }
    ]


def test_a_lost_arms_task_goes_back_to_the_pool_unless_the_part_is_in_its_claw():
    lg = Ledger(load_scene("sorting_line"))
    lg.arrived(0, "mixed", 0, 1.0)
    lg.arrived(1, "mixed", 1, 1.5)
    first, second = lg.refresh(2.0)
    assert (first.target, second.target) == ("bin_0", "bin_1")  # by colour
    lg.assign(first.task_id, "arm_0", 2.0)
    lg.arm_report("arm_0", first.task_id, "approach", 2.1)
    assert lg.arm_lost("arm_0", 3.0) == [first.task_id]
    again = [t for t in lg.refresh(3.0) if t.part_id == 0]
    assert len(again) == 1 and again[0].task_id != first.task_id  # a new task for the same part
    lg.assign(second.task_id, "arm_1", 3.0)
    lg.arm_report("arm_1", second.task_id, "transfer", 4.0)
    lg.arm_lost("arm_1", 5.0)
    assert lg.parts[1].fate.value == "failed" and "lost arm arm_1" in lg.parts[1].reason


def test_a_part_that_falls_is_missed_and_every_part_is_accounted_for():
    lg = ledger()
    for pid in range(3):
        lg.arrived(pid, "bases", 0, float(pid))
    lg.lost(1, "fell to the floor", 5.0)
    t = lg.totals()
    assert t["parts_spawned"] == 3 and t["parts_missed"] == 1 and t["parts_in_progress"] == 2
    assert t["parts_completed"] + t["parts_missed"] + t["parts_failed"] + t["parts_in_progress"] == t["parts_spawned"]


def test_one_station_serves_one_task_at_a_time():
    lg = ledger()
    lg.arrived(0, "bases", 0, 1.0)
    task = only(lg.refresh(1.0))
    assert lg.busy_stations() == set()
    lg.assign(task.task_id, "arm_0", 1.0)
    assert lg.busy_stations() == {"fixture_0"}


def test_a_grasp_that_closed_on_nothing_gives_the_part_a_new_task_from_where_it_lay():
    lg = ledger()
    lg.arrived(0, "bases", 0, 1.0)
    task = only(lg.refresh(1.0))
    lg.assign(task.task_id, "arm_0", 1.0)
    lg.arm_report("arm_0", task.task_id, "lift", 3.0)  # the skill lifts: the ledger takes the part as in the claw
    lg.arm_report("arm_0", task.task_id, "failed", 3.5, "grasp of part 0 missed: the claw closed on nothing")
    again = only(lg.refresh(4.0))
    assert again.task_id != task.task_id and (again.source, again.target) == ("conveyor", "fixture_0")
    assert lg.parts[0].attempts == 1


def test_a_ship_that_left_the_assembly_behind_is_tried_again_with_the_stack_as_it_was():
    lg = ledger()
    lg.arrived(0, "bases", 0, 1.0)
    lg.arrived(1, "tops", 0, 1.5)
    lg.at_station(1, "tops_bin", 2.0)
    lg.at_station(0, "fixture_0", 5.0)
    lg.at_station(1, "fixture_0", 9.0)
    ship = only(lg.refresh(9.0))
    lg.assign(ship.task_id, "arm_2", 9.0)
    lg.arm_report("arm_2", ship.task_id, "transfer", 10.0)
    assert lg.stacks["fixture_0"] == []
    lg.arm_report("arm_2", ship.task_id, "done", 12.0)
    lg.arm_report("arm_2", ship.task_id, "done", 15.5)  # never seen resting at the tray: it never left the fixture
    assert ship.state == TaskState.FAILED and lg.stacks["fixture_0"] == [0, 1]
    again = only(lg.refresh(16.0))
    assert (again.part_id, again.source, again.target) == (0, "fixture_0", "output_tray")


def test_an_arm_whose_skill_cannot_reach_a_part_as_it_lies_is_not_given_it_again():
    """mixed_fleet's SO-101 refused a green part three times in a row (a 5-joint arm cannot turn its claw to every
    part's yaw) and the part failed while the Panda downstream could have taken it: the refusal is remembered for
    that part, so the next task for it goes to another arm. A grasp that closed on nothing is no such refusal."""
    scene = load_scene("mixed_fleet")
    lg = Ledger(scene)
    lg.arrived(0, "mixed", 1, 1.0)
    task = only(lg.refresh(1.0))
    lg.assign(task.task_id, "arm_1", 2.0)
    lg.arm_report(
        "arm_1", task.task_id, "failed", 2.1, f"part 0 {UNREACHABLE} at [0.523, -0.017, 0.135]", FailureCode.UNREACHABLE
    )
    again = only(lg.refresh(2.2))
    assert again.task_id != task.task_id and again.refused_by == ("arm_1",)
    views = {v.name: v for v in arm_views(scene)}
    rules = Eligibility(scene, list(views.values()))
    x, y, z = scene.conveyor.point_at(1.1)  # where arm_1 reaches it
    part = PartView(np.array([x, y, z + 0.015]), np.array(scene.conveyor.direction) * scene.conveyor.speed_m_per_s)
    assert rules.can_serve(views["arm_1"], task, part) and not rules.can_serve(views["arm_1"], again, part)
    lg.assign(again.task_id, "arm_2", 3.0)
    lg.arm_report(
        "arm_2",
        again.task_id,
        "failed",
        3.1,
        "grasp of part 0 missed: the claw closed on nothing",
        FailureCode.GRASP_MISSED,
    )
    assert only(lg.refresh(3.2)).refused_by == ("arm_1",)


def test_a_denied_approach_is_no_attempt_and_holds_the_arm_off_the_part_while_it_gives_way():
    """After an e-stop two arms planned again at once, each standing in the other's way: the guard denied one's
    approach three times in 0.3 s and the part was given up. A denied approach touched nothing: no attempt is
    spent, and the arm is not given the part again for `DENIAL_HOLD_S` (meanwhile it goes home, out of the way)."""
    lg = ledger()
    lg.arrived(0, "bases", 0, 1.0)
    now = 2.0
    for denial in range(MAX_DENIALS):
        task = only(lg.refresh(now))
        assert task.refused_by == ()
        lg.assign(task.task_id, "arm_0", now)
        reason = "motion denied: the approach would pass within the margin of arm_1"
        lg.arm_report("arm_0", task.task_id, "failed", now + 0.1, reason, FailureCode.MOTION_DENIED)
        assert lg.parts[0].attempts == 0
        if denial == MAX_DENIALS - 1:
            break
        held = only(lg.refresh(now + 0.2))
        assert held.refused_by == ("arm_0",), "another arm may take it meanwhile"
        assert only(lg.refresh(now + 0.1 + DENIAL_HOLD_S - 0.05)) is held and held.refused_by == ("arm_0",)
        now += 0.1 + DENIAL_HOLD_S
    assert lg.refresh(now + 10.0) == []
    assert lg.unfinished()[0]["reason"].startswith(f"{MAX_DENIALS} approaches denied; last: motion denied")


def one_buffer_line():
    """The main job's line with arm_1's buffer only."""
    scene = load_scene("assembly_line")
    return scene.model_copy(update={"stations": [s for s in scene.stations if s.name != "infeed_buffer"]})


def test_a_base_about_to_ride_off_while_the_fixture_is_taken_is_set_down_at_the_buffer_and_goes_on_from_there():
    lg = Ledger(one_buffer_line())  # pipelined, as `fleet run`
    lg.arrived(0, "bases", 0, 1.0)
    first = only(lg.refresh(1.0))
    lg.assign(first.task_id, "arm_0", 1.0)
    lg.arm_report("arm_0", first.task_id, "lift", 4.0)  # held at the fixture's edge, say
    lg.arrived(1, "bases", 0, 5.0)
    assert lg.refresh(5.0, soon_lost=lambda part, buffer: False) == [], (
        "the fixture's base is on its way: the next waits"
    )
    buffered = only(lg.refresh(6.0, soon_lost=lambda part, buffer: part.part_id == 1))
    assert (buffered.part_id, buffered.source, buffered.target) == (1, "conveyor", "base_buffer")
    assert buffered.stations == ("base_buffer",) and buffered.alternatives == ()
    lg.assign(buffered.task_id, "arm_1", 6.0)
    lg.arrived(2, "bases", 0, 7.0)
    assert lg.refresh(8.0, soon_lost=lambda part, buffer: True) == [], "one part at a time on a buffer"
    lg.at_station(1, "base_buffer", 11.0)
    assert buffered.state == TaskState.DONE and lg.parts[1].location == "base_buffer" and lg.parts[1].hop == 0
    assert lg.totals()["parts_buffered"] == 1
    lg.at_station(0, "fixture_0", 12.0)
    lg.arrived(3, "tops", 0, 12.0)
    lg.at_station(3, "tops_bin", 12.5)
    top = only(lg.refresh(13.0))
    lg.assign(top.task_id, "arm_1", 13.0)
    lg.at_station(3, "fixture_0", 18.0)
    ship = only(lg.refresh(18.0))
    lg.assign(ship.task_id, "arm_2", 18.0)
    belt_first = only(lg.refresh(18.5))  # the assembly whole and its ship given out: a base may come
    assert (belt_first.part_id, belt_first.target) == (2, "fixture_0"), "the belt's base first: it cannot wait"
    lg.lost(2, "fell to the floor", 19.0)
    onward = only(lg.refresh(19.0))
    assert (onward.part_id, onward.source, onward.target) == (1, "base_buffer", "fixture_0")


def assembly_sent_for(near) -> Ledger:
    """The main job's line with an assembly on its fixture and an arm sent to ship it (the next base may come, but
    may not go in yet)."""
    lg = Ledger(load_scene("assembly_line"))
    lg.arrived(0, "bases", 0, 1.0)
    lg.assign(only(lg.refresh(1.0, near=near)).task_id, "arm_0", 1.0)
    lg.at_station(0, "fixture_0", 3.0)
    lg.arrived(9, "tops", 0, 3.0)
    lg.at_station(9, "tops_bin", 3.5)
    lg.assign(only(lg.refresh(4.0, near=near)).task_id, "arm_1", 4.0)
    lg.at_station(9, "fixture_0", 5.0)
    lg.assign(only(lg.refresh(5.0, near=near)).task_id, "arm_2", 5.0)  # the ship: the assembly is still there
    return lg


def test_a_base_for_a_taken_fixture_goes_to_a_buffer_near_it_while_more_bases_ride_behind_it():
    near = {"fixture_0": ("base_buffer",)}.get
    lg = assembly_sent_for(near)
    lg.arrived(1, "bases", 0, 6.0)
    held = only(lg.refresh(6.0, near=near))
    assert held.target == "fixture_0", "alone on the belt: picked and held at the fixture's edge, as before"
    lg.arrived(2, "bases", 0, 7.0)
    assert only(lg.refresh(7.0, near=lambda station: ())) is held and held.target == "fixture_0", "no buffer near"
    buffered, behind = lg.refresh(7.0, near=near)
    assert buffered is held and (held.target, held.stations) == ("base_buffer", ("base_buffer",)), "one rides behind"
    assert (behind.part_id, behind.target) == (2, "fixture_0"), "the base behind it is next at the fixture"
    lg.assign(held.task_id, "arm_1", 7.5)
    assert held.target == "base_buffer" and lg.parts[1].route == ["fixture_0", "output_tray"], "a detour"
    lg.lost(2, "fell to the floor", 8.0)
    assert lg.refresh(8.0, near=near) == [] and held.target == "base_buffer", "an arm that took it keeps it"


def test_a_buffered_base_keeps_its_buffer_when_the_fixture_frees_while_another_rides_behind_it():
    near = {"fixture_0": ("base_buffer", "infeed_buffer")}.get
    lg = assembly_sent_for(near)
    for part, at in ((1, 6.0), (2, 7.0), (3, 7.5)):
        lg.arrived(part, "bases", 0, at)
        lg.refresh(at, near=near)
    assert [(t.part_id, t.target) for t in lg.refresh(7.6, near=near)] == [
        (1, "base_buffer"),
        (2, "infeed_buffer"),
        (3, "fixture_0"),
    ]
    lg.lost(3, "fell to the floor", 7.9)  # the fixture's next slot is free again; base 2 still rides behind base 1
    for now in (8.0, 8.1):
        assert [(t.part_id, t.target) for t in lg.refresh(now, near=near)] == [
            (1, "base_buffer"),
            (2, "fixture_0"),
        ], "its own buffer is free to it: no going back and forth between refreshes"


def test_a_buffer_task_offers_only_buffers_still_free():
    lg = Ledger(load_scene("assembly_line"))  # two buffers: base_buffer (arm_1's), infeed_buffer (arm_0's)
    lg.arrived(0, "bases", 0, 1.0)
    lg.assign(only(lg.refresh(1.0)).task_id, "arm_0", 1.0)
    lg.arrived(1, "bases", 0, 2.0)
    lg.arrived(2, "bases", 0, 2.5)
    first, second = lg.refresh(3.0, soon_lost=lambda part, buffer: True)
    assert (first.target, first.alternatives) == ("base_buffer", ("infeed_buffer",))
    assert (second.target, second.alternatives) == ("infeed_buffer", ()), "one part on its way to a buffer at a time"
    lg.assign(first.task_id, "arm_0", 3.0, "infeed_buffer")  # the allocator chose the alternative
    assert lg.parts[1].route == ["fixture_0", "output_tray"], "a buffer is a detour, not a stage of the route"
    assert only(lg.refresh(3.1, soon_lost=lambda part, buffer: True)) is second
    assert (second.target, second.alternatives) == ("base_buffer", ()), "its buffer was taken: the other one"
    lg.arrived(3, "bases", 0, 3.3)
    lg.assign(second.task_id, "arm_1", 3.4)
    assert lg.refresh(3.5, soon_lost=lambda part, buffer: True) == [], "both buffers taken: nowhere to set part 3 down"


def test_a_buffer_task_no_arm_took_yet_goes_straight_to_the_station_once_it_is_ready():
    lg = Ledger(load_scene("assembly_line"))
    lg.arrived(0, "bases", 0, 1.0)
    first = only(lg.refresh(1.0))
    lg.assign(first.task_id, "arm_0", 1.0)
    lg.arrived(1, "bases", 0, 2.0)
    buffered = only(lg.refresh(3.0, soon_lost=lambda part, buffer: True))
    assert buffered.target == "base_buffer"
    lg.lost(0, "fell to the floor", 4.0)  # the fixture's base is gone: the fixture is free again
    assert only(lg.refresh(4.5)) is buffered and (buffered.target, buffered.stations) == ("fixture_0", ("fixture_0",))


@pytest.mark.parametrize(
    "change, field, says",
    [
        (lambda d: d["stations"][3].update(kind="fixture"), "stations.3", "a buffer is a plain tray or bin"),
        (lambda d: d["stations"][3].update(accepts_colour="#3070d0"), "stations.3", "a buffer is a plain tray or bin"),
        (lambda d: d["feeders"][0]["route"].insert(1, "base_buffer"), "feeders.0.route.1", "is a buffer"),
        (lambda d: d["feeders"][1].update(into="base_buffer"), "feeders.1.into", "is a buffer"),
    ],
    ids=["fixture", "colour", "on a route", "fed"],
)
def test_a_buffer_is_a_plain_surface_off_every_route(tmp_path, change, field, says):
    data = yaml.safe_load((BUNDLED_DIR / "assembly_line.yaml").read_text())
    assert data["stations"][3]["name"] == "base_buffer"
    change(data)
    path = tmp_path / "line.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(SceneError) as raised:
        load_scene(path)
    assert str(path) in str(raised.value) and field in str(raised.value) and says in str(raised.value)
