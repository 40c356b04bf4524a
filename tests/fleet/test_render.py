"""Rendering is optional: detection answers either way, and asking for images without a device is a clear error."""

import pytest

from fleet.sim.render import RenderUnavailable, render_device, require_render


def test_detection_answers_with_a_reason():
    ok, reason = render_device()
    assert isinstance(ok, bool) and reason
    if ok:
        require_render()
    else:
        with pytest.raises(RenderUnavailable, match="no Vulkan device to render cameras on"):
            require_render()
