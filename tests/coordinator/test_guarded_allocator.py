"""A plug-in allocator runs behind a guard: whatever it does wrong (raise, answer with arms or tasks it was not
given, take too long) costs that decision only: greedy decides instead, the fault is said once and counted."""

import numpy as np
import pytest

from coordinator.allocation import ArmView, CachedReach, GreedyNearest, PartView
from coordinator.allocator_plugins import AllocatorError, allocator_factory, known_allocators, make_any_allocator
from coordinator.guarded_allocator import GuardedAllocator, assignment_problem, reach_search_s
from coordinator.ledger import Ledger
from robots.frames import yaw_transform
from robots.registry import get_robot
from robots.top_down import TopDownIK
from scenes import load_scene

FAULTY = "tests.coordinator.faulty_allocators"


@pytest.fixture(scope="module")
def decision():
    """A sorting line of 3 arms, arm_2 busy, a part of each colour in front of each arm: one decision's inputs."""
    scene = load_scene("sorting_line", arms=3)
    home = tuple(get_robot("openclaw").home_q)
    reach = {
        a.name: CachedReach(TopDownIK(get_robot(a.model), yaw_transform(a.base.xyz, a.base.yaw_rad)))
        for a in scene.arms
    }
    arms = [ArmView(a.name, a.base.xyz, a.name != "arm_2", reach[a.name], home) for a in scene.arms]
    ledger, parts = Ledger(scene), {}
    for pid in range(3):
        parts[pid] = PartView(np.array([scene.arms[pid].base.xyz[0] - 0.09, 0.0, 0.095]), np.array([0.06, 0.0, 0.0]))
        ledger.arrived(pid, "mixed", pid, 1.0)
    return scene, ledger.refresh(1.0), arms, parts


def test_a_sound_plug_in_decides_and_nothing_is_counted(decision):
    scene, tasks, arms, parts = decision
    guarded = make_any_allocator(f"{FAULTY}:RaisesEveryThird", scene)
    assert isinstance(guarded, GuardedAllocator) and guarded.name == "raises_every_third"
    assert guarded.allocate(tasks, arms, parts, set()) == GreedyNearest(scene).allocate(tasks, arms, parts, set())
    assert not guarded.faults


@pytest.mark.parametrize(
    "plug_in, kind, said",
    [
        ("Raises", "raised", "ZeroDivisionError: division by zero in the plug-in"),
        ("GivesBusyArms", "invalid", "arm 'arm_2' is not a free arm of this line"),
        ("Slow", "overran", "(budget 50 ms)"),
    ],
)
def test_each_fault_costs_one_decision_greedy_takes_said_once_counted_always(decision, plug_in, kind, said):
    scene, tasks, arms, parts = decision
    lines = []
    guarded = GuardedAllocator(allocator_factory(f"{FAULTY}:{plug_in}")(scene), scene, say=lines.append)
    greedy = GreedyNearest(scene).allocate(tasks, arms, parts, set())
    for _ in range(3):
        assert guarded.allocate(tasks, arms, parts, set()) == greedy
    assert guarded.faults == {kind: 3} and len(lines) == 1 and said in lines[0] and "greedy decides" in lines[0]


def test_a_plug_in_is_not_charged_for_the_reach_searches_of_spots_asked_the_first_time():
    """The budget is the plug-in's own time: clawfleet's IK for a spot nobody asked before (cached after) is not."""
    scene = load_scene("mixed_fleet")  # an OpenClaw, an SO-101 (whose searches are the long ones) and a Panda
    arms = [ArmView(a.name, a.base.xyz, True, CachedReach.of(a), tuple(get_robot(a.model).home_q)) for a in scene.arms]
    guarded = make_any_allocator(f"{FAULTY}:SearchesNewSpots", scene)
    for _ in range(2):
        assert guarded.allocate([], arms, {}, set()) == []
    assert reach_search_s(arms) > 2 * guarded.budget_s, "the searches took longer than the budget"
    assert not guarded.faults


def test_answers_that_break_the_rules_every_allocator_obeys_are_named(decision):
    scene, tasks, arms, parts = decision
    first, second = tasks[0].task_id, tasks[1].task_id
    assert assignment_problem("arm_0", tasks, arms, parts, set(), scene).startswith("returned str")
    assert "not one of the open tasks" in assignment_problem([(999, "arm_0")], tasks, arms, parts, set(), scene)
    assert "given twice" in assignment_problem([(first, "arm_0"), (first, "arm_1")], tasks, arms, parts, set(), scene)
    assert "given twice" in assignment_problem([(first, "arm_0"), (second, "arm_0")], tasks, arms, parts, set(), scene)
    far = [t for t in tasks if parts[t.part_id].position[0] > scene.arms[1].base.xyz[0]][0].task_id
    assert "cannot serve" in assignment_problem([(far, "arm_0")], tasks, arms, parts, set(), scene)
    assert assignment_problem([], tasks, arms, parts, set(), scene) == ""


def test_allocators_are_found_by_name_and_a_bad_one_is_one_line():
    assert list(known_allocators())[:3] == ["optimal", "auction", "greedy"]
    with pytest.raises(AllocatorError, match="valid allocators: optimal, auction, greedy"):
        allocator_factory("fastest")
    with pytest.raises(AllocatorError, match="cannot load tests.coordinator.nowhere:X"):
        allocator_factory("tests.coordinator.nowhere:X")
    with pytest.raises(AllocatorError, match="has no allocate"):
        make_any_allocator(f"{FAULTY}:not_an_allocator", load_scene("sorting_line", arms=2))


def test_an_allocator_that_sees_asks_at_a_brains_rate_and_has_eyes_or_is_one_line():
    from coordinator.allocator_plugins import check_allocator, sees

    with pytest.raises(AllocatorError, match="asks for frames at 30.0 Hz: it may look at 1-5 Hz"):
        check_allocator(f"{FAULTY}:SeesTooFast")
    with pytest.raises(AllocatorError, match="has no see"):
        check_allocator(f"{FAULTY}:SeesWithoutEyes")
    assert sees(f"{FAULTY}:RaisesOnSight") and not sees("optimal") and not sees(None) and not sees("nowhere:X")


def test_a_look_that_raises_costs_that_look_only_said_once_counted_always(decision):
    said: list[str] = []
    guarded = GuardedAllocator(allocator_factory(f"{FAULTY}:RaisesOnSight")(decision[0]), decision[0], say=said.append)
    assert guarded.frames_hz == 2.0
    guarded.see([])
    guarded.see([])
    assert guarded.faults["see_raised"] == 2 and len(said) == 1 and "cannot stand the sight" in said[0]
    assert guarded.allocate(*decision[1:], set()), "it decides on, on what it saw before"
