"""The scene of a running line on the bus: whoever plays the line (the sim, a replay) answers `Keys.scene` with
it as JSON; a monitor or a recorder asks."""

from __future__ import annotations

import time

import zenoh

from fleet.bus.keys import Keys
from fleet.scene_loading import use_scene_robots
from scenes.schema import Scene
from scenes.yaml_file import DeclarationError


class SceneUnavailable(RuntimeError):
    """No sim answered the scene query in time."""


def fetch_scene(session: zenoh.Session, keys: Keys, timeout_s: float = 10.0) -> Scene:
    """The scene the running sim serves (`Keys.scene`), asked until it answers or `timeout_s` passes."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for reply in session.get(keys.scene, timeout=min(1.0, max(deadline - time.monotonic(), 0.1))):
            if reply.ok is not None:
                scene = Scene.model_validate_json(reply.ok.payload.to_bytes())
                try:
                    return use_scene_robots(scene)
                except DeclarationError as exc:  # the run's robot files are not on this host (or not the same)
                    raise SceneUnavailable(f"the scene of run {keys.run!r} names a robot file that cannot be used here: {exc}") from None
        time.sleep(0.1)
    raise SceneUnavailable(f"no sim of run {keys.run!r} answered on {keys.scene} within {timeout_s:.0f} s")


def serve_scene(session: zenoh.Session, keys: Keys, scene_json: str) -> zenoh.Queryable:
    """Answer scene queries with `scene_json` until the returned queryable is undeclared."""
    payload = scene_json.encode()
    return session.declare_queryable(keys.scene, lambda query: query.reply(keys.scene, payload))
