"""Offered load as a sweep axis: the saturation curve of a one-arm cell, from the command a user runs."""

import csv
import subprocess
import sys

import pytest

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out


def test_the_saturation_curve_of_a_tiny_cell_rises_with_load_then_levels(tmp_path):
    out = tmp_path / "sweep"
    # one seed shows it (lockstep: the same curve every time; a second doubled the test's time): 6, 12, 12 parts a
    # minute, 0, 1, 2 missed, the arm busy 0.57, 0.97, 0.97 of the time
    argv = ["sweep", "pick_cell", "--load", "0.25,0.75,1.5", "--seeds", "0", "--duration", "40"]
    done = subprocess.run(
        [sys.executable, "-m", "fleet", *argv, "--allocator", "greedy", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    cells = sorted(csv.DictReader((out / "cells.csv").open()), key=lambda c: float(c["set:load"]))
    assert [float(c["set:load"]) for c in cells] == [0.25, 0.75, 1.5]
    throughput = [float(c["throughput_per_min_mean"]) for c in cells]
    missed = [float(c["parts_missed_mean"]) for c in cells]
    busy = [float(c["utilisation_mean_mean"]) for c in cells]
    assert throughput == sorted(throughput) and throughput[0] < throughput[-1], throughput
    assert missed[0] <= missed[-1] and missed[-1] > 0, "past capacity parts are missed"
    assert busy == sorted(busy) and busy[-1] > 0.8, "and the arm is busy almost all the time"
    for plot in ("throughput_vs_load.png", "parts_missed_vs_load.png", "utilisation_mean_vs_load.png"):
        assert (out / plot).stat().st_size > 10_000
