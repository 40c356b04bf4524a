"""Optional rendering: detected, never required. Physics runs without any render device."""

from __future__ import annotations

import functools

import sapien


class RenderUnavailable(RuntimeError):
    """Asked for images on a machine where SAPIEN finds no render device."""


@functools.cache
def render_device() -> tuple[bool, str]:
    """Whether SAPIEN can render here, and why not if it cannot (checked once per process)."""
    try:
        sapien.render.RenderSystem()
    except RuntimeError as exc:
        return False, f"SAPIEN found no render device ({exc}); physics works without one, images do not"
    return True, "ok"


def require_render() -> None:
    """Raise a clear error where images are asked for and none can be made."""
    ok, reason = render_device()
    if not ok:
        raise RenderUnavailable(reason)
