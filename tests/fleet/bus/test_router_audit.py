"""The run's router counts what its access control refuses, by login and key, from Zenoh's own log."""

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def test_the_router_counts_each_message_it_refuses_by_login_and_key(tmp_path):
    probe = subprocess.run(
        [sys.executable, "-m", "tests.fleet.bus.router_audit_probe", str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert probe.returncode == 0, probe.stderr
    out = json.loads(probe.stdout.strip().splitlines()[-1])
    assert out["heard"] == ["clawfleet/r/arm/arm_0/goal"] * 6, "only what arm_0 may say got through"
    assert out["refused"] == {"arm_0: put on clawfleet/r/arm/arm_1/goal": 6, "arm_0: put on clawfleet/r/estop": 3}, (
        "each refused put counted once, under its own key, whether decided per message or from the router's cache"
    )
    assert sum(f.stat().st_size for f in tmp_path.glob("router.log*")) < 100_000, "the log is counted, not kept"
