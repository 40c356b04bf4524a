"""Arms whose motion requests the guard denies, and because of whom: what tells a deadlock of two arms (each
denied because of the other) from an arm that simply waits, and how long each has waited for a grant."""

from __future__ import annotations

from dataclasses import dataclass, field

BLOCKED_FOR_S = 1.0  # a denial this recent (sim s) means the arm still waits (skills ask again every decision)


@dataclass(frozen=True)
class Denial:
    by: str  # the arm in the way
    since_s: float  # when its requests were first denied (since its last grant)
    last_s: float  # when last


@dataclass
class DeniedArms:
    """The latest denial of each arm, until it is granted."""

    denials: dict[str, Denial] = field(default_factory=dict)

    def denied(self, arm: str, by: str, at_s: float) -> None:
        earlier = self.denials.get(arm)
        self.denials[arm] = Denial(by, earlier.since_s if earlier else at_s, at_s)

    def granted(self, arm: str) -> None:
        self.denials.pop(arm, None)

    def blocks(self, waiting: str, arm: str, now_s: float) -> bool:
        """Whether `waiting` is denied because of `arm` lately, and still waits."""
        d = self.denials.get(waiting)
        return d is not None and d.by == arm and now_s - d.last_s <= BLOCKED_FOR_S

    def waiting_s(self, now_s: float) -> dict[str, float]:
        """The arms still denied (asked again within `BLOCKED_FOR_S`): how long each has waited for a grant."""
        return {a: now_s - d.since_s for a, d in self.denials.items() if now_s - d.last_s <= BLOCKED_FOR_S}
