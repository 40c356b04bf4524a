"""A servo joint as a worn real one reads: backlash (the output lags the motor by up to half the play each way, so a
joint that turns back reads the play behind) and encoder noise (Gaussian, per read, rounded to ticks). It wraps any
`ServoJoint`: `fleet twin serve-bus --backlash-deg --noise-deg` serves a sim arm as a less perfect real one, the
"real" side against which a twin's deviation figures are checked."""

from __future__ import annotations

import math

import numpy as np

from robots.feetech.control_table import TICKS_PER_TURN
from robots.feetech.servos import ServoJoint

TICKS_PER_DEG = TICKS_PER_TURN / 360.0


class ImperfectJoint:
    """`joint` read through `backlash_deg` of play and `noise_deg` of encoder noise (standard deviation), drawn from
    `rng`; goals pass through unchanged."""

    def __init__(self, joint: ServoJoint, backlash_deg: float, noise_deg: float, rng: np.random.Generator) -> None:
        if not (math.isfinite(backlash_deg) and backlash_deg >= 0.0):
            raise ValueError(f"backlash {backlash_deg!r} degrees: give a finite number, 0 or more")
        if not (math.isfinite(noise_deg) and noise_deg >= 0.0):
            raise ValueError(f"noise {noise_deg!r} degrees: give a finite number, 0 or more")
        self.joint, self.rng = joint, rng
        self.half_play_ticks = backlash_deg * TICKS_PER_DEG / 2.0
        self.noise_ticks = noise_deg * TICKS_PER_DEG
        self._motor: float | None = None  # the motor's ticks, unwrapped (a turn past 4095 goes on to 4096)
        self._output = 0.0  # where the output stands within the play (ticks, unwrapped)

    def position_ticks(self) -> int:
        ticks = self.joint.position_ticks()
        if self._motor is None:
            self._motor = self._output = float(ticks)
        half = TICKS_PER_TURN // 2
        self._motor += (ticks - self._motor + half) % TICKS_PER_TURN - half
        motor = self._motor
        # the output follows only once the motor has taken up the play on its side
        self._output = min(max(self._output, motor - self.half_play_ticks), motor + self.half_play_ticks)
        noise = self.rng.normal(0.0, self.noise_ticks) if self.noise_ticks else 0.0
        return int(round(self._output + noise)) % TICKS_PER_TURN

    def velocity_ticks_per_s(self) -> int:
        return self.joint.velocity_ticks_per_s()

    def drive(self, goal_ticks: int | None) -> None:
        self.joint.drive(goal_ticks)
