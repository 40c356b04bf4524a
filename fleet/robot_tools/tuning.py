"""A seeded search over a robot's drive gains and pick timing, each setting judged by the same seeded pick trials:
what `fleet tune` runs, so that every registered robot's values come from measurement, not from guesses.

The first candidate is the robot as registered; the others are drawn from `SPACE` with the search's seed. Each
is registered under a uid of its own (`<uid>__tune<k>`) and tried on trials `seed .. seed + trials - 1`; the
best places the most parts, then takes the least sim time per trial.
"""

from __future__ import annotations

import dataclasses
import itertools
import multiprocessing
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np

from fleet.robot_tools.trials import run_trials
from robots.registry import get_robot, register, robot_names
from robots.skills.pick_place import PickPlaceTiming
from robots.spec import DriveGains, RobotSpec

SPACE: dict[str, tuple[float, ...]] = {
    "arm_stiffness_scale": (0.5, 1.0, 2.0),
    "gripper_force_scale": (0.5, 1.0, 2.0, 4.0),
    "approach_speed": (0.2, 0.4, 0.6, 0.8, 1.0),
    "transfer_speed": (0.15, 0.3, 0.45, 0.7, 1.0),
    "lift_s": (0.5, 0.8),
    "hover_m": (0.04, 0.06, 0.08, 0.10),
    "lift_m": (0.06, 0.09, 0.12),
    "pregrasp_clearance_m": (0.016, 0.024, 0.032),
    "fixed_jaw_gap_m": (0.0, 0.002, 0.004, 0.006),
    "finger_friction": (1.2, 1.5, 2.0),
}
"""What is searched: factors on the registered drive gains (arm stiffness and damping together; the gripper's force
limit), the skill's speeds (fractions of the joints' velocity limits), the lift's duration (seconds) and the pick's
heights and widths: how high the claw hovers before it descends (and over the place), how high it lifts a part, how
much wider than the part it opens on the way down, how far clear of the part a fixed jaw comes down (metres); and
the friction of the finger pads (the material both sides of a grasp are given)."""
TIMING = (
    "approach_speed",
    "transfer_speed",
    "lift_s",
    "hover_m",
    "lift_m",
    "pregrasp_clearance_m",
    "fixed_jaw_gap_m",
)
"""The searched values that are pick timing fields (`PickPlaceTiming`); the others scale drive gains."""


@dataclass(frozen=True)
class Candidate:
    """One setting tried: factors on the registered gains and the pick timing values it sets."""

    arm_stiffness_scale: float = 1.0
    gripper_force_scale: float = 1.0
    approach_speed: float | None = None
    transfer_speed: float | None = None
    lift_s: float | None = None
    hover_m: float | None = None
    lift_m: float | None = None
    pregrasp_clearance_m: float | None = None
    fixed_jaw_gap_m: float | None = None
    finger_friction: float | None = None

    def spec_for(self, spec: RobotSpec, uid: str) -> RobotSpec:
        """The robot with this setting, under `uid`."""
        a, g = spec.arm_gains, spec.gripper_gains
        timing = dict(spec.pick_timing)
        for name in TIMING:
            value = getattr(self, name)
            if value is not None:
                timing[name] = value
        return dataclasses.replace(
            spec,
            uid=uid,
            arm_gains=DriveGains(
                a.stiffness * self.arm_stiffness_scale, a.damping * self.arm_stiffness_scale, a.force_limit
            ),
            gripper_gains=DriveGains(g.stiffness, g.damping, g.force_limit * self.gripper_force_scale),
            pick_timing=timing,
            finger_friction=spec.finger_friction if self.finger_friction is None else self.finger_friction,
        )

    def describe(self, spec: RobotSpec) -> dict[str, float]:
        """The values this setting gives the robot, as a robot file or `RobotSpec` would carry them."""
        tuned = self.spec_for(spec, spec.uid)
        timing = PickPlaceTiming.for_robot(tuned)
        return {
            "arm_stiffness": tuned.arm_gains.stiffness,
            "arm_damping": tuned.arm_gains.damping,
            "gripper_force_limit": tuned.gripper_gains.force_limit,
            "finger_friction": tuned.finger_friction,
            **{name: getattr(timing, name) for name in TIMING},
        }


@dataclass(frozen=True)
class Tried:
    """A candidate's trials: how many placed their part and the mean sim seconds a trial took."""

    candidate: Candidate
    successes: int
    trials: int
    mean_sim_s: float
    failures: tuple[str, ...]

    @property
    def rank_key(self) -> tuple[float, float]:
        return (-self.successes, self.mean_sim_s)


def candidates(count: int, seed: int, vary: Sequence[str] | None = None) -> list[Candidate]:
    """The registered robot first, then `count - 1` distinct settings drawn from `SPACE` with `seed` (only the
    values named in `vary`, when given: the others stay as registered)."""
    names = list(SPACE) if vary is None else list(dict.fromkeys(vary))
    unknown = [n for n in names if n not in SPACE]
    if unknown or not names:
        raise ValueError(f"cannot vary {', '.join(unknown) or 'nothing'}; valid values: {', '.join(SPACE)}")
    grid = list(itertools.product(*(SPACE[n] for n in names)))
    rng = np.random.default_rng(seed)
    picks = rng.choice(len(grid), size=min(count - 1, len(grid)), replace=False) if count > 1 else []
    return [Candidate()] + [Candidate(**dict(zip(names, (float(v) for v in grid[i])))) for i in picks]


def try_candidate(uid: str, k: int, cand: Candidate, trials: int, seed: int) -> Tried:
    """One candidate's trials, under its own uid (`<uid>__tune<k>`)."""
    name = f"{uid}__tune{k}"
    if name not in robot_names():
        register(cand.spec_for(get_robot(uid), name))
    runs = run_trials(name, trials, seed)
    failed = tuple(f"seed {r.seed}: {r.phase}: {r.reason}" for r in runs if not r.success)
    return Tried(cand, sum(r.success for r in runs), len(runs), float(np.mean([r.sim_seconds for r in runs])), failed)


def search(
    uid: str,
    count: int,
    trials: int,
    seed: int,
    on_tried: Callable[[Tried], None] | None = None,
    jobs: int = 1,
    vary: Sequence[str] | None = None,
) -> list[Tried]:
    """Try `count` candidates on `trials` seeded trials each, `jobs` candidates at once (forked processes: a robot
    registered here, from a file too, is theirs); best first, ties in the order drawn (the same for any `jobs`)."""
    get_robot(uid)  # an unknown name or a missing extra fails before any work
    drawn = candidates(count, seed, vary)
    if jobs <= 1:
        results = []
        for k, cand in enumerate(drawn):
            results.append(try_candidate(uid, k, cand, trials, seed))
            if on_tried is not None:
                on_tried(results[-1])
    else:
        with ProcessPoolExecutor(min(jobs, len(drawn)), mp_context=multiprocessing.get_context("fork")) as pool:
            futures = [pool.submit(try_candidate, uid, k, cand, trials, seed) for k, cand in enumerate(drawn)]
            for done in as_completed(futures):
                if on_tried is not None:
                    on_tried(done.result())
            results = [f.result() for f in futures]
    return sorted(results, key=lambda t: t.rank_key)
