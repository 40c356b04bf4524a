"""The physics world (the only package that imports SAPIEN).

SAPIEN warns on import when the system has no Vulkan loader; there is none on
these machines and physics does not need one, so that one warning is muted.
"""

import warnings

with warnings.catch_warnings():
    warnings.filterwarnings("ignore", message="Failed to find system libvulkan")
    import sapien  # noqa: F401
