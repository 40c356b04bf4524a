"""Offered load: a scene's feeders scaled so that parts arrive at a chosen multiple of what its arms can complete.

Load 1.0 is the saturating rate: the most the capacity model (`capacity_bound`, a linear programme over arms, hops
and stations) says the line completes with its parts in the scene's own mix. Below it the line has spare
capacity and any sensible allocator keeps up; above it parts must be missed, and which ones is the allocator's
choice. `fleet sweep SCENE --load 0.5,1.0,1.5` runs the curve.
"""

from __future__ import annotations

from coordinator.capacity import arrival_rate_per_s, capacity_bound, route_hops
from scenes.schema import Scene

MAX_RATE_PER_MIN = 600.0  # the schema's most for one feeder
_TOLERANCE = 1e-3  # a bound within this share of its arrivals takes them all


def nominal_arrivals_per_s(scene: Scene) -> dict[tuple[str, int], float]:
    """Each part type's mean arrival rate (per feeder and type index), as the scene's feeders give them."""
    types = sorted({(h.feeder, h.type_index) for h in route_hops(scene)})
    return {(f, t): arrival_rate_per_s(scene, f) / len(scene.feeder(f).parts) for f, t in types}


def saturating_scale(scene: Scene, iterations: int = 40) -> float:
    """The factor on every feeder's rate at which the line's bound just takes every part (bisection over the capacity
    model, its hop times worked out once). Infinite for a scene where nothing bounds it but arrivals."""
    rates = nominal_arrivals_per_s(scene)
    if not rates or not sum(rates.values()):
        raise ValueError("the scene has no feeder: there is no load to scale")
    model = capacity_bound(scene).model

    def takes_all(scale: float) -> bool:
        scaled = {k: v * scale for k, v in rates.items()}
        bound = capacity_bound(scene, model=model, arrivals_per_s=scaled).throughput_bound_per_min
        return bound >= 60.0 * sum(scaled.values()) * (1.0 - _TOLERANCE)

    low, high = 0.0, 1.0
    while takes_all(high):
        low, high = high, high * 2.0
        if high > 1e4:
            return float("inf")
    for _ in range(iterations):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if takes_all(middle) else (low, middle)
    return low


def feeder_rates_for_load(scene: Scene, load: float) -> dict[str, float]:
    """Each feeder's rate (parts a minute) at `load` times the saturating rate; ValueError when one would pass
    the schema's most or the scene cannot be scaled."""
    if not load > 0:
        raise ValueError(f"load {load:g}: give a positive multiple of the line's capacity, e.g. 0.5,1.0,1.5")
    scale = saturating_scale(scene) * load
    if scale == float("inf"):
        raise ValueError("nothing but arrivals bounds this line: it has no capacity to offer a load against")
    out = {}
    for feeder in scene.feeders:
        rate = 60.0 * arrival_rate_per_s(scene, feeder.name) * scale
        if rate > MAX_RATE_PER_MIN:
            raise ValueError(
                f"load {load:g}: feeder {feeder.name} would release {rate:.0f} parts a minute "
                f"(at most {MAX_RATE_PER_MIN:.0f})"
            )
        out[feeder.name] = round(rate, 4)
    return out
