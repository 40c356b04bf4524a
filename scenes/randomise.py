"""Domain randomisation: ranges in a scene file, drawn once per run from the run's seed into a concrete scene.

A scene's `randomise` section gives a draw (uniform [low, high], or normal (mean, std) clipped
to the field's limits) for part friction, mass and size, belt speed, arrival rates, arm drive
gains and the noise on the part poses controllers see. `draw(scene)` returns the same scene with
the values applied and listed in `randomised`, so one seed is still one exact run, and every
process (sim, coordinator, controllers) that loads the scene with that seed sees the same line.
"""

from __future__ import annotations

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
    return scene.revalidated(**update)
