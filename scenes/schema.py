"""The scene file format: pydantic models for a cell (pure data, no physics, no robots).

Every model forbids unknown fields, so a typo in a scene file is an error that
names the field rather than a silently ignored key. Units are in the field
names: metres, seconds, kilograms, degrees for yaw in files.
"""

from __future__ import annotations

import math
import re
from typing import Annotated, Literal, get_args

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, field_validator, model_validator

FLOOR_M = 0.008
"""Thickness of bin and tray floors and walls (metres)."""
BELT_DROP_ALONG_M = 0.06  # a conveyor feeder sets its parts down this far along the belt, unless it says
NAME_PATTERN = r"^[a-z][a-z0-9_]*$"
MAX_NAME_CHARS = 40  # an id is a bus key's segment, a folder's name and a ROS name: short enough for every one
WORLD_M = 100.0  # every position in a scene lies within this of the origin (a line is metres, not kilometres)
MAX_ARMS = 64  # arms in one scene: each is an OS process of its own (`fleet run` forks one per arm)
Name = Annotated[str, Field(pattern=NAME_PATTERN, max_length=MAX_NAME_CHARS)]


def _no_nul(name: str) -> str:
    if "\x00" in name:
        raise ValueError("a file name cannot hold a NUL byte")
    return name


FileName = Annotated[str, Field(min_length=1), AfterValidator(_no_nul)]  # a file a declaration names
Vec3 = tuple[float, float, float]


def sizes_between(v: Vec3, low_m: float, high_m: float) -> Vec3:
    """`v` when every size lies within [low_m, high_m]; else the one error a part's and a station's sizes give."""
    if any(not (low_m <= s <= high_m) for s in v):
        raise ValueError(f"every size must lie between {low_m:g} and {high_m:g} m")
    return v


MAX_SEED = 2**63 - 1  # a seed is a signed 64-bit integer on the bus, in summaries and in CSV files


class Strict(BaseModel):
    """Base for every scene model: unknown fields are errors, every number is finite; models are immutable."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    def revalidated(self, **update: object):
        """A copy with `update` applied and every field and rule checked again (`model_copy` alone checks nothing)."""
        return type(self).model_validate(self.model_copy(update=update).model_dump())


class Pose2D(Strict):
    """A placement on the floor: position in metres (world frame) and yaw about +z in degrees."""

    xyz: Vec3
    yaw_deg: float = Field(0.0, ge=-360, le=360)

    @field_validator("xyz")
    @classmethod
    def _within_the_world(cls, v: Vec3) -> Vec3:
        if any(abs(c) > WORLD_M for c in v):
            raise ValueError(f"every coordinate must lie within {WORLD_M:g} m of the origin")
        return v

    @property
    def yaw_rad(self) -> float:
        return math.radians(self.yaw_deg)


class Conveyor(Strict):
    """A straight belt; parts ride along its local +x at `speed_m_per_s`. `pose` is the belt's start, top centre
    line."""

    pose: Pose2D
    length_m: float = Field(gt=0.2, le=20.0)
    width_m: float = Field(gt=0.05, le=1.0)
    speed_m_per_s: float = Field(ge=0.0, le=0.5)

    def point_at(self, s_m: float, lateral_m: float = 0.0) -> tuple[float, float, float]:
        """World point on the belt's top surface, `s_m` along it and `lateral_m` to its left."""
        c, s = math.cos(self.pose.yaw_rad), math.sin(self.pose.yaw_rad)
        x0, y0, z0 = self.pose.xyz
        return (x0 + c * s_m - s * lateral_m, y0 + s * s_m + c * lateral_m, z0)

    @property
    def direction(self) -> tuple[float, float, float]:
        return (math.cos(self.pose.yaw_rad), math.sin(self.pose.yaw_rad), 0.0)


Colour = Annotated[str, Field(pattern=r"^#[0-9a-fA-F]{6}$")]


class PartType(Strict):
    """A kind of part: a box (size x, y, z) or a cylinder (diameter, diameter, height), in metres."""

    kind: Literal["box", "cylinder"]
    size_m: Vec3
    mass_kg: float = Field(gt=0.005, le=1.0)
    colour: Colour = "#3070d0"
    friction: float = Field(0.8, ge=0.05, le=2.0)

    @field_validator("size_m")
    @classmethod
    def _positive_sizes(cls, v: Vec3) -> Vec3:
        return sizes_between(v, 0.005, 0.2)

    @model_validator(mode="after")
    def _round_cylinder(self) -> PartType:
        if self.kind == "cylinder" and self.size_m[0] != self.size_m[1]:
            raise ValueError("a cylinder's size_m is [diameter, diameter, height]: the first two must be equal")
        return self

    @property
    def round(self) -> bool:
        """Round about its up axis (a cylinder): a grasp at any yaw closes across it."""
        return self.kind == "cylinder"

    @property
    def rgb(self) -> tuple[float, float, float]:
        h = self.colour.lstrip("#")
        return tuple(int(h[i : i + 2], 16) / 255 for i in (0, 2, 4))  # type: ignore[return-value]


class Arrival(Strict):
    """When a feeder releases parts: a Poisson rate, or a fixed schedule of times, in sim seconds."""

    rate_per_min: float | None = Field(None, gt=0, le=600)
    schedule_s: list[Annotated[float, Field(ge=0)]] | None = None
    first_at_s: float = Field(1.0, ge=0)

    @model_validator(mode="after")
    def _exactly_one(self) -> Arrival:
        if (self.rate_per_min is None) == (self.schedule_s is None):
            raise ValueError("give exactly one of rate_per_min or schedule_s")
        return self


class Feeder(Strict):
    """A source of parts: onto the conveyor (near its start, or `along_m` down it), or into a station (a bin of parts
    to pick)."""

    name: Name
    parts: list[PartType] = Field(min_length=1)
    arrival: Arrival
    into: Name = "conveyor"
    along_m: float | None = Field(None, ge=0.0, le=20.0)
    """A conveyor feeder: how far along the belt it sets its parts down (None: `BELT_DROP_ALONG_M`, near the start);
    an infeed part way down a long line."""
    lateral_jitter_m: float = Field(0.0, ge=0, le=0.2)
    capacity: int = Field(8, ge=1, le=64)
    route: list[Name] = []
    """Stations a part visits in order after its source; the last is its destination. Empty: the
    station that accepts the part's colour."""


class Station(Strict):
    """A place on the line: a bin (walled box), an assembly fixture (low plate) or an output tray."""

    name: Name
    kind: Literal["bin", "fixture", "tray"]
    pose: Pose2D
    size_m: Vec3 = (0.16, 0.16, 0.05)

    @field_validator("size_m")
    @classmethod
    def _a_station_sized(cls, v: Vec3) -> Vec3:
        return sizes_between(v, 0.005, 3.0)

    accepts_colour: Colour | list[Colour] | None = None
    assembles: list[Name] = []
    """Feeders whose parts are stacked here, bottom first; the bottom part moves on only when the stack is whole."""
    buffer: bool = False
    """A spot to set one belt part down on when its next station is not ready for it and it would otherwise ride
    off the belt (a second base while the fixture is taken); the part goes on from here once the station is ready.
    On no route, takes any colour, holds one part at a time."""

    @model_validator(mode="after")
    def _buffer_is_a_plain_surface(self) -> Station:
        if self.buffer and (self.kind == "fixture" or self.assembles or self.accepts_colour is not None):
            raise ValueError("a buffer is a plain tray or bin: no fixture, assembles or accepts_colour")
        return self

    @property
    def surface_z_m(self) -> float:
        """Height of the surface a part rests on here: a fixture's top, a bin's or tray's floor."""
        return self.pose.xyz[2] + (self.size_m[2] if self.kind == "fixture" else FLOOR_M)

    @property
    def colours(self) -> list[str]:
        """The part colours this station accepts (lower case), none if it takes any."""
        c = self.accepts_colour
        return [] if c is None else [x.lower() for x in ([c] if isinstance(c, str) else c)]


class Arm(Strict):
    """One arm: its id (used everywhere: bus key, env agent, monitor node), model uid and base placement."""

    name: Name
    model: Name = "openclaw"
    base: Pose2D


class ArmRow(Strict):
    """A row of identical arms along the conveyor, each with its own bin; `--arms N` changes `count`."""

    model: Name = "openclaw"
    count: int = Field(ge=1, le=24)
    first_xyz: Vec3
    spacing_m: float = Field(gt=0.2, le=3.0)
    bin_offset_m: float = Field(0.15, ge=0.0, le=1.0)
    """How far each bin stands behind its arm's base, away from the belt."""
    bin_along_m: float = Field(0.27, ge=-1.0, le=1.0)
    """How far each bin stands beside its arm's base, downstream along the belt."""
    max_count: int = Field(12, ge=1, le=24)
    belt_past_last_m: float | None = Field(None, ge=0.0, le=2.0)
    """At least this much belt beyond the last arm's base: a longer row lengthens the conveyor (None: the belt stays
    as declared, and a row past its end is the scene's choice)."""


class BayRow(Strict):
    """The scene's arms, stations and feeders are one bay of a line; `--arms N` (a multiple of the bay's arms)
    repeats it along the conveyor, each copy `spacing_m` further downstream, its conveyor feeders setting their parts
    down as much further along the belt, which grows to carry them past the last bay."""

    count: int = Field(1, ge=1, le=12)
    max_count: int = Field(8, ge=1, le=12)
    spacing_m: float = Field(gt=0.5, le=3.0)


class Draw(Strict):
    """One value drawn per run: `uniform: [low, high]` or `normal: [mean, std]` (clipped to the field's limits)."""

    uniform: tuple[float, float] | None = None
    normal: tuple[float, float] | None = None

    @model_validator(mode="after")
    def _one_distribution(self) -> Draw:
        if (self.uniform is None) == (self.normal is None):
            raise ValueError("give exactly one of uniform: [low, high] or normal: [mean, std]")
        values = self.uniform or self.normal
        if not all(math.isfinite(v) for v in values):
            raise ValueError("the range must be finite numbers")
        if self.uniform is not None and self.uniform[0] > self.uniform[1]:
            raise ValueError(f"uniform low {self.uniform[0]} is above high {self.uniform[1]}")
        if self.normal is not None and self.normal[1] < 0:
            raise ValueError(f"normal std {self.normal[1]} is negative")
        return self


class Randomisation(Strict):
    """Domain randomisation, drawn once per run from the run's seed (`scenes/randomise.py`). Scales are factors on
    the scene's own values; `part_friction` replaces every part's friction; `part_pose_noise_m` is the standard
    deviation of the noise on the part positions controllers see. The visual draws (light, belt and part shades,
    camera jitter) change what cameras see, never the physics."""

    part_friction: Draw | None = None
    part_mass_scale: Draw | None = None
    part_size_scale: Draw | None = None
    belt_speed_scale: Draw | None = None
    arrival_rate_scale: Draw | None = None
    arm_gain_scale: Draw | None = None
    part_pose_noise_m: Draw | None = None
    light_yaw_deg: Draw | None = None
    """Visual (cameras only): the light's direction turned about +z by this many degrees."""
    light_intensity_scale: Draw | None = None
    belt_grey: Draw | None = None
    part_shade: Draw | None = None
    camera_jitter_m: Draw | None = None
    """Visual: the standard deviation of a shift drawn for each camera's position and aim (metres)."""


LatencyMs = Annotated[float, Field(ge=0.0, le=2000.0)]
JitterMs = Annotated[float, Field(ge=0.0, le=1000.0)]
LossProbability = Annotated[float, Field(ge=0.0, lt=1.0)]


class LinkFaults(Strict):
    """Faults on one bus link between the sim and a process, each way: a delay (mean and jitter, milliseconds; the
    jitter is the standard deviation of a normal draw, clipped at zero, so messages can overtake each other) and a
    loss probability per message."""

    latency_ms: LatencyMs = 0.0
    jitter_ms: JitterMs = 0.0
    loss: LossProbability = 0.0

    @property
    def active(self) -> bool:
        return self.latency_ms > 0 or self.jitter_ms > 0 or self.loss > 0


class Network(Strict):
    """Network faults on the bus (`fleet/bus/faults.py`): the faults of every link (`latency_ms`, `jitter_ms`,
    `loss`, as `LinkFaults`), and per link (an arm's name or `coordinator`) a replacement. In lockstep they act in
    sim time and repeat exactly for a seed; in realtime in wall time."""

    latency_ms: LatencyMs = 0.0
    jitter_ms: JitterMs = 0.0
    loss: LossProbability = 0.0
    links: dict[str, LinkFaults] = {}

    @property
    def every_link(self) -> LinkFaults:
        """The faults of every link that `links` does not replace."""
        return LinkFaults(latency_ms=self.latency_ms, jitter_ms=self.jitter_ms, loss=self.loss)

    def link(self, name: str) -> LinkFaults:
        """The faults on the link to `name` (an arm or `coordinator`)."""
        return self.links.get(name, self.every_link)


ImageKind = Literal["rgb", "depth", "segmentation"]
IMAGE_KINDS: tuple[str, ...] = get_args(ImageKind)
MAX_CAMERAS = 16
MAX_CAMERA_PIXELS_PER_S = 3_000_000
"""The pixel budget: width x height x rate, summed over a scene's cameras. On a 2-core machine rendering on the CPU
(docs/cameras.md) this is about 13 s of rendering per sim second; past it a line is a render farm, not a line."""
MOUNT_PATTERN = r"^(world|[a-z][a-z0-9_]*/[A-Za-z0-9_.\-]+)$"


class CameraPlacement(Strict):
    """Where a camera stands and what it looks at, in its mount's frame (the world, or an arm link's), in metres;
    `up` says which way is up in its image."""

    xyz: Vec3
    look_at: Vec3
    up: Vec3 = (0.0, 0.0, 1.0)

    @model_validator(mode="after")
    def _a_view(self) -> CameraPlacement:
        if any(abs(c) > WORLD_M for c in (*self.xyz, *self.look_at)):
            raise ValueError(f"every coordinate must lie within {WORLD_M:g} m of the origin")
        forward = [b - a for a, b in zip(self.xyz, self.look_at)]
        if math.hypot(*forward) < 1e-3:
            raise ValueError("look_at must lie at least 1 mm from xyz")
        if math.hypot(*self.up) < 1e-6:
            raise ValueError("up must not be zero")
        cross = (
            forward[1] * self.up[2] - forward[2] * self.up[1],
            forward[2] * self.up[0] - forward[0] * self.up[2],
            forward[0] * self.up[1] - forward[1] * self.up[0],
        )
        if math.hypot(*cross) < 1e-6 * math.hypot(*forward) * math.hypot(*self.up):
            raise ValueError("up lies along the view (xyz to look_at): give an up across it, e.g. [1, 0, 0]")
        return self


class Camera(Strict):
    """A camera on the line: fixed in the world or mounted on an arm's link, the images it makes and how often (in
    sim time). `fov_deg` is the vertical field of view; depth is in metres between `near_m` and `far_m`."""

    name: Name
    mount: Annotated[str, Field(pattern=MOUNT_PATTERN, max_length=120)] = "world"
    """`world`, or `<arm>/<link>`: the camera rides on that link of that arm (`pose` in the link's frame)."""
    pose: CameraPlacement
    width_px: int = Field(ge=8, le=1920)
    height_px: int = Field(ge=8, le=1080)
    fov_deg: float = Field(60.0, ge=5.0, le=150.0)
    near_m: float = Field(0.02, ge=0.001, le=10.0)
    far_m: float = Field(10.0, ge=0.01, le=200.0)
    rate_hz: float = Field(5.0, gt=0.0, le=60.0)
    images: list[ImageKind] = Field(["rgb"], min_length=1, max_length=3)

    @model_validator(mode="after")
    def _consistent(self) -> Camera:
        if self.near_m >= self.far_m:
            raise ValueError(f"near_m {self.near_m:g} must be below far_m {self.far_m:g}")
        if len(set(self.images)) != len(self.images):
            raise ValueError("images names each of rgb, depth, segmentation at most once")
        return self

    @property
    def arm(self) -> str | None:
        """The arm it rides on, None for a fixed camera."""
        return None if self.mount == "world" else self.mount.split("/", 1)[0]

    @property
    def link(self) -> str | None:
        """The link of its arm it rides on, None for a fixed camera."""
        return None if self.mount == "world" else self.mount.split("/", 1)[1]

    @property
    def pixels_per_s(self) -> float:
        return self.width_px * self.height_px * self.rate_hz


class Appearance(Strict):
    """How the cameras' scene looks (never the physics, nor a part's colour as stations sort by it): one directional
    light (`light_direction_xyz`, pointing from the light; `light_intensity`) over an even `ambient` light, whether
    it casts shadows, the belt's grey and a factor on every part's colour in images."""

    light_direction_xyz: Vec3 = (0.3, 0.4, -1.0)
    light_intensity: float = Field(0.75, ge=0.0, le=5.0)
    ambient: float = Field(0.45, ge=0.0, le=2.0)
    shadows: bool | Literal["auto"] = "auto"
    """`auto`: shadows where a GPU renders, none on a CPU renderer (lavapipe), where SAPIEN drawing the shadow map
    again for every camera's frame costs about twice a small frame's render (docs/cameras.md)."""
    belt_grey: float = Field(0.12, ge=0.0, le=1.0)
    part_shade: float = Field(1.0, ge=0.0, le=2.0)

    @field_validator("light_direction_xyz")
    @classmethod
    def _points_somewhere(cls, v: Vec3) -> Vec3:
        if math.hypot(*v) < 1e-6:
            raise ValueError("the light's direction must not be zero")
        return v


class Scene(Strict):
    """A whole cell."""

    name: Name
    description: str = ""
    physics_hz: float = Field(200.0, ge=60, le=5000)
    """200 Hz holds friction grasps (`fleet trials`: 100 of 100 from 100 Hz up, docs/benchmarks.md) at 40% of 500 Hz's
    cost."""
    control_hz: float = Field(100.0, ge=1, le=500)
    solver_position_iterations: int = Field(20, ge=1, le=255)
    """PhysX position iterations per step for every body and arm: 20 holds friction grasps; a cell with no
    grasps moves the same with fewer (PhysX's default is 4) at about half the physics time."""
    gravity_m_per_s2: Vec3 = (0.0, 0.0, -9.81)
    seed: int = Field(0, ge=0, le=MAX_SEED)
    conveyor: Conveyor | None = None
    feeders: list[Feeder] = []
    stations: list[Station] = []
    arms: list[Arm] = Field([], max_length=MAX_ARMS)
    """At most `MAX_ARMS` (64): each arm is an OS process of its own, and the guard checks every pair."""
    arm_row: ArmRow | None = None
    bay_row: BayRow | None = None
    randomise: Randomisation | None = None
    randomised: dict[str, float] = {}
    """The values drawn for this run (filled by `scenes.randomise.draw`; listed in the run summary)."""
    safety_separation_m: float = Field(0.01, ge=0.0, le=0.5)
    """The plant's safety layer refuses any goal, from any source, whose path would bring two arms closer than this,
    and stops a motion that does (metres). The coordinator's guard plans with a wider margin (2 cm)."""
    drive_gain_scale: float = Field(1.0, gt=0.05, le=20.0)
    """Factor on every arm's drive stiffness and damping (a randomised arm gain lands here)."""
    part_pose_noise_m: float = Field(0.0, ge=0.0, le=0.05)
    """Standard deviation of the noise added to the part positions controllers see (metres)."""
    network: Network | None = None
    """Latency, jitter and loss on the bus between the sim and each controller and the coordinator (none by default)."""
    appearance: Appearance = Appearance()
    """How the cameras' scene looks: light, shadows, belt and part shades (no effect on physics)."""
    cameras: list[Camera] = Field([], max_length=MAX_CAMERAS)
    """Cameras (docs/cameras.md). Rendered only where something asks for images (`fleet run --cameras`, the env's
    `cameras=True`): a run that asks for none builds no renderer and pays nothing."""
    robot_files: list[Annotated[FileName, Field(max_length=4096)]] = Field([], max_length=16)
    """Robot declaration files (YAML, docs/robots.md) whose uids this scene's arms may name; relative to the scene
    file."""

    @model_validator(mode="after")
    def _consistent(self) -> Scene:
        if self.control_hz > self.physics_hz:
            raise ValueError("control_hz must not exceed physics_hz")
        ratio = self.physics_hz / self.control_hz
        if abs(ratio - round(ratio)) > 1e-9:
            raise ValueError("physics_hz must be a whole multiple of control_hz")
        if not self.arms and self.arm_row is None:
            raise ValueError("a scene needs at least one arm (arms or arm_row)")
        if self.bay_row is not None and (self.arm_row is not None or self.conveyor is None):
            raise ValueError("a bay_row repeats a bay of declared arms along the conveyor: no arm_row, a conveyor")
        return self

    @field_validator("cameras")
    @classmethod
    def _within_the_pixel_budget(cls, cameras: list[Camera]) -> list[Camera]:
        names = [c.name for c in cameras]
        if len(set(names)) != len(names):
            raise ValueError(f"camera names must differ: {', '.join(names)}")
        total = sum(c.pixels_per_s for c in cameras)
        if total > MAX_CAMERA_PIXELS_PER_S:
            raise ValueError(
                f"{total:,.0f} pixels/s over all cameras (width_px x height_px x rate_hz); the budget is "
                f"{MAX_CAMERA_PIXELS_PER_S:,} (docs/cameras.md)"
            )
        return cameras

    def camera(self, name: str) -> Camera:
        for c in self.cameras:
            if c.name == name:
                return c
        raise KeyError(f"no camera {name!r}; cameras: {', '.join(c.name for c in self.cameras) or 'none'}")

    def drop_along_m(self, feeder: Feeder) -> float:
        """How far along the belt a conveyor feeder sets its parts down."""
        return BELT_DROP_ALONG_M if feeder.along_m is None else feeder.along_m

    @property
    def substeps(self) -> int:
        """Physics steps per control tick."""
        return round(self.physics_hz / self.control_hz)

    def feeder(self, name: str) -> Feeder:
        for f in self.feeders:
            if f.name == name:
                return f
        raise KeyError(f"no feeder {name!r}; feeders: {', '.join(f.name for f in self.feeders) or 'none'}")

    def round_part_types(self) -> frozenset[tuple[str, int]]:
        """The (feeder, type index) of each round part type (`PartType.round`), as the parts message names them."""
        return frozenset((f.name, t) for f in self.feeders for t, p in enumerate(f.parts) if p.round)

    def route(self, feeder_name: str, type_index: int) -> list[str]:
        """The stations a part of this feeder and type visits after its source, in order."""
        feeder = self.feeder(feeder_name)
        if feeder.route:
            return list(feeder.route)
        return self.stations_for_colour(feeder_name, type_index)[:1]

    def stations_for_colour(self, feeder_name: str, type_index: int) -> list[str]:
        """Every station that accepts this part's colour, in scene order (none for a feeder with its own route):
        a sorted part may go to any of them; `route` names the first."""
        feeder = self.feeder(feeder_name)
        if feeder.route:
            return []
        colour = feeder.parts[type_index].colour.lower()
        return [s.name for s in self.stations if colour in s.colours]

    def buffers(self) -> list[str]:
        """The buffer stations, in scene order (`Station.buffer`)."""
        return [s.name for s in self.stations if s.buffer]

    def source_names(self) -> set[str]:
        """Where feeders put parts: `conveyor` and the stations fed directly."""
        return {f.into for f in self.feeders}

    def arm(self, name: str) -> Arm:
        for a in self.arms:
            if a.name == name:
                return a
        raise KeyError(f"no arm {name!r}; arms: {', '.join(a.name for a in self.arms) or 'none'}")

    def station(self, name: str) -> Station:
        for s in self.stations:
            if s.name == name:
                return s
        raise KeyError(f"no station {name!r}; stations: {', '.join(s.name for s in self.stations) or 'none'}")


def is_valid_name(name: str) -> bool:
    """Whether `name` is an id: lower-case letters, digits and _, starting with a letter, at most `MAX_NAME_CHARS`."""
    return len(name) <= MAX_NAME_CHARS and re.match(NAME_PATTERN, name) is not None
