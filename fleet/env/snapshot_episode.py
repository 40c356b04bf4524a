"""Env episodes that start where a line's snapshot was taken (`reset(options={"snapshot": PATH})`, or a list of paths
to draw from): the hard moments of real runs as starting states for training.

What the env takes of the line: the world (joints, parts, belt, feeders, the sim clock), the line's bookkeeping (the
sim's watcher, the coordinator's ledger and dispatcher); in the allocate action mode also every arm's skill, tracker
and goals not yet applied, and the orders each controller had received and not yet acted on (acted on now, as the
controller would have at its next state).
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from pathlib import Path

import msgspec
import numpy as np

from coordinator.dispatch_state import restore_dispatcher
from coordinator.dispatcher import Dispatcher
from fleet.bus.goals import goal_from_message
from fleet.sim.line_watch import LineWatcher
from fleet.sim.sim_state import read_sim_state
from fleet.sim.tracking import TrackedArms
from fleet.sim.world import World, WorldState
from fleet.snapshot.controller_state import ControllerState, read_controller_state
from fleet.snapshot.coordinator_state import read_coordinator_state
from fleet.snapshot.process_state import StateError
from fleet.snapshot.snapshot_file import SnapshotError, read_snapshot
from robots.joint_trajectory import GoalResult
from robots.skills.skill_state import restore_skill


class SnapshotEpisodeError(ValueError):
    """A snapshot an episode cannot start from (another scene, other arms, a bad file); one line."""


@dataclass
class LineMoment:
    """A line's state at a snapshot, as an env episode takes it."""

    path: str
    sim_time_s: float
    world: WorldState
    watcher: LineWatcher
    dispatcher: Dispatcher
    tracked: TrackedArms  # the sim's trackers, pointing at the env's world
    goals_not_applied: dict[str, list]  # arm -> goal messages in, due at a later tick (lockstep)
    controllers: dict[str, ControllerState]


def pick_snapshot(option: object, rng: np.random.Generator) -> str:
    """The snapshot path an episode starts from: the one given, or one drawn from a list (the env's stream)."""
    if isinstance(option, (str, Path)):
        return str(option)
    paths = list(option) if isinstance(option, (list, tuple)) else []
    if not paths or not all(isinstance(p, (str, Path)) for p in paths):
        raise SnapshotEpisodeError(f"options['snapshot']: a path or a list of paths, not {option!r}")
    return str(paths[int(rng.integers(len(paths)))])


def read_moment(path: str, world: World, agents: list[str]) -> LineMoment:
    """The line's state in the snapshot at `path`, for an env on `world` with `agents`."""
    try:
        snapshot = read_snapshot(path)
    except SnapshotError as exc:
        raise SnapshotEpisodeError(str(exc)) from None
    scene = world.scene_model
    if snapshot.scene_name != scene.name or sorted(snapshot.arms) != sorted(agents):
        raise SnapshotEpisodeError(
            f"{path}: a snapshot of {snapshot.scene_name} with arms {', '.join(snapshot.arms)}; this env runs "
            f"{scene.name} with arms {', '.join(agents)}"
        )
    try:
        sim = read_sim_state(zlib.decompress(snapshot.states["sim"]))
        coordinator = read_coordinator_state(zlib.decompress(snapshot.states["coordinator"]))
        controllers = {a: read_controller_state(zlib.decompress(snapshot.states[a]), a) for a in agents}
    except (StateError, zlib.error, KeyError) as exc:
        raise SnapshotEpisodeError(f"{path}: {exc}") from None
    dispatcher = Dispatcher(scene)  # the env's own bookkeeping: it allocates nothing (its policy chooses)
    restore_dispatcher(dispatcher, coordinator.dispatcher)
    watcher = LineWatcher(scene)
    watcher.restore(sim.watcher)
    tracked = TrackedArms(world)  # the sim's trackers, over the env's world
    tracked.restore(sim.tracked)
    return LineMoment(
        path,
        snapshot.sim_time_s,
        sim.world,
        watcher,
        dispatcher,
        tracked,
        {name: list(link.goals) for name, link in sim.links.items()},
        controllers,
    )


def restore_world(world: World, moment: LineMoment) -> None:
    """The world as the line had it (its clock counted in this world's ticks, where the env runs another rate)."""
    ticks = round(moment.sim_time_s * world.scene_model.control_hz)
    world.restore_state(msgspec.structs.replace(moment.world, tick=ticks))


def apply_goals(tracked: TrackedArms, moment: LineMoment) -> None:
    """Goals the controllers had sent that the line would have applied at a later tick: applied now."""
    for arm, goals in moment.goals_not_applied.items():
        for msg in goals:
            goal = goal_from_message(msg)
            if not isinstance(goal, GoalResult):
                tracked.submit(arm, goal)


def resume_chooser(chooser, moment: LineMoment) -> None:
    """The allocate mode's arms as the line had them: skills, trackers (with the goals not yet applied), the task
    each works on; the orders each controller had received and not acted on, acted on now (a grant answered, a
    cancel, an assignment started when its skill is free: `TaskChooser.unstarted`)."""
    chooser.tracked = moment.tracked
    apply_goals(chooser.tracked, moment)
    now = chooser.world.sim_time_s
    for arm, c in moment.controllers.items():
        skill = chooser.skills[arm]
        restore_skill(skill, c.skill)
        task = chooser.ledger.tasks.get(c.task_id) if c.task_id is not None else None
        chooser.task_of[arm] = task.task_id if task is not None and skill.job is not None else None
        pending, grants = c.orders.pending, list(c.orders.grants)
        for order in c.orders.received:  # as the controller would act on them once the sim announced them
            if hasattr(order, "decision"):
                grants.append(order)
            elif order.task_id is None:
                pending = None
                if skill.active:
                    skill.cancel("cancelled by the coordinator")
            else:
                pending = order
        for g in grants:
            skill.on_grant(
                g.request_seq, g.decision, g.conflict_arm, now, g.start_time_s if g.start_time_s >= 0 else None
            )
        chooser.unstarted[arm] = pending
        if pending is not None:  # taken: no other task is offered to it meanwhile
            chooser.task_of[arm] = pending.task_id


def start_from_snapshot(env, option: object, feeder_seed: int) -> LineMoment:
    """An episode of `env` (scenario `line`) from a snapshot: the world and the line's bookkeeping as the line had
    them, the feeders drawing arrivals from `feeder_seed` from there on."""
    if env.scenario_name != "line":
        raise SnapshotEpisodeError(
            f"an episode from a line's snapshot needs scenario='line' (this env runs {env.scenario_name!r})"
        )
    path = pick_snapshot(option, env.np_random)
    # a world built afresh: PhysX put back into a world that has run keeps contact caches a fresh one has not, and
    # one seed must give one episode
    env.use_world(World(env.scene))
    moment = read_moment(path, env.world, list(env.possible_agents))
    restore_world(env.world, moment)
    env.world.reseed_feeders(feeder_seed)
    book = env.scenario.book
    book.watcher, book.dispatcher = moment.watcher, moment.dispatcher
    book.net_gain()  # rewards count the parts from the snapshot on
    return moment
