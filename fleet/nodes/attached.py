"""What the nodes that attach to a running line over the bus (monitor, rosbridge, ROS 2 publisher) share: the
line's scene, asked of its sim, or one line saying why there is none."""

from __future__ import annotations

import sys

import zenoh

from fleet.bus.keys import Keys
from fleet.bus.scene_query import SceneUnavailable, fetch_scene
from scenes.schema import Scene


def line_scene(session: zenoh.Session, keys: Keys, timeout_s: float, prog: str) -> Scene | None:
    """The scene the line's sim serves; None after printing `prog: why` when no sim answered in `timeout_s`."""
    try:
        return fetch_scene(session, keys, timeout_s)
    except SceneUnavailable as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return None
