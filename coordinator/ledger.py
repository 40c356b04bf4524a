"""The task ledger: line events in, tasks out, every part accounted for at the end.

Pure bookkeeping on sim time: the coordinator node feeds it the sim's line events
(`arrived`, `at_station`, `lost`) and each arm's phase report, and asks it for
the tasks that are ready. A part's route comes from the scene; an assembly
fixture (`Station.assembles`) takes its layers bottom first and lets the bottom
part move on only once the stack is whole.

With `pipeline`, a fixture's next part may be given to an arm before the fixture is ready for it (the
layer below still on its way, the assembly before it not yet taken away): the arm picks it and holds
it, and `may_enter` says when it may move in. One part (or one assembly) ahead at most.
"""

from __future__ import annotations

from coordinator import ledger_accounts
from coordinator.ledger_buffers import Buffering, BuffersNear, SoonLost
from coordinator.ledger_holds import DENIAL_HOLD_S, MAX_DENIALS, deny, refused_by, release_holds  # noqa: F401
from coordinator.ledger_records import LedgerRecords
from coordinator.ledger_stations import StationTurns, alternatives, other_stations
from coordinator.tasks import CONVEYOR, OPEN_STATES, PartFate, PartRecord, Task, TaskState
from robots.failures import FailureCode
from robots.phase import HOLDING_PHASES, IDLE_PHASES, Phase
from scenes.schema import Scene

HELD = "held"
EVENT_KINDS = ("arrived", "at_station", "lost", "retired")
INCOMING = "incoming"  # dropped into a station by a feeder, not yet at rest there
MAX_ATTEMPTS = 3
PLACED_GRACE_S = 3.0


# fixtures are pipelined unless a run asks otherwise (`--no-pipeline`): the one default of every front end
PIPELINE_DEFAULT = True


class Ledger:
    """Parts and tasks of one run; all times are sim seconds. Its records (`LedgerRecords`) are shared by the
    stations' turns (`StationTurns`) and the buffers (`Buffering`), each handed them."""

    def __init__(self, scene: Scene, first_task_id: int = 1, pipeline: bool = PIPELINE_DEFAULT) -> None:
        self.scene = scene
        self.records = LedgerRecords(scene, first_task_id)
        self.turns = StationTurns(self.records, scene, pipeline)
        self.buffering = Buffering(self.records, self.turns, scene)
        self._station_names = {s.name for s in scene.stations}

    @property
    def parts(self) -> dict[int, PartRecord]:
        return self.records.parts

    @property
    def tasks(self) -> dict[int, Task]:
        return self.records.tasks

    @property
    def stacks(self) -> dict[str, list[int]]:
        return self.records.stacks

    @property
    def pipeline(self) -> bool:
        """Whether a fixture's next part may be given to an arm before the fixture is ready for it."""
        return self.turns.pipeline

    @property
    def gated(self) -> set[str]:
        """The fixtures: one part or assembly at a time."""
        return self.turns.gated

    @property
    def buffers(self) -> frozenset[str]:
        return self.buffering.buffers

    # --- line events ------------------------------------------------------------------
    def arrived(self, part_id: int, feeder: str, type_index: int, now_s: float) -> None:
        f = self.scene.feeder(feeder)
        self.parts[part_id] = PartRecord(
            part_id,
            feeder,
            type_index,
            float(f.parts[type_index].size_m[2]),
            self.scene.route(feeder, type_index),
            now_s,
            location=CONVEYOR if f.into == CONVEYOR else INCOMING,
        )

    def at_station(self, part_id: int, station: str, now_s: float) -> None:
        part = self.parts.get(part_id)
        if part is None or part.fate != PartFate.ON_LINE:
            return
        self.records.leave_stack(part)
        part.location = station
        task = self.records.open_task(part_id)
        # another bin of its colour does as well
        if station != part.next_station and station in alternatives(self.scene, part):
            part.route[part.hop] = station
            if task is not None:
                task.retarget(station)
        if station == part.next_station:
            part.hop += 1
            if task is not None and task.target == station:
                task.done_s = now_s
                self.records.close(task, TaskState.DONE, "")
            if station in self.stacks and part.feeder in self.scene.station(station).assembles:
                self.stacks[station].append(part_id)
            if part.next_station is None:
                part.fate = PartFate.COMPLETED
        elif task is not None and task.target == station:  # set down at a buffer: its next hop is still to come
            task.done_s = now_s
            self.records.close(task, TaskState.DONE, "")

    def lost(self, part_id: int, reason: str, now_s: float) -> None:
        part = self.parts.get(part_id)
        if part is None:
            return
        self.records.leave_stack(part)
        task = self.records.open_task(part_id)
        if task is not None:
            self.records.close(task, TaskState.FAILED, f"part lost: {reason}")
        if part.fate == PartFate.ON_LINE:
            part.fate, part.reason = PartFate.MISSED, reason

    def event_problem(self, kind: str, part_id: int, detail: str, type_index: int) -> str:
        """Why a well-formed event cannot be true of this line ("" if it can): unknown kind, feeder, type, station
        or part, or a part arriving twice. The node drops such events and counts them."""
        if kind not in EVENT_KINDS:
            return f"unknown event kind {kind!r}"
        if part_id < 0:
            return "a negative part id"
        if kind == "arrived":
            feeder = next((f for f in self.scene.feeders if f.name == detail), None)
            if feeder is None:
                return f"part {part_id} arrived from no feeder of this line ({detail!r})"
            if not 0 <= type_index < len(feeder.parts):
                return f"feeder {detail} has no part type {type_index}"
            if part_id in self.parts:
                return f"part {part_id} arrived twice"
            return ""
        if part_id not in self.parts:
            return f"{kind} of part {part_id}, which never arrived"
        if kind in ("at_station", "retired") and detail not in self._station_names:
            return f"{kind} at no station of this line ({detail!r})"
        return ""

    def on_event(self, kind: str, part_id: int, detail: str, type_index: int, now_s: float) -> None:
        """One line event as the sim reports it (`arrived`: detail is the feeder; `at_station`: the station;
        `lost`: why); other kinds (`retired`) change nothing here."""
        if kind == "arrived":
            self.arrived(part_id, detail, type_index, now_s)
        elif kind == "at_station":
            self.at_station(part_id, detail, now_s)
        elif kind == "lost":
            self.lost(part_id, detail, now_s)

    # --- arms -----------------------------------------------------------------------
    def arm_report(
        self, arm: str, task_id: int | None, phase: str, now_s: float, failure: str = "", failure_code: str = ""
    ) -> None:
        """What an arm's skill says it is doing (echoed by the sim each tick); a failure's code decides what
        follows, its text explains."""
        task = self.tasks.get(task_id) if task_id is not None else None
        if task is None or task.arm != arm or task.state not in OPEN_STATES:
            return
        part = self.parts[task.part_id]
        if phase in HOLDING_PHASES and part.location != HELD:
            part.held_from, part.held_stack = part.location, tuple(self.stacks.get(part.location, ()))
            self.records.leave_stack(part)
            part.location = HELD
        if task.state == TaskState.ASSIGNED and phase not in IDLE_PHASES:
            task.state = TaskState.ACTIVE
        if phase == Phase.FAILED:
            self._fail_attempt(task, failure or "the arm's skill failed", now_s, failure_code)
        elif phase == Phase.DONE:
            first = self.records.finished_at.setdefault(task.task_id, now_s)
            if now_s - first > PLACED_GRACE_S:
                self._fail_attempt(task, f"placed, but never seen resting at {task.target}", now_s)

    def arm_lost(self, arm: str, now_s: float) -> list[int]:
        """Put a lost arm's tasks back; a part already in its claw is given up. Returns the task ids."""
        ids = []
        for task in self.tasks.values():
            if task.arm == arm and task.state in OPEN_STATES:
                ids.append(task.task_id)
                part = self.parts[task.part_id]
                self.records.close(task, TaskState.FAILED, f"arm {arm} lost")
                if part.location == HELD and part.fate == PartFate.ON_LINE:
                    part.fate, part.reason = PartFate.FAILED, f"in the claw of lost arm {arm}"
        return ids

    def _fail_attempt(self, task: Task, reason: str, now_s: float, code: str = "") -> None:
        part = self.parts[task.part_id]
        self.records.close(task, TaskState.FAILED, reason, getattr(code, "value", code))
        if code == FailureCode.MOTION_DENIED and task.arm is not None:
            deny(part, task.arm, reason, now_s)
            return
        # its pose will not change: another arm must take it
        if code == FailureCode.UNREACHABLE and task.arm is not None:
            part.refused_by.add(task.arm)
        if part.location == HELD and part.fate == PartFate.ON_LINE:
            self._put_back(part)
        part.attempts += 1
        if part.attempts >= MAX_ATTEMPTS and part.fate == PartFate.ON_LINE:
            part.fate, part.reason = PartFate.FAILED, f"{MAX_ATTEMPTS} attempts failed; last: {reason}"

    def _put_back(self, part: PartRecord) -> None:
        """A task failed with its part thought in the claw (a grasp that closed on nothing, a part never seen resting
        where it was placed): the part is taken to be where it was last seen resting, so it gets a new task; if it
        is elsewhere, the sim's next event for it (at a station, fallen) says so."""
        part.location = part.held_from or CONVEYOR
        stack = self.stacks.get(part.location)
        if stack is not None and not stack and part.part_id in part.held_stack:
            stack.extend(p for p in part.held_stack if self.parts[p].location == part.location or p == part.part_id)

    # --- tasks ----------------------------------------------------------------------
    def refresh(self, now_s: float, soon_lost: SoonLost | None = None, near: BuffersNear | None = None) -> list[Task]:
        """Create a task for every part that is ready for its next hop; returns the pending tasks. `soon_lost`: whether
        a belt part soon rides past its last chance to be set down on a buffer (the dispatcher knows the belt); such
        a part whose next station is not ready for it is set down there instead (`Station.buffer`), and goes on from
        there.
        `near`: the buffers near a station, where a part for a taken fixture goes while more ride behind it."""
        behind = self.buffering.waiting_on_belt() if self.buffers else []
        for part in self.buffering.in_turn():
            if part.held_off:
                release_holds(part, now_s, self.records)
            self.buffering.review(part, behind, near)
            waiting = part.fate == PartFate.ON_LINE and part.location not in (HELD, INCOMING)
            if not waiting or part.part_id in self.records.open_by_part:
                continue
            target = part.next_station
            if target is None:
                continue
            if self.turns.ready(part, target):
                self.buffering.rebuffer(self._new_task(part, now_s), part, behind, near)
            elif buffers := self.buffering.buffer_for(part, soon_lost):
                self._new_task(part, now_s, target=buffers[0]).go_to(buffers[0], buffers[1:])
        return [t for t in self.tasks.values() if t.state == TaskState.PENDING]

    def _new_task(self, part: PartRecord, now_s: float, task_id: int | None = None, target: str | None = None) -> Task:
        """A task for the part's next hop, or to `target` (a buffer) on the way; `task_id`: one an arm already works
        on. Pending."""
        task_id = self.records.next_task_id if task_id is None else task_id
        task = Task(task_id, part.part_id, part.location, target or part.next_station, now_s)
        if task.target == part.next_station:
            task.alternatives = other_stations(self.scene, part)
        task.refused_by = refused_by(part)
        self.records.next_task_id = max(self.records.next_task_id, task_id + 1)
        self.tasks[task.task_id] = task
        self.records.open_by_part[part.part_id] = task.task_id
        return task

    def adopt(self, task_id: int, part_id: int, target: str, arm: str, now_s: float) -> str:
        """A task `arm` already works on, as the arm tells it (a respawned coordinator takes over a running line):
        it joins the ledger assigned to `arm`. Returns why it cannot ("" when adopted): the part is not on the
        line, has a task already, or `target` is not where it goes next (the hop was done meanwhile)."""
        part = self.parts.get(part_id)
        if part is None or part.fate != PartFate.ON_LINE:
            return f"part {part_id} is not on the line"
        if part_id in self.records.open_by_part or task_id in self.tasks:
            return f"part {part_id} has a task already"
        buffer = target in self.buffers and part.location == CONVEYOR
        if part.next_station is None or (
            target != part.next_station and target not in alternatives(self.scene, part) and not buffer
        ):
            return f"part {part_id} does not go to {target} next"
        task = self._new_task(part, now_s, task_id, target=target if buffer else None)
        self.assign(task.task_id, arm, now_s, None if buffer else target)
        return ""

    def assign(self, task_id: int, arm: str, now_s: float, target: str | None = None) -> Task:
        """Give a pending task to `arm`; `target`: which of its stations (its target or an alternative) it goes to."""
        task = self.tasks[task_id]
        if target is not None and target != task.target:
            task.retarget(target)
            part = self.parts[task.part_id]
            if target not in self.buffers:  # a buffer is a detour, not a stage of the route
                part.route[part.hop] = target
        task.state, task.arm, task.assigned_s = TaskState.ASSIGNED, arm, now_s
        return task

    def requeue(self, task_id: int, reason: str) -> Task:
        """An assigned task its arm cannot meet goes back to the pool (not a failed attempt: nothing was tried)."""
        task = self.tasks[task_id]
        task.state, task.arm, task.assigned_s, task.reason = TaskState.PENDING, None, None, reason
        task.reassignments += 1
        return task

    # --- stations and accounts (the components' answers) --------------------------------
    def open_tasks(self) -> list[Task]:
        """The tasks not finished (pending, or given to an arm), without walking every task of the run."""
        return self.records.open_tasks()

    def may_enter(self, task: Task, station: str) -> bool:
        """May the arm of `task` move into `station` now (`StationTurns.may_enter`)."""
        return self.turns.may_enter(task, station)

    def place_height_m(self, target: str, part_id: int | None = None) -> float:
        """Where a part's bottom goes at `target` (`StationTurns.place_height_m`)."""
        return self.turns.place_height_m(target, part_id)

    def busy_stations(self) -> set[str]:
        """Stations some assigned or running task picks from or places at (one arm at a time there)."""
        return self.turns.busy_stations()

    def totals(self) -> dict:
        """The run's counts of parts by fate and tasks by outcome."""
        return ledger_accounts.totals(self.records, self.buffers)

    def unfinished(self) -> list[dict]:
        """Each part not completed, with its fate and why."""
        return ledger_accounts.unfinished(self.records)
