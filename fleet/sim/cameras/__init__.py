"""Cameras: a render-only mirror of the physics world, the scene's cameras in it, and the frames they make.

The physics world never renders: it has no render system and pays nothing for
cameras. A `CameraRig` mirrors its bodies' poses into a scene of its own and
renders there, on a GPU where there is one, else on the CPU (Mesa's lavapipe).
"""
