"""When a camera's frame is taken, and which frame's detections a node may act on at a control tick: a frame is
usable `latency_s` after it was taken (the detector's budget), so every node of a lockstep line acts on the same
frame at the same tick."""

from __future__ import annotations

import math

DETECTION_LATENCY_S = 0.05  # a frame's detections reach the line this long after it was taken (its detection budget)


def frame_index(tick: int, rate_hz: float, control_hz: float) -> int:
    """The number of a camera's frame period that control tick `tick` falls in."""
    return math.floor(tick * rate_hz / control_hz + 1e-9)


def frame_due(tick: int, rate_hz: float, control_hz: float) -> bool:
    """Whether a frame falls on this control tick: the first tick at or after each multiple of 1 / rate_hz."""
    return tick == 0 or frame_index(tick, rate_hz, control_hz) != frame_index(tick - 1, rate_hz, control_hz)


def frame_tick(index: int, rate_hz: float, control_hz: float) -> int:
    """The control tick that frame number `index` is taken at (the first tick of its period)."""
    tick = max(0, math.ceil(index * control_hz / rate_hz) - 1)
    while frame_index(tick, rate_hz, control_hz) < index:
        tick += 1
    return tick


class SeenTicks:
    """The frames of cameras at `rates_hz` on a line ticking at `control_hz`, and the newest a node may act on."""

    def __init__(self, rates_hz: list[float], control_hz: float, latency_s: float = DETECTION_LATENCY_S) -> None:
        if not rates_hz or min(rates_hz) <= 0:
            raise ValueError("seen ticks need at least one camera, each with a positive rate")
        self.rates_hz, self.control_hz = list(rates_hz), control_hz
        self.latency_ticks = max(0, math.ceil(latency_s * control_hz - 1e-9))

    def due(self, tick: int) -> bool:
        """Whether any camera takes a frame at `tick`."""
        return any(frame_due(tick, rate, self.control_hz) for rate in self.rates_hz)

    def usable_at(self, tick: int) -> int:
        """The tick of the newest frame whose detections a node may act on at `tick` (-1: none yet)."""
        taken_by = tick - self.latency_ticks
        if taken_by < 0:
            return -1
        return max(frame_tick(frame_index(taken_by, r, self.control_hz), r, self.control_hz) for r in self.rates_hz)
