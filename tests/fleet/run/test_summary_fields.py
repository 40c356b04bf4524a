"""The run summary holds every key `docs/running.md` documents, and none is null where a node's report knows it."""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest

from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.test_run import QUICK_LINE, assert_nothing_left

pytestmark = pytest.mark.slow

DOCS = Path(__file__).parents[3] / "docs" / "running.md"


def documented_keys() -> list[str]:
    """The keys of the summary table of `docs/running.md` (the table under `| key | meaning |`)."""
    lines = DOCS.read_text().splitlines()
    start = lines.index("| key | meaning |") + 2
    keys = []
    for line in lines[start:]:
        if not line.startswith("| `"):
            break
        keys += re.findall(r"`([a-z_0-9]+)`", line.split("|")[1])
    return keys


def test_every_documented_key_is_in_the_summary_and_never_null_where_a_node_knows_it():
    options = RunOptions(scene=QUICK_LINE, duration_s=3.0, seed=2, keep_logs=True)
    with Launcher(options) as launcher:
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    reports = {}
    for name in ("sim_server", "coordinator"):
        reports |= {k: v for k, v in json.loads((launcher.dir / f"{name}.json").read_text()).items() if v is not None}
    shutil.rmtree(launcher.dir)
    keys = documented_keys()
    assert len(keys) > 60, keys
    assert not [k for k in keys if k not in summary], "documented keys missing from the summary"
    nulls = [k for k in keys if summary[k] is None and k in reports]
    assert not nulls, {k: reports[k] for k in nulls}
