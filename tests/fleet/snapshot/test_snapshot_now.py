"""A snapshot asked for while a realtime line runs (the monitor's button sends what `LineControls.snapshot` sends)
is taken at the next tick boundary, the line paused for it, and starts a line again; a run with nowhere to write
one refuses it and says why."""

from __future__ import annotations

import threading
import time

import pytest

from fleet.bus.keys import Keys
from fleet.bus.session import open_session
from fleet.monitor.controls import LineControls
from fleet.run.launcher import Launcher, RunOptions
from fleet.run.restore import restore_options
from fleet.snapshot.snapshot_file import read_snapshot
from tests.fleet.snapshot.test_restore_line import run

pytestmark = pytest.mark.slow


def run_asking_for_a_snapshot(options: RunOptions, after_s: float) -> dict:
    """A line run with `options`, asked (as the monitor asks) for a snapshot `after_s` wall seconds in."""
    with Launcher(options, on_message=lambda _text: None) as launcher:
        asked = threading.Event()

        def ask() -> None:
            time.sleep(after_s)
            with open_session(launcher.client_endpoints("monitor")) as session:
                controls = LineControls(session, Keys(options.run_id))
                time.sleep(0.5)  # the router learns of the publisher
                controls.snapshot()
                controls.close()
            asked.set()

        threading.Thread(target=ask, daemon=True).start()
        summary = launcher.run()
    assert asked.is_set()
    return summary


def test_a_snapshot_asked_of_a_realtime_line_is_taken_and_starts_a_line_again(tmp_path):
    options = RunOptions(scene="pick_cell", duration_s=8.0, mode="realtime", speed=2.0, snapshot_dir=str(tmp_path))
    summary = run_asking_for_a_snapshot(options, after_s=2.0)
    assert summary["status"] == "ok" and not summary["snapshots_failed"], summary["snapshots_failed"]
    assert len(summary["snapshots"]) == 1 and summary["sim_seconds"] == pytest.approx(8.0)
    snapshot = read_snapshot(summary["snapshots"][0])
    assert snapshot.mode == "realtime" and 0.0 < snapshot.sim_time_s < 8.0
    again = run(restore_options(summary["snapshots"][0], tmp_path / "scene", 2.0)[0])  # lockstep by default
    assert again["status"] == "ok" and again["restored_from"]["tick"] == snapshot.tick
    assert again["sim_seconds"] == pytest.approx(snapshot.sim_time_s + 2.0)


def test_a_snapshot_asked_of_a_run_with_nowhere_to_write_it_is_refused_and_said(tmp_path):
    summary = run_asking_for_a_snapshot(RunOptions(scene="pick_cell", duration_s=6.0, mode="realtime", speed=2.0), 1.0)
    assert summary["status"] == "ok" and not summary["snapshots"]
    assert summary["snapshots_refused"] == ["monitor: this run writes no snapshots (fleet run --out DIR)"]
