"""The scene of a running line on the bus: whoever plays the line (the sim, a replay) answers `Keys.scene` with
it as JSON; a monitor or a recorder asks."""

from __future__ import annotations

import zenoh

from fleet.bus.keys import Keys
from fleet.bus.query import first_answer
from fleet.common.scene_loading import use_scene_robots
from scenes.schema import Scene
from scenes.yaml_file import DeclarationError


class SceneUnavailable(RuntimeError):
    """No sim answered the scene query in time."""


def run_scene(scene_json: str | bytes, run: str) -> Scene:
    """A run's scene as its sim sent it (over the bus, or in its spool), with the robots it names registered here;
    `SceneUnavailable` if a robot file it names cannot be used on this host."""
    try:
        return use_scene_robots(Scene.model_validate_json(scene_json))
    except DeclarationError as exc:  # the run's robot files are not on this host (or not the same)
        raise SceneUnavailable(f"the scene of run {run!r} names a robot file that cannot be used here: {exc}") from None


def fetch_scene(session: zenoh.Session, keys: Keys, timeout_s: float = 10.0) -> Scene:
    """The scene the running sim serves (`Keys.scene`), asked until it answers or `timeout_s` passes."""
    scene = first_answer(session, keys.scene, lambda payload: run_scene(payload, keys.run), timeout_s)
    if scene is None:
        raise SceneUnavailable(f"no sim of run {keys.run!r} answered on {keys.scene} within {timeout_s:.0f} s")
    return scene


def serve_scene(session: zenoh.Session, keys: Keys, scene_json: str) -> zenoh.Queryable:
    """Answer scene queries with `scene_json` until the returned queryable is undeclared."""
    payload = scene_json.encode()
    return session.declare_queryable(keys.scene, lambda query: query.reply(keys.scene, payload))
