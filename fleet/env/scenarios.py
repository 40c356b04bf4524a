"""What each env task asks of the arms: how the cell is set up, where each claw should go next, and the task's reward.

A task sees the world after each step and returns, per arm, its task reward and
whether it succeeded; the env adds the terms every task shares (team, near
misses, contacts, joint limits, effort). Dense terms use `1 - tanh(5 d)` of a
distance `d` in metres, as ManiSkill's dense rewards do, so every term stays in [0, 1].
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np

from fleet.env.line_bookkeeping import LineBookkeeping
from fleet.robot_tools.trials import part_in_bin
from fleet.sim.world import World
from scenes.schema import Arrival, Scene, Station

HOVER_M = 0.10  # a carried part's goal point is this far above the station's surface
LIFTED_M = 0.03  # a part is lifted when its bottom is this far above where it started
SUCCESS_BONUS = 5.0


def closeness(distance_m: float) -> float:
    """1 at zero distance, towards 0 far away."""
    return 1.0 - math.tanh(5.0 * distance_m)


def without_arrivals(scene: Scene, belt_speed_m_per_s: float | None = None) -> Scene:
    """The scene with its feeders silent (the task places its own parts) and, if given, the belt at a new speed."""
    feeders = [f.model_copy(update={"arrival": Arrival(schedule_s=[])}) for f in scene.feeders]
    update: dict = {"feeders": feeders}
    if belt_speed_m_per_s is not None and scene.conveyor is not None:
        update["conveyor"] = scene.conveyor.model_copy(update={"speed_m_per_s": belt_speed_m_per_s})
    return scene.model_copy(update=update)


def above(station: Station) -> np.ndarray:
    return np.array([station.pose.xyz[0], station.pose.xyz[1], station.surface_z_m + HOVER_M])


def belt_spot_near(
    scene: Scene, xyz: tuple[float, float, float], along_m: float = 0.0, lateral_m: float = 0.0
) -> tuple[float, float, float]:
    """The belt-top point nearest a base, moved `along_m` along the belt and `lateral_m` across it."""
    c = scene.conveyor
    cos, sin = math.cos(c.pose.yaw_rad), math.sin(c.pose.yaw_rad)
    s = (xyz[0] - c.pose.xyz[0]) * cos + (xyz[1] - c.pose.xyz[1]) * sin
    s = min(max(s + along_m, 0.05), c.length_m - 0.05)
    return c.point_at(s, lateral_m)


class Scenario(ABC):
    """One task of the env. `prepare` shapes the scene before the world is built; `reset` sets an episode up."""

    name: str
    physics_hz: float = 500.0  # grasps need contact resolution at this rate

    def __init__(self, agents: list[str]) -> None:
        self.agents = agents
        self.home_tool: dict[str, np.ndarray] = {}

    def prepare(self, scene: Scene) -> Scene:
        return scene

    def check(self, scene: Scene) -> None:
        """Raise ValueError naming what the scene lacks for this task."""

    @abstractmethod
    def reset(self, world: World, rng: np.random.Generator) -> None: ...

    def on_tick(self, world: World) -> None:
        """After every control tick (the line's bookkeeping)."""

    @abstractmethod
    def target(self, agent: str, world: World) -> np.ndarray:
        """Where `agent`'s claw should go now (world frame)."""

    @abstractmethod
    def progress(
        self, world: World, tools: dict[str, np.ndarray], targets: dict[str, np.ndarray]
    ) -> tuple[dict[str, float], dict[str, bool]]:
        """Per arm: this step's task reward, and whether the task counts as achieved (`tools` and `targets`: each
        claw's position and `target` now, as the env computed them for this step's observations)."""


class Reach(Scenario):
    """Each arm's claw to its own target, circling a point in front of it."""

    name = "reach"
    physics_hz = 100.0  # no grasp-grade contacts needed
    SOLVER_POSITION_ITERATIONS = 4  # PhysX's default: over 200 random-action steps the claws' paths stay within
    # 0.3 mm of those with the 20 iterations grasps need, for half the physics time
    ORBIT_M = 0.05
    RAD_PER_S = 0.5
    SUCCESS_M = 0.03

    def prepare(self, scene: Scene) -> Scene:
        quiet = without_arrivals(scene, belt_speed_m_per_s=0.0)  # nothing rides the belt
        return quiet.model_copy(update={"solver_position_iterations": self.SOLVER_POSITION_ITERATIONS})

    def reset(self, world: World, rng: np.random.Generator) -> None:
        self.centres, self.phases = {}, {}
        for a in self.agents:
            arm = world.scene_model.arm(a)
            forward, side, up = rng.uniform([0.25, -0.15, 0.12], [0.45, 0.15, 0.30])
            c, s = math.cos(arm.base.yaw_rad), math.sin(arm.base.yaw_rad)
            self.centres[a] = np.array(
                [arm.base.xyz[0] + c * forward - s * side, arm.base.xyz[1] + s * forward + c * side, up]
            )
            self.phases[a] = float(rng.uniform(0, 2 * math.pi))

    def target(self, agent: str, world: World) -> np.ndarray:
        angle = self.phases[agent] + self.RAD_PER_S * world.sim_time_s
        x, y, z = self.centres[agent]
        return np.array([x + self.ORBIT_M * math.cos(angle), y + self.ORBIT_M * math.sin(angle), z])

    def progress(self, world, tools, targets):
        distance = {a: math.dist(tools[a], targets[a]) for a in self.agents}
        success = {a: d < self.SUCCESS_M for a, d in distance.items()}
        return {a: -distance[a] + (1.0 if success[a] else 0.0) for a in self.agents}, success


class PickPlace(Scenario):
    """Each arm its own part, set on the stopped belt in front of it, into the station nearest its base."""

    name = "pick_place"

    def check(self, scene: Scene) -> None:
        if scene.conveyor is None or not scene.feeders or not scene.stations:
            raise ValueError(
                f"task pick_place needs a scene with a conveyor, a feeder and stations; {scene.name} lacks one"
            )

    def prepare(self, scene: Scene) -> Scene:
        return without_arrivals(scene, belt_speed_m_per_s=0.0)

    def reset(self, world: World, rng: np.random.Generator) -> None:
        scene = world.scene_model
        feeder = scene.feeders[0]
        self.part, self.goal, self.start_z = {}, {}, {}
        for i, a in enumerate(self.agents):
            base = scene.arm(a).base.xyz
            self.goal[a] = min(
                scene.stations, key=lambda s: math.hypot(s.pose.xyz[0] - base[0], s.pose.xyz[1] - base[1])
            )
            spot = belt_spot_near(scene, base, float(rng.uniform(-0.06, 0.06)), float(rng.uniform(-0.03, 0.03)))
            self.part[a] = world.place_part(
                feeder.name, i % len(feeder.parts), spot, float(rng.uniform(-math.pi, math.pi))
            )
            self.start_z[a] = spot[2]

    def _lifted(self, agent: str, world: World) -> bool:
        info = world.part_info(self.part[agent])
        return info.position[2] - info.height_m / 2 > self.start_z[agent] + LIFTED_M

    def target(self, agent: str, world: World) -> np.ndarray:
        return above(self.goal[agent]) if self._lifted(agent, world) else world.part_info(self.part[agent]).position

    def progress(self, world, tools, targets):
        rewards, success = {}, {}
        for a in self.agents:
            part = world.part_info(self.part[a]).position
            done = part_in_bin(world, self.part[a], self.goal[a].name)
            lifted = self._lifted(a, world)
            rewards[a] = (
                closeness(float(np.linalg.norm(tools[a] - part)))
                + (1.0 + closeness(float(np.linalg.norm(part - above(self.goal[a])))) if lifted else 0.0)
                + (SUCCESS_BONUS if done else 0.0)
            )
            success[a] = done
        return rewards, success


class Handover(Scenario):
    """Two arms pass one part: the arm nearer the part's spot on the belt (the giver) brings it to the route's
    shared station; the other (the taker) carries it on to the route's last station. One team reward."""

    name = "handover"

    def check(self, scene: Scene) -> None:
        if len(scene.arms) != 2:
            raise ValueError(f"task handover needs exactly 2 arms; the scene has {len(scene.arms)} (n_arms=2)")
        if scene.conveyor is None or not scene.feeders or len(scene.route(scene.feeders[0].name, 0)) < 2:
            raise ValueError(
                "task handover needs a conveyor and a feeder whose route passes a shared station first (scene "
                f"'handover'); {scene.name} has none"
            )

    def prepare(self, scene: Scene) -> Scene:
        return without_arrivals(scene, belt_speed_m_per_s=0.0)

    def reset(self, world: World, rng: np.random.Generator) -> None:
        scene = world.scene_model
        feeder = scene.feeders[0]
        route = scene.route(feeder.name, 0)
        self.shared, self.goal = scene.station(route[0]), scene.station(route[-1])
        bases = {a: scene.arm(a).base.xyz for a in self.agents}
        self.giver = min(self.agents, key=lambda a: self._belt_gap(scene, bases[a]))
        self.taker = next(a for a in self.agents if a != self.giver)
        self.bases = bases
        spot = belt_spot_near(
            scene, bases[self.giver], float(rng.uniform(-0.05, 0.05)), float(rng.uniform(-0.03, 0.03))
        )
        self.part = world.place_part(feeder.name, 0, spot, float(rng.uniform(-math.pi, math.pi)))
        self.start_z = spot[2]
        self.book = LineBookkeeping(scene)

    @staticmethod
    def _belt_gap(scene: Scene, base: tuple[float, float, float]) -> float:
        spot = belt_spot_near(scene, base)
        return math.hypot(spot[0] - base[0], spot[1] - base[1])

    def on_tick(self, world: World) -> None:
        self.book.update(world)

    def _holder(self, position: np.ndarray) -> str:
        """Whose side of the cell the part is on."""
        gaps = {a: math.hypot(position[0] - self.bases[a][0], position[1] - self.bases[a][1]) for a in self.agents}
        return min(self.agents, key=gaps.get)

    def _position(self, world: World) -> np.ndarray | None:
        try:
            return world.part_info(self.part).position
        except KeyError:  # retired: it rested in the last station, or fell
            return None

    def target(self, agent: str, world: World) -> np.ndarray:
        part = self._position(world)
        if part is None:
            return above(self.goal)
        lifted = part[2] > self.start_z + LIFTED_M + 0.02
        if self._holder(part) != agent:
            return above(self.shared)
        if agent == self.giver:
            return above(self.shared) if lifted else part
        return above(self.goal) if lifted else part

    def progress(self, world, tools, targets):
        completed = self.book.completed > 0
        part = self._position(world)
        if part is None:
            team = 2.0 if completed else 0.0
            rewards = {a: team for a in self.agents}
        else:
            team = 0.5 * closeness(float(np.linalg.norm(part - above(self.shared)))) + closeness(
                float(np.linalg.norm(part - above(self.goal)))
            )
            holder = self._holder(part)
            rewards = {
                a: team + (closeness(float(np.linalg.norm(tools[a] - part))) if a == holder else 0.0)
                for a in self.agents
            }
        if completed:
            rewards = {a: r + SUCCESS_BONUS for a, r in rewards.items()}
        return rewards, {a: completed for a in self.agents}


class Line(Scenario):
    """The full line: parts arrive as the scene says, routes as the scene says; the team earns each part completed
    and loses each part missed, and each arm is drawn towards the nearest part."""

    name = "line"

    def check(self, scene: Scene) -> None:
        if not scene.feeders:
            raise ValueError(f"task line needs a scene with feeders; {scene.name} has none")

    def reset(self, world: World, rng: np.random.Generator) -> None:
        self.book = LineBookkeeping(world.scene_model)

    def on_tick(self, world: World) -> None:
        self.book.update(world)

    def target(self, agent: str, world: World) -> np.ndarray:
        parts = world.active_parts()
        if not parts:
            return self.home_tool[agent]
        tool = self.home_tool[agent]
        return min((p.position for p in parts), key=lambda p: float(np.linalg.norm(p - tool)))

    def progress(self, world, tools, targets):
        gained = self.book.net_gain()
        rewards = {a: 0.5 * closeness(math.dist(tools[a], targets[a])) + SUCCESS_BONUS * gained for a in self.agents}
        return rewards, {a: gained > 0 for a in self.agents}


SCENARIOS: dict[str, type[Scenario]] = {t.name: t for t in (Reach, PickPlace, Handover, Line)}


def make_scenario(name: str, agents: list[str]) -> Scenario:
    if name not in SCENARIOS:
        raise ValueError(f"task {name!r} is not available; valid: {', '.join(SCENARIOS)}")
    return SCENARIOS[name](agents)
