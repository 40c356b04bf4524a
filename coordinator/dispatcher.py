"""Every decision of the line's coordinator, in one pure class: no bus, no clock of its own.

Events, arm reports and motion requests go in; at each decision (`decide(tick)`) orders come out,
in the order they must be published: grants and denials of motion requests, cancellations of
belt tasks an arm can no longer meet, and new assignments. The coordinator node decodes, feeds a
`Dispatcher` and publishes what it returns; the PettingZoo env's allocate mode drives the same class
(its tasks, belt deadlines and reassignment), so the two cannot drift apart. Liveness is the
caller's to judge (it owns the clock): it calls `arm_lost` and `arm_rejoined`.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from coordinator.allocation import Allocator, ArmView, CachedReach, Eligibility, PartView, TimeCost, make_allocator
from coordinator.cadence import decision_period_ticks
from coordinator.capacity import (
    CapacityBound,
    capacity_bound,
)
from coordinator.deadlines import cannot_make_it, layout_belt_reach, task_deadline_s
from coordinator.dispatch_drivers import OutsideDrivers
from coordinator.dispatch_grants import GrantAnswers
from coordinator.dispatch_report import DispatchReport
from coordinator.dispatch_takeover import TakeOver
from coordinator.dispatch_views import AllocatorViews
from coordinator.geometry import ArmGeometry
from coordinator.guard import CollisionGuard, TimedPath
from coordinator.ledger import PIPELINE_DEFAULT, Ledger
from coordinator.orders import AssignOrder, CancelOrder, Decision, Order
from coordinator.tasks import CONVEYOR, Task, TaskState
from robots.frames import yaw_transform
from robots.phase import IDLE_PHASES, Phase
from robots.registry import get_robot
from scenes.schema import Scene

# a belt part this close (sim seconds) to riding out of every arm's reach, its next station not ready for it, is set
# down at a buffer if the scene has a free one: about an approach and a grasp before the part is out of reach
BUFFER_LEAD_S = 8.0


class Dispatcher(AllocatorViews, DispatchReport, GrantAnswers, TakeOver, OutsideDrivers):
    """The coordinator's decisions over one scene: tasks (`Ledger`), allocation, belt deadlines, late-task
    reassignment, the collision guard's grants and the busy-until estimates."""

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
        self.arm_names = [a.name for a in scene.arms]
        self.guard = CollisionGuard(
            {
                a.name: ArmGeometry(a.name, get_robot(a.model), yaw_transform(a.base.xyz, a.base.yaw_rad))
                for a in scene.arms
            }
        )
        self.reach = {a.name: CachedReach.of(a) for a in scene.arms}
        self.bases = {a.name: a.base.xyz for a in scene.arms}
        self.period_ticks = decision_period_ticks(scene)
        self.phase = {a: Phase.IDLE for a in self.arm_names}
        self.acts_at_tick = {a: 0 for a in self.arm_names}  # when an order sent now takes effect on each arm
        self.last_stations: dict[str, tuple[str, ...]] = {a: () for a in self.arm_names}
        self.last_task: dict[str, int] = {}  # each arm's latest task (where it is leaving from, once it is closed)
        self.requests: dict[str, TimedPath] = {}  # motion requests waiting for a decision, by arm (the newest wins)
        self.request_seq: dict[str, int] = {a: 0 for a in self.arm_names}
        self.lost: dict[str, float] = {}
        self.taken: set[str] = set()  # arms an outside client drives (`OutsideDrivers`)
        self.cancels: list[CancelOrder] = []  # orders to drop tasks, out with the next decision
        self.busy_until_s: dict[str, float] = {}  # when each arm's current task should end (the allocator's estimate)
        self.deadline_known: set[int] = set()  # tasks whose belt deadline was worked out (once each)
        self.parts: dict[int, PartView] = {}
        self.sim_time_s = 0.0
        # the latest line event heard (the run's end, at its report, may be later than its parts)
        self.last_event_s = 0.0
        self.last_decision_tick = -(10**9)
        self.decisions = 0
        self.grants_given = 0
        self.reassigned = 0
        self.min_separation_m = math.inf
        self.closest_pair: tuple[str, str] | None = None
        self.losses: list[dict] = []
        self.unsettled: set[str] = set()  # after a take-over: arms that may still move under a grant given before it
        self.settle_by_s = -math.inf
        self.adopted: list[dict] = []
        self.held_at_station_s: dict[str, float] = {}  # pipelining: how long each arm's moves waited for a fixture
        self.held_now: dict[str, str] = {}  # arm -> the fixture its waiting move is held for, at the last decision
        self.told_standby: set[int] = set()  # tasks whose held transfer was told to stand by (once a task)
        # candidate id -> (task id, station), of the last `candidates`
        self._candidates: dict[int, tuple[int, str]] = {}
        # where a belt task's deadline falls
        self.belt_reach = layout_belt_reach(self.scene, self.arm_views())

    @functools.cached_property
    def capacity(self) -> CapacityBound:
        """What the line could do at best (worked out when first asked: an env resets often)."""
        self._capacity_of = self.scene.model_dump_json()
        return capacity_bound(self.scene, reach=self.reach)

    def scene_changed(self) -> None:
        """After a restore into a scene with a field set otherwise (`fleet run --from SNAPSHOT --set`): what was
        worked out from the old one is worked out again when next asked."""
        if "capacity" in vars(self) and getattr(self, "_capacity_of", None) != self.scene.model_dump_json():
            del self.capacity

    # --- inputs ---------------------------------------------------------------------
    def on_event(self, kind: str, part_id: int, detail: str, type_index: int, time_s: float) -> None:
        """A line event (`arrived`, `at_station`, `lost`, `retired`) at sim time `time_s`."""
        self.ledger.on_event(kind, part_id, detail, type_index, time_s)
        self.last_event_s = max(self.last_event_s, time_s)

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
        self.acts_at_tick[arm] = acts_at_tick
        self.phase[arm] = phase
        if request_seq > 0 or phase in IDLE_PHASES:  # holding still for a grant, or not working: no move of old
            self.unsettled.discard(arm)
        self.guard.set_state(arm, np.asarray(q), gripper_q)
        if request is not None and request_seq > 0 and request_seq != self.request_seq[arm]:
            self.request_seq[arm] = request_seq
            self.requests[arm] = request
        returned = None
        if lost and arm not in self.lost:
            returned = self.arm_lost(arm, "the sim stopped hearing its controller", silent_for_s)
        self.ledger.arm_report(arm, task_id, phase, time_s, failure, failure_code)
        return returned

    def on_parts(self, parts: dict[int, PartView], time_s: float) -> None:
        """The parts on the line (positions and velocities, world frame) at sim time `time_s`."""
        self.parts = parts
        self.sim_time_s = time_s

    def arm_lost(self, arm: str, why: str, silent_for_s: float) -> list[int]:
        """An arm stopped answering: its granted path is void (it holds still), its tasks go back to the pool."""
        self.lost[arm] = self.sim_time_s
        self.unsettled.discard(arm)  # a lost arm holds still
        self.requests.pop(arm, None)
        self.guard.release(arm)
        returned = self.ledger.arm_lost(arm, self.sim_time_s)
        self.losses.append(
            {
                "arm": arm,
                "event": "lost",
                "why": why,
                "sim_time_s": round(self.sim_time_s, 3),
                "silent_for_s": round(silent_for_s, 3),
                "tasks_returned": returned,
            }
        )
        return returned

    def arm_rejoined(self, arm: str) -> None:
        """A lost arm's controller is heard again (an arm an outside client drives stays out until let go)."""
        if arm not in self.taken and self.lost.pop(arm, None) is not None:
            self.losses.append({"arm": arm, "event": "rejoined", "sim_time_s": round(self.sim_time_s, 3)})

    # --- taking over a running line ---------------------------------------------------

    # --- what the allocator sees ----------------------------------------------------

    # --- decisions ------------------------------------------------------------------
    def decide(self, tick: int) -> Decision:
        """One decision at `tick`: answer motion requests, take late belt tasks back, refresh and allocate tasks."""
        now = tick / self.scene.control_hz
        self.last_decision_tick = tick
        self.decisions += 1
        separations = self.watch_separations() if len(self.arm_names) > 1 else []
        orders: list[Order] = [*self.take_cancels(), *self.answer_motion_requests(now), *self.reassign_late_tasks()]
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
        self.busy_until_s[arm.name] = now_s + cost_s(arm, task, self.parts[task.part_id])
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
                task.state == TaskState.ACTIVE and self.phase.get(arm) == Phase.APPROACH and arm in self.requests
            )
            part = self.parts.get(task.part_id)
            if arm is None or part is None or not not_started or not cannot_make_it(rules, views[arm], task, part):
                continue
            self.ledger.requeue(task.task_id, f"{arm} could no longer meet the part")
            self.requests.pop(arm, None)
            self.reassigned += 1
            out.append(CancelOrder(arm, task.part_id))
        return out

    def assignment(self, task: Task, arm: str) -> AssignOrder:
        """The order that gives `task` to `arm` (and reserves its stations until the arm is idle again)."""
        part, rec = self.parts[task.part_id], self.ledger.parts[task.part_id]
        station = self.scene.station(task.target)
        velocity = self.belt_velocity() if task.source == CONVEYOR else (0.0, 0.0, 0.0)
        place = (station.pose.xyz[0], station.pose.xyz[1], self.ledger.place_height_m(task.target, task.part_id))
        self.last_stations[arm], self.last_task[arm] = task.stations, task.task_id
        return AssignOrder(arm, task.task_id, task.part_id, float(part.position[2] - rec.height_m / 2), place, velocity)

    def belt_velocity(self) -> tuple[float, float, float]:
        c = self.scene.conveyor
        return tuple(d * c.speed_m_per_s for d in c.direction) if c else (0.0, 0.0, 0.0)

    # --- the summary ----------------------------------------------------------------
