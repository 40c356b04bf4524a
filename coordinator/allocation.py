"""Who does which task: the allocator interface, the rules every allocator obeys, and three allocators (optimal,
auction, greedy).

An allocator sees the pending tasks, the arms (free or not) and where the parts
are, and returns (task id, arm) pairs. Every allocator obeys the same rules:
an arm takes a task only if it reaches both the pick point and the target;
a station serves one task at a time; and a conveyor stretch belongs to the arm
whose base is nearest (with a margin), so neighbours never reach for the same
spot of belt.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from scipy.optimize import linear_sum_assignment

from coordinator.reach_cache import REACH_IK, CachedReach  # noqa: F401 (re-exported: the allocators' public helpers)
from coordinator.tasks import CONVEYOR, Task
from robots.skills.pick_place import PickPlaceTiming
from robots.trajectory import JointSegment
from scenes.schema import Scene, Station

EARLIEST_ARRIVAL_S = 0.6  # the soonest an arm can be above a part
PICK_LEAD_S = 1.5  # about the time an arm needs to arrive above a part
GRASP_WINDOW_S = 1.5  # descend, close and lift: the part must stay in reach this long after arrival
HOVER_M = 0.1  # reach is checked this far above the part or the station surface
CELL_MARGIN_M = 0.06
# optimal: which tasks go first is earliest-due first; which arm takes each is the least total time
URGENCY_S_PER_S = 10.0
LOOKAHEAD_S, LOOKAHEAD_STEP_S = 4.0, 0.5  # optimal: a free arm may wait this long for a belt part riding into its reach
# a task with no deadline (a part at rest in a station) counts as due this long after it appeared
NO_DEADLINE_HORIZON_S = 30.0


@dataclass(frozen=True)
class ArmView:
    """What an allocator knows of an arm: where it stands, whether it can take work, what it reaches, its joints now."""

    name: str
    base_xyz: tuple[float, float, float]
    free: bool
    reach: CachedReach = field(compare=False, repr=False)
    q: tuple[float, ...] = ()
    free_in_s: float | None = None  # a busy arm: about when its task ends (None: unknown, so it is not planned for)
    live: bool = True  # False for a lost arm: it owns no stretch of the belt, so its neighbours take over its parts


@dataclass(frozen=True)
class PartView:
    """Where a part is now and how it moves (world frame, metres, m/s)."""

    position: np.ndarray
    velocity: np.ndarray


class Allocator(Protocol):
    """Chooses arms for pending tasks; must be deterministic for the same inputs."""

    name: str

    def allocate(
        self, tasks: list[Task], arms: list[ArmView], parts: dict[int, PartView], busy_stations: set[str]
    ) -> list[tuple[int, str]]: ...


def horizontal_distance_m(a, b) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


class Eligibility:
    """The rules every allocator shares: reach, and conveyor stretches owned by the nearest live arm."""

    def __init__(self, scene: Scene, arms: list[ArmView]) -> None:
        self.scene = scene
        self.bases = {a.name: a.base_xyz for a in arms if a.live}

    @staticmethod
    def in_reach(arm: ArmView, point) -> bool:
        return arm.reach(np.asarray(point, float) + [0.0, 0.0, HOVER_M])

    @staticmethod
    def reaches_station(arm: ArmView, station: Station) -> bool:
        """Whether `arm` reaches the middle of `station`'s surface (where it sets parts down and picks them up)."""
        return Eligibility.in_reach(arm, (*station.pose.xyz[:2], station.surface_z_m))

    def may_own_belt_points(self, arms: list[ArmView], points: np.ndarray, paired: bool = False) -> np.ndarray:
        """For points (..., 3): (..., arms), False where an arm certainly does not own the point (`owns_belt_point`),
        in one numpy pass; True where it may (a hair of slack, so the exact check alone decides the close calls).
        Lets an allocator skip the arms a belt part's pick point is not near, without a reach check for each.
        `paired`: points (..., arms, 3), each asked of its own arm only: (..., arms), the same answers as the
        diagonal of the unpaired call, for a tenth of its work on a long line."""
        points = np.asarray(points, float)[..., None, :2]
        live = list(self.bases)
        if len(live) < 2:
            return np.ones((*points.shape[: -3 if paired else -2], len(arms)), bool)
        xy = np.array([self.bases[n][:2] for n in live])
        to_live = np.hypot(*np.moveaxis(points - xy, -1, 0))  # (..., [arms,] live arms)
        nearest = to_live.argmin(axis=-1)[..., None]
        two = np.partition(to_live, 1, axis=-1)
        bases = np.array([a.base_xyz[:2] for a in arms])
        if paired:  # each point against its own arm: (..., arms)
            mine = np.hypot(*np.moveaxis(points[..., 0, :] - bases, -1, 0))
            nearest, two = nearest[..., 0], two[..., :2]
            first, second = two[..., 0], two[..., 1]
        else:
            mine = np.hypot(*np.moveaxis(points - bases, -1, 0))  # (..., arms)
            first, second = two[..., 0:1], two[..., 1:2]
        index = np.array([live.index(a.name) if a.name in self.bases else -1 for a in arms])  # -1: not a live arm
        others = np.where(nearest == index, second, first)  # each arm's nearest live other
        return mine + CELL_MARGIN_M <= others + 1e-9

    def owns_belt_point(self, arm: ArmView, point) -> bool:
        mine = horizontal_distance_m(arm.base_xyz, point)
        return all(
            mine + CELL_MARGIN_M <= horizontal_distance_m(b, point) for n, b in self.bases.items() if n != arm.name
        )

    def pick_point(self, task: Task, part: PartView) -> np.ndarray:
        """Where the arm will meet the part: ahead along the belt for conveyor parts."""
        if task.source == CONVEYOR:
            return lead_pick_point(part)
        return part.position

    def can_serve(self, arm: ArmView, task: Task, part: PartView) -> bool:
        if arm.name in task.refused_by:
            return False  # its skill found this part out of its reach as it lies
        if not self.reaches_station(arm, self.scene.station(task.target)):
            return False
        pick = self.pick_point(task, part)
        if task.source != CONVEYOR:
            return self.in_reach(arm, pick)
        if not self.owns_belt_point(arm, pick):
            return False
        soonest = part.position + part.velocity * EARLIEST_ARRIVAL_S
        latest = pick + part.velocity * GRASP_WINDOW_S
        return self.in_reach(arm, soonest) and self.in_reach(arm, latest)

    def cost_m(self, arm: ArmView, task: Task, part: PartView) -> float:
        """A distance-only cost: how far the pick point is from the arm's base."""
        return horizontal_distance_m(arm.base_xyz, self.pick_point(task, part))


def assign_min_cost(cost: np.ndarray) -> list[tuple[int, int]]:
    """Rows to columns at least total cost (scipy's LAP solver); infinite entries are never chosen."""
    if cost.size == 0:
        return []
    finite = np.isfinite(cost)
    if not finite.any():
        return []
    big = (np.abs(cost[finite]).max() + 1.0) * (min(cost.shape) + 1)
    rows, cols = linear_sum_assignment(np.where(finite, cost, big))
    return [(int(r), int(c)) for r, c in zip(rows, cols) if finite[r, c]]


class TimeCost:
    """Estimated seconds for an arm to finish a task from where it stands: joint travel at the skill's speeds
    (Pinocchio IK for the pick and place poses, velocity limits for the time) plus the fixed primitives."""

    def __init__(self, rules: Eligibility, timing: PickPlaceTiming | None = None) -> None:
        self.rules, self.t = rules, timing  # None: each arm's robot's own timing (arms of several models on one line)

    def timing(self, arm: ArmView) -> PickPlaceTiming:
        return self.t if self.t is not None else PickPlaceTiming.for_robot(arm.reach.top_down.spec)

    def __call__(self, arm: ArmView, task: Task, part: PartView) -> float:
        poses = self._poses(arm, task, part)
        if poses is None:
            return math.inf
        q_pick, q_place = poses
        t, v = self.timing(arm), arm.reach.velocity_limit
        q_now = np.asarray(arm.q, float) if arm.q else q_pick
        approach = float(np.max(np.abs(q_pick - q_now) / (v * t.approach_speed)))
        transfer = float(np.max(np.abs(q_place - q_pick) / (v * t.transfer_speed)))
        return approach + transfer + self._primitives_s(t)

    def cycle_s(self, arm: ArmView, task: Task, part: PartView) -> float:
        """The least time the arm is busy with a task: its transfer timed as the pick skill times it
        (`JointSegment.timed`: quintic, peaking at the skill's speed; the estimate above times moves at their peak
        speed throughout) and its primitives, the approach left out (it may be given the task right where it is)."""
        poses = self._poses(arm, task, part)
        if poses is None:
            return math.inf
        t = self.timing(arm)
        transfer = JointSegment.timed(poses[0], poses[1], 0.0, arm.reach.velocity_limit, t.transfer_speed).duration_s
        return transfer + self._primitives_s(t)

    def _poses(self, arm: ArmView, task: Task, part: PartView) -> tuple[np.ndarray, np.ndarray] | None:
        """The arm's joints above the pick and above the place, or None when it cannot serve the task."""
        if not self.rules.can_serve(arm, task, part):
            return None
        station = self.rules.scene.station(task.target)
        q_pick = arm.reach.joints(self.rules.pick_point(task, part) + [0.0, 0.0, HOVER_M])
        q_place = arm.reach.joints(np.array([*station.pose.xyz[:2], station.surface_z_m + HOVER_M]))
        return None if q_pick is None or q_place is None else (q_pick, q_place)

    @staticmethod
    def _primitives_s(t: PickPlaceTiming) -> float:
        """The grasp and place primitives, fixed in length: descend, close, lift; lower, release, retreat."""
        return t.descend_s + t.close_s + t.lift_s + t.lower_s + t.release_s + t.retreat_s


def open_candidates(tasks: list[Task], parts: dict[int, PartView], busy_stations: set[str]) -> list[Task]:
    """Pending tasks whose part is seen and whose stations are free, oldest first."""
    return [
        t
        for t in sorted(tasks, key=lambda t: (t.created_s, t.task_id))
        if t.part_id in parts and not busy_stations.intersection(t.stations)
    ]


def one_task_at_a_time(
    tasks: list[Task],
    arms: list[ArmView],
    parts: dict[int, PartView],
    busy_stations: set[str],
    score: Callable[[ArmView, Task, PartView], float],
) -> list[tuple[int, str]]:
    """Oldest part first, each to the free arm with the lowest score (infinite: cannot serve) over the part's
    candidate tasks (one per station it may go to: a sorted part, any bin of its colour); one task per station."""
    free = [a for a in arms if a.free]
    busy, out = set(busy_stations), []
    by_part: dict[int, list[Task]] = {}
    for task in open_candidates(tasks, parts, busy_stations):
        by_part.setdefault(task.part_id, []).append(task)
    for part_id, candidates in by_part.items():
        if not free:
            break
        options = [
            (score(a, t, parts[part_id]), a.name, k, a, t)
            for k, t in enumerate(candidates)
            if not busy.intersection(t.stations)
            for a in free
        ]
        if not options:
            continue
        value, _, _, arm, task = min(options, key=lambda o: o[:3])
        if not math.isfinite(value):
            continue
        out.append((task.task_id, arm.name))
        free.remove(arm)
        busy.update(task.stations)
    return out


class GreedyNearest:
    """The baseline: oldest part first, each to the nearest free arm that can serve it."""

    name = "greedy"

    def __init__(self, scene: Scene) -> None:
        self.scene = scene

    def allocate(
        self, tasks: list[Task], arms: list[ArmView], parts: dict[int, PartView], busy_stations: set[str]
    ) -> list[tuple[int, str]]:
        rules = Eligibility(self.scene, arms)

        def distance(arm: ArmView, task: Task, part: PartView) -> float:
            return rules.cost_m(arm, task, part) if rules.can_serve(arm, task, part) else math.inf

        return one_task_at_a_time(tasks, arms, parts, busy_stations, distance)


def due_s(task: Task) -> float:
    """When a task must be done by: its belt deadline, else a horizon after it appeared."""
    return task.deadline_s if task.deadline_s is not None else task.created_s + NO_DEADLINE_HORIZON_S


def later(part: PartView, dt_s: float) -> PartView:
    """Where a part will be in `dt_s` seconds (a belt part rides on; a part at rest stays)."""
    return PartView(part.position + part.velocity * dt_s, part.velocity) if dt_s else part


class OptimalAssignment:
    """All pending tasks against all arms at once, least total estimated time plus urgency
    (`linear_sum_assignment`): with more tasks than arms, a part about to ride out of reach goes before one
    that can wait, as it would be missed otherwise. A busy arm whose task ends soon is planned for too (its
    cost starts when it is free): only free arms are dispatched, but a free arm no longer takes a task that a
    soon-free arm does better while work only it can do waits."""

    name = "optimal"

    def __init__(self, scene: Scene) -> None:
        self.scene = scene

    def allocate(
        self, tasks: list[Task], arms: list[ArmView], parts: dict[int, PartView], busy_stations: set[str]
    ) -> list[tuple[int, str]]:
        rules = Eligibility(self.scene, arms)
        cost_of = TimeCost(rules)
        free = [a for a in arms if a.free]
        pending = open_candidates(tasks, parts, busy_stations)
        if not free or not pending:
            return []
        soon = [a for a in arms if not a.free and a.free_in_s is not None]
        columns = free + soon
        wait_s = [0.0] * len(free) + [a.free_in_s for a in soon]
        cost = self._cost_matrix(pending, columns, wait_s, parts, cost_of)
        coming = self._coming(pending, free, parts, cost, cost_of)  # belt parts a free arm can take once in its reach
        # more tasks than arms: the sooner due go first
        cost += URGENCY_S_PER_S * np.array([[due_s(t)] for t in pending])
        chosen = sorted(assign_min_cost(cost), key=lambda rc: (cost[rc], rc))
        busy, out = set(busy_stations), []
        for r, c in chosen:  # two tasks for one station in the same round: the cheaper goes first
            if c >= len(free) or (r, c) in coming or busy.intersection(pending[r].stations):
                continue  # a soon-free arm's task, or a free arm kept for a belt part still riding in
            busy.update(pending[r].stations)
            out.append((pending[r].task_id, free[c].name))
        return out

    @staticmethod
    def _cost_matrix(
        pending: list[Task], columns: list[ArmView], wait_s: list[float], parts: dict[int, PartView], cost_of: TimeCost
    ) -> np.ndarray:
        """(tasks, columns): the wait plus the estimated seconds of each task by each arm then (inf: cannot serve).
        A belt task is costed only for the arms that may own its pick point then (most arms of a long line
        cannot, and a reach check each would dominate the decision)."""
        cost = np.full((len(pending), len(columns)), math.inf)
        belt = [r for r, t in enumerate(pending) if t.source == CONVEYOR]
        may = np.ones(cost.shape, bool)
        if belt:
            picks = lead_pick_points([parts[pending[r].part_id] for r in belt], wait_s)
            may[belt] = cost_of.rules.may_own_belt_points(columns, picks, paired=True)  # each arm at its own wait
        for r, t in enumerate(pending):
            for c, (a, w) in enumerate(zip(columns, wait_s)):
                if may[r, c]:
                    cost[r, c] = w + cost_of(a, t, later(parts[t.part_id], w))
        return cost

    @staticmethod
    def _coming(
        pending: list[Task], free: list[ArmView], parts: dict[int, PartView], cost: np.ndarray, cost_of: TimeCost
    ) -> set[tuple[int, int]]:
        """Fill in, for each belt task a free arm cannot serve yet, the cost of waiting for its part to ride into
        reach and serving it then (`served_after_wait`); returns those (task row, arm column) pairs. An arm the
        assignment gives such a task stays free for it instead of starting work that can wait (a tray part) and
        losing the belt part meanwhile."""
        out = set()
        belt = [r for r, t in enumerate(pending) if t.source == CONVEYOR]  # a part at rest does not come nearer
        if not belt:
            return out
        picks = lead_pick_points([parts[pending[r].part_id] for r in belt], LOOKAHEAD_WAITS_S)
        may_all = cost_of.rules.may_own_belt_points(free, picks)  # (belt rows, waits, free arms)
        comes_all = may_all.any(axis=1)
        for c, a in enumerate(free):
            may, comes = may_all[..., c], comes_all[:, c]
            for row, r in enumerate(belt):
                if math.isfinite(cost[r, c]) or not comes[row]:
                    continue  # served now, or its part never rides onto this arm's stretch in time
                found = served_after_wait(a, pending[r], parts[pending[r].part_id], cost_of, may[row])
                if found is not None:
                    cost[r, c] = sum(found)
                    out.add((r, c))
        return out


LOOKAHEAD_WAITS_S = tuple(k * LOOKAHEAD_STEP_S for k in range(1, int(LOOKAHEAD_S / LOOKAHEAD_STEP_S) + 1))


def lead_pick_point(part: PartView) -> np.ndarray:
    """Where an arm meets a belt part (`Eligibility.pick_point` of a belt task); `lead_pick_points` for many."""
    return part.position + part.velocity * PICK_LEAD_S


def lead_pick_points(parts: list[PartView], waits_s) -> np.ndarray:
    """(parts, waits, 3): `lead_pick_point` of each part after each wait (`later`), in one numpy pass (the same
    arithmetic, so the same floats)."""
    position = np.array([p.position for p in parts], float)[:, None, :]
    velocity = np.array([p.velocity for p in parts], float)[:, None, :]
    return position + velocity * np.asarray(waits_s, float)[None, :, None] + velocity * PICK_LEAD_S


def served_after_wait(
    arm: ArmView, task: Task, part: PartView, cost_of: TimeCost, may: np.ndarray | None = None
) -> tuple[float, float] | None:
    """For a belt task `arm` cannot serve yet: the least wait (within `LOOKAHEAD_S`, in `LOOKAHEAD_STEP_S` steps)
    after which its part has ridden into the arm's reach, and the estimated seconds of the task then. None for a
    part at rest, a station out of the arm's reach wherever the part is, or a part that does not come in time.
    `may`: per wait, whether the arm may own the pick point then (`Eligibility.may_own_belt_points`), if known."""
    if task.source != CONVEYOR:
        return None
    if may is None:
        may = cost_of.rules.may_own_belt_points([arm], lead_pick_points([part], LOOKAHEAD_WAITS_S)[0])[:, 0]
    if not may.any():
        return None  # its pick point never comes onto this arm's stretch of belt in time
    if not Eligibility.reaches_station(arm, cost_of.rules.scene.station(task.target)):
        return None
    for wait, maybe in zip(LOOKAHEAD_WAITS_S, may):
        if not maybe:
            continue
        ahead = cost_of(arm, task, later(part, wait))
        if math.isfinite(ahead):
            return wait, ahead
    return None


class Auction:
    """Tasks auctioned one at a time, oldest first; every free arm bids its estimated time, the lowest bid wins
    (as Open-RMF's dispatcher does with fleet adapters' bids)."""

    name = "auction"

    def __init__(self, scene: Scene) -> None:
        self.scene = scene

    def allocate(
        self, tasks: list[Task], arms: list[ArmView], parts: dict[int, PartView], busy_stations: set[str]
    ) -> list[tuple[int, str]]:
        return one_task_at_a_time(tasks, arms, parts, busy_stations, TimeCost(Eligibility(self.scene, arms)))


ALLOCATORS: dict[str, type] = {"optimal": OptimalAssignment, "auction": Auction, "greedy": GreedyNearest}


def make_allocator(name: str, scene: Scene) -> Allocator:
    """A built-in allocator by name; an unknown name is an error that lists the valid ones (plug-ins as well:
    `coordinator.allocator_plugins.make_any_allocator` makes those too)."""
    if name not in ALLOCATORS:
        raise ValueError(f"unknown allocator {name!r}; valid allocators: {', '.join(ALLOCATORS)}")
    return ALLOCATORS[name](scene)
