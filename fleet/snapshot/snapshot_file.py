"""The snapshot file: one run's state at a lockstep tick boundary, every process's part of it, and the scene (with its
robot files) that run loaded, so the file alone starts the line again.

On disk: `CLAWSNAP`, the format version (4 bytes), the SHA-256 of the body (32 bytes), then the body: the
`RunSnapshot` as MessagePack, zlib-compressed. A file is checked whole (magic, version, checksum) before any byte of a
process's state is read back: a truncated, corrupted or other-version file is refused in one line. Every process's
state is typed (msgspec structs: `fleet/sim/sim_state.py`, `fleet/snapshot/*_state.py`): nothing in a file is unpickled.
"""

from __future__ import annotations

import hashlib
import os
import struct
import zlib
from pathlib import Path

import msgspec
import yaml

from fleet.bus.messages import PROTOCOL_VERSION
from scenes.loader import resolve_scene_path
from scenes.yaml_file import named_in, parse_yaml

MAGIC = b"CLAWSNAP"
FORMAT_VERSION = 5  # 3: the belt reach per station; 4: the controllers and coordinator as typed states; 5: the sim
SUFFIX = ".clawsnap"
_HEADER = struct.Struct("<8sI32s")


class SnapshotError(ValueError):
    """A snapshot file that cannot be used (missing, truncated, corrupted, another version or scene); one line."""


class SceneSource(msgspec.Struct, frozen=True):
    """The scene as a run loaded it, made to stand alone: its file's text (its robot files renamed to lie beside it),
    each robot file (its URDF, when given by a relative path, renamed to lie beside it too), keyed by file name; the
    arm count and seed it was loaded with. Meshes a URDF names are not carried: they must be where it says."""

    file_name: str
    text: str
    files: dict[str, str]  # file name -> text: the robot files and their URDFs, beside the scene
    arms: int | None
    seed: int | None

    @classmethod
    def of(cls, name_or_path: str, arms: int | None, seed: int | None) -> SceneSource:
        """The source of a scene given by bundled name or path (as `fleet run` takes it)."""
        path = resolve_scene_path(name_or_path)
        text = path.read_text(encoding="utf-8")
        declared = parse_yaml(text, str(path), "scene") or {}
        named = declared.get("robot_files") or []
        if not named:
            return cls(path.name, text, {}, arms, seed)
        files: dict[str, str] = {}
        renamed = []
        for i, name in enumerate(named):
            robot_path = named_in(path, name)
            robot = parse_yaml(robot_path.read_text(encoding="utf-8"), str(robot_path), "robot") or {}
            urdf = robot.get("urdf")
            if isinstance(urdf, str) and not Path(urdf).expanduser().is_absolute():
                urdf_name = f"robot_{i}_{Path(urdf).name}"
                files[urdf_name] = named_in(robot_path, urdf).read_text(encoding="utf-8")
                robot["urdf"] = urdf_name
            renamed.append(f"robot_{i}_{Path(name).name}")
            files[renamed[-1]] = yaml.safe_dump(robot, sort_keys=False)
        declared["robot_files"] = renamed
        return cls(path.name, yaml.safe_dump(declared, sort_keys=False), files, arms, seed)

    def write(self, directory: Path) -> Path:
        """The scene file and the files beside it written into `directory`; the scene's path."""
        directory.mkdir(parents=True, exist_ok=True)
        for name in (self.file_name, *self.files):
            if Path(name).name != name or name in ("", ".", ".."):
                raise SnapshotError(f"the snapshot names a file {name!r} that is not a plain file name")
        for name, text in self.files.items():
            (directory / name).write_text(text, encoding="utf-8")
        scene = directory / self.file_name
        scene.write_text(self.text, encoding="utf-8")
        return scene


class RunSnapshot(msgspec.Struct, frozen=True):
    """A whole run at the start of tick `tick`: each process's state by node (`sim`, `coordinator`, arm ids),
    zlib-compressed by the process that wrote it (`node_state` gives it back as written)."""

    scene_name: str
    scene: SceneSource
    mode: str
    tick: int
    sim_time_s: float
    end_tick: int  # where the run that took it was to end
    allocator: str
    states: dict[str, bytes]
    # the run's later snapshots (ticks, and every so many ticks): a run restored from this one takes them too, for
    # a snapshot goes on from a world built afresh (it matches the one packed to about 1e-6, not exactly)
    later_ticks: list[int] = []
    every_ticks: int = 0
    incarnations: dict[str, int] = {}  # node -> which start of it the run was in (after a respawn: 2, ...)
    protocol_version: int = PROTOCOL_VERSION

    @property
    def arms(self) -> list[str]:
        return [n for n in self.states if n not in ("sim", "coordinator")]


def write_snapshot(snapshot: RunSnapshot, path: str | Path) -> int:
    """Write `snapshot` to `path` (whole or not at all: a reader never sees half a file); the bytes written."""
    body = zlib.compress(msgspec.msgpack.encode(snapshot), 1)  # the states are compressed already
    data = _HEADER.pack(MAGIC, FORMAT_VERSION, hashlib.sha256(body).digest()) + body
    target = Path(path)
    tmp = target.with_name(target.name + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, target)
    return len(data)


def read_snapshot(path: str | Path) -> RunSnapshot:
    """The snapshot in `path`, checked whole; a `SnapshotError` (one line) for anything else."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise SnapshotError(f"{p}: no such snapshot file") from None
    except OSError as exc:
        raise SnapshotError(f"{p}: cannot read it ({exc.strerror or exc})") from None
    return parse_snapshot(data, p)


def parse_snapshot(data: bytes, label: str | Path) -> RunSnapshot:
    """A snapshot file's bytes (`label` names it in errors), checked whole; a `SnapshotError` (one line) for
    anything else."""
    p = label
    if len(data) < _HEADER.size or not data.startswith(MAGIC):
        raise SnapshotError(f"{p}: not a clawfleet snapshot (it does not start with {MAGIC.decode()})")
    _, version, digest = _HEADER.unpack_from(data)
    if version != FORMAT_VERSION:
        raise SnapshotError(f"{p}: snapshot format {version}; this clawfleet reads format {FORMAT_VERSION}")
    body = data[_HEADER.size :]
    if hashlib.sha256(body).digest() != digest:
        raise SnapshotError(f"{p}: truncated or corrupted (its checksum does not match its {len(body)} bytes)")
    try:
        snapshot = msgspec.msgpack.decode(zlib.decompress(body), type=RunSnapshot)
    except (zlib.error, msgspec.MsgspecError, ValueError) as exc:
        raise SnapshotError(f"{p}: unreadable snapshot body ({str(exc)[:120]})") from None
    if snapshot.protocol_version != PROTOCOL_VERSION:
        raise SnapshotError(
            f"{p}: taken by a clawfleet with bus protocol {snapshot.protocol_version}; "
            f"this one speaks {PROTOCOL_VERSION}"
        )
    missing = [n for n in ("sim", "coordinator") if n not in snapshot.states]
    if missing:
        raise SnapshotError(f"{p}: holds no state for {', '.join(missing)}")
    return snapshot


def node_state(path: str | Path, node: str) -> tuple[RunSnapshot, bytes]:
    """The snapshot in `path` and `node`'s state in it; a `SnapshotError` if either is not there."""
    snapshot = read_snapshot(path)
    return snapshot, state_of(snapshot, node, path)


def check_holds(snapshot: RunSnapshot, nodes: list[str], label: str | Path) -> None:
    """A `SnapshotError` (one line) unless `snapshot` holds a readable state for each of `nodes` (the processes a
    run restored from it starts): said before any of them starts, not after the line waits for one that cannot."""
    for node in nodes:
        state_of(snapshot, node, label)


def state_of(snapshot: RunSnapshot, node: str, label: str | Path) -> bytes:
    """`node`'s state in a snapshot read already (`label` names the file in errors), as its process wrote it."""
    if node not in snapshot.states:
        raise SnapshotError(f"{label}: holds no state for {node!r}; nodes: {', '.join(snapshot.states)}")
    try:
        return zlib.decompress(snapshot.states[node])
    except zlib.error as exc:
        raise SnapshotError(f"{label}: the state of {node} is damaged ({exc})") from None
