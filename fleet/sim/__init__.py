"""The sim server's side of the line: the physics world (the only package that imports SAPIEN), its parts and arms,
the trackers that drive them, the line watcher, observations and the world's bus messages.

SAPIEN warns on import when the system has no Vulkan loader; there is none on
these machines and physics does not need one, so that one warning is muted.
"""

import warnings

with warnings.catch_warnings():
    warnings.filterwarnings("ignore", message="Failed to find system libvulkan")
    import sapien  # noqa: F401
