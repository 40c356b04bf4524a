"""Loading scene files: YAML -> validated `Scene`, with errors that name the file and the field.

`scenes/` imports no robot code: what it must know of robots (which model
names exist and how far each reaches) is passed in by the caller as `RobotFacts`.
"""

from __future__ import annotations

import math
from collections import ChainMap
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from pydantic import ValidationError

from scenes.bay_row import BayRowError, expand_bay_row
from scenes.randomise import draw
from scenes.schema import Arm, ArmRow, Conveyor, Scene, Station
from scenes.yaml_file import DeclarationError, first_error, named_in, read_declaration, regular_file  # noqa: F401 (first_error: re-exported)
from scenes.yaml_file import yaml_text as declaration_text

MIN_BASE_SEPARATION_M = 0.25
BUNDLED_DIR = Path(str(resources.files("scenes") / "bundled"))


@dataclass(frozen=True)
class RobotFacts:
    """What scene validation needs of a robot model: its horizontal reach from the base, in metres, and its links
    (empty: not known, so a camera's mount link is checked when the cell is built)."""

    reach_m: float
    links: tuple[str, ...] = ()


RobotFileReader = Callable[[Path], tuple[str, RobotFacts]]
"""Reads (and registers) a robot file a scene names: its uid and facts, or a `ValueError` saying what is wrong."""


class SceneError(DeclarationError):
    """A scene that cannot be used: names the file, the field path and the reason, on one line."""


def bundled_scene_names() -> list[str]:
    """Names of the scenes shipped with clawfleet (runnable by name)."""
    return sorted(p.stem for p in BUNDLED_DIR.glob("*.yaml"))


MAX_SCENE_BYTES = 1_000_000  # a scene is a page of YAML; anything this large is not one


def resolve_scene_path(name_or_path: str | Path) -> Path:
    """A bundled scene's file for a name, or the given path; error lists the bundled names."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        return regular_file(path, "scene", SceneError)
    bundled = BUNDLED_DIR / f"{name_or_path}.yaml"
    if bundled.is_file():
        return bundled
    raise SceneError(str(name_or_path), "", f"no such scene; bundled scenes: {', '.join(bundled_scene_names())}")


def yaml_text(path: Path, label: str) -> str:
    """The scene file's text: refused at once when too large for a scene, or when it is not UTF-8."""
    return declaration_text(path, label, "scene", MAX_SCENE_BYTES, SceneError)


def load_scene(
    name_or_path: str | Path,
    *,
    arms: int | None = None,
    robots: Mapping[str, RobotFacts] | None = None,
    seed: int | None = None,
    read_robot_file: RobotFileReader | None = None,
) -> Scene:
    """Read, validate and expand a scene. `arms` sets an arm row's count; `robots` enables model and reach checks;
    `seed` replaces the scene's. Its `randomise` ranges are drawn from the seed (`scenes.randomise`).
    Its `robot_files` become absolute paths, each given to `read_robot_file`, whose robots join `robots`."""
    path = resolve_scene_path(name_or_path)
    label = str(path)
    scene = read_declaration(path, label, "scene", MAX_SCENE_BYTES, Scene, SceneError)
    scene, robots = with_robot_files(scene, path, label, robots, read_robot_file)
    try:
        scene = expand_bay_row(scene, arms)
    except BayRowError as exc:
        raise SceneError(label, exc.field, exc.why) from None
    scene = expand_arm_row(scene, arms, label)
    if seed is not None:
        if seed < 0:
            raise SceneError(label, "seed", f"{seed} must not be negative")
        scene = scene.model_copy(update={"seed": seed})
    scene = draw(scene)
    check_scene(scene, label, robots)
    return scene


def with_robot_files(
    scene: Scene,
    path: Path,
    label: str,
    robots: Mapping[str, RobotFacts] | None,
    read_robot_file: RobotFileReader | None,
) -> tuple[Scene, Mapping[str, RobotFacts] | None]:
    """The scene with its robot files as absolute paths, and `robots` with theirs (each read by `read_robot_file`)."""
    if not scene.robot_files:
        return scene, robots
    files = [str(named_in(path, f)) for f in scene.robot_files]
    known = ChainMap({}, robots) if robots is not None else None  # no robot's facts worked out before asked
    for i, file in enumerate(files):
        if read_robot_file is None:
            continue
        try:
            uid, facts = read_robot_file(Path(file))
        except ValueError as exc:
            raise SceneError(label, f"robot_files.{i}", str(exc)) from None
        if known is not None:
            known[uid] = facts
    return scene.model_copy(update={"robot_files": files}), known


def expand_arm_row(scene: Scene, count: int | None, label: str = "<scene>") -> Scene:
    """Turn an `arm_row` into named arms `arm_i`, each with a bin `bin_i` beside it, colours taken in turn."""
    row = scene.arm_row
    if row is None:
        if count is not None and count != len(scene.arms):
            raise SceneError(
                label, "arms", f"this scene has a fixed set of {len(scene.arms)} arms; --arms does not apply"
            )
        return scene
    n = row.count if count is None else count
    if not 1 <= n <= row.max_count:
        raise SceneError(label, "arm_row.count", f"{n} arms asked for; this scene takes 1 to {row.max_count}")
    yaw = scene.conveyor.pose.yaw_rad if scene.conveyor else 0.0
    along = (math.cos(yaw), math.sin(yaw))
    away = (math.sin(yaw), -math.cos(yaw))  # to the belt's right, where the arms stand
    colours = [p.colour for f in scene.feeders for p in f.parts] or ["#3070d0"]
    arms, stations = list(scene.arms), list(scene.stations)
    x0, y0, _ = row.first_xyz
    try:
        _row_arms_and_bins(row, n, colours, (along, away), arms, stations)
    except ValidationError as exc:  # a row that runs off the floor plan
        raise SceneError(label, "arm_row.first_xyz", f"{n} arms: {exc.errors()[0]['msg']}") from None
    update = {"arms": arms, "stations": stations, "arm_row": None}
    if scene.conveyor is not None and row.belt_past_last_m is not None:
        last = (x0 + along[0] * row.spacing_m * (n - 1), y0 + along[1] * row.spacing_m * (n - 1))
        try:
            update["conveyor"] = belt_reaching(scene.conveyor, last, row.belt_past_last_m)
        except ValidationError as exc:
            why = f"{n} arms need a longer belt than a conveyor may be: {exc.errors()[0]['msg']}"
            raise SceneError(label, "arm_row.belt_past_last_m", why) from None
    return scene.model_copy(update=update)


def _row_arms_and_bins(
    row: ArmRow, n: int, colours: list[str], axes: tuple[tuple[float, float], ...], arms: list, stations: list
) -> None:
    """The row's `n` arms `arm_i`, each facing the belt, and a bin `bin_i` beside each (appended)."""
    (along, away), (x0, y0, z0) = axes, row.first_xyz
    for i in range(n):
        bx, by = x0 + along[0] * row.spacing_m * i, y0 + along[1] * row.spacing_m * i
        base_yaw_deg = math.degrees(math.atan2(-away[1], -away[0]))  # facing the belt
        arms.append(Arm(name=f"arm_{i}", model=row.model, base={"xyz": (bx, by, z0), "yaw_deg": base_yaw_deg}))
        bin_xy = (
            bx + away[0] * row.bin_offset_m + along[0] * row.bin_along_m,
            by + away[1] * row.bin_offset_m + along[1] * row.bin_along_m,
        )
        stations.append(
            Station(
                name=f"bin_{i}",
                kind="bin",
                pose={"xyz": (bin_xy[0], bin_xy[1], z0), "yaw_deg": 0.0},
                accepts_colour=colours[i % len(colours)] if n >= len(colours) else colours[i::n],
            )
        )


def belt_reaching(conveyor: Conveyor, xy: tuple[float, float], past_m: float) -> Conveyor:
    """`conveyor`, lengthened where it must be to run `past_m` beyond the point of `xy` along it (never shortened)."""
    x0, y0, _ = conveyor.pose.xyz
    yaw = conveyor.pose.yaw_rad
    along_m = (xy[0] - x0) * math.cos(yaw) + (xy[1] - y0) * math.sin(yaw)
    length_m = max(conveyor.length_m, round(along_m + past_m, 6))
    if length_m == conveyor.length_m:
        return conveyor
    return Conveyor.model_validate(conveyor.model_dump() | {"length_m": length_m})


def _unique(label: str, field: str, names: list[str]) -> None:
    seen: set[str] = set()
    for i, n in enumerate(names):
        if n in seen:
            raise SceneError(label, f"{field}.{i}.name", f"duplicate name {n!r}")
        seen.add(n)


def _horizontal_distance(a: tuple[float, float, float], b: tuple[float, float, float]) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


def check_scene(scene: Scene, label: str = "<scene>", robots: Mapping[str, RobotFacts] | None = None) -> None:
    """Checks that need the whole scene: names, references, overlaps, models and reach."""
    _unique(label, "arms", [a.name for a in scene.arms])
    _unique(label, "stations", [s.name for s in scene.stations])
    _unique(label, "feeders", [f.name for f in scene.feeders])
    _check_links(scene, label)
    _check_cameras(scene, label, robots)
    _check_feeders(scene, label)
    _check_assemblies(scene, label)
    _check_bases(scene, label)
    if robots is not None:
        _check_reach(scene, label, robots)


def _check_links(scene: Scene, label: str) -> None:
    """Each network link the scene names is an arm or the coordinator."""
    if scene.network is not None:
        linked = {a.name for a in scene.arms} | {"coordinator"}
        for name in scene.network.links:
            if name not in linked:
                raise SceneError(label, f"network.links.{name}", f"no such link; links: {', '.join(sorted(linked))}")


def _check_cameras(scene: Scene, label: str, robots: Mapping[str, RobotFacts] | None) -> None:
    """Each mounted camera rides on an arm of the scene, on a link its robot has (where the robot is known)."""
    arms = {a.name: a for a in scene.arms}
    for i, camera in enumerate(scene.cameras):
        if camera.arm is None:
            continue
        if camera.arm not in arms:
            raise SceneError(label, f"cameras.{i}.mount", f"no arm {camera.arm!r}; arms: {', '.join(sorted(arms))}")
        model = arms[camera.arm].model
        links = robots[model].links if robots is not None and model in robots else ()
        if links and camera.link not in links:
            why = f"{model} has no link {camera.link!r}; links: {', '.join(links)}"
            raise SceneError(label, f"cameras.{i}.mount", why)


def _check_feeders(scene: Scene, label: str) -> None:
    """Each feeder feeds something that exists and routes its parts to stations that exist and take them."""
    station_names = {s.name for s in scene.stations}
    for i, f in enumerate(scene.feeders):
        if f.into == "conveyor" and scene.conveyor is None:
            raise SceneError(label, f"feeders.{i}.into", "feeds the conveyor, but the scene has none")
        if f.along_m is not None and f.into != "conveyor":
            raise SceneError(label, f"feeders.{i}.along_m", "only a conveyor feeder sets parts down along the belt")
        if f.along_m is not None and f.along_m > scene.conveyor.length_m - 0.05:
            why = f"{f.along_m:g} m is past the belt's end (it is {scene.conveyor.length_m:g} m long)"
            raise SceneError(label, f"feeders.{i}.along_m", why)
        if f.into != "conveyor" and f.into not in station_names:
            raise SceneError(
                label, f"feeders.{i}.into", f"no station {f.into!r}; stations: {', '.join(sorted(station_names))}"
            )
    buffers = set(scene.buffers())
    for i, f in enumerate(scene.feeders):
        if f.into in buffers:
            raise SceneError(label, f"feeders.{i}.into", f"{f.into!r} is a buffer: only arms set parts down there")
        for k, stop in enumerate(f.route):
            if stop not in station_names:
                raise SceneError(
                    label,
                    f"feeders.{i}.route.{k}",
                    f"no station {stop!r}; stations: {', '.join(sorted(station_names))}",
                )
            if stop in buffers:
                raise SceneError(
                    label,
                    f"feeders.{i}.route.{k}",
                    f"{stop!r} is a buffer: a part goes there only when "
                    "its next station is not ready for it, never as a stop of its route",
                )
        if not f.route:
            for t, part in enumerate(f.parts):
                if not scene.route(f.name, t):
                    raise SceneError(
                        label,
                        f"feeders.{i}.route",
                        f"empty, and no station accepts colour {part.colour} of parts.{t}: give a route or a "
                        "station's accepts_colour",
                    )


def _check_assemblies(scene: Scene, label: str) -> None:
    """Each assembly names feeders that exist and visit its station."""
    feeder_names = {f.name for f in scene.feeders}
    for i, s in enumerate(scene.stations):
        for k, name in enumerate(s.assembles):
            if name not in feeder_names:
                raise SceneError(
                    label,
                    f"stations.{i}.assembles.{k}",
                    f"no feeder {name!r}; feeders: {', '.join(sorted(feeder_names))}",
                )
            if s.name not in scene.feeder(name).route:
                raise SceneError(
                    label,
                    f"stations.{i}.assembles.{k}",
                    f"feeder {name!r} never visits {s.name!r}: add it to that feeder's route",
                )


def _check_bases(scene: Scene, label: str) -> None:
    """No two arms stand closer than their bases allow."""
    for i, a in enumerate(scene.arms):
        for j in range(i):
            d = _horizontal_distance(a.base.xyz, scene.arms[j].base.xyz)
            if d < MIN_BASE_SEPARATION_M:
                raise SceneError(
                    label,
                    f"arms.{i}.base.xyz",
                    f"arm {a.name!r} stands {d:.3f} m from {scene.arms[j].name!r}; bases need {MIN_BASE_SEPARATION_M} "
                    "m",
                )


def _check_reach(scene: Scene, label: str, robots: Mapping[str, RobotFacts]) -> None:
    """Every arm's model is known, and every station and some stretch of the conveyor are within an arm's reach."""
    for i, a in enumerate(scene.arms):
        if a.model not in robots:
            raise SceneError(
                label, f"arms.{i}.model", f"unknown robot model {a.model!r}; valid models: {', '.join(sorted(robots))}"
            )
    for i, s in enumerate(scene.stations):
        if not any(_horizontal_distance(s.pose.xyz, a.base.xyz) <= robots[a.model].reach_m for a in scene.arms):
            raise SceneError(label, f"stations.{i}.pose", f"station {s.name!r} is out of every arm's reach")
    if scene.conveyor is not None:
        c = scene.conveyor
        samples = [c.point_at(c.length_m * k / 50) for k in range(51)]
        if not any(_horizontal_distance(p, a.base.xyz) <= robots[a.model].reach_m for p in samples for a in scene.arms):
            raise SceneError(label, "conveyor.pose", "no stretch of the conveyor is within any arm's reach")
