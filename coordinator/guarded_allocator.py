"""A plug-in allocator behind a guard: it gets copies of what it is given, its answer is checked against the rules
every allocator obeys, and a call that raises, answers wrongly or takes longer than its budget costs only that
decision: greedy decides instead. Each kind of fault is said once (standard error) and every one is counted
(`faults`, the run's summary `allocator_faults`).

Timing a call is the one thing that makes a lockstep run depend on the machine: a plug-in close to its budget
may fall back on one run and not on another. The budget is the plug-in's own time: a reach answer clawfleet
searches for it the first time a spot is asked (Pinocchio IK, up to ~90 ms where a leaning arm cannot reach it;
cached for the line after) is not charged to it. The built-ins are not guarded.
"""

from __future__ import annotations

import sys
import time
from collections import Counter
from collections.abc import Callable

from coordinator.allocation import Allocator, ArmView, Eligibility, GreedyNearest, PartView, open_candidates
from coordinator.tasks import Task
from scenes.schema import Scene

DEFAULT_BUDGET_S = 0.05  # a decision's allowance: the built-ins take <= 5 ms for 12 arms and 50 pending hops


def say_once(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


class GuardedAllocator:
    """Runs `inner`; on a fault, greedy's decision for that call."""

    def __init__(
        self, inner: Allocator, scene: Scene, budget_s: float = DEFAULT_BUDGET_S, say: Callable[[str], None] = say_once
    ) -> None:
        self.inner, self.scene, self.budget_s, self.say = inner, scene, budget_s, say
        self.name = str(getattr(inner, "name", type(inner).__name__))
        self.fallback = GreedyNearest(scene)
        self.faults: Counter[str] = Counter()
        self.decisions = 0
        if getattr(inner, "frames_hz", None) is not None:  # it looks at the cameras (`see`)
            self.frames_hz = float(inner.frames_hz)

    def see(self, frames: list) -> None:
        """Hand the plug-in the cameras' frames; a fault in looking costs that look only (counted)."""
        try:
            self.inner.see(list(frames))
        except Exception as exc:  # a plug-in's own fault: it decides on what it saw before
            if not self.faults["see_raised"]:
                self.say(f"allocator {self.name}: see raised {exc.__class__.__name__}: {str(exc)[:200]} (said once)")
            self.faults["see_raised"] += 1

    def allocate(
        self, tasks: list[Task], arms: list[ArmView], parts: dict[int, PartView], busy_stations: set[str]
    ) -> list[tuple[int, str]]:
        self.decisions += 1
        searched, started = reach_search_s(arms), time.perf_counter()
        try:
            answer = self.inner.allocate(list(tasks), list(arms), dict(parts), set(busy_stations))
        except Exception as exc:  # a plug-in's own fault, whatever it is: the line goes on without this decision
            return self._fall_back("raised", f"{exc.__class__.__name__}: {exc}", tasks, arms, parts, busy_stations)
        took_s = time.perf_counter() - started - (reach_search_s(arms) - searched)
        problem = assignment_problem(answer, tasks, arms, parts, busy_stations, self.scene)
        if problem:
            return self._fall_back("invalid", problem, tasks, arms, parts, busy_stations)
        if took_s > self.budget_s:
            why = f"took {took_s * 1e3:.0f} ms (budget {self.budget_s * 1e3:.0f} ms)"
            return self._fall_back("overran", why, tasks, arms, parts, busy_stations)
        return [(int(t), str(a)) for t, a in answer]

    def _fall_back(
        self, kind: str, why: str, tasks: list[Task], arms: list[ArmView], parts: dict[int, PartView], busy: set[str]
    ) -> list[tuple[int, str]]:
        if not self.faults[kind]:
            self.say(
                f"allocator {self.name}: {kind}: {why[:200]}; greedy decides instead (said once; every one counted)"
            )
        self.faults[kind] += 1
        return self.fallback.allocate(tasks, arms, parts, busy)


def reach_search_s(arms: list[ArmView]) -> float:
    """The time the arms' reach caches have spent searching new spots so far (each arm's cache counted once)."""
    return sum({id(a.reach): a.reach.search_s for a in arms}.values())


def assignment_problem(
    answer: object,
    tasks: list[Task],
    arms: list[ArmView],
    parts: dict[int, PartView],
    busy_stations: set[str],
    scene: Scene,
) -> str:
    """What is wrong with an allocator's answer ('' if nothing): it must be (task id, arm) pairs, each task one of
    those open now (seen part, free stations) and given once, each arm free, alive and given once, no station given
    twice, and each arm able to serve its task (reach, belt stretches: `Eligibility`)."""
    if not isinstance(answer, (list, tuple)):
        return f"returned {type(answer).__name__}, not a list of (task id, arm) pairs"
    open_tasks = {t.task_id: t for t in open_candidates(tasks, parts, busy_stations)}
    by_name = {a.name: a for a in arms}
    rules = Eligibility(scene, arms)
    seen_tasks, seen_arms, stations = set(), set(), set()
    for pair in answer:
        if not (isinstance(pair, (list, tuple)) and len(pair) == 2 and isinstance(pair[1], str)):
            return f"{pair!r} is not a (task id, arm) pair"
        task_id, arm_name = pair
        task, arm = open_tasks.get(task_id) if isinstance(task_id, int) else None, by_name.get(arm_name)
        if task is None:
            return f"task {task_id!r} is not one of the open tasks it was given"
        if arm is None or not arm.free or not arm.live:
            return f"arm {arm_name!r} is not a free arm of this line"
        if task_id in seen_tasks or arm_name in seen_arms or stations.intersection(task.stations):
            return f"({task_id}, {arm_name}): a task, arm or station given twice"
        if not rules.can_serve(arm, task, parts[task.part_id]):
            return f"({task_id}, {arm_name}): the arm cannot serve that task (reach or belt stretch)"
        seen_tasks.add(task_id)
        seen_arms.add(arm_name)
        stations.update(task.stations)
    return ""
