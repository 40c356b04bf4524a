"""The physics world: a physics-only SAPIEN scene built from a scene file.

One world serves `fleet trials`, the sim server and the PettingZoo env. It
needs no render device: no visual shapes are added. Time advances by control
ticks of `scene.substeps` physics steps; drive targets are set once per tick.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sapien

from fleet.sim.arm import SimArm, yaw_pose
from fleet.sim.part_feeders import FeederClockState, PartFeeders
from fleet.sim.parts import FeederClock, SimPart
from fleet.sim.world_events import WorldEvent
from robots.registry import get_robot
from robots.saved_state import SavedState
from scenes.schema import Scene, Station
from scenes.shapes import belt_box, station_boxes

FLOOR_TOP_M = 0.0


@dataclass(frozen=True)
class PartInfo:
    """What the world tells about one active part (world frame, quaternion wxyz)."""

    part_id: int
    feeder: str
    type_index: int
    position: np.ndarray
    quaternion_wxyz: np.ndarray
    velocity: np.ndarray
    width_m: float
    height_m: float
    size_m: tuple[float, float, float]
    round: bool = False  # round about its up axis (`PartType.round`)


class WorldState(SavedState, frozen=True):
    """Everything needed to put a world back exactly: PhysX bodies, drive targets, pool and feeder clocks."""

    physx: bytes
    tick: int
    drive_targets: dict[str, np.ndarray]
    drive_velocity_targets: dict[str, np.ndarray]
    part_ids: list[int | None]
    feeders: list[FeederClockState]
    next_part_id: int
    events: list[WorldEvent] = []
    belt_running: bool = True  # False while the line is e-stopped
    gripper_force_limits: dict[str, float] = {}  # arm -> its gripper drives' force limit


def configure_physx(scene: Scene) -> None:
    """Global PhysX settings for a world: gravity, determinism, the scene's solver iterations (20 for friction
    grasps)."""
    sapien.physx.set_scene_config(
        gravity=np.array(scene.gravity_m_per_s2, dtype=np.float32),
        enable_enhanced_determinism=True,
        enable_pcm=True,
        enable_tgs=True,
    )
    sapien.physx.set_body_config(
        solver_position_iterations=scene.solver_position_iterations, solver_velocity_iterations=2, sleep_threshold=0.0
    )
    sapien.physx.set_shape_config(contact_offset=0.004, rest_offset=0.0)


class World:
    """A cell in SAPIEN: arms by id, the conveyor, stations, and its parts and their feeders (`PartFeeders`)."""

    def __init__(self, scene: Scene) -> None:
        self.scene_model = scene
        configure_physx(scene)
        self.physx = sapien.physx.PhysxCpuSystem()
        self.scene = sapien.Scene([self.physx])
        self.scene.set_timestep(1.0 / scene.physics_hz)
        self.substeps = scene.substeps
        self.control_dt_s = 1.0 / scene.control_hz
        self.tick = 0
        self.belt_running = True  # False while the line is e-stopped: the belt stands, parts stay where they lie
        self.events: list[WorldEvent] = []
        self._build_floor()
        self.belt = self._build_conveyor()
        for station in scene.stations:
            self._build_station(station)
        self.arms: dict[str, SimArm] = {}
        for i, arm in enumerate(scene.arms):
            spec = get_robot(arm.model)
            self.arms[arm.name] = SimArm(
                self.scene, spec, arm.name, yaw_pose(arm.base.xyz, arm.base.yaw_rad), i, scene.drive_gain_scale
            )
        self._arm_of_body = {link: name for name, a in self.arms.items() for link in a.articulation.get_links()}
        self.part_feeders = PartFeeders(self.scene, scene)

    @property
    def parts(self) -> list[SimPart]:
        """Every pooled part, in play (`active`) or parked."""
        return self.part_feeders.parts

    @property
    def feeders(self) -> list[FeederClock]:
        return self.part_feeders.clocks

    @property
    def next_part_id(self) -> int:
        return self.part_feeders.next_part_id

    # --- building -----------------------------------------------------------------
    def _static_boxes(
        self, name: str, boxes: list[tuple[list[float], list[float]]], pose: sapien.Pose, friction: float = 0.8
    ) -> sapien.Entity:
        material = sapien.physx.PhysxMaterial(friction, friction, 0.0)
        builder = self.scene.create_actor_builder()
        for centre, half in boxes:
            builder.add_box_collision(pose=sapien.Pose(centre), half_size=half, material=material)
        builder.set_name(name)
        entity = builder.build_static()
        entity.name = name  # SAPIEN's static and kinematic builders leave the entity unnamed; cameras label by name
        entity.set_pose(pose)
        return entity

    def _build_floor(self) -> None:
        self._static_boxes("floor", [([0, 0, -0.05], [20, 20, 0.05])], sapien.Pose())

    def _build_conveyor(self) -> sapien.physx.PhysxRigidDynamicComponent | None:
        """The belt: a kinematic slab that moves at belt speed within each tick and is set back each tick."""
        c = self.scene_model.conveyor
        if c is None:
            return None
        self._belt_home = yaw_pose(c.pose.xyz, c.pose.yaw_rad)
        builder = self.scene.create_actor_builder()
        material = sapien.physx.PhysxMaterial(0.9, 0.9, 0.0)
        centre, half = belt_box(c)
        builder.add_box_collision(pose=sapien.Pose(centre), half_size=half, material=material)
        builder.set_name("conveyor_belt")
        entity = builder.build_kinematic()
        entity.name = "conveyor_belt"
        entity.set_pose(self._belt_home)
        self._belt_entity = entity
        self._belt_step = np.array(c.direction) * c.speed_m_per_s * self.scene.get_timestep()
        home = self._belt_home.p
        self._belt_targets = [
            sapien.Pose(home + self._belt_step * k, self._belt_home.q) for k in range(1, self.substeps + 1)
        ]
        return entity.find_component_by_type(sapien.physx.PhysxRigidDynamicComponent)

    def _build_station(self, s: Station) -> None:
        boxes = station_boxes(s)
        self._static_boxes(s.name, boxes, yaw_pose(s.pose.xyz, s.pose.yaw_rad))

    # --- time ---------------------------------------------------------------------
    @property
    def sim_time_s(self) -> float:
        return self.tick * self.control_dt_s

    def step(self, ticks: int = 1) -> None:
        """Advance `ticks` control ticks: release due parts, then the physics steps with the belt running."""
        for _ in range(ticks):
            self.events += self.part_feeders.release_due(self.tick, self.sim_time_s, self.control_dt_s)
            if self.belt is not None and self.belt_running and self._belt_step.any():  # else a plain kinematic box
                self._belt_entity.set_pose(self._belt_home)
                for target in self._belt_targets:
                    self.belt.set_kinematic_target(target)
                    self.scene.step()
            else:
                for _ in range(self.substeps):
                    self.scene.step()
            self.tick += 1

    # --- parts --------------------------------------------------------------------

    def place_part(
        self, feeder_name: str, type_index: int, surface_xyz: tuple[float, float, float], yaw_rad: float = 0.0
    ) -> int:
        """Set a free part of a feeder's pool down at a chosen spot (the env's scenarios); returns its id."""
        part_id, spawned = self.part_feeders.place(feeder_name, type_index, surface_xyz, yaw_rad, self.tick)
        self.events.append(spawned)
        return part_id

    def spawn_now(self, feeder_name: str) -> int:
        """Release one part from a feeder at once (trials and tests); returns its id."""
        part_id, events = self.part_feeders.spawn_now(feeder_name, self.tick)
        self.events += events
        return part_id

    def retire_part(self, part_id: int) -> None:
        """Take a finished or lost part off the stage, back into its pool."""
        self.events.append(self.part_feeders.retire(part_id, self.tick))

    def part_info(self, part_id: int) -> PartInfo:
        return self._info(self.part_feeders.part(part_id))

    @staticmethod
    def _info(p: SimPart) -> PartInfo:
        pose = p.entity.pose
        return PartInfo(
            p.part_id,
            p.feeder,
            p.type_index,
            np.asarray(pose.p, float),
            np.asarray(pose.q, float),
            np.asarray(p.body.linear_velocity, float),
            p.width_m,
            p.height_m,
            tuple(p.part_type.size_m),
            p.part_type.round,
        )

    def active_parts(self) -> list[PartInfo]:
        return [self._info(p) for p in self.parts if p.part_id is not None]

    def belt_velocity(self) -> np.ndarray:
        c = self.scene_model.conveyor
        if c is None or not self.belt_running:
            return np.zeros(3)
        return np.array(c.direction) * c.speed_m_per_s

    # --- contacts -----------------------------------------------------------------
    def inter_arm_contacts(self) -> list[tuple[str, str]]:
        """Pairs of arms whose links touch now, as the physics sees it."""
        pairs = []
        for contact in self.physx.get_contacts():
            a = self._arm_of_body.get(contact.bodies[0])
            b = self._arm_of_body.get(contact.bodies[1])
            if a and b and a != b and any(pt.impulse.any() or pt.separation < 0 for pt in contact.points):
                pairs.append(tuple(sorted((a, b))))
        return sorted(set(pairs))

    # --- state --------------------------------------------------------------------
    def pack_state(self) -> WorldState:
        """A snapshot of the whole world; `restore_state` on this or a fresh world of the same scene puts it back."""
        return WorldState(
            physx=self.physx.pack(),
            tick=self.tick,
            drive_targets={n: a.drive_targets() for n, a in self.arms.items()},
            drive_velocity_targets={n: a.drive_velocity_targets() for n, a in self.arms.items()},
            part_ids=[p.part_id for p in self.parts],
            feeders=self.part_feeders.clock_states(),
            next_part_id=self.next_part_id,
            events=list(self.events),
            belt_running=self.belt_running,
            gripper_force_limits={n: a.gripper_force_limit() for n, a in self.arms.items()},
        )

    def observable_state(self) -> np.ndarray:
        """Every observable quantity as one vector: arm joints, velocities and targets, part and belt poses and
        velocities.

        A restored world matches an uninterrupted one on this exactly; the packed PhysX
        bytes may differ in solver bookkeeping that no observation depends on.
        """
        chunks = []
        for arm in self.arms.values():
            chunks += [arm.qpos(), arm.qvel(), arm.drive_targets(), arm.drive_velocity_targets()]
        for part in self.parts:
            pose = part.entity.pose
            chunks += [pose.p, pose.q, part.body.linear_velocity, part.body.angular_velocity]
        if self.belt is not None:
            chunks += [self._belt_entity.pose.p]
        chunks.append([self.tick, self.next_part_id])
        return np.concatenate([np.asarray(c, dtype=np.float64).ravel() for c in chunks])

    def reseed_feeders(self, seed: int) -> None:
        """The feeders' random streams (arrival gaps, part types, drop offsets) from `seed`, as a world built with
        that scene seed has them: on a world restored to its start, the arrivals of `fleet run --seed SEED`."""
        self.part_feeders.reseed(seed)

    def restore_state(self, state: WorldState) -> None:
        """Put back a snapshot from `pack_state` (of this world or another built from the same scene)."""
        self.part_feeders.restore(state.part_ids, state.feeders, state.next_part_id)
        self.physx.unpack(state.physx)
        for name, arm in self.arms.items():
            arm.restore_targets(state.drive_targets[name], state.drive_velocity_targets[name])
            if name in state.gripper_force_limits:  # a grasp's effort is the drive's, not in PhysX's pack
                arm.set_gripper_effort(state.gripper_force_limits[name])
        self.tick = state.tick
        self.events = list(state.events)
        self.belt_running = state.belt_running
