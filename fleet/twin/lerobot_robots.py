"""LeRobot robots by type, as LeRobot's own commands make them from `--robot.type=T --robot.KEY=VALUE`: its built-in
types and the plug-ins installed beside it (`lerobot_robot_*`). Imported only in LeRobot's Python."""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
import io
import pkgutil
from collections.abc import Mapping


class RobotTypeError(ValueError):
    """A robot type LeRobot does not know, or settings its config does not take; the message says which."""


def _known_types() -> dict[str, type]:
    """Every robot config type LeRobot and its installed plug-ins register."""
    import lerobot.robots as robots
    from lerobot.robots import RobotConfig
    from lerobot.utils.import_utils import register_third_party_plugins

    for module in pkgutil.iter_modules(robots.__path__):
        if module.ispkg:
            with contextlib.suppress(Exception):  # a robot whose own extras are not installed is not offered
                importlib.import_module(f"lerobot.robots.{module.name}")
    register_third_party_plugins()
    return dict(RobotConfig.get_known_choices())


def robot_config(robot_type: str, settings: Mapping[str, str]):
    """The config of a `robot_type` robot with `settings` (field -> value as typed on a command line), parsed by
    LeRobot's own parser (draccus)."""
    import draccus

    known = _known_types()
    if robot_type not in known:
        raise RobotTypeError(f"robot type {robot_type!r}: LeRobot knows {', '.join(sorted(known))}")
    cls = known[robot_type]
    fields = [f.name for f in dataclasses.fields(cls)]
    if unknown := [k for k in settings if k not in fields]:
        raise RobotTypeError(f"robot setting {unknown[0]!r}: a {robot_type} robot takes {', '.join(fields)}")
    said = io.StringIO()
    try:
        with contextlib.redirect_stderr(said):
            return draccus.parse(config_class=cls, args=[f"--{k}={v}" for k, v in settings.items()])
    except (SystemExit, draccus.utils.DecodingError) as exc:
        why = str(exc) if isinstance(exc, draccus.utils.DecodingError) else said.getvalue()
        raise RobotTypeError(f"robot settings of {robot_type}: {' '.join(why.split()) or 'refused'}") from None


def make_robot(robot_type: str, settings: Mapping[str, str]):
    """A `robot_type` robot (not connected yet)."""
    from lerobot.robots import make_robot_from_config

    return make_robot_from_config(robot_config(robot_type, settings))
