"""A sweep's grid: every combination of seeds, allocators and scene overrides, each one run with a stable id.

An override (`--set conveyor.speed_m_per_s=0.05,0.1`) sets one field of the scene file, by its dotted path
(list items by index: `feeders.0.arrival.rate_per_min`), to each of its values in turn (YAML scalars:
`none` removes an optional section, e.g. `randomise=none`). Each overridden scene is written to the sweep's
folder and checked like any scene file, so a bad path or value names the field and the file.

Offered load (`--load 0.5,1.0,1.5`) is the override `load`: every feeder's rate scaled so parts arrive at that
multiple of the rate the line's arms can just complete (`coordinator.offered_load`), after the other overrides.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import yaml

from fleet.common.scene_overrides import scene_with
from scenes.schema import MAX_SEED

MAX_RUNS = 100_000  # runs in one sweep: at a few seconds each, more would take a machine weeks


class GridError(ValueError):
    """A sweep flag that cannot work: one line for the user."""


@dataclass(frozen=True)
class Override:
    """One `--set PATH=V1,V2,...`: a dotted field path and the values it takes."""

    path: str
    values: tuple

    @classmethod
    def parse(cls, text: str) -> Override:
        path, sep, values = text.partition("=")
        if not sep or not path or not values:
            raise GridError(f"--set {text!r}: write FIELD.PATH=VALUE[,VALUE...], e.g. conveyor.speed_m_per_s=0.05,0.1")
        try:  # one YAML flow sequence: `0.05,0.1` is two values, `[0,0,0]` one list
            loaded = yaml.safe_load(f"[{values}]")
        except yaml.YAMLError as exc:
            problem = str(getattr(exc, "problem", "") or exc).splitlines()[0]
            raise GridError(
                f"--set {text!r}: {values!r} is not a YAML value or a comma-separated list of them ({problem})"
            ) from None
        if not isinstance(loaded, list) or not loaded:
            raise GridError(f"--set {text!r}: give at least one value after '='")
        parsed = [None if isinstance(v, str) and v.lower() == "none" else v for v in loaded]
        return cls(path.strip(), tuple(parsed))


@dataclass(frozen=True)
class RunCell:
    """One run of a sweep: what `fleet run` would be given."""

    scene: str
    seed: int
    allocator: str
    duration_s: float
    arms: int | None = None
    overrides: dict = field(default_factory=dict)
    restore_from: str | None = None  # a snapshot every run branches from (the seed then draws its later arrivals)
    perception: str = "truth"  # where the line's parts come from (`fleet run --perception`)

    @property
    def group(self) -> dict:
        """The cell's arguments but its seed: runs of one group are averaged."""
        return {
            "scene": self.scene,
            "arms": self.arms,
            "allocator": self.allocator,
            "duration_s": self.duration_s,
            **({"from": Path(self.restore_from).name} if self.restore_from else {}),
            **({"perception": self.perception} if self.perception != "truth" else {}),
            **self.overrides,
        }

    @property
    def run_id(self) -> str:
        """Stable across sweeps: a finished run is found again by it (a run on the truth as before perception was
        a choice)."""
        fields = asdict(self)
        if fields["perception"] == "truth":
            del fields["perception"]
        text = json.dumps(fields, sort_keys=True, default=str)
        return "r" + hashlib.sha256(text.encode()).hexdigest()[:12]


def scenes_for(cells: list[RunCell], folder: Path) -> dict[str, str]:
    """Each cell's scene to run (by run id): every distinct set of overrides written and checked once."""
    made: dict[str, str] = {}
    for overrides in {json.dumps([c.scene, c.overrides], sort_keys=True, default=str) for c in cells}:
        scene, values = json.loads(overrides)
        made[overrides] = scene_with(scene, values, folder)
    return {c.run_id: made[json.dumps([c.scene, c.overrides], sort_keys=True, default=str)] for c in cells}


def grid(
    scene: str,
    seeds: list[int],
    allocators: list[str],
    duration_s: float,
    arms: int | None = None,
    overrides: list[Override] = (),
    restore_from: str | None = None,
    perceptions: list[str] = ("truth",),
) -> list[RunCell]:
    """Every combination, seeds innermost (so the first runs already cover every group); refused in one line when
    there would be more than `MAX_RUNS` (counted before any is made)."""
    count = len(seeds) * len(allocators) * len(perceptions) * math.prod(len(o.values) for o in overrides)
    if count > MAX_RUNS:
        raise GridError(
            f"{count:,} runs ({len(seeds):,} seeds x {len(allocators)} allocators x the --set values): "
            f"a sweep takes at most {MAX_RUNS:,}"
        )
    paths = [o.path for o in overrides]
    combos = itertools.product(allocators, perceptions, *(o.values for o in overrides))
    cells = []
    for allocator, seeing, *values in combos:
        for seed in seeds:
            cell = RunCell(scene, seed, allocator, duration_s, arms, dict(zip(paths, values)), restore_from, seeing)
            cells.append(cell)
    return sorted(cells, key=lambda c: (c.seed, json.dumps(c.group, sort_keys=True, default=str)))


def parse_seeds(text: str) -> range | list[int]:
    """`0-19` (a range, never spelt out), `3`, or `1,4,9`: seeds from 0 to `MAX_SEED`, at most `MAX_RUNS` of them
    (counted before any is made)."""
    try:
        if "-" in text and "," not in text:
            low, high = (int(v) for v in text.split("-", 1))
            if high < low or low < 0:
                raise ValueError
            seeds = range(low, high + 1)
            count, top = high - low + 1, high  # not len(): a range past 2**63 has none
        else:
            seeds = [int(v) for v in text.split(",")]
            if min(seeds) < 0:
                raise ValueError
            count, top = len(seeds), max(seeds)
    except ValueError:
        raise GridError(f"--seeds {text!r}: give a range like 0-19, or a list like 1,4,9 (non-negative)") from None
    if top > MAX_SEED:
        raise GridError(f"--seeds {text[:40]!r}: a seed is at most {MAX_SEED:,} (a signed 64-bit integer)")
    if count > MAX_RUNS:
        raise GridError(f"--seeds {text[:40]!r}: {count:,} seeds; a sweep takes at most {MAX_RUNS:,} runs")
    return seeds
