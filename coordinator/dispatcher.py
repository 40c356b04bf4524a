"""Every decision of the line's coordinator, in one pure class: no bus, no clock of its own.

Events, arm reports and motion requests go in; at each decision (`decide(tick)`) orders come out,
in the order they must be published: grants and denials of motion requests, cancellations of
belt tasks an arm can no longer meet, and new assignments. The coordinator node decodes, feeds a
`Dispatcher` and publishes what it returns; the PettingZoo env's allocate mode drives the same class
(its tasks, belt deadlines and reassignment), so the two cannot drift apart. Liveness is the
caller's to judge (it owns the clock): it calls `arm_lost` and `arm_rejoined`.
"""

from __future__ import annotations

import math

import numpy as np

from coordinator.allocation import Allocator, ArmView, CachedReach, Eligibility, PartView, TimeCost, make_allocator
from coordinator.cadence import decision_period_ticks
from coordinator.capacity import (
    CapacityBound,
    capacity_bound,
)
from coordinator.deadlines import cannot_make_it, layout_belt_reach, task_deadline_s
from coordinator.dispatch_book import ArmBook, DispatchClock
from coordinator.dispatch_drivers import OutsideDrivers
from coordinator.dispatch_grants import GrantAnswers
from coordinator.dispatch_report import grant_requests_open, measured_capacity, run_capacity, task_rows
from coordinator.dispatch_takeover import TakeOver
from coordinator.dispatch_views import AllocatorViews
from coordinator.geometry import ArmGeometry
from coordinator.guard import CollisionGuard, TimedPath
from coordinator.ledger import PIPELINE_DEFAULT, Ledger
from coordinator.orders import AssignOrder, CancelOrder, Decision, GrantOrder, Order
from coordinator.tasks import CONVEYOR, Task, TaskState
from robots.frames import yaw_transform
from robots.phase import IDLE_PHASES, Phase
from robots.registry import get_robot
from scenes.schema import Scene

# a belt part this close (sim seconds) to riding out of every arm's reach, its next station not ready for it, is set
# down at a buffer if the scene has a free one: about an approach and a grasp before the part is out of reach
BUFFER_LEAD_S = 8.0


class Dispatcher:
    """The coordinator's decisions over one scene: tasks (`Ledger`), allocation, belt deadlines, late-task
    reassignment, the collision guard's grants and the busy-until estimates. What it knows of each arm is its
    `ArmBook`, handed with the ledger and the guard to the components that answer grants (`GrantAnswers`), show the
    arms to the allocator (`AllocatorViews`), let outside drivers take arms (`OutsideDrivers`) and take over a
    running line (`TakeOver`)."""

    def __init__(
        self,
        scene: Scene,
        allocator: Allocator | None = None,
        first_task_id: int = 1,
        pipeline: bool = PIPELINE_DEFAULT,
    ) -> None:
        self.scene = scene
        self.ledger = Ledger(scene, first_task_id, pipeline)
        self.allocator = allocator or make_allocator("optimal", scene)
        self.guard = CollisionGuard(
            {
                a.name: ArmGeometry(a.name, get_robot(a.model), yaw_transform(a.base.xyz, a.base.yaw_rad))
                for a in scene.arms
            }
        )
        self.reach = {a.name: CachedReach.of(a) for a in scene.arms}
        self.period_ticks = decision_period_ticks(scene)
        self.arms = ArmBook([a.name for a in scene.arms])
        self.clock = DispatchClock()
        hz = scene.control_hz
        bases = {a.name: a.base.xyz for a in scene.arms}
        self.views = AllocatorViews(self.arms, self.clock, self.ledger, self.guard, self.reach, bases, hz)
        self.grants = GrantAnswers(self.arms, self.clock, self.ledger, self.guard, hz, self.period_ticks / hz)
        self.drivers = OutsideDrivers(self.arms, self.clock, self.ledger, self.guard)
        self.takeover = TakeOver(self.arms, self.clock, self.ledger, scene)
        self.deadline_known: set[int] = set()  # tasks whose belt deadline was worked out (once each)
        self.parts: dict[int, PartView] = {}
        self.decisions = 0
        self.reassigned = 0
        # candidate id -> (task id, station), of the last `candidates`
        self._candidates: dict[int, tuple[int, str]] = {}
        # where a belt task's deadline falls
        self.belt_reach = layout_belt_reach(self.scene, self.arm_views())
        self._capacity: tuple[str, CapacityBound] | None = None  # (the scene it was worked out of, the bound)

    @property
    def arm_names(self) -> list[str]:
        """The arms, in scene order."""
        return self.arms.names

    @property
    def lost(self) -> dict[str, float]:
        """The arms out of the allocation (lost, or taken by an outside driver), and since when (sim s)."""
        return self.arms.lost

    @property
    def losses(self) -> list[dict]:
        """Arms lost, rejoined, taken and let go: the summary's `arm_events`."""
        return self.arms.losses

    @property
    def sim_time_s(self) -> float:
        return self.clock.sim_time_s

    @property
    def capacity(self) -> CapacityBound:
        """What the line could do at best (worked out when first asked: an env resets often)."""
        if self._capacity is None:
            self._capacity = (self.scene.model_dump_json(), capacity_bound(self.scene, reach=self.reach))
        return self._capacity[1]

    def scene_changed(self) -> None:
        """After a restore into a scene with a field set otherwise (`fleet run --from SNAPSHOT --set`): what was
        worked out from the old one is worked out again when next asked."""
        if self._capacity is not None and self._capacity[0] != self.scene.model_dump_json():
            self._capacity = None

    # --- inputs ---------------------------------------------------------------------
    def on_event(self, kind: str, part_id: int, detail: str, type_index: int, time_s: float) -> None:
        """A line event (`arrived`, `at_station`, `lost`, `retired`) at sim time `time_s`."""
        self.ledger.on_event(kind, part_id, detail, type_index, time_s)
        self.clock.last_event_s = max(self.clock.last_event_s, time_s)

    def on_arm(
        self,
        arm: str,
        q: np.ndarray,
        phase: str,
        time_s: float,
        *,
        task_id: int | None = None,
        failure: str = "",
        failure_code: str = "",
        request_seq: int = 0,
        request: TimedPath | None = None,
        acts_at_tick: int = 0,
        lost: bool = False,
        silent_for_s: float = 0.0,
        gripper_q: np.ndarray | None = None,
    ) -> list[int] | None:
        """An arm's state: its joints, its skill's phase and task, and the motion request it holds still for
        (`request_seq` > 0; a request is new when its number differs from the last taken: a restarted
        controller counts from 1 again). `acts_at_tick`: when an order sent now would take effect on it.
        `lost`: the sim stopped hearing its controller; returns the tasks put back if that makes the arm lost.
        `gripper_q`: its claw's joints, so the cell's separations measure the claw as it is."""
        arms = self.arms
        arms.acts_at_tick[arm] = acts_at_tick
        arms.phase[arm] = phase
        if request_seq > 0 or phase in IDLE_PHASES:  # holding still for a grant, or not working: no move of old
            arms.unsettled.discard(arm)
        self.guard.set_state(arm, np.asarray(q), gripper_q)
        if request is not None and request_seq > 0 and request_seq != arms.request_seq[arm]:
            arms.request_seq[arm] = request_seq
            arms.requests[arm] = request
        returned = None
        if lost and arm not in arms.lost:
            returned = self.arm_lost(arm, "the sim stopped hearing its controller", silent_for_s)
        self.ledger.arm_report(arm, task_id, phase, time_s, failure, failure_code)
        return returned

    def on_parts(self, parts: dict[int, PartView], time_s: float) -> None:
        """The parts on the line (positions and velocities, world frame) at sim time `time_s`."""
        self.parts = parts
        self.clock.sim_time_s = time_s

    def arm_lost(self, arm: str, why: str, silent_for_s: float) -> list[int]:
        """An arm stopped answering: its granted path is void (it holds still), its tasks go back to the pool."""
        arms, now_s = self.arms, self.clock.sim_time_s
        arms.lost[arm] = now_s
        arms.unsettled.discard(arm)  # a lost arm holds still
        arms.requests.pop(arm, None)
        self.guard.release(arm)
        returned = self.ledger.arm_lost(arm, now_s)
        arms.losses.append(
            {
                "arm": arm,
                "event": "lost",
                "why": why,
                "sim_time_s": round(now_s, 3),
                "silent_for_s": round(silent_for_s, 3),
                "tasks_returned": returned,
            }
        )
        return returned

    def arm_rejoined(self, arm: str) -> None:
        """A lost arm's controller is heard again (an arm an outside client drives stays out until let go)."""
        if arm not in self.arms.taken and self.arms.lost.pop(arm, None) is not None:
            self.arms.losses.append({"arm": arm, "event": "rejoined", "sim_time_s": round(self.clock.sim_time_s, 3)})

    # --- outside drivers, taking over a running line ----------------------------------------
    def arm_taken(self, arm: str) -> None:
        """An outside client took `arm`: nothing is given to it until `arm_let_go` (`OutsideDrivers`)."""
        self.drivers.arm_taken(arm)

    def arm_let_go(self, arm: str) -> None:
        """The outside client let go of `arm`: the allocator may give it tasks again."""
        self.drivers.arm_let_go(arm)

    def take_over(self, time_s: float) -> None:
        """This dispatcher replaces one that crashed (`TakeOver.take_over`)."""
        self.takeover.take_over(time_s)

    def adopt(self, arm: str, task_id: int, part_id: int, place_xyz: tuple[float, ...], time_s: float) -> str:
        """The task `arm` says it works on joins the ledger as that arm's (`TakeOver.adopt`); why not, or ""."""
        return self.takeover.adopt(arm, task_id, part_id, place_xyz, time_s)

    # --- what the allocator sees ----------------------------------------------------
    def arm_views(self) -> list[ArmView]:
        return self.views.arm_views()

    def busy_stations(self, for_arm: str | None = None) -> set[str]:
        """Stations in use, as `for_arm` sees them (`AllocatorViews.busy_stations`)."""
        return self.views.busy_stations(for_arm)

    def busy_for_all(self, arms: list[str]) -> set[str]:
        """The stations busy for every one of `arms` (`AllocatorViews.busy_for_all`)."""
        return self.views.busy_for_all(arms)

    def free_in_s(self, arm: str, now_s: float | None = None) -> float | None:
        """About when a busy arm's task ends (`AllocatorViews.free_in_s`)."""
        return self.views.free_in_s(arm, now_s)

    # --- decisions ------------------------------------------------------------------
    def decide(self, tick: int) -> Decision:
        """One decision at `tick`: answer motion requests, take late belt tasks back, refresh and allocate tasks."""
        now = tick / self.scene.control_hz
        self.clock.last_decision_tick = tick
        self.decisions += 1
        separations = self.grants.watch_separations() if len(self.arm_names) > 1 else []
        answers = self.grants.answer_motion_requests(now)
        orders: list[Order] = [*self.drivers.take_cancels(), *answers, *self.reassign_late_tasks()]
        pending = self.pending(now)
        if pending:
            views = self.arm_views()
            cost_s = TimeCost(Eligibility(self.scene, views))
            taken: set[int] = set()
            candidates = {t.task_id: t for t in self.candidates(pending)}
            busy = self.busy_for_all([v.name for v in views if v.free])
            for candidate_id, arm in self.allocator.allocate(list(candidates.values()), views, self.parts, busy):
                if self.real(candidate_id).task_id in taken:
                    # two arms chose one task, each for another station: the first keeps it, the other waits a round
                    continue
                if self.busy_stations(arm).intersection(candidates[candidate_id].stations):
                    continue  # a station another arm is still moving away from: free to that arm only
                order = self.start(candidate_id, next(v for v in views if v.name == arm), now, cost_s)
                taken.add(order.task_id)
                orders.append(order)
        return Decision(tick, orders, separations)

    def candidates(self, pending: list[Task]) -> list[Task]:
        """The pending tasks as the allocators see them: a task that may go to one of several stations (a sorted
        part: any bin of its colour) once per station, each copy with an id of its own (negative), so that each
        arm is weighed with the station it reaches. `take` turns the chosen one back into the task."""
        out: list[Task] = []
        for task in pending:
            out.append(task)
            for k, station in enumerate(task.alternatives, start=1):
                copy = Task(
                    -(task.task_id * 64 + k),
                    task.part_id,
                    task.source,
                    station,
                    task.created_s,
                    deadline_s=task.deadline_s,
                    refused_by=task.refused_by,
                )
                self._candidates[copy.task_id] = (task.task_id, station)
                out.append(copy)
        return out

    def real(self, candidate_id: int) -> Task:
        """The ledger's task behind a candidate id."""
        return self.ledger.tasks[self._candidates.get(candidate_id, (candidate_id, ""))[0]]

    def take(self, candidate_id: int, arm: str, now_s: float) -> Task:
        """Assign the task behind a candidate to `arm`, going to the candidate's station."""
        task_id, station = self._candidates.get(candidate_id, (candidate_id, None))
        return self.ledger.assign(task_id, arm, now_s, station)

    def start(self, candidate_id: int, arm: ArmView, now_s: float, cost_s: TimeCost) -> AssignOrder:
        """Give the task behind a candidate to `arm`: take it, note when the arm should be free again (the estimate
        the optimal allocator plans a soon-free arm with) and return the order that starts it. Every front end
        starts tasks here (the coordinator node's decisions, the env's allocate mode)."""
        task = self.take(candidate_id, arm.name, now_s)
        self.arms.busy_until_s[arm.name] = now_s + cost_s(arm, task, self.parts[task.part_id])
        return self.assignment(task, arm.name)

    def pending(self, now_s: float) -> list[Task]:
        """The tasks waiting for an arm, each belt task with its deadline (worked out once, when first seen)."""
        belt, reach, parts = self.scene.conveyor, self.belt_reach, self.parts
        pending = self.ledger.refresh(now_s, reach.riding_off(belt, parts, BUFFER_LEAD_S), reach.buffers_near)
        for task in pending:
            if task.source == CONVEYOR and task.task_id not in self.deadline_known and task.part_id in self.parts:
                self.deadline_known.add(task.task_id)
                task.deadline_s = task_deadline_s(belt, reach, task, self.parts[task.part_id], now_s)
        return pending

    def reassign_late_tasks(self) -> list[CancelOrder]:
        """A belt task whose arm has not started moving for it, and can no longer meet the part, goes back to the
        pool (its arm is told to drop it), so an arm further down the belt can still take it before its deadline."""
        views = {v.name: v for v in self.arm_views()}
        rules = Eligibility(self.scene, list(views.values()))
        out = []
        for task in list(self.ledger.tasks.values()):
            arm = task.arm
            not_started = task.state == TaskState.ASSIGNED or (
                task.state == TaskState.ACTIVE
                and self.arms.phase.get(arm) == Phase.APPROACH
                and arm in self.arms.requests
            )
            part = self.parts.get(task.part_id)
            if arm is None or part is None or not not_started or not cannot_make_it(rules, views[arm], task, part):
                continue
            self.ledger.requeue(task.task_id, f"{arm} could no longer meet the part")
            self.arms.requests.pop(arm, None)
            self.reassigned += 1
            out.append(CancelOrder(arm, task.part_id))
        return out

    def assignment(self, task: Task, arm: str) -> AssignOrder:
        """The order that gives `task` to `arm` (and reserves its stations until the arm is idle again)."""
        part, rec = self.parts[task.part_id], self.ledger.parts[task.part_id]
        station = self.scene.station(task.target)
        velocity = self.belt_velocity() if task.source == CONVEYOR else (0.0, 0.0, 0.0)
        place = (station.pose.xyz[0], station.pose.xyz[1], self.ledger.place_height_m(task.target, task.part_id))
        self.arms.last_stations[arm], self.arms.last_task[arm] = task.stations, task.task_id
        return AssignOrder(arm, task.task_id, task.part_id, float(part.position[2] - rec.height_m / 2), place, velocity)

    def belt_velocity(self) -> tuple[float, float, float]:
        c = self.scene.conveyor
        return tuple(d * c.speed_m_per_s for d in c.direction) if c else (0.0, 0.0, 0.0)

    # --- grants -----------------------------------------------------------------------
    def answer(self, tick: int) -> list[GrantOrder]:
        """Only the motion requests, at `tick`: for a front end whose tasks are chosen elsewhere (the env's allocate
        mode, where the policy allocates)."""
        self.clock.last_decision_tick = tick
        return self.grants.answer_motion_requests(tick / self.scene.control_hz)

    # --- the summary ----------------------------------------------------------------
    def report(self) -> dict:
        """The run summary's coordinator part: parts and their fates, grants, the line's bound and the run's own."""
        grants, arms, end_s = self.grants, self.arms, max(self.clock.sim_time_s, self.clock.last_event_s)
        return self.ledger.totals() | {
            "allocator": self.allocator.name,
            "allocator_faults": dict(getattr(self.allocator, "faults", {})),  # a plug-in's (`GuardedAllocator`)
            "pipeline": self.ledger.pipeline,
            "arm_events": arms.losses,
            "unfinished_parts": self.ledger.unfinished(),
            "tasks": task_rows(self.ledger),
            "decisions": self.decisions,
            "grants_denied": self.guard.denied,
            "grants_given": grants.grants_given,
            "tasks_reassigned": self.reassigned,
            "tasks_adopted": self.takeover.adopted,
            "grant_waits": self.guard.waits,
            "grant_requests_open": grant_requests_open(arms, self.guard, grants.held_now, self.clock.sim_time_s),
            "held_at_station_s": {a: round(s, 2) for a, s in grants.held_at_station_s.items()},
            "min_separation_m": round(grants.min_separation_m, 4) if math.isfinite(grants.min_separation_m) else None,
            "closest_pair": list(grants.closest_pair) if grants.closest_pair else None,
            "capacity": self.capacity.as_dict(),
            "capacity_measured": measured_capacity(self.scene, self.ledger, self.reach, self.capacity),
            "capacity_of_run": run_capacity(self.scene, self.ledger, self.reach, self.capacity, end_s),
        }
