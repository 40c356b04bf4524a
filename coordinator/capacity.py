"""What a line could do at best: an upper bound on its throughput, from the scene and the arms' task times.

A small linear programme (`scipy.optimize.linprog`): each part type arrives at its feeder's mean
rate and must make every hop of its route (source to first station, station to station); a hop is
done by any arm that can serve it (the coordinator's own `Eligibility`: reach, and the stretch of
belt each arm owns), keeping that arm busy at least as long as the pick skill's own transfer and
primitives take (`TimeCost.cycle_s`; the approach left out: the arm may already be there). No arm may be busy more than
all the time, no
station may serve more than one task at a time, and an assembly takes as many parts of each feeder
it assembles (no top is finished without its base, nor a base without its top). The bound is the most parts a minute
the line can complete; the binding
arm or station is its bottleneck. Every time is an underestimate, so the bound is an upper one.
After a run, the same programme with the hop times the run measured (assignment to the part at
rest, per arm) says what the line could do with arms as fast as they really were, and with the
parts the run's feeders really released in time to be finished (`finishable_arrivals`) in place of
the mean rates, what this run could have completed at best: a few dozen random arrivals differ
from the mean by up to half.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linprog

from coordinator.allocation import ArmView, CachedReach, Eligibility, PartView, TimeCost
from coordinator.tasks import CONVEYOR, Task
from robots.registry import get_robot
from scenes.schema import Scene

BELT_SAMPLE_M = 0.05  # belt pick points are tried this far apart


@dataclass(frozen=True)
class Hop:
    """One move of a part type's route: from `source` (the conveyor or a station) to station `target`; `stage` is its
    place in the route (a sorted part's one stage has a hop per station that takes its colour: any of them will do)."""

    feeder: str
    type_index: int
    source: str
    target: str
    stage: int = 0


@dataclass(frozen=True)
class HopModel:
    """The least time each arm is busy with each hop, (arms, hops) in seconds (inf: the arm cannot serve the hop): its
    moves timed as the pick skill times them, its approach left out (it may be given the task right where the part
    is, even on its way home); the least time from a part's release to each hop done (a belt part rides from the
    drop point to where the arm meets it first); and for a belt hop, when after its release the coordinator's
    rules let the arm be given the part (`window_s[..., 0]` to `window_s[..., 1]`, widened by a sample step each way;
    NaN: never, or not from the belt); `after_place_s`, per arm: the end of its busy time that comes after the
    part is set down (the retreat), which the part's own time leaves out. IK at every belt sample: worked out once,
    reused."""

    seconds: np.ndarray
    from_release_s: np.ndarray
    window_s: np.ndarray
    after_place_s: np.ndarray

    @property
    def to_rest_s(self) -> np.ndarray:
        """(arms, hops): the least time from an arm being given a part to that part set down."""
        return self.seconds - self.after_place_s[:, None]


@dataclass
class CapacityBound:
    """The line's best throughput (parts a minute), what limits it, and each arm's and station's busy fraction there."""

    arrivals_per_min: float
    throughput_bound_per_min: float
    bottleneck: str  # an arm or station id, or "arrivals" when the line can take every part that comes
    bottleneck_busy_fraction: float  # of the busiest arm or station (the bottleneck when it limits)
    busiest: str = ""  # the busiest arm or station at the bound, whether or not it limits the line
    arm_busy: dict[str, float] = field(default_factory=dict)
    station_busy: dict[str, float] = field(default_factory=dict)
    unservable: list[str] = field(default_factory=list)  # hops no arm can do: their parts can never be completed
    idle_arms: list[str] = field(default_factory=list)  # arms that can do no hop at all: they stand idle all run
    model: HopModel | None = field(default=None, repr=False, compare=False)  # the model's hop times, to reuse

    def as_dict(self) -> dict:
        return {
            "arrivals_per_min": round(self.arrivals_per_min, 3),
            "throughput_bound_per_min": round(self.throughput_bound_per_min, 3),
            "bottleneck": self.bottleneck,
            "bottleneck_busy_fraction": round(self.bottleneck_busy_fraction, 3),
            "busiest": self.busiest,
            "arm_busy_at_bound": {a: round(v, 3) for a, v in self.arm_busy.items()},
            "station_busy_at_bound": {s: round(v, 3) for s, v in self.station_busy.items()},
            "unservable_hops": self.unservable,
        }


def arrival_rate_per_s(scene: Scene, feeder_name: str) -> float:
    """A feeder's mean release rate: its Poisson rate, or its schedule's count over its span."""
    arrival = scene.feeder(feeder_name).arrival
    if arrival.rate_per_min is not None:
        return arrival.rate_per_min / 60.0
    times = arrival.schedule_s or []
    return len(times) / max(max(times, default=0.0), 1.0)


def route_hops(scene: Scene) -> list[Hop]:
    """Every hop of every part type's route; a sorted part's one hop to each station of its colour (the coordinator
    sends it to whichever of them the arm that takes it reaches)."""
    hops = []
    for f in scene.feeders:
        for t in range(len(f.parts)):
            stations = scene.route(f.name, t)
            for stage, (source, target) in enumerate(zip([f.into, *stations], stations)):
                hops.append(Hop(f.name, t, source, target, stage))
            hops += [Hop(f.name, t, f.into, other, 0) for other in scene.stations_for_colour(f.name, t)[1:]]
    return hops


def _stages(hops: list[Hop]) -> dict[tuple[str, int, int], list[int]]:
    """The hops (by index) of each route stage of each part type: one of them must be made per part."""
    out: dict[tuple[str, int, int], list[int]] = {}
    for j, h in enumerate(hops):
        out.setdefault((h.feeder, h.type_index, h.stage), []).append(j)
    return out


def arm_views(scene: Scene, reach: dict[str, CachedReach] | None = None) -> list[ArmView]:
    """Every arm at its home pose, free, with its reach (`reach`: caches to share, e.g. the coordinator's)."""
    reach = reach or {a.name: CachedReach.of(a) for a in scene.arms}
    return [ArmView(a.name, a.base.xyz, True, reach[a.name], tuple(get_robot(a.model).home_q)) for a in scene.arms]


def pick_points(scene: Scene, hop: Hop) -> list[tuple[float, PartView]]:
    """Where a part of this hop may be picked, each with the least seconds it rides from its release to there: along
    the belt every `BELT_SAMPLE_M`, or at its source station (no ride)."""
    part = scene.feeder(hop.feeder).parts[hop.type_index]
    half = part.size_m[2] / 2
    if hop.source != CONVEYOR:
        s = scene.station(hop.source)
        return [(0.0, PartView(np.array([s.pose.xyz[0], s.pose.xyz[1], s.surface_z_m + half]), np.zeros(3)))]
    c = scene.conveyor
    velocity = np.array(c.direction) * c.speed_m_per_s
    drop_m = min(scene.drop_along_m(scene.feeder(hop.feeder)), c.length_m)
    if c.speed_m_per_s <= 0.0:  # a stopped belt: a part stays where it is dropped
        x, y, z = c.point_at(drop_m, 0.0)
        return [(0.0, PartView(np.array([x, y, z + half]), velocity))]
    n = max(2, int(c.length_m / BELT_SAMPLE_M) + 1)
    out = []
    for along in np.linspace(0.0, c.length_m, n):
        if along < drop_m - 2 * BELT_SAMPLE_M:  # well upstream of its infeed: no part of this feeder is ever there
            continue  # (the samples just before it count as at it, as the belt's start always has)
        x, y, z = c.point_at(float(along), 0.0)
        out.append(
            (
                max(0.0, float(along) - drop_m) / c.speed_m_per_s,
                PartView(np.array([x, y, z + half]), velocity),
            )
        )
    return out


def hop_seconds(
    scene: Scene,
    views: list[ArmView],
    hops: list[Hop],
    measured_s: dict[tuple[str, str, str], float] | None = None,
    model: HopModel | None = None,
) -> np.ndarray:
    """(arms, hops): the least time each arm needs for each hop (inf: it cannot serve it); where `measured_s` has
    the mean time an arm took for a (source, target) hop in a run, that time instead of the model's. `model`:
    the model worked out before (`hop_model`), reused."""
    out = (model or hop_model(scene, views, hops)).seconds.copy()
    for j, hop in enumerate(hops):
        for i, view in enumerate(views):
            seen = (measured_s or {}).get((view.name, hop.source, hop.target))
            if seen is not None and np.isfinite(out[i, j]):
                out[i, j] = seen
    return out


def hop_model(scene: Scene, views: list[ArmView], hops: list[Hop]) -> HopModel:
    """Each arm's least busy time for each hop, the least time from a part's release to it done, and its belt window."""
    cost = TimeCost(Eligibility(scene, views))
    seconds = np.full((len(views), len(hops)), math.inf)
    from_release = seconds.copy()
    window = np.full((len(views), len(hops), 2), math.nan)
    step_s = BELT_SAMPLE_M / scene.conveyor.speed_m_per_s if scene.conveyor and scene.conveyor.speed_m_per_s else 0.0
    after_place = np.array([cost.timing(v).retreat_s for v in views])
    for j, hop in enumerate(hops):
        task = Task(0, 0, hop.source, hop.target, 0.0)
        points = pick_points(scene, hop)
        for i, view in enumerate(views):
            times = [(ride_s, cost.cycle_s(view, task, p)) for ride_s, p in points]
            seconds[i, j] = min((t for _, t in times), default=math.inf)
            from_release[i, j] = min((r + t for r, t in times), default=math.inf) - after_place[i]
            rides = [r for r, t in times if math.isfinite(t)]
            if hop.source == CONVEYOR and rides:
                window[i, j] = (max(0.0, min(rides) - step_s), max(rides) + step_s)
    return HopModel(seconds, from_release, window, after_place)


def measured_hop_seconds(tasks: list) -> dict[tuple[str, str, str], float]:
    """Mean seconds from assignment to the part at rest, per (arm, source, target), over a run's done tasks."""
    times: dict[tuple[str, str, str], list[float]] = {}
    for t in tasks:
        if t.state.value == "done" and t.arm is not None and t.assigned_s is not None and t.done_s is not None:
            times.setdefault((t.arm, t.source, t.target), []).append(t.done_s - t.assigned_s)
    return {k: float(np.mean(v)) for k, v in times.items()}


def _balanced(
    x: np.ndarray,
    best_per_s: float,
    n_r: int,
    a_ub: np.ndarray,
    b_ub: list[float],
    labels: list[str],
    a_eq: list,
    b_eq: list,
    bounds: list,
) -> np.ndarray:
    """Of the ways to reach the bound, one that loads the busiest arm or station least (a second programme: the
    first's answer is any vertex, and with several stations for a part it may heap the work on a few arms); the
    first answer if this one does not solve."""
    n = a_ub.shape[1]
    loaded = [k for k, label in enumerate(labels) if label]  # arms and stations; the assembly rows keep their bound
    rows = np.hstack([a_ub, np.zeros((len(labels), 1))])
    rows[loaded, -1] = -1.0  # usage - z <= 0
    limits = [0.0 if label else b for label, b in zip(labels, b_ub)]
    keep = np.r_[-np.ones(n_r), np.zeros(n - n_r + 1)]  # completed parts at least the bound (less a hair)
    result = linprog(
        np.r_[np.zeros(n), 1.0],
        A_ub=np.vstack([rows, keep]),
        b_ub=[*limits, -best_per_s * (1 - 1e-9)],
        A_eq=np.hstack([np.array(a_eq), np.zeros((len(a_eq), 1))]) if a_eq else None,
        b_eq=b_eq or None,
        bounds=[*bounds, (0.0, 1.0)],
        method="highs",
    )
    return result.x[:n] if result.status == 0 else x


def least_route_seconds(scene: Scene, model: HopModel) -> dict[tuple[str, int], float]:
    """The least time from a part's release to its whole route done, every stage by its quickest arm, a belt part
    met where it first can be (inf: no arm can make one of its stages)."""
    out: dict[tuple[str, int], float] = {}
    for (feeder, type_index, stage), js in _stages(route_hops(scene)).items():
        times = model.from_release_s if stage == 0 else model.to_rest_s
        out[(feeder, type_index)] = out.get((feeder, type_index), 0.0) + float(times[:, js].min(initial=math.inf))
    return out


def finishable_arrivals(scene: Scene, arrived: list[tuple[str, int, float]], end_s: float, model: HopModel) -> Counter:
    """Of the parts that arrived (feeder, type, sim time), how many of each type arrived early enough to be finished by
    `end_s` if an arm took each at once, every hop by its quickest arm."""
    least = least_route_seconds(scene, model)
    return Counter((f, t) for f, t, at_s in arrived if at_s + least.get((f, t), math.inf) <= end_s)


@dataclass(frozen=True)
class WindowCap:
    """An arm alone on its stretch of belt for some part types (no other arm can take them): of the parts of those types
    that arrived (`arrived`), the most it could take (`at_most`), each given to it inside the part's window on the
    belt and each keeping it busy at least its least hop time."""

    arm: str
    types: tuple[tuple[str, int], ...]
    arrived: int
    at_most: int


def belt_window_caps(
    scene: Scene, arrived: list[tuple[str, int, float]], end_s: float, model: HopModel
) -> list[WindowCap]:
    """For each arm that alone serves some belt part types, the most of this run's parts of those types it could take:
    the most jobs one machine starts inside their windows, each start at least the least busy time after the last
    and early enough to be done by `end_s`. Windows on one belt are one length, so a part that arrives later is due
    later and a dynamic programme in arrival order is exact; an arm whose windows are not so gets no cap."""
    hops = route_hops(scene)
    names = [a.name for a in scene.arms]
    alone: dict[int, list[tuple[tuple[str, int], list[int]]]] = {}
    for (feeder, type_index, stage), js in _stages(hops).items():
        servers = [i for i in range(len(names)) if np.isfinite(model.seconds[i, js]).any()]
        if stage == 0 and hops[js[0]].source == CONVEYOR and len(servers) == 1:
            alone.setdefault(servers[0], []).append(((feeder, type_index), js))
    out = []
    for i, kinds in alone.items():
        busy_s = min(float(model.seconds[i, js].min()) for _, js in kinds)
        placed_s = busy_s - float(model.after_place_s[i])  # the last part must be set down by the end, not the arm back
        spans = {
            key: (float(np.nanmin(model.window_s[i, js, 0])), float(np.nanmax(model.window_s[i, js, 1])))
            for key, js in kinds
        }
        jobs = sorted(
            (at_s + spans[(f, t)][0], min(at_s + spans[(f, t)][1], end_s - placed_s))
            for f, t, at_s in arrived
            if (f, t) in spans
        )
        if any(later[1] < earlier[1] for earlier, later in zip(jobs, jobs[1:])):
            continue  # windows not in arrival order: the programme would not be exact
        least_end = [-math.inf] + [math.inf] * len(jobs)  # least_end[c]: the soonest c of the parts so far are done
        for release_s, due_s in jobs:
            for c in range(len(jobs) - 1, -1, -1):
                start = max(release_s, least_end[c])
                if start <= due_s and start + busy_s < least_end[c + 1]:
                    least_end[c + 1] = start + busy_s
        taken = max(c for c, end in enumerate(least_end) if end < math.inf)
        out.append(WindowCap(names[i], tuple(k for k, _ in kinds), len(jobs), taken))
    return out


def _short_pairing(pairings: list[tuple[str, list[int], list[int]]], x: np.ndarray, types: list, rate: dict) -> str:
    """The fixture whose assembly waits for a part that comes too seldom ("fixture_0 pairing"), when that and no busy
    arm or station limits the line: of its feeders, one's parts are all taken and another's are not."""
    for station, first, other in pairings:
        short = [all(x[k] >= rate[types[k]] - 1e-9 for k in side) for side in (first, other)]
        spare = [any(x[k] < rate[types[k]] - 1e-9 for k in side) for side in (first, other)]
        if (short[0] and spare[1]) or (short[1] and spare[0]):
            return f"{station} pairing"
    return ""


@dataclass
class _Programme:
    """The capacity bound's linear programme. Variables: r[type] (parts completed a second), then x[arm, hop] (hops
    done a second) where the arm can serve the hop."""

    pairs: list[tuple[int, int]]
    a_eq: list = field(default_factory=list)
    b_eq: list = field(default_factory=list)
    a_ub: list = field(default_factory=list)
    b_ub: list = field(default_factory=list)
    labels: list[str] = field(default_factory=list)
    pairings: list = field(default_factory=list)  # (fixture, first feeder's types, a later feeder's types)
    limit_rows: list = field(default_factory=list)  # (name, row index) of each cap on some part types together


def _programme(
    scene: Scene,
    views: list[ArmView],
    hops: list[Hop],
    seconds: np.ndarray,
    types: list[tuple[str, int]],
    stages: dict[tuple[str, int, int], list[int]],
    type_limits: list[tuple[str, tuple[tuple[str, int], ...], float]] | None,
) -> _Programme:
    """The programme's rows: each stage made as often as its type completes, each arm and station busy at most all
    the time, an assembly's parts paired, and the caps on some part types together."""
    pairs = [(i, j) for i in range(len(views)) for j in range(len(hops)) if np.isfinite(seconds[i, j])]
    n_r = len(types)
    index = {p: n_r + k for k, p in enumerate(pairs)}
    n = n_r + len(pairs)
    lp = _Programme(pairs)
    for (feeder, type_index, _), js in stages.items():  # every stage of a type is made as often as that type completes
        row = np.zeros(n)
        row[types.index((feeder, type_index))] = -1.0
        for j in js:
            for i in range(len(views)):
                if (i, j) in index:
                    row[index[(i, j)]] = 1.0
        lp.a_eq.append(row)
        lp.b_eq.append(0.0)
    for i, view in enumerate(views):  # an arm works at most all the time
        row = np.zeros(n)
        for j in range(len(hops)):
            if (i, j) in index:
                row[index[(i, j)]] = seconds[i, j]
        lp.a_ub.append(row), lp.b_ub.append(1.0), lp.labels.append(view.name)
    for station in scene.stations:  # a station serves one task at a time
        row = np.zeros(n)
        for (i, j), k in index.items():
            if station.name in (hops[j].source, hops[j].target):
                row[k] = seconds[i, j]
        if row.any():
            lp.a_ub.append(row), lp.b_ub.append(1.0), lp.labels.append(station.name)
    for station in scene.stations:  # an assembly takes one part of each feeder it assembles: as many of each
        first = [types.index(t) for t in types if t[0] == station.assembles[0]] if station.assembles else []
        for later in station.assembles[1:]:
            other = [types.index(t) for t in types if t[0] == later]
            row = np.zeros(n)
            row[first], row[other] = 1.0, -1.0
            lp.a_eq.append(row), lp.b_eq.append(0.0)
            lp.pairings.append((station.name, first, other))
    for name, keys, most_per_s in type_limits or []:
        row = np.zeros(n)
        row[[types.index(k) for k in keys if k in types]] = 1.0
        lp.limit_rows.append((name, len(lp.a_ub)))
        lp.a_ub.append(row), lp.b_ub.append(most_per_s), lp.labels.append("")
    return lp


def _solve(
    scene: Scene, lp: _Programme, type_bounds: list[tuple[float, float]]
) -> tuple[float, np.ndarray, np.ndarray]:
    """The programme solved: the most parts a minute, the rates of its most even solution, and how busy each arm
    and station (each upper-bound row) is at it."""
    n_r, pairs, a_eq, b_eq, a_ub, b_ub = len(type_bounds), lp.pairs, lp.a_eq, lp.b_eq, lp.a_ub, lp.b_ub
    bounds = type_bounds + [(0.0, None)] * len(pairs)
    result = linprog(
        -np.r_[np.ones(n_r), np.zeros(len(pairs))],
        A_ub=np.array(a_ub) if a_ub else None,
        b_ub=b_ub or None,
        A_eq=np.array(a_eq) if a_eq else None,
        b_eq=b_eq or None,
        bounds=bounds,
        method="highs",
    )
    if result.status != 0:
        raise RuntimeError(f"the capacity programme of {scene.name} did not solve: {result.message}")
    best = float(-result.fun) * 60.0
    x = _balanced(result.x, best / 60.0, n_r, np.array(a_ub), b_ub, lp.labels, a_eq, b_eq, bounds) if a_ub else result.x
    return best, x, (np.array(a_ub) @ x) if a_ub else np.zeros(0)


def _part_types(scene: Scene, hops: list[Hop]) -> list[tuple[str, int]]:
    """Every (feeder, part type index) of the scene, sorted."""
    return sorted(
        {(h.feeder, h.type_index) for h in hops} | {(f.name, t) for f in scene.feeders for t in range(len(f.parts))}
    )


def capacity_bound(
    scene: Scene,
    measured_s: dict[tuple[str, str, str], float] | None = None,
    reach: dict[str, CachedReach] | None = None,
    model: HopModel | None = None,
    arrivals_per_s: dict[tuple[str, int], float] | None = None,
    type_limits: list[tuple[str, tuple[tuple[str, int], ...], float]] | None = None,
) -> CapacityBound:
    """The throughput bound of a scene (parts completed a minute), by linear programming over arms, hops and stations;
    with `measured_s` (from `measured_hop_seconds`), the hop times a run measured replace the model's; `reach` shares
    the arms' reach caches (the coordinator's) instead of building new ones; `model` the model's hop times
    (`CapacityBound.model` of an earlier bound of the same scene); `arrivals_per_s`, per (feeder, type), replaces
    the feeders' mean rates (a run's own arrivals: `finishable_arrivals` over its length); `type_limits` caps the
    completions of some part types together ((name, types, parts a second): an arm's belt window,
    `belt_window_caps`)."""
    hops = route_hops(scene)
    views = arm_views(scene, reach)
    model = model or hop_model(scene, views, hops)
    seconds = hop_seconds(scene, views, hops, measured_s, model)
    types = _part_types(scene, hops)
    if not types:  # no feeder: nothing ever arrives, nothing to bound
        return CapacityBound(0.0, 0.0, "arrivals", 0.0, model=model)
    if arrivals_per_s is None:
        rate = {(f, t): arrival_rate_per_s(scene, f) / len(scene.feeder(f).parts) for f, t in types}
    else:
        rate = {k: arrivals_per_s.get(k, 0.0) for k in types}
    arrivals = 60.0 * sum(rate.values())
    stages = _stages(hops)
    dead = [js for js in stages.values() if not np.isfinite(seconds[:, js]).any()]  # no arm can make any hop of it
    unservable = [
        f"{hops[js[0]].feeder}[{hops[js[0]].type_index}]: {hops[js[0]].source} -> "
        f"{' or '.join(hops[j].target for j in js)}"
        for js in dead
    ]
    lp = _programme(scene, views, hops, seconds, types, stages, type_limits)
    unreachable = {(hops[js[0]].feeder, hops[js[0]].type_index) for js in dead}
    best, x, usage = _solve(scene, lp, [(0.0, 0.0 if t in unreachable else rate[t]) for t in types])
    labels, b_ub, pairings, limit_rows = lp.labels, lp.b_ub, lp.pairings, lp.limit_rows
    arm_busy = {v.name: float(usage[i]) for i, v in enumerate(views)}
    station_busy = {labels[k]: float(usage[k]) for k in range(len(views), len(labels)) if labels[k]}
    busiest = max([*arm_busy.items(), *station_busy.items()], key=lambda kv: kv[1], default=("", 0.0))
    limited = best < arrivals - 1e-6 - 60.0 * sum(rate[t] for t in unreachable)
    capped = next((name for name, k in limit_rows if usage[k] >= b_ub[k] - 1e-9), "")
    bottleneck = (
        (busiest[0] if busiest[1] >= 1.0 - 1e-6 else _short_pairing(pairings, x, types, rate) or capped or busiest[0])
        if limited
        else "arrivals"
    )
    return CapacityBound(
        arrivals,
        max(0.0, best) + 0.0,  # a solver's -0.0 reads as a negative bound
        bottleneck,
        busiest[1],
        busiest[0],
        arm_busy,
        station_busy,
        unservable,
        [v.name for i, v in enumerate(views) if not np.isfinite(seconds[i]).any()],
        model=model,
    )
