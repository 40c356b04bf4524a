"""`fleet bench cameras`: what rendering costs: frames per second by size and number of cameras, and the env's
agent-steps per second with a wrist camera on every arm against none.

The world is the 4-arm sorting line with parts on the belt; between two renders it runs a tenth of a second of
physics, so every frame shows moved arms and parts. The first frame of a process (the renderer compiling its
pipelines) is timed apart.
"""

from __future__ import annotations

import math
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from fleet.bench.camera_choices import IMAGES
from fleet.bench.physics import populated_sorting_world
from fleet.sim.cameras.rig import CameraRig
from fleet.sim.render import casts_shadows
from scenes.schema import Camera


@dataclass(frozen=True)
class CameraBenchRow:
    width_px: int
    height_px: int
    cameras: int
    images: str
    frames: int
    render_s: float
    first_frame_s: float

    @property
    def ms_per_pass(self) -> float:
        """Wall time of one render of every camera (mirror sync, render, read back), in milliseconds."""
        return 1000.0 * self.render_s / self.frames

    @property
    def frames_per_s(self) -> float:
        """Camera frames per wall second (a pass of n cameras makes n frames)."""
        return self.cameras * self.frames / self.render_s


def views(count: int, size: tuple[int, int], images: list[str]) -> list[Camera]:
    """`count` cameras over the sorting line's first arms: one straight down, the others from around it."""
    centre = (0.8, -0.2, 0.05)
    cameras = []
    for k in range(count):
        if k == 0:
            xyz, up = (0.8, -0.2, 2.0), (0.0, 1.0, 0.0)
        else:
            angle = 2 * math.pi * (k - 1) / max(1, count - 1)
            xyz, up = (0.8 + 1.2 * math.cos(angle), -0.2 + 1.2 * math.sin(angle), 1.2), (0.0, 0.0, 1.0)
        cameras.append(
            Camera(
                name=f"cam_{k}",
                pose={"xyz": xyz, "look_at": centre, "up": up},
                width_px=size[0],
                height_px=size[1],
                rate_hz=5,
                images=images,
            )
        )
    return cameras


def bench_cameras(size: tuple[int, int], count: int, images: str = "rgbd", frames: int = 20) -> CameraBenchRow:
    """Time `frames` renders of `count` cameras of `size` making `images` over the populated 4-arm sorting line."""
    world = populated_sorting_world(4)
    rig = CameraRig(world, views(count, size, IMAGES[images]))
    start = time.perf_counter()
    rig.frames()
    first = time.perf_counter() - start
    spent = 0.0
    for _ in range(frames):
        world.step(10)
        start = time.perf_counter()
        made = rig.frames()
        spent += time.perf_counter() - start
    assert all(np.any(f.rgb) for f in made.values()), "every camera shows something"
    return CameraBenchRow(size[0], size[1], count, images, frames, spent, first)


@dataclass(frozen=True)
class EnvCameraRow:
    arms: int
    size_px: int
    steps: int
    shadows: bool
    without_s: float
    with_s: float

    @property
    def agent_steps_per_s_without(self) -> float:
        return self.arms * self.steps / self.without_s

    @property
    def agent_steps_per_s(self) -> float:
        return self.arms * self.steps / self.with_s


def wrist_cameras(arms: int, size_px: int) -> list[dict]:
    """An RGB-D camera of `size_px` square on every arm's claw (`arm_<i>/tool_link`), as pick_cell's wrist camera."""
    return [
        {
            "name": f"wrist_{i}",
            "mount": f"arm_{i}/tool_link",
            "pose": {"xyz": [0.05, 0.0, -0.06], "look_at": [0.0, 0.0, 0.12], "up": [1.0, 0.0, 0.0]},
            "width_px": size_px,
            "height_px": size_px,
            "fov_deg": 75,
            "near_m": 0.01,
            "far_m": 3.0,
            "images": ["rgb", "depth"],
        }
        for i in range(arms)
    ]


def scene_file(folder: Path, arms: int, cameras: list[Camera], shadows: bool | str) -> Path:
    """The sorting line with `arms` arms and `cameras`, its light's `shadows` as given: a scene file in `folder`."""
    from fleet.common.scene_loading import load_checked_scene

    scene = load_checked_scene("sorting_line", arms=arms)
    appearance = scene.appearance.model_copy(update={"shadows": shadows})
    data = scene.model_copy(update={"cameras": cameras, "appearance": appearance})
    path = folder / "sorting_line_bench.yaml"
    path.write_text(yaml.safe_dump(data.model_dump(mode="json", exclude={"randomised"})))
    return path


def bench_env_cameras(
    arms: int = 4, size_px: int = 64, steps: int = 200, seed: int = 0, shadows: bool | str = "auto"
) -> EnvCameraRow:
    """The env's `reach` with random actions, without cameras and with an RGB-D wrist camera on every arm (its
    light's `shadows` as given; the row says whether they were drawn)."""
    from fleet.env.cell_env import CellParallelEnv  # the env only for this row

    timings = []
    with tempfile.TemporaryDirectory() as folder:
        scene = str(scene_file(Path(folder), arms, [], shadows))
        for cameras in (False, wrist_cameras(arms, size_px)):
            timings.append(_time_env(CellParallelEnv(scene, arms, "reach", max_cycles=steps, cameras=cameras), seed))
    return EnvCameraRow(arms, size_px, steps, casts_shadows(shadows), *timings)


def _time_env(env, seed: int) -> float:
    """Seconds `env` takes for its `max_cycles` steps of seeded random actions (then closed)."""
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    actions = [
        {a: rng.uniform(-1, 1, env.action_space(a).shape).astype(np.float32) for a in env.possible_agents}
        for _ in range(env.max_cycles)
    ]
    start = time.perf_counter()
    for act in actions:
        env.step(act)
    elapsed = time.perf_counter() - start
    env.close()
    return elapsed


@dataclass(frozen=True)
class LineCameraRow:
    arms: int
    width_px: int
    height_px: int
    images: str
    rate_hz: float
    sim_seconds: float
    shadows: bool
    encoding: str
    loop_without_s: float
    loop_with_s: float
    render_s: float
    encode_s: float
    frames: int

    @property
    def ratio(self) -> float:
        """The line's loop wall time with the camera over without it."""
        return self.loop_with_s / self.loop_without_s

    @property
    def added_over_render(self) -> float:
        """Wall time the camera added to the loop, over the wall time its frames took to render."""
        return (self.loop_with_s - self.loop_without_s) / self.render_s


def bench_line_cameras(
    size: tuple[int, int],
    images: str = "rgbd",
    rate_hz: float = 5.0,
    arms: int = 4,
    sim_seconds: float = 30.0,
    shadows: bool | str = "auto",
    encoding: str = "auto",
) -> LineCameraRow:
    """The sorting line in lockstep (all its processes), without a camera and with one over its arms (the
    `views` overhead, `size`, `images`, `rate_hz`), one after the other with the same seed: the sim's loop wall time
    of each and what the camera's frames cost."""
    from fleet.run.launcher import Launcher, RunOptions

    camera = views(1, size, IMAGES[images])[0].model_copy(update={"name": "bench", "rate_hz": rate_hz})
    loops, report = [], {}
    with tempfile.TemporaryDirectory() as folder:
        path = scene_file(Path(folder), arms, [camera], shadows)
        for cameras in (None, "bench"):
            options = RunOptions(
                scene=str(path), duration_s=sim_seconds, run_id="benchcam", cameras=cameras, camera_encoding=encoding
            )
            with Launcher(options) as launcher:
                summary = launcher.run()
            if summary["status"] != "ok":
                raise RuntimeError(f"the benchmark's line failed: {summary.get('error')}")
            loops.append(summary["loop_wall_seconds"])
            report = summary.get("cameras") or report
    return LineCameraRow(
        arms, size[0], size[1], images, rate_hz, sim_seconds, casts_shadows(shadows), options.rgb_encoding(),
        loops[0], loops[1],
        report["render_s"], report["encode_s"], report["frames"],
    )  # fmt: skip
