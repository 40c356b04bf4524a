"""A scene with some of its fields set otherwise (`--set conveyor.speed_m_per_s=0.05`, `--load 1.25`): a checked copy
of its file, written elsewhere, so a bad path or value names the field and the file.

A field is named by its dotted path (list items by index: `feeders.0.arrival.rate_per_min`); a value is a YAML scalar
(`none` removes an optional section). Offered load (`load`) scales every feeder's rate so parts arrive at that
multiple of the rate the line's arms can just complete (`coordinator.offered_load`), after the other overrides.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import yaml

from fleet.common.scene_loading import load_checked_scene
from scenes.loader import SceneError, resolve_scene_path, yaml_text
from scenes.schema import Scene
from scenes.yaml_file import named_in

LOAD = "load"  # the override that scales the feeders (`--load`), not a field of the scene file


def set_path(data: dict, path: str, value: object, label: str) -> None:
    """Set `data`'s field at a dotted path (list items by index); the error names the path."""
    parts = path.split(".")
    node: object = data
    for i, part in enumerate(parts[:-1]):
        node = _child(node, part, ".".join(parts[: i + 1]), label)
    last = parts[-1]
    if isinstance(node, list):
        index = _index(node, last, path, label)
        node[index] = value
    elif isinstance(node, dict):
        if value is None:
            node.pop(last, None)
        else:
            node[last] = value
    else:
        raise SceneError(label, path, f"{'.'.join(parts[:-1]) or '(top level)'} holds no fields")


def _child(node: object, part: str, where: str, label: str) -> object:
    if isinstance(node, list):
        return node[_index(node, part, where, label)]
    if isinstance(node, dict):
        if node.get(part) is None:  # a section the file leaves out (or removed): set fields of a new one
            node[part] = {}
        if not isinstance(node[part], (dict, list)):
            raise SceneError(label, where, f"is a value ({node[part]!r}), not a section with fields")
        return node[part]
    raise SceneError(label, where, "holds no fields")


def _index(node: list, part: str, where: str, label: str) -> int:
    if not part.isdigit() or int(part) >= len(node):
        raise SceneError(label, where, f"give a list index from 0 to {len(node) - 1}")
    return int(part)


def scene_with(scene: str, overrides: dict, folder: Path) -> str:
    """The scene to run: `scene` itself without overrides, else a checked copy with them written under `folder`
    (the offered load last: it scales the feeders of the scene the other overrides make)."""
    if not overrides:
        return scene
    source = resolve_scene_path(scene)
    data = yaml.safe_load(yaml_text(source, str(source)))
    # the copy lives elsewhere: keep them found
    if isinstance(data, dict) and isinstance(data.get("robot_files"), list):
        data["robot_files"] = [str(named_in(source, f)) if isinstance(f, str) else f for f in data["robot_files"]]
    label = f"{source} with --set {', '.join(f'{k}={v}' for k, v in overrides.items())}"
    for path, value in overrides.items():
        if path != LOAD:
            set_path(data, path, value, label)
    target, made = _write_checked(data, source, folder, label)
    if LOAD not in overrides:
        return target
    _scale_feeders(data, made, overrides[LOAD], label)
    return _write_checked(data, source, folder, label)[0]


def _write_checked(data: dict, source: Path, folder: Path, label: str) -> tuple[str, Scene]:
    """`data` written as a scene file under `folder` and loaded (so checked): its path and the scene."""
    digest = hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()[:12]
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / f"{source.stem}-{digest}.yaml"
    target.write_text(yaml.safe_dump(data, sort_keys=False))
    try:
        return str(target), load_checked_scene(target)
    except SceneError as exc:
        raise SceneError(label, exc.field, exc.reason) from None


def _scale_feeders(data: dict, scene: Scene, load: object, label: str) -> None:
    """Each feeder of the file at the rate of the offered load (a scheduled feeder's times drawn closer or apart)."""
    from coordinator.offered_load import feeder_rates_for_load

    if not isinstance(load, (int, float)) or isinstance(load, bool):
        raise SceneError(label, LOAD, f"{load!r} is not a number")
    try:
        rates = feeder_rates_for_load(scene, float(load))
    except ValueError as exc:
        raise SceneError(label, LOAD, str(exc)) from None
    feeders = {f.get("name"): f for f in data.get("feeders") or [] if isinstance(f, dict)}
    for name, rate in rates.items():
        arrival = feeders[name].setdefault("arrival", {})
        if arrival.get("rate_per_min") is not None:
            arrival["rate_per_min"] = rate
        else:
            factor = 60.0 * len(arrival["schedule_s"]) / max(max(arrival["schedule_s"]), 1.0) / rate
            arrival["schedule_s"] = [round(t * factor, 4) for t in arrival["schedule_s"]]
