"""Scene files: what a cell holds (conveyor, feeders, stations, arms), as validated pure data."""

from scenes.loader import RobotFacts, SceneError, bundled_scene_names, load_scene
from scenes.schema import Scene

__all__ = ["RobotFacts", "Scene", "SceneError", "bundled_scene_names", "load_scene"]
