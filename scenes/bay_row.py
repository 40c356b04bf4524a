"""A row of bays: a scene's arms, stations and feeders repeated along its conveyor (`bay_row`, `--arms N`).

Bay 0 is the scene as declared. Bay k stands `k * spacing_m` further downstream: its arms are `arm_<k*n+i>` (the
scene's bay must name its n arms `arm_0` .. `arm_<n-1>`), its stations and feeders the bay's names with `_b<k>`,
its routes and assemblies its own; its conveyor feeders set their parts down as much further along the belt (an
infeed per bay), and the belt grows at its downstream end by the row's extra length.
"""

from __future__ import annotations

import math

from pydantic import ValidationError

from scenes.schema import Arm, Conveyor, Feeder, Scene, Station


class BayRowError(ValueError):
    """A row of bays that cannot be made: the field at fault and why (the loader names the file)."""

    def __init__(self, field: str, why: str) -> None:
        super().__init__(why)
        self.field, self.why = field, why


def expand_bay_row(scene: Scene, arms: int | None) -> Scene:
    """The scene with its `bay_row` expanded to `arms` arms (its own count when None); unchanged without one."""
    row = scene.bay_row
    if row is None:
        return scene
    per_bay = len(scene.arms)
    bays = row.count if arms is None else arms // per_bay
    if arms is not None and arms % per_bay:
        raise BayRowError("bay_row.count", f"{arms} arms asked for; this scene takes bays of {per_bay} arms")
    if not 1 <= bays <= row.max_count:
        top = per_bay * row.max_count
        why = f"{bays * per_bay} arms asked for; this scene takes {per_bay} to {top}, {per_bay} a bay"
        raise BayRowError("bay_row.count", why)
    if bays == 1:
        return scene.model_copy(update={"bay_row": None})
    if [a.name for a in scene.arms] != [f"arm_{i}" for i in range(per_bay)]:
        raise BayRowError("bay_row", f"a repeated bay names its arms arm_0 .. arm_{per_bay - 1} in order")
    copies = [_bay(scene, k, row.spacing_m) for k in range(1, bays)]
    update = {
        "arms": scene.arms + [a for arms_k, _, _ in copies for a in arms_k],
        "stations": scene.stations + [s for _, stations_k, _ in copies for s in stations_k],
        "feeders": scene.feeders + [f for _, _, feeders_k in copies for f in feeders_k],
        "bay_row": None,
    }
    try:
        update["conveyor"] = Conveyor.model_validate(
            scene.conveyor.model_dump() | {"length_m": round(scene.conveyor.length_m + (bays - 1) * row.spacing_m, 6)}
        )
    except ValidationError as exc:
        why = f"{bays} bays need a longer belt than a conveyor may be: {exc.errors()[0]['msg']}"
        raise BayRowError("bay_row.spacing_m", why) from None
    return scene.model_copy(update=update)


def _bay(scene: Scene, k: int, spacing_m: float) -> tuple[list[Arm], list[Station], list[Feeder]]:
    """Bay k's arms, stations and feeders: the scene's own, `k * spacing_m` downstream, renamed as its own."""
    yaw = scene.conveyor.pose.yaw_rad
    dx, dy = k * spacing_m * math.cos(yaw), k * spacing_m * math.sin(yaw)
    per_bay = len(scene.arms)
    own = {s.name: f"{s.name}_b{k}" for s in scene.stations} | {f.name: f"{f.name}_b{k}" for f in scene.feeders}

    def moved(pose):
        x, y, z = pose.xyz
        return pose.model_copy(update={"xyz": (x + dx, y + dy, z)})

    arms = [
        a.model_copy(update={"name": f"arm_{k * per_bay + i}", "base": moved(a.base)}) for i, a in enumerate(scene.arms)
    ]
    stations = [
        s.model_copy(update={"name": own[s.name], "pose": moved(s.pose), "assembles": [own[f] for f in s.assembles]})
        for s in scene.stations
    ]
    feeders = []
    for f in scene.feeders:
        change = {"name": own[f.name], "route": [own.get(r, r) for r in f.route], "into": own.get(f.into, f.into)}
        if f.into == "conveyor":
            change["along_m"] = round(scene.drop_along_m(f) + k * spacing_m, 6)
        feeders.append(f.model_copy(update=change))
    return arms, stations, feeders
