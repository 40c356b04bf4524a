"""PettingZoo's own conformance tests over every scenario and action mode the env offers.

    python -m fleet.env.conformance          # prints one line per configuration, exits 1 on a failure

The test suite runs the same checks (tests/fleet/env/test_conformance.py); shipping them in the
package lets anyone check a scene or setting of their own the same way.
"""

from __future__ import annotations

import functools
import sys
import types
import warnings

from pettingzoo.test import api_test, max_cycles_test, parallel_api_test, parallel_seed_test

from fleet.env import env, parallel_env
from fleet.env.cell_env import ACTION_MODES, ALLOCATE_SCENARIOS
from fleet.env.scenarios import SCENARIOS

CONFIGURATIONS = [(s, m) for s in SCENARIOS for m in ACTION_MODES if m != "allocate" or s in ALLOCATE_SCENARIOS]


def check(scenario: str, action_mode: str, n_arms: int | None = 2, cycles: int = 40, **kwargs) -> None:
    """Run PettingZoo's parallel, AEC, seed and max-cycles tests for one configuration; raises on a failure."""
    n_arms = 2 if scenario == "handover" else n_arms
    options = dict(scenario=scenario, action_mode=action_mode, n_arms=n_arms, max_cycles=cycles, **kwargs)
    parallel_api_test(parallel_env(**options), num_cycles=cycles)
    api_test(env(**options), num_cycles=cycles)
    parallel_seed_test(lambda: parallel_env(**options), num_cycles=cycles)
    if kwargs.get("choice_steps"):
        return  # an episode lasts max_cycles periods of sim time, in fewer steps: PettingZoo's test counts steps
    without_cycles = {k: v for k, v in options.items() if k != "max_cycles"}
    max_cycles_test(
        types.SimpleNamespace(
            parallel_env=functools.partial(parallel_env, **without_cycles),
            env=functools.partial(env, **without_cycles),
        )
    )


def main() -> int:
    failed = 0
    for scenario, mode in CONFIGURATIONS:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                check(scenario, mode)
            print(f"{scenario} / {mode}: ok", flush=True)
        except Exception as exc:  # report every configuration, then fail
            failed += 1
            print(f"{scenario} / {mode}: FAILED: {type(exc).__name__}: {exc}", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
