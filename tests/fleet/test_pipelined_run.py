"""The main job's line with and without pipelined fixtures, as real processes: with it, arms are held at the
fixture's edge (and say so in the summary) and the line finishes more; without it, nobody is held."""

import functools
from concurrent.futures import ThreadPoolExecutor

import pytest

from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.test_run import assert_nothing_left

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out


# the shortest run that shows the gain: at 80 s pipelining completes 6 parts to 5 (lockstep, seed 0: the same every
# time), at 60 s 4 to 4; the main job's 120 s gave the same verdicts and took 50% longer
DURATION_S = 80.0


def run(pipeline: bool) -> dict:
    with Launcher(RunOptions(scene="assembly_line", duration_s=DURATION_S, pipeline=pipeline)) as launcher:
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert summary["status"] == "ok" and summary["inter_arm_contacts"] == 0, summary
    return summary


@functools.cache
def three_lines() -> tuple[dict, dict, dict]:
    """The main job's line twice pipelined and once in turns, all three at once on a machine they load (lockstep: an
    outcome must not depend on sharing it), run once for the tests below."""
    with ThreadPoolExecutor(3) as pool:
        return tuple(pool.map(run, (True, True, False)))


def test_pipelined_fixtures_hold_arms_at_the_edge_and_finish_more_than_arms_taking_turns():
    pipelined, _, in_turns = three_lines()
    assert pipelined["pipeline"] is True and in_turns["pipeline"] is False
    held = {a: t["held_at_fixture"] for a, t in pipelined["arm_time"].items()}
    assert held["arm_1"] > 0 and held["arm_2"] > 0, held  # the top waited for its base, the ship for its top
    assert all(t["held_at_fixture"] == 0 for t in in_turns["arm_time"].values())
    assert pipelined["held_at_station_s"] and not in_turns["held_at_station_s"]
    assert pipelined["parts_completed"] > in_turns["parts_completed"], (
        pipelined["parts_completed"],
        in_turns["parts_completed"],
    )


def test_two_pipelined_runs_side_by_side_repeat_exactly():
    """Two lockstep runs of one seed at once, beside a third: the coordinator's decisions must not depend on when a
    later tick's event reaches it (`lockstep_timeouts` says whether a wait ran out)."""
    summaries = three_lines()[:2]
    timeouts = [s["lockstep_timeouts"] for s in summaries]
    assert all(t["coordinator_decisions"] == 0 and not any(t["controllers"].values()) for t in timeouts), timeouts
    same = (
        "parts_spawned",
        "parts_completed",
        "parts_missed",
        "parts_failed",
        "grants_given",
        "goal_results",
        "held_at_station_s",
        "min_separation_m",
    )
    first, second = ({k: s[k] for k in same} for s in summaries)
    assert first == second
