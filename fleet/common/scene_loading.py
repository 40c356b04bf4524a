"""Scenes as clawfleet's programs load them: every robot known (built in, from entry points, the scene's robot files).

Every process of a run loads its scene through here, so a robot that a scene
declares in a file (`robot_files`) is registered in each of them before any
arm is built, planned for or drawn.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from pathlib import Path

from robots.measured_reach import reach_m_of
from robots.registry import declared_robots, get_robot, register_file
from scenes import loader
from scenes.loader import RobotFacts
from scenes.schema import Scene


class RegisteredRobots(Mapping[str, RobotFacts]):
    """What scene validation needs of every registered robot, worked out only for the models a scene uses (a reach
    is measured from the robot's kinematics: a model the scene does not name need not even be installed)."""

    def __getitem__(self, uid: str) -> RobotFacts:
        if uid not in self:
            raise KeyError(uid)
        spec = get_robot(uid)
        return RobotFacts(reach_m_of(spec), spec.link_names())

    def __contains__(self, uid: object) -> bool:
        return uid in {spec.uid for spec in declared_robots()}

    def __iter__(self) -> Iterator[str]:
        return iter([spec.uid for spec in declared_robots()])

    def __len__(self) -> int:
        return len(declared_robots())


def robot_facts() -> Mapping[str, RobotFacts]:
    """What scene validation needs of every registered robot."""
    return RegisteredRobots()


def read_robot_file(path: Path) -> tuple[str, RobotFacts]:
    """Register the robot a scene's robot file declares; its uid and facts."""
    spec = register_file(path)
    return spec.uid, RobotFacts(reach_m_of(spec), spec.link_names())


def load_checked_scene(name_or_path: str | Path, *, arms: int | None = None, seed: int | None = None) -> Scene:
    """A scene by bundled name or path, checked against the known robots, its own robot files registered."""
    return loader.load_scene(name_or_path, arms=arms, seed=seed, robots=robot_facts(), read_robot_file=read_robot_file)


def use_scene_robots(scene: Scene) -> Scene:
    """Register the robot files of a scene that arrived already loaded (over the bus, from a recording)."""
    for file in scene.robot_files:
        register_file(file)
    return scene
