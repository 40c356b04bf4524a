"""Domain randomisation: ranges in a scene file, drawn once per run from the run's seed into a concrete scene.

A scene's `randomise` section gives a draw (uniform [low, high], or normal (mean, std) clipped
to the field's limits) for part friction, mass and size, belt speed, arrival rates, arm drive
gains and the noise on the part poses controllers see; and, for the cameras only, the light's direction and
intensity, the belt's grey, the parts' shade and a shift of each camera. `draw(scene)` returns the same scene with
the values applied and listed in `randomised`, so one seed is still one exact run, and every
process (sim, coordinator, controllers) that loads the scene with that seed sees the same line.
"""

from __future__ import annotations

import math

import numpy as np

from scenes.schema import Draw, Scene

STREAM = 0x5EED_D0  # the draws' own random stream beside the feeders', from the same seed


def _value(draw: Draw, rng: np.random.Generator, low: float, high: float) -> float:
    if draw.uniform is not None:
        value = rng.uniform(*draw.uniform)
    else:
        value = rng.normal(*draw.normal)
    return float(min(max(value, low), high))


def draw(scene: Scene) -> Scene:
    """The scene with its `randomise` ranges drawn from `scene.seed` (unchanged without them)."""
    r = scene.randomise
    if r is None:
        return scene
    rng = np.random.default_rng([scene.seed, STREAM])
    drawn: dict[str, float] = {}

    def take(name: str, low: float, high: float, default: float = 1.0) -> float:
        d = getattr(r, name)
        if d is None:
            return default
        drawn[name] = round(_value(d, rng, low, high), 6)
        return drawn[name]

    friction = take("part_friction", 0.05, 2.0, default=None)
    mass, size = take("part_mass_scale", 0.05, 20.0), take("part_size_scale", 0.2, 5.0)
    belt, arrivals = take("belt_speed_scale", 0.0, 10.0), take("arrival_rate_scale", 0.01, 100.0)
    gains, noise = take("arm_gain_scale", 0.1, 10.0), take("part_pose_noise_m", 0.0, 0.05, default=0.0)
    feeders = []
    for f in scene.feeders:
        parts = [
            p.model_copy(
                update={
                    "friction": p.friction if friction is None else friction,
                    "mass_kg": min(max(p.mass_kg * mass, 0.0051), 1.0),
                    "size_m": tuple(min(max(s * size, 0.005), 0.2) for s in p.size_m),
                }
            )
            for p in f.parts
        ]
        a = f.arrival
        arrival = a.model_copy(
            update={"rate_per_min": min(a.rate_per_min * arrivals, 600.0)}
            if a.rate_per_min is not None
            else {"schedule_s": [t / arrivals for t in a.schedule_s]}
        )
        feeders.append(f.model_copy(update={"parts": parts, "arrival": arrival}))
    update = {
        "feeders": feeders,
        "randomise": None,
        "randomised": drawn,
        "drive_gain_scale": gains,
        "part_pose_noise_m": noise,
    }
    if scene.conveyor is not None:
        update["conveyor"] = scene.conveyor.model_copy(
            update={"speed_m_per_s": min(scene.conveyor.speed_m_per_s * belt, 0.5)}
        )
    update |= _looks(scene, take, rng)
    return scene.revalidated(**update)


def _looks(scene: Scene, take, rng: np.random.Generator) -> dict:
    """The visual draws: the light turned and scaled, the belt's grey, the parts' shade, each camera shifted."""
    looks = scene.appearance
    yaw = math.radians(take("light_yaw_deg", -180.0, 180.0, default=0.0))
    x, y, z = looks.light_direction_xyz
    turned = (x * math.cos(yaw) - y * math.sin(yaw), x * math.sin(yaw) + y * math.cos(yaw), z)
    appearance = looks.model_copy(
        update={
            "light_direction_xyz": turned,
            "light_intensity": min(looks.light_intensity * take("light_intensity_scale", 0.0, 5.0), 5.0),
            "belt_grey": take("belt_grey", 0.0, 1.0, default=looks.belt_grey),
            "part_shade": take("part_shade", 0.0, 2.0, default=looks.part_shade),
        }
    )
    jitter_m = take("camera_jitter_m", 0.0, 0.5, default=0.0)
    cameras = []
    for camera in scene.cameras:
        pose = camera.pose
        shift = rng.normal(0.0, jitter_m, size=(2, 3)) if jitter_m > 0 else np.zeros((2, 3))
        moved = {"xyz": tuple(np.add(pose.xyz, shift[0])), "look_at": tuple(np.add(pose.look_at, shift[1]))}
        cameras.append(camera.model_copy(update={"pose": pose.model_copy(update=moved)}))
    return {"appearance": appearance, "cameras": cameras}
