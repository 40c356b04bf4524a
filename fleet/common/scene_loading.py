"""Scenes as clawfleet's programs load them: every robot known (built in, from entry points, the scene's robot files).

Every process of a run loads its scene through here, so a robot that a scene
declares in a file (`robot_files`) is registered in each of them before any
arm is built, planned for or drawn.
"""

from __future__ import annotations

from pathlib import Path

from robots.registry import declared_robots, register_file
from scenes import loader
from scenes.loader import RobotFacts
from scenes.schema import Scene


def robot_facts() -> dict[str, RobotFacts]:
    """What scene validation needs of every registered robot."""
    return {spec.uid: RobotFacts(spec.reach_m) for spec in declared_robots()}


def read_robot_file(path: Path) -> tuple[str, RobotFacts]:
    """Register the robot a scene's robot file declares; its uid and facts."""
    spec = register_file(path)
    return spec.uid, RobotFacts(spec.reach_m)


def load_scene(name_or_path: str | Path, *, arms: int | None = None, seed: int | None = None) -> Scene:
    """A scene by bundled name or path, checked against the known robots, its own robot files registered."""
    return loader.load_scene(name_or_path, arms=arms, seed=seed, robots=robot_facts(), read_robot_file=read_robot_file)


def use_scene_robots(scene: Scene) -> Scene:
    """Register the robot files of a scene that arrived already loaded (over the bus, from a recording)."""
    for file in scene.robot_files:
        register_file(file)
    return scene
