"""What each agent of the env sees through the scene's cameras: spaces and images (`parallel_env(cameras=True)`).

An agent sees every camera fixed in the world and the cameras mounted on its own arm. Every camera renders at
every env step (all in one pass), so an observation's images are of the state it reports; the scene's `rate_hz`
paces a running line's cameras, not the env's.
"""

from __future__ import annotations

import gymnasium
import numpy as np

from fleet.sim.cameras.frames import CameraFrame
from fleet.sim.cameras.rig import CameraRig
from fleet.sim.world import World
from scenes.schema import Camera

SEGMENTATION_HIGH = 2**31 - 1


def chosen_cameras(scene_cameras: list[Camera], cameras: bool | list[Camera | dict]) -> list[Camera]:
    """The cameras an env renders: the scene's (`True`), none (`False`), or the list given (models or dicts of the
    scene format, replacing the scene's)."""
    if cameras is True:
        if not scene_cameras:
            raise ValueError("cameras=True, but the scene declares no cameras: give cameras=[...] (docs/cameras.md)")
        return list(scene_cameras)
    if cameras is False:
        return []
    chosen = [c if isinstance(c, Camera) else Camera.model_validate(c) for c in cameras]
    if len({c.name for c in chosen}) != len(chosen):
        raise ValueError(f"camera names must differ: {', '.join(c.name for c in chosen)}")
    return chosen


def image_spaces(camera: Camera) -> dict[str, gymnasium.spaces.Box]:
    """The observation keys and spaces of one camera's images."""
    h, w = camera.height_px, camera.width_px
    spaces = {
        "rgb": gymnasium.spaces.Box(0, 255, shape=(h, w, 3), dtype=np.uint8),
        "depth": gymnasium.spaces.Box(0.0, camera.far_m, shape=(h, w), dtype=np.float32),
        "segmentation": gymnasium.spaces.Box(0, SEGMENTATION_HIGH, shape=(h, w), dtype=np.int32),
    }
    return {f"{camera.name}_{kind}": spaces[kind] for kind in camera.images}


def frame_images(frame: CameraFrame) -> dict[str, np.ndarray]:
    """A frame's images under their observation keys."""
    return {f"{frame.camera}_{kind}": image for kind, image in frame.images().items()}


class EnvCameras:
    """The env's cameras over its world: who sees which, the spaces, and each step's images."""

    def __init__(self, world: World, cameras: list[Camera], agents: list[str]) -> None:
        self.rig = CameraRig(world, cameras)
        self.seen_by = {a: [c.name for c in cameras if c.arm is None or c.arm == a] for a in agents}
        self._models = {c.name: c for c in cameras}
        self._frames: dict[str, CameraFrame] = {}

    def space(self, agent: str, state: gymnasium.spaces.Space) -> gymnasium.spaces.Dict:
        """The agent's observation space: its usual observation under `state`, then its cameras' images."""
        spaces = {"state": state}
        for name in self.seen_by[agent]:
            spaces |= image_spaces(self._models[name])
        return gymnasium.spaces.Dict(spaces)

    def render(self) -> None:
        """Render every camera of the world as it stands now (one pass)."""
        self._frames = self.rig.frames()

    def observation(self, agent: str, state: object) -> dict:
        """The agent's observation: `state`, then the images of the cameras it sees from the last `render`."""
        out = {"state": state}
        for name in self.seen_by[agent]:
            out |= frame_images(self._frames[name])
        return out

    def picture(self) -> np.ndarray:
        """The picture `render_mode="rgb_array"` gives: the `overhead` camera's RGB, else the first fixed camera's."""
        fixed = [n for n, c in self._models.items() if c.arm is None and "rgb" in c.images]
        if not fixed:
            raise ValueError('render_mode="rgb_array" needs a fixed camera that makes rgb images (docs/cameras.md)')
        name = "overhead" if "overhead" in fixed else fixed[0]
        frame = self._frames.get(name) or self.rig.frames([name])[name]
        return frame.rgb
