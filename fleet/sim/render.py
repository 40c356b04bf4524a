"""Rendering, only where asked: a render system for cameras, or one line saying what to install.

Physics never needs a render device. Cameras need Vulkan: a GPU's driver, or
Mesa 25's software renderer (lavapipe) on the CPU; Debian 12's own Mesa 22.3
is refused by SAPIEN.
"""

from __future__ import annotations

import functools

import sapien

INSTALL_HINT = (
    "install Mesa's Vulkan drivers, version 25 or newer (Debian 12: mesa-vulkan-drivers from bookworm-backports; "
    "Debian 13, Ubuntu 24.04: mesa-vulkan-drivers), or a GPU's Vulkan driver (docs/cameras.md)"
)


class RenderUnavailable(RuntimeError):
    """Asked for images on a machine where SAPIEN finds no render device."""


SHADER = "minimal"  # SAPIEN's lightest camera shader: colour, and camera-space position (mm) with segmentation in one
# image, so a frame of all three kinds is two reads back, not three (about half the env's render time on a CPU)
_KEPT: list[sapien.render.RenderSystem] = []  # one held for the process: the renderer's set-up (seconds) is paid once


@functools.cache
def render_device() -> tuple[bool, str]:
    """Whether SAPIEN can render here, and why not if it cannot (checked once per process)."""
    try:
        sapien.render.set_camera_shader_dir(SHADER)
        _KEPT.append(sapien.render.RenderSystem())
    except RuntimeError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        return False, f"no Vulkan device to render cameras on ({first}): {INSTALL_HINT}"
    return True, "ok"


def require_render() -> None:
    """Raise a clear error where images are asked for and none can be made."""
    ok, reason = render_device()
    if not ok:
        raise RenderUnavailable(reason)


def renders_on_cpu() -> bool:
    """Whether this process's render device is a CPU renderer (Mesa's lavapipe, which Vulkan names llvmpipe)."""
    require_render()
    return "llvmpipe" in _KEPT[0].device.name.lower()


def casts_shadows(shadows: bool | str) -> bool:
    """A scene's `appearance.shadows` as drawn here: `auto` is shadows on a GPU, none on a CPU renderer."""
    return (not renders_on_cpu()) if shadows == "auto" else bool(shadows)


def render_system() -> sapien.render.RenderSystem:
    """A new render system (for one camera scene); `RenderUnavailable`, in one line, where none can be made."""
    require_render()
    return sapien.render.RenderSystem()
