"""The realtime pacing's own measure of itself, on the wall clock with a sim clock stepped by hand: a loop that
keeps up reports the speed it was asked for and ticks started on time; one whose ticks take longer than they last
falls behind, and says so; a stall left out (a snapshot) costs the clock nothing."""

import time
from collections import Counter

import pytest

from fleet.sim.realtime_clock import ClockFigures, RealtimePacing, spread_ms

TICK_S = 0.01  # sim seconds a tick


class SteppedClock:
    """A sim clock moved one tick at a time, each tick taking `work_s` of wall time."""

    def __init__(self, work_s: float = 0.0) -> None:
        self.sim_s, self.work_s = 0.0, work_s

    def tick(self) -> None:
        time.sleep(self.work_s)
        self.sim_s += TICK_S


def paced(clock: SteppedClock, speed: float, ticks: int, figures: ClockFigures) -> RealtimePacing:
    pace = RealtimePacing(lambda: clock.sim_s, lambda: (speed, True), time.sleep, Counter(), figures)
    for _ in range(ticks):
        clock.tick()
        pace.wait()
    return pace


def test_a_loop_that_keeps_up_reports_the_speed_it_was_asked_and_ticks_on_time():
    figures = ClockFigures()
    paced(SteppedClock(), 2.0, 100, figures).close()  # 1 sim s at 2x: half a second
    report = figures.report(2.0)
    assert report["rtf"] == pytest.approx(2.0, rel=0.05) and abs(report["rtf_error"]) < 0.05
    assert report["paced_sim_s"] == pytest.approx(1.0)
    late = report["sim_tick_late_ms"]
    assert late["p50"] < 2.0, late  # a sleep overshoots by a fraction of a millisecond on an idle machine


def test_a_loop_whose_ticks_outlast_them_falls_behind_and_says_so():
    figures = ClockFigures()
    paced(SteppedClock(work_s=2 * TICK_S), 1.0, 30, figures).close()  # each 10 ms tick takes 20 ms
    report = figures.report(1.0)
    assert report["rtf"] < 0.6 and report["rtf_error"] < -0.4, report
    assert report["sim_tick_late_ms"]["worst"] > 250.0, "the last tick started about 300 ms after it was due"


def test_a_stall_left_out_of_the_measure_costs_the_clock_nothing():
    figures, clock = ClockFigures(), SteppedClock()
    pace = paced(clock, 1.0, 20, figures)
    pace.restart()  # a snapshot is taken here: the line stands still for it
    time.sleep(0.3)
    pace.restart(measure=False)
    for _ in range(20):
        clock.tick()
        pace.wait()
    pace.close()
    assert abs(figures.report(1.0)["rtf_error"]) < 0.05, figures.report(1.0)


def test_figures_of_nothing_are_none():
    assert spread_ms([]) is None
    assert ClockFigures().report(1.0)["rtf"] is None
