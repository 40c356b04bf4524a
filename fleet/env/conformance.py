"""PettingZoo's own conformance tests over every task and action mode the env offers.

    python -m fleet.env.conformance          # prints one line per configuration, exits 1 on a failure

The test suite runs the same checks (tests/fleet/test_env.py); shipping them in the
package lets anyone check a scene or setting of their own the same way.
"""

from __future__ import annotations

import sys
import warnings

from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test

from fleet.env import env, parallel_env
from fleet.env.cell_env import ACTION_MODES, TASKS


def check(task: str, action_mode: str, n_arms: int = 2, cycles: int = 60, **kwargs) -> None:
    """Run PettingZoo's parallel, AEC and seed tests for one configuration; raises on a failure."""
    options = dict(task=task, action_mode=action_mode, n_arms=n_arms, max_cycles=cycles, **kwargs)
    parallel_api_test(parallel_env(**options), num_cycles=cycles)
    api_test(env(**options), num_cycles=cycles)
    parallel_seed_test(lambda: parallel_env(**options), num_cycles=cycles)


def main() -> int:
    failed = 0
    for task in TASKS:
        for mode in ACTION_MODES:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    check(task, mode)
                print(f"{task} / {mode}: ok")
            except Exception as exc:  # report every configuration, then fail
                failed += 1
                print(f"{task} / {mode}: FAILED: {exc}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
