"""A run started from a snapshot: the launcher's options for it (its scene, written out of the snapshot, its seed and
arm count, its end), whoever starts it (`fleet run --from`, a sweep, a test).

A branch may set a field of the scene otherwise (`--set`), but only one every process reads afresh from its scene
after the restore (`RESTORE_OVERRIDES`): each process's state holds what it worked out from the rest (geometry,
reach, feeder clocks, stations' bodies), so any other change would take effect in some processes and not others.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from fleet.common.scene_loading import load_checked_scene
from fleet.common.scene_overrides import scene_with
from fleet.record.mcap_file import MAGIC, Recording, RecordingError
from fleet.run.launcher import RunOptions
from fleet.snapshot.snapshot_file import RunSnapshot, SceneSource, SnapshotError, check_holds, read_snapshot
from scenes.loader import MAX_SCENE_BYTES, SceneError
from scenes.schema import Scene
from scenes.yaml_file import read_declaration

# fields a restored run takes from its scene afresh (the belt's speed: the sim's belt is built from the scene, and the
# coordinator reads the speed at each decision and works its bound out again)
RESTORE_OVERRIDES = ("conveyor.speed_m_per_s",)


def check_restore_overrides(overrides: dict) -> None:
    """A `SnapshotError` (one line) naming a field a restored run cannot take otherwise."""
    refused = [path for path in overrides if path not in RESTORE_OVERRIDES]
    if refused:
        raise SnapshotError(
            f"--set {refused[0]}: a run restored from a snapshot can set only {', '.join(RESTORE_OVERRIDES)} "
            "(its processes hold what they worked out from the rest of the scene)"
        )


def restore_options(
    path: str | Path, folder: Path, duration_s: float | None = None, overrides: dict | None = None, **options
) -> tuple[RunOptions, RunSnapshot]:
    """Options that start every process from the snapshot at `path` (its scene and robot files written under
    `folder`, which must outlive the run; `overrides` set in it, of `RESTORE_OVERRIDES`), running to where the
    snapshot's run was to end, or `duration_s` sim seconds more; `options` sets the rest (another allocator,
    `reseed`: a branch; `mode`: lockstep by default, and only lockstep repeats). A `SnapshotError` (one line) if it
    cannot."""
    check_restore_overrides(overrides or {})
    snapshot = read_snapshot(path)
    scene = snapshot.scene.write(Path(folder))
    try:
        arms = [a.name for a in load_checked_scene(str(scene), arms=snapshot.scene.arms, seed=snapshot.scene.seed).arms]
    except SceneError as exc:
        raise SnapshotError(f"{path}: its scene cannot be read: {exc}") from None
    check_holds(snapshot, ["sim", "coordinator", *arms], path)  # said now, not after the line waits for a node
    if overrides:
        try:
            scene = Path(scene_with(str(scene), overrides, Path(folder) / "set"))
        except SceneError as exc:
            raise SnapshotError(str(exc)) from None
    seconds_per_tick = snapshot.sim_time_s / snapshot.tick
    end_s = snapshot.end_tick * seconds_per_tick if duration_s is None else snapshot.sim_time_s + duration_s
    base = RunOptions(
        scene=str(scene),
        arms=snapshot.scene.arms,
        seed=snapshot.scene.seed,
        duration_s=end_s,
        allocator=snapshot.allocator,
        restore_from=str(Path(path).resolve()),
        incarnations=tuple(sorted(snapshot.incarnations.items())),
    )
    return dataclasses.replace(base, **options), snapshot


def snapshot_path(path: str | Path, at_s: float | None, folder: Path) -> Path:
    """The snapshot file to start from: `path` itself, or, where `path` is a recording, the newest snapshot it
    carries at or before `at_s` sim seconds (None: its last), written into `folder`. A `SnapshotError` (one line)
    for a recording without one, or `at_s` given with a snapshot file."""
    p = Path(path)
    try:
        with open(p, "rb") as f:
            is_recording = f.read(len(MAGIC)) == MAGIC
    except OSError:
        is_recording = False  # read_snapshot says what is wrong with it
    if not is_recording:
        if at_s is not None:
            raise SnapshotError(f"--at picks a snapshot in a recording; {p} is a snapshot file itself")
        return p
    try:
        name, data = Recording(p).snapshot_at(at_s)
    except RecordingError as exc:
        raise SnapshotError(str(exc)) from None
    folder.mkdir(parents=True, exist_ok=True)
    (folder / name).write_bytes(data)
    return folder / name


def _declared(source: SceneSource, folder: Path) -> dict:
    """A scene source's declaration as its schema reads it (defaults filled in), robot files apart."""
    path = source.write(folder)
    scene = read_declaration(path, source.file_name, "scene", MAX_SCENE_BYTES, Scene, SceneError)
    return scene.model_dump(mode="json", exclude={"robot_files"})


def _first_difference(a: object, b: object, path: str = "") -> tuple[str, object, object] | None:
    """The first field (a dotted path) where two declarations differ, with both values; None where they agree."""
    if isinstance(a, dict) and isinstance(b, dict):
        for key in [*a, *(k for k in b if k not in a)]:
            found = _first_difference(a.get(key), b.get(key), f"{path}.{key}" if path else str(key))
            if found:
                return found
        return None
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            found = _first_difference(x, y, f"{path}.{i}")
            if found:
                return found
        return None
    return None if a == b else (path or "<scene>", a, b)


def check_same_scene(given: str, snapshot: RunSnapshot, folder: Path) -> None:
    """A `SnapshotError` (one line) naming the first field where the scene `given` with `--from` differs from the
    one the snapshot holds: a restore runs the snapshot's own scene, so a scene given beside it must be that scene
    (a field of `RESTORE_OVERRIDES` is set with `--set`, never by an edited file)."""
    try:
        source = SceneSource.of(given, snapshot.scene.arms, snapshot.scene.seed)
        mine = _declared(source, folder / "given")
    except (SceneError, OSError) as exc:
        raise SnapshotError(str(exc)) from None
    theirs = _declared(snapshot.scene, folder / "snapshot")
    found = _first_difference(theirs, mine)
    if found is None and source.files != snapshot.scene.files:
        found = ("robot_files", "the snapshot's robot files", "other robot files")
    if found is None:
        return
    field, was, now = found
    how = f"; set it with --set {field}=V" if field in RESTORE_OVERRIDES else ""
    raise SnapshotError(
        f"{given}: {field} is {_short(now)} where the snapshot's scene has {_short(was)}: a restore runs the "
        f"snapshot's own scene{how}"
    )


def _short(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
