"""A temporary folder that fills up: the run stops in one line while every node can still write, and the recording
it made so far reads back. Each case runs `fleet run` in a mount namespace of its own over a small tmpfs (root only:
skipped elsewhere), so nothing is left mounted."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import pytest
from mcap.reader import make_reader

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(os.geteuid() != 0 or shutil.which("unshare") is None, reason="needs root and unshare"),
]


def fleet_on_small_disk(size: str, *args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    """`fleet ARGS` with TMPDIR on a tmpfs of `size`, in a mount namespace that ends with it."""
    script = 'mkdir -p "$1" && mount -t tmpfs -o size="$2" tmpfs "$1" && shift 2 && TMPDIR="$TINY" "$@"'
    tiny = "/tmp/clawfleet-test-tiny"
    command = ["unshare", "-m", "sh", "-c", script, "sh", tiny, size, sys.executable, "-m", "fleet", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=timeout, env=os.environ | {"TINY": tiny})


def test_a_run_on_a_disk_without_the_reserve_is_refused_in_one_line_before_it_starts():
    result = fleet_on_small_disk("8M", "run", "pick_cell", "--duration", "5")
    assert result.returncode != 0
    last = result.stderr.strip().splitlines()[-1]
    assert "the temporary folder" in last and "MiB a run keeps in reserve" in last, result.stderr
    assert "Traceback" not in result.stderr and "sim 0.0" not in result.stderr, result.stderr


def test_a_temporary_folder_that_fills_stops_the_run_in_one_line_with_a_readable_recording(tmp_path):
    recording = tmp_path / "run.mcap"
    result = fleet_on_small_disk("20M", "run", "sorting_line", "--duration", "120", "--record", str(recording))
    assert result.returncode == 1, result.stderr
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("fleet: error: the temporary folder") and "the line stopped at" in last, result.stderr
    assert "Traceback" not in result.stderr and "Panic" not in result.stderr, result.stderr
    with open(recording, "rb") as f:
        topics = {channel.topic for _, channel, _ in make_reader(f).iter_messages()}
    assert len(topics) > 5, topics  # the line's messages up to the stop
