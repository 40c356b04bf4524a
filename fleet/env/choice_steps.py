"""Choice stepping (allocate mode, `choice_steps=True`): an env step runs on, period after period with every arm
waiting, until some arm has a choice (or the episode's time is up), so training sees choices, not ticks.

The time in between is simulated as in any step: the world, the skills, the ledger. A step's rewards are summed over
the periods it covered; its infos are the last period's, with `success` and `collision` true if they were in any
period, the choice's outcome (`choice`) from the first, and `periods`, how many it covered. An episode still lasts
`max_cycles` periods of sim time, so a fixed policy's episode is the tick-stepping one's (tests/fleet/env).
"""

from __future__ import annotations

from collections.abc import Callable

ANY_PERIOD = ("success", "collision")  # info flags true for a step if true in any period it covered


Outcome = tuple[dict, dict, tuple]  # one period's (or step's) rewards, infos and observation inputs


def run_on_to_a_choice(
    step_once: Callable[[], Outcome], any_choice: Callable[[], bool], time_left: Callable[[], bool], first: Outcome
) -> Outcome:
    """After a step's `first` period: further periods (`step_once`, every arm waiting) while no arm has a choice and
    time is left; the summed rewards, the merged infos and the last period's observation inputs."""
    rewards, infos, seen = first
    periods = 1
    while time_left() and not any_choice():
        more, later, seen = step_once()
        periods += 1
        for a in rewards:
            rewards[a] += more[a]
            merged = later[a] | {k: infos[a][k] or later[a][k] for k in ANY_PERIOD}
            infos[a] = merged | ({"choice": infos[a]["choice"]} if "choice" in infos[a] else {})
    for a in infos:
        infos[a]["periods"] = periods
    return rewards, infos, seen
