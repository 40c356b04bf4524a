"""The last measurement of each pair of arms, reused while neither arm has moved: most arms of a line stand still
from one decision to the next (98% of arm-decisions in an 8-arm sorting row), and the cell's separation watch
measures the same still pairs at every decision."""

from __future__ import annotations

from collections.abc import Callable

from coordinator.geometry import ArmGeometry

Measure = Callable[[ArmGeometry, ArmGeometry, float], tuple | None]


class PairMeasurements:
    """What `measure(a, b, below_m)` said of each pair (its first item the distance, exact; None: not below
    `below_m`), kept with the joints both arms were placed at; an answer is reused only where it is the answer a
    new measurement would give (the same placements, and the distance known to be below or not below the bound)."""

    def __init__(self) -> None:
        self._last: dict[tuple[str, str], tuple[bytes, bytes, float, tuple | None]] = {}
        self.reused = 0

    def measured(self, a: ArmGeometry, b: ArmGeometry, below_m: float, measure: Measure) -> tuple | None:
        last = self._last.get((a.name, b.name))
        if last is not None and last[0] == a.placed_key and last[1] == b.placed_key:
            _, _, was_below_m, found = last
            if found is not None:
                self.reused += 1
                return found if found[0] < below_m else None
            if below_m <= was_below_m:
                self.reused += 1
                return None
        found = measure(a, b, below_m)
        self._last[(a.name, b.name)] = (a.placed_key, b.placed_key, below_m, found)
        return found
