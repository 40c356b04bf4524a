"""What the sim and the coordinator must agree on: when the coordinator decides (the phases they reason about are
`robots.phase`'s). One place, imported by both."""

from __future__ import annotations

from scenes.schema import Scene

COORD_RATE_HZ = 10.0  # coordinator decisions per second of sim time


def decision_period_ticks(scene: Scene) -> int:
    """Sim ticks between two coordinator decisions."""
    return max(1, round(scene.control_hz / COORD_RATE_HZ))


def moves_need_grants(scene: Scene) -> bool:
    """Whether the arms ask the coordinator before each free move: whenever another arm could be in the way."""
    return len(scene.arms) > 1
