"""The `allocate` action mode: each free arm chooses which pending task of the line it takes next, and the
pick-and-place skill does the work. A policy learns allocation on the same choices the coordinator's
allocators make (`allocator_actions` turns an allocator's answer into env actions, for comparison). What an arm
may choose and what it sees of its choices are `coordinator.choice_slots`, which the coordinator's `policy:FILE`
allocator builds the same way, so a policy trained here runs the real line.

The tasks, their belt deadlines, their eligibility (reach, belt stretches, one task per station), their
time estimates, the orders that start them and the reassignment of belt tasks an arm can no longer meet
are the coordinator's own (`Dispatcher`, `Eligibility`, `TimeCost`): one implementation, in process.
"""

from __future__ import annotations

import numpy as np

from coordinator.allocation import Allocator, ArmView, CachedReach, Eligibility, PartView, TimeCost
from coordinator.cadence import moves_need_grants
from coordinator.choice_slots import WAIT, ArmChoices, arm_choices, choice_features
from coordinator.deadlines import time_left_s
from coordinator.dispatcher import Dispatcher
from coordinator.guard import TimedPath
from coordinator.tasks import OPEN_STATES, Task, TaskState
from fleet.env.env_sight import EnvSight
from fleet.sim.observe import arm_observation, base_transform, part_observations
from fleet.sim.tracking import TrackedArms
from fleet.sim.world import World
from robots.skills.interface import PickPlaceJob
from robots.skills.pick_place import DEFAULT_DECISION_HZ, PickPlaceSkill
from scenes.schema import Scene


class TaskChooser:
    """Runs the skills of the arms and turns each free arm's choice into an assignment on the ledger."""

    def __init__(self, scene: Scene, world: World, agents: list[str], sight: EnvSight | None = None) -> None:
        """`sight`: the parts come from the cameras (`perception="cameras"`), not the world's truth."""
        self.scene, self.agents, self.sight = scene, agents, sight
        self.reach = {a.name: CachedReach.of(a) for a in scene.arms}
        self.bases = {a.name: a.base.xyz for a in scene.arms}
        self.world = world

    def reset(self, dispatcher: Dispatcher) -> None:
        self.dispatcher = dispatcher
        self.ledger = dispatcher.ledger
        # as `fleet run` does it: the arms ask for their free moves and the dispatcher's guard answers (on a line
        # with a fixture, pipelined by default: holding an arm at a fixture that is not ready); a lone arm moves unasked
        self.grants = moves_need_grants(self.scene)
        # the skills decide as controllers do
        self.period_ticks = max(1, round(self.scene.control_hz / DEFAULT_DECISION_HZ))
        period_s = self.period_ticks / self.scene.control_hz
        self.skills = {
            a: PickPlaceSkill(
                self.world.arms[a].spec,
                base_transform(self.world, a),
                decision_period_s=period_s,
                grants_required=self.grants,
            )
            for a in self.agents
        }
        self.tracked = TrackedArms(self.world)  # the arms follow the skills' goals, as the sim server's trackers do
        self.task_of: dict[str, int | None] = {a: None for a in self.agents}
        self.unstarted: dict[str, object] = {}  # arm -> an assignment given it, to start when its skill is free
        self.arm_choices: dict[str, ArmChoices] = {}
        self.seen: dict[int, PartView] = {}
        self.outcomes: dict[str, list[TaskState]] = {a: [] for a in self.agents}

    # --- what each arm sees ---------------------------------------------------------
    def parts(self) -> dict[int, PartView]:
        if self.sight is not None:
            return self.sight.views(self.world.tick)
        return {p.part_id: PartView(p.position, p.velocity) for p in self.world.active_parts()}

    def part_observations(self) -> dict:
        """The parts as the skills see them: the world's, or the cameras'."""
        return self.sight.observations(self.world.tick) if self.sight is not None else part_observations(self.world)

    def arm_views(self) -> list[ArmView]:
        """Each arm as the allocators see it: free or not, where it stands, and a busy arm's estimated time to free
        (the dispatcher's, from when its task started), as the coordinator node's allocator sees it."""
        now = self.world.sim_time_s
        return [
            ArmView(
                a,
                self.bases[a],
                self.task_of[a] is None and self.skills[a].available and not self.dispatcher.views.leaving_fixture(a),
                self.reach[a],
                tuple(self.world.arms[a].qpos()[: self.world.arms[a].spec.arm_dof].tolist()),
                self.dispatcher.free_in_s(a, now) if self._working(a) else None,
            )
            for a in self.agents
        ]

    def _working(self, agent: str) -> bool:
        """The arm's task is still open (its skill may be retreating from a closed one)."""
        task_id = self.task_of[agent]
        return task_id is not None and self.ledger.tasks[task_id].state in OPEN_STATES

    def busy_stations(self, agent: str | None = None) -> set[str]:
        """Stations no new task may use now (for `agent`; else for every free arm): the dispatcher's rule (stations of
        open tasks and of other arms still moving away; fixtures ordered by the ledger when pipelined)."""
        if agent is not None:
            return self.dispatcher.busy_stations(agent)
        return self.dispatcher.busy_for_all([v.name for v in self.arm_views() if v.free])

    def pending(self) -> list[Task]:
        """The tasks waiting for an arm (belt tasks with their deadlines), as the coordinator sees them now."""
        self.dispatcher.on_parts(self.parts(), self.world.sim_time_s)
        return self.dispatcher.pending(self.world.sim_time_s)

    def choices(self) -> dict[str, list[tuple[Task, float]]]:
        """Per arm: the tasks it may take now (and their estimated seconds), oldest first, at most SLOTS, as the
        coordinator's `policy:FILE` allocator works them out (`coordinator.choice_slots`: the stations busy for every
        free arm, the belt parts coming into reach). Kept, with the parts seen, for this step's features."""
        views, self.seen = self.arm_views(), self.parts()
        cost = TimeCost(Eligibility(self.scene, views))
        candidates = self.dispatcher.candidates(self.pending())
        busy = self.dispatcher.busy_for_all([v.name for v in views if v.free])  # as `busy_stations()`, views in hand
        self.arm_choices = arm_choices(views, candidates, self.seen, busy, cost)
        return {a: list(c.options) for a, c in self.arm_choices.items()}

    def features(self, agent: str) -> np.ndarray:
        """What an arm sees of its choices (`coordinator.choice_slots.choice_features`)."""
        conveyor, reach = self.scene.conveyor, self.dispatcher.belt_reach
        return choice_features(
            self.scene,
            self.arm_choices.get(agent, ArmChoices()),
            self.seen,
            lambda task: time_left_s(conveyor, reach.for_station(task.target), self.seen[task.part_id]),
        )

    # --- acting ---------------------------------------------------------------------
    def choose(self, actions: dict[str, int], options: dict[str, list[tuple[Task, float]]]) -> dict[str, str]:
        """Start each free arm's chosen task, arms in id order; a task or station already taken this step is refused.
        Returns, per arm, what became of its choice (`took`, `waited`, `refused: ...`)."""
        taken: set[str] = set()
        out = {}
        for agent in self.agents:
            k = int(actions.get(agent, WAIT))
            if k == WAIT or not options[agent]:
                out[agent] = "waited"
                continue
            if k > len(options[agent]):
                out[agent] = f"refused: slot {k} is empty ({len(options[agent])} choices)"
                continue
            task = options[agent][k - 1][0]
            if self.dispatcher.real(task.task_id).state != TaskState.PENDING or (
                taken | self.busy_stations(agent)
            ).intersection(task.stations):
                out[agent] = f"refused: task {task.task_id} was taken by an arm before it"
                continue
            self._start(agent, task)
            taken.update(task.stations)
            out[agent] = "took"
        return out

    def _start(self, agent: str, candidate: Task) -> None:
        views = self.arm_views()
        view = next(v for v in views if v.name == agent)
        order = self.dispatcher.start(
            candidate.task_id, view, self.world.sim_time_s, TimeCost(Eligibility(self.scene, views))
        )
        task = self.ledger.tasks[order.task_id]
        self.dispatcher.on_parts(self.parts(), self.world.sim_time_s)
        job = PickPlaceJob(order.part_id, order.surface_z_m, order.place_xyz, order.surface_velocity)
        parts = self.part_observations()
        self.skills[agent].start(
            job, arm_observation(self.world, agent, self.tracked.trackers[agent]), parts[task.part_id]
        )
        self.tracked.decide(agent, self.skills[agent], parts)
        self.task_of[agent] = task.task_id

    def command(self) -> None:
        """Before a tick: at decision ticks the dispatcher answers the arms' motion requests (pipelined) and every
        working arm's skill sends its goals; the trackers set the drive targets."""
        if self.world.tick % self.period_ticks == 0:
            if self.grants:
                for order in self.dispatcher.answer(self.world.tick):
                    self.skills[order.arm].on_grant(
                        order.request_seq, order.decision, order.conflict_arm, self.world.sim_time_s, order.start_s
                    )
            parts = self.part_observations()
            for agent in [a for a, order in self.unstarted.items() if order is not None and self.skills[a].available]:
                self._start_assigned(agent, self.unstarted.pop(agent), parts)
            for agent in self.agents:
                if self.skills[agent].active:
                    self.tracked.decide(agent, self.skills[agent], parts)
        self.tracked.apply()

    def _start_assigned(self, agent: str, order, parts: dict) -> None:
        """An assignment the arm had been given (an episode from a line's snapshot) started now its skill is free."""
        if order.part_id not in parts:
            self.skills[agent].reject(f"part {order.part_id} is not on the line")
            return
        job = PickPlaceJob(order.part_id, order.surface_z_m, tuple(order.place_xyz), tuple(order.surface_velocity))
        observed = arm_observation(self.world, agent, self.tracked.trackers[agent])
        self.skills[agent].start(job, observed, parts[order.part_id])
        self.task_of[agent] = order.task_id

    def report(self) -> None:
        """After a tick: the trackers' results; each arm's skill phase goes to the ledger; a closed task frees its
        arm."""
        self.tracked.update()
        now = self.world.sim_time_s
        for agent in self.agents:
            task_id = self.task_of[agent]
            skill = self.skills[agent]
            task = self.ledger.tasks[task_id] if task_id is not None else None
            was_open = task is not None and task.state in OPEN_STATES
            joints, dof = self.world.arms[agent].qpos(), self.world.arms[agent].spec.arm_dof
            q = joints[:dof]
            asked = skill.request if self.grants else None
            request = (
                None
                if asked is None
                else TimedPath(
                    agent,
                    tuple(map(float, q)),
                    asked.q_to,
                    now,
                    now + asked.duration_s,
                    asked.then_q,
                    asked.then_after_s,
                )
            )
            self.dispatcher.on_arm(
                agent,
                q,
                skill.phase.value,
                now,
                task_id=task_id if was_open else None,
                failure=skill.failure_reason,
                failure_code=skill.failure_code,
                request_seq=asked.seq if asked else 0,
                request=request,
                acts_at_tick=self.world.tick + 1,
                gripper_q=joints[dof:],
            )
            if task is None:
                continue
            if was_open and task.state not in OPEN_STATES:
                self.outcomes[agent].append(task.state)
            # the skill finishes its retreat first (home may be given up)
            if task.state not in OPEN_STATES and skill.available:
                self.task_of[agent] = None
        if self.world.tick % self.period_ticks == 0:
            self._take_back_late_tasks()

    def _take_back_late_tasks(self) -> None:
        """The coordinator's rule: a belt task its arm has not started on and can no longer meet goes back to the
        pool."""
        self.dispatcher.on_parts(self.parts(), self.world.sim_time_s)
        for cancel in self.dispatcher.reassign_late_tasks():
            self.skills[cancel.arm].cancel("the part can no longer be met")
            self.task_of[cancel.arm] = None


def allocator_actions(
    chooser: TaskChooser, allocator: Allocator, options: dict[str, list[tuple[Task, float]]]
) -> dict[str, int]:
    """What the coordinator's allocator would choose now, as `task`-mode actions (a task outside an arm's slots:
    wait)."""
    views, parts = chooser.arm_views(), chooser.parts()
    pairs = allocator.allocate(chooser.dispatcher.candidates(chooser.pending()), views, parts, chooser.busy_stations())
    actions = {a: WAIT for a in chooser.agents}
    for task_id, arm in pairs:
        ids = [t.task_id for t, _ in options.get(arm, [])]
        if task_id in ids:
            actions[arm] = ids.index(task_id) + 1
    return actions
