"""A seeded generator of messages a line must survive: random bytes, truncated messages, and well-formed
messages that are wrong (unknown ids, ticks and order counts from the far future, NaN and infinite numbers,
lengths that do not fit), on every key of a run. None of them is a plausible true message: each must be
dropped or refused, and counted, by whoever receives it."""

from __future__ import annotations

import math
import random
from collections.abc import Iterator

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.messages import (
    ArmState,
    ArmStatus,
    Assignment,
    ControllerStep,
    CoordTick,
    GripperGoalMsg,
    LineEvent,
    LineView,
    MotionGrant,
    PartsState,
    TrajectoryGoalMsg,
)

FAR = 10**18
NAN, INF = math.nan, math.inf


class BusFuzzer:
    """`messages(n)` yields (key, payload) pairs, the same ones for the same seed."""

    def __init__(self, keys: Keys, arms: list[str], n_joints: int, seed: int = 0) -> None:
        self.keys, self.arms, self.n = keys, arms, n_joints
        self.rng = random.Random(seed)

    def messages(self, count: int) -> Iterator[tuple[str, bytes]]:
        makers = [
            self._event,
            self._frame,
            self._parts,
            self._coord_tick,
            self._state,
            self._step,
            self._order,
            self._goal,
            self._status,
        ]
        for _ in range(count):
            key, payload = self.rng.choice(makers)()
            roll = self.rng.random()
            if roll < 0.2:
                payload = self.rng.randbytes(self.rng.randrange(0, 200))  # noise
            elif roll < 0.3:
                payload = payload[: self.rng.randrange(0, max(1, len(payload)))]  # cut short
            yield key, payload

    # --- one wrong message per kind of key --------------------------------------------
    def _arm(self) -> str:
        return self.rng.choice(self.arms)

    def _bad(self) -> float:
        return self.rng.choice((NAN, INF, -INF))

    def _joints(self, ok: bool = False) -> tuple[float, ...]:
        n = self.n if ok else self.rng.choice((0, 1, self.n + 3))
        return tuple(self.rng.uniform(-3, 3) for _ in range(n))

    def _event(self):
        kind = self.rng.choice(("arrived", "at_station", "lost", "retired", "exploded"))
        part = self.rng.randrange(10**6, 10**9)  # no such part
        return self.keys.events, encode(
            LineEvent(kind, part, self.rng.choice((FAR, -5)), self.rng.choice(("nope", "bin_x", "")), -1)
        )

    def _state(self, arm: str | None = None) -> tuple[str, bytes]:
        arm = arm or self._arm()
        wrong = self.rng.randrange(3)
        tick = FAR if wrong == 0 else self.rng.randrange(0, 100)
        q = self._joints(ok=wrong != 1)
        dq = tuple(self._bad() for _ in range(self.n)) if wrong == 2 else self._joints(ok=True)
        msg = ArmState(
            arm, tick, 1e16 if wrong == 0 else 0.5, q, dq, (0.0, 0.0), (0.0,) * 3, (1.0, 0.0, 0.0, 0.0), lost=True
        )
        return self.keys.arm_state(arm), encode(msg)

    def _frame(self):
        states = tuple(ArmState(a, FAR, 1e16, self._joints(), (), (), (), ()) for a in self.arms)
        return self.keys.frame, encode(LineView(FAR, 1e16, states, PartsState(FAR, 1e16, (), (), (), (), (), (), ())))

    def _parts(self):
        k = self.rng.randrange(1, 4)
        wrong = self.rng.randrange(2)
        msg = PartsState(
            FAR if wrong == 0 else self.rng.randrange(0, 50),
            0.5,
            tuple(range(10**6, 10**6 + k)),
            ("x",) * k,
            (0,) * k,
            (self._bad(),) * (3 * k) if wrong else (0.0,) * (3 * k + 1),
            (1.0, 0.0, 0.0, 0.0) * k,
            (0.0,) * (3 * k),
            (0.05,) * (3 * k),
        )
        return self.keys.parts, encode(msg)

    def _coord_tick(self):
        return self.keys.coord("tick"), encode(CoordTick(FAR, tuple(2**62 for _ in self.arms)))

    def _step(self):
        arm = self._arm()
        msg = ControllerStep(
            arm,
            self.rng.randrange(0, 50),
            FAR,
            (),
            None,
            "approach",
            0.1,
            "",
            self.rng.randrange(1, 99),
            (self._bad(),) * self.n,
            1.0,
        )
        return self.keys.arm_step(arm), encode(msg)

    def _order(self):
        arm = self._arm()
        seq = self.rng.choice((2**63 - 1, FAR, -1))
        if self.rng.random() < 0.5:
            msg = Assignment(arm, seq, 7, 10**6, 0.1, (self._bad(), 0.0, 0.0), (0.0, 0.0, 0.0))
        else:
            msg = MotionGrant(arm, seq, 10**6, "grant", "", -1.0, self._bad())
        return self.keys.arm_assign(arm), encode(msg)

    def _goal(self):
        arm = self._arm()
        if self.rng.random() < 0.5:
            msg = TrajectoryGoalMsg(
                arm, self.rng.randrange(1, 10**6), ("no_such_joint",) * self.n, (0.5,), (self._bad(),) * self.n
            )
        else:
            msg = GripperGoalMsg(arm, self.rng.randrange(1, 10**6), self._bad())
        return self.keys.arm_goal(arm), encode(msg)

    def _status(self):
        return self.keys.arm_status("arm_nope"), encode(ArmStatus("arm_nope", FAR, 1e16, "idle", None, 0.0))
