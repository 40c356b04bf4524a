"""Every decision of the line's coordinator, in one pure class: no bus, no clock of its own.

Events, arm reports and motion requests go in; at each decision (`decide(tick)`) orders come out,
in the order they must be published: grants and denials of motion requests, cancellations of
belt tasks an arm can no longer meet, and new assignments. The coordinator node decodes, feeds a
`Dispatcher` and publishes what it returns; the PettingZoo env's allocate mode drives the same class
(its tasks, belt deadlines and reassignment), so the two cannot drift apart. Liveness is the
caller's to judge (it owns the clock): it calls `arm_lost` and `arm_rejoined`.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from coordinator.allocation import Allocator, ArmView, CachedReach, Eligibility, PartView, TimeCost, make_allocator
from coordinator.cadence import decision_period_ticks
from coordinator.capacity import (
    CapacityBound,
    belt_window_caps,
    capacity_bound,
    finishable_arrivals,
    measured_hop_seconds,
)
from coordinator.deadlines import belt_deadline_s, cannot_make_it, last_reach_along_belt_m
from coordinator.geometry import ArmGeometry
from coordinator.guard import CollisionGuard, NearestPair, TimedPath
from coordinator.ledger import PIPELINE_DEFAULT, Ledger
from coordinator.tasks import CONVEYOR, TAKEN_STATES, Task, TaskState
from robots.frames import yaw_transform
from robots.phase import AVAILABLE_PHASES, GRASP_PHASES, IDLE_PHASES, LOCAL_PHASES, PLACE_PHASES, Phase
from robots.registry import get_robot
from scenes.schema import Scene

OVERRUN_S = 2.0  # a task this late on its estimate: its arm's end is unknown
SETTLE_CAP_S = (
    10.0  # after a take-over, no grant until the arms settle or this long (sim s): longer than any granted move
)
STATION_MATCH_M = 0.01  # a place position this close (x, y) to a station's is that station
_BELT_REACH_M: dict[str, float | None] = {}  # layout -> the belt's last reachable point


@dataclass(frozen=True)
class AssignOrder:
    """Take `task_id`: pick part `part_id` from a surface at `surface_z_m` moving at `surface_velocity`,
    place it at `place_xyz` (the part's bottom, world frame, metres)."""

    arm: str
    task_id: int
    part_id: int
    surface_z_m: float
    place_xyz: tuple[float, float, float]
    surface_velocity: tuple[float, float, float]


@dataclass(frozen=True)
class CancelOrder:
    """Drop the task on part `part_id`: the arm can no longer meet it (another arm may)."""

    arm: str
    part_id: int


@dataclass(frozen=True)
class GrantOrder:
    """The answer to motion request `request_seq`: `grant` (the move starts at `start_s`) or `deny` (`conflict_arm`
    stands in the way); `min_separation_m` is the closest approach checked (inf: no neighbour)."""

    arm: str
    request_seq: int
    decision: str
    conflict_arm: str
    min_separation_m: float
    start_s: float | None


Order = AssignOrder | CancelOrder | GrantOrder


@dataclass(frozen=True)
class Decision:
    """What one decision produced: the orders in publishing order, and the arms' nearest neighbours then."""

    tick: int
    orders: list[Order]
    separations: list[NearestPair]


class Dispatcher:
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
        self.requests: dict[str, TimedPath] = {}  # motion requests waiting for a decision, by arm (the newest wins)
        self.request_seq: dict[str, int] = {a: 0 for a in self.arm_names}
        self.lost: dict[str, float] = {}
        self.busy_until_s: dict[str, float] = {}  # when each arm's current task should end (the allocator's estimate)
        self.deadline_known: set[int] = set()  # tasks whose belt deadline was worked out (once each)
        self.parts: dict[int, PartView] = {}
        self.sim_time_s = 0.0
        self.last_event_s = (
            0.0  # the latest line event heard (the run's end, at its report, may be later than its parts)
        )
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
        self.last_reach_along_belt_m = self._belt_reach()  # where a belt task's deadline falls

    def _belt_reach(self) -> float | None:
        """The belt's last point an arm reaches: IK misses cost, so worked out once per layout (an env resets often)."""
        conveyor = self.scene.conveyor
        if conveyor is None:
            return None
        key = repr((conveyor.model_dump_json(), [(a.model, a.base.xyz, a.base.yaw_rad) for a in self.scene.arms]))
        if key not in _BELT_REACH_M:
            _BELT_REACH_M[key] = last_reach_along_belt_m(conveyor, self.arm_views(), conveyor.pose.xyz[2] + 0.015)
        return _BELT_REACH_M[key]

    @functools.cached_property
    def capacity(self) -> CapacityBound:
        """What the line could do at best (worked out when first asked: an env resets often)."""
        return capacity_bound(self.scene, reach=self.reach)

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
    ) -> list[int] | None:
        """An arm's state: its joints, its skill's phase and task, and the motion request it holds still for
        (`request_seq` > 0; a request is new when its number differs from the last taken: a restarted
        controller counts from 1 again). `acts_at_tick`: when an order sent now would take effect on it.
        `lost`: the sim stopped hearing its controller; returns the tasks put back if that makes the arm lost."""
        self.acts_at_tick[arm] = acts_at_tick
        self.phase[arm] = phase
        if request_seq > 0 or phase in IDLE_PHASES:  # holding still for a grant, or not working: no move of old
            self.unsettled.discard(arm)
        self.guard.set_state(arm, np.asarray(q))
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
        if self.lost.pop(arm, None) is not None:
            self.losses.append({"arm": arm, "event": "rejoined", "sim_time_s": round(self.sim_time_s, 3)})

    # --- taking over a running line ---------------------------------------------------
    def take_over(self, time_s: float) -> None:
        """This dispatcher replaces one that crashed (events replayed with `on_event`): the grants it gave are
        unknown, so none is given until every arm was seen holding still for a grant or idle (an arm may still
        be moving under an old grant), or `SETTLE_CAP_S` passed."""
        self.sim_time_s = max(self.sim_time_s, time_s)
        self.unsettled = set(self.arm_names) - set(self.lost)
        self.settle_by_s = time_s + SETTLE_CAP_S

    def adopt(self, arm: str, task_id: int, part_id: int, place_xyz: tuple[float, ...], time_s: float) -> str:
        """The task `arm` says it works on (its controller's heartbeat) joins the ledger as that arm's, if the
        ledger does not know it: a take-over, or an order of the crashed dispatcher that it never announced.
        Returns why not ("" when adopted)."""
        if task_id in self.ledger.tasks:
            return "known"
        station = self.station_at(place_xyz)
        why = (
            f"no station at {tuple(round(v, 3) for v in place_xyz)}"
            if station is None
            else self.ledger.adopt(task_id, part_id, station, arm, time_s)
        )
        if not why:
            self.last_stations[arm] = self.ledger.tasks[task_id].stations
        self.adopted.append(
            {
                "arm": arm,
                "task_id": task_id,
                "part_id": part_id,
                "station": station,
                "sim_time_s": round(time_s, 3),
                "adopted": not why,
                "reason": why,
            }
        )
        return why

    def station_at(self, place_xyz: tuple[float, ...]) -> str | None:
        """The station whose place position (x, y) is `place_xyz`'s, if one is."""
        if len(place_xyz) != 3:
            return None
        for station in self.scene.stations:
            if math.dist(station.pose.xyz[:2], place_xyz[:2]) < STATION_MATCH_M:
                return station.name
        return None

    # --- what the allocator sees ----------------------------------------------------
    def arm_views(self) -> list[ArmView]:
        open_arms = {t.arm for t in self.ledger.open_tasks() if t.state in TAKEN_STATES}
        return [
            ArmView(
                a,
                self.bases[a],
                a not in self.lost
                and a not in open_arms
                and self.phase[a] in AVAILABLE_PHASES
                and not self.leaving_fixture(a),
                self.reach[a],
                tuple(self.guard.state[a].tolist()),
                self.free_in_s(a) if a in open_arms else None,
                a not in self.lost,
            )
            for a in self.arm_names
        ]

    def leaving_fixture(self, arm: str) -> bool:
        """Pipelined: an arm on its way home from a fixture takes no task until home. A task taken on the way would
        start its approach from where the way home has got to by its grant, not from where it asked: harmless
        in open space, not next to the arm that works the fixture next."""
        return (
            self.ledger.pipeline
            and self.phase[arm] == Phase.HOME
            and bool(self.ledger.gated.intersection(self.last_stations[arm]))
        )

    def free_in_s(self, arm: str, now_s: float | None = None) -> float | None:
        """About when a busy arm's task ends (from `now_s`, else the last decision); None once it overran its
        estimate (or is lost): not planned for."""
        now_s = self.last_decision_tick / self.scene.control_hz if now_s is None else now_s
        remaining = self.busy_until_s.get(arm, -math.inf) - now_s
        return None if arm in self.lost or remaining < -OVERRUN_S else max(remaining, 0.0)

    def busy_stations(self, for_arm: str | None = None) -> set[str]:
        """Stations in use: by open tasks, and by arms still moving away from their last task's stations; `for_arm`:
        as that arm sees them (a station it is itself moving away from is free to it: it may go straight back)."""
        busy = self.ledger.busy_stations()
        for arm, stations in self.last_stations.items():
            if arm != for_arm and self.phase[arm] not in IDLE_PHASES and arm not in self.lost:
                busy.update(stations)
        if self.ledger.pipeline:
            busy -= self.ledger.gated  # their order is the ledger's, their moves wait at `station_ahead`
        return busy

    def busy_for_all(self, arms: list[str]) -> set[str]:
        """The stations busy for every one of `arms` (the free ones: what an allocator may be told is busy); a task
        chosen at another station must still be checked against `busy_stations(arm)` for the arm it goes to."""
        return set.intersection(*(self.busy_stations(a) for a in arms)) if arms else self.busy_stations()

    def busy_arms(self) -> int:
        return sum(s not in IDLE_PHASES for s in self.phase.values())

    # --- decisions ------------------------------------------------------------------
    def decide(self, tick: int) -> Decision:
        """One decision at `tick`: answer motion requests, take late belt tasks back, refresh and allocate tasks."""
        now = tick / self.scene.control_hz
        self.last_decision_tick = tick
        self.decisions += 1
        separations = self.watch_separations() if len(self.arm_names) > 1 else []
        orders: list[Order] = [*self.answer_motion_requests(now), *self.reassign_late_tasks()]
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
        pending = self.ledger.refresh(now_s)
        for task in pending:
            if task.source == CONVEYOR and task.task_id not in self.deadline_known and task.part_id in self.parts:
                self.deadline_known.add(task.task_id)
                task.deadline_s = belt_deadline_s(
                    self.scene.conveyor, self.last_reach_along_belt_m, self.parts[task.part_id], now_s
                )
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

    def answer(self, tick: int) -> list[GrantOrder]:
        """Only the motion requests, at `tick`: for a front end whose tasks are chosen elsewhere (the env's allocate
        mode,
        where the policy allocates)."""
        self.last_decision_tick = tick
        return self.answer_motion_requests(tick / self.scene.control_hz)

    def answer_motion_requests(self, now_s: float) -> list[GrantOrder]:
        """Check every waiting request with the guard, arms in scene order (one global order: no cycle of waits).

        A grant starts when the arm next hears from the sim (its controller acts on it then), for the duration
        asked; `deny` (an arm that is not moving is in the way) goes back to the arm; `wait` (an arm with a
        granted move is in the way) stays here until that move is over.
        """
        self.guard.expire(now_s)
        if self.unsettled and now_s < self.settle_by_s:
            return []  # taken over: an arm may still move under a grant this dispatcher never saw
        self.unsettled.clear()
        out = []
        self.held_now = {}
        for arm in [a for a in self.arm_names if a in self.requests]:
            station = self.station_ahead(arm)
            if station is not None:  # pipelined: the fixture is not ready for this arm's part yet
                self.held_now[arm] = station
                self.held_at_station_s[arm] = (
                    self.held_at_station_s.get(arm, 0.0) + self.period_ticks / self.scene.control_hz
                )
                task = self.open_task(arm)
                # wait beside it, part in hand
                if self.phase[arm] == Phase.TRANSFER and task.task_id not in self.told_standby:
                    self.told_standby.add(task.task_id)
                    del self.requests[arm]
                    out.append(GrantOrder(arm, self.request_seq[arm], "standby", "", math.inf, None))
                continue
            asked = self.requests[arm]
            start = max(self.acts_at_tick[arm], self.last_decision_tick + 1) / self.scene.control_hz
            path = dataclasses.replace(asked, t_start_s=start, t_end_s=start + (asked.t_end_s - asked.t_start_s))
            self.guard.set_state(arm, np.asarray(asked.q_from))
            verdict = self.guard.request(path)
            if verdict.decision == "wait":
                continue
            del self.requests[arm]
            self.grants_given += verdict.granted
            out.append(
                GrantOrder(
                    arm,
                    self.request_seq[arm],
                    verdict.decision,
                    verdict.conflict_arm or "",
                    verdict.min_separation_m,
                    start if verdict.granted else None,
                )
            )
        return out

    def open_task(self, arm: str) -> Task | None:
        """The task `arm` was given and has not finished."""
        return next((t for t in self.ledger.open_tasks() if t.arm == arm and t.state in TAKEN_STATES), None)

    def station_ahead(self, arm: str) -> str | None:
        """The fixture `arm`'s waiting move would take it into while it is not ready (None: no such fixture): an
        approach to take from one, a transfer to place on one. Not ready: the ledger holds the part back, or
        another arm works there or is on its way in (`_at_station`)."""
        if not self.ledger.pipeline:
            return None
        task = self.open_task(arm)
        phase = self.phase.get(arm)
        station = (
            task.source
            if task and phase == Phase.APPROACH
            else task.target
            if task and phase == Phase.TRANSFER
            else None
        )
        if station is None or station not in self.ledger.gated:
            return None
        if not self.ledger.may_enter(task, station):
            return station
        return station if any(b != arm and self._at_station(b, station) for b in self.arm_names) else None

    def _at_station(self, arm: str, station: str) -> bool:
        """Is `arm` working at `station` or moving into it under a grant: taking from it (its approach granted,
        the grasp), placing on it (its transfer granted, the place), or still grasping or placing there after its
        task closed. One arm at a fixture at a time, whatever the ledger thinks is there: the guard checks moves,
        but two arms working one spot leave it no safe order."""
        phase = self.phase[arm]
        if arm in self.lost:
            return False
        if station in self.last_stations[arm] and phase in LOCAL_PHASES:
            return True
        task = self.open_task(arm)
        if task is None:
            return False
        granted = arm not in self.requests
        if station == task.source:
            return phase in GRASP_PHASES or (phase == Phase.APPROACH and granted)
        if station == task.target:
            return phase in PLACE_PHASES or (phase == Phase.TRANSFER and granted)
        return False

    def watch_separations(self) -> list[NearestPair]:
        """The cell's closest approach, sampled at the decision rate; each arm's nearest neighbour."""
        pairs = self.guard.nearest_pairs()
        if pairs and pairs[0].distance_m < self.min_separation_m:
            self.min_separation_m, self.closest_pair = pairs[0].distance_m, (pairs[0].a, pairs[0].b)
        return pairs

    def assignment(self, task: Task, arm: str) -> AssignOrder:
        """The order that gives `task` to `arm` (and reserves its stations until the arm is idle again)."""
        part, rec = self.parts[task.part_id], self.ledger.parts[task.part_id]
        station = self.scene.station(task.target)
        velocity = self.belt_velocity() if task.source == CONVEYOR else (0.0, 0.0, 0.0)
        place = (station.pose.xyz[0], station.pose.xyz[1], self.ledger.place_height_m(task.target, task.part_id))
        self.last_stations[arm] = task.stations
        return AssignOrder(arm, task.task_id, task.part_id, float(part.position[2] - rec.height_m / 2), place, velocity)

    def belt_velocity(self) -> tuple[float, float, float]:
        c = self.scene.conveyor
        return tuple(d * c.speed_m_per_s for d in c.direction) if c else (0.0, 0.0, 0.0)

    # --- the summary ----------------------------------------------------------------
    def report(self) -> dict:
        return self.ledger.totals() | {
            "allocator": self.allocator.name,
            "pipeline": self.ledger.pipeline,
            "arm_events": self.losses,
            "unfinished_parts": self.ledger.unfinished(),
            "tasks": [
                {
                    "task_id": t.task_id,
                    "part_id": t.part_id,
                    "source": t.source,
                    "target": t.target,
                    "state": t.state.value,
                    "arm": t.arm,
                    "created_s": t.created_s,
                    "assigned_s": t.assigned_s,
                    "deadline_s": t.deadline_s,
                    "done_s": t.done_s,
                    "reassignments": t.reassignments,
                    "reason": t.reason,
                }
                for t in self.ledger.tasks.values()
            ],
            "decisions": self.decisions,
            "grants_denied": self.guard.denied,
            "grants_given": self.grants_given,
            "tasks_reassigned": self.reassigned,
            "tasks_adopted": self.adopted,
            "grant_waits": self.guard.waits,
            "grant_requests_open": {
                a: round(self.sim_time_s - p.t_start_s, 3) for a, p in self.requests.items() if a not in self.held_now
            },
            "held_at_station_s": {a: round(s, 2) for a, s in self.held_at_station_s.items()},
            "min_separation_m": round(self.min_separation_m, 4) if math.isfinite(self.min_separation_m) else None,
            "closest_pair": list(self.closest_pair) if self.closest_pair else None,
            "capacity": self.capacity.as_dict(),
            "capacity_measured": self.measured_capacity(),
            "capacity_of_run": self.run_capacity(),
        }

    def run_capacity(self) -> dict | None:
        """The capacity bound with this run's own arrivals, those in time to be finished by now, in place of the mean
        rates (None before any time passed): what this run could have completed at best."""
        end_s = max(self.sim_time_s, self.last_event_s)
        if end_s <= 0:
            return None
        arrived = [(p.feeder, p.type_index, p.arrived_s) for p in self.ledger.parts.values()]
        model = self.capacity.model
        counts = finishable_arrivals(self.scene, arrived, end_s, model)
        caps = belt_window_caps(self.scene, arrived, end_s, model)
        bound = capacity_bound(
            self.scene,
            reach=self.reach,
            model=model,
            arrivals_per_s={k: n / end_s for k, n in counts.items()},
            type_limits=[(f"{c.arm} belt window", c.types, c.at_most / end_s) for c in caps],
        )
        return bound.as_dict() | {
            "parts_finishable": sum(counts.values()),
            "sim_seconds": round(end_s, 3),
            "belt_windows": {c.arm: {"parts": c.arrived, "at_most": c.at_most} for c in caps},
        }

    def measured_capacity(self) -> dict | None:
        """The capacity bound again with the hop times this run measured (None before any task was done)."""
        measured = measured_hop_seconds(list(self.ledger.tasks.values()))
        if not measured:
            return None
        return capacity_bound(self.scene, measured, self.reach, self.capacity.model).as_dict() | {
            "measured_hop_s": {
                f"{arm}: {source} -> {target}": round(s, 3) for (arm, source, target), s in sorted(measured.items())
            }
        }
