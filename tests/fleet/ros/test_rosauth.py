"""Beyond loopback a rosbridge server needs its clients to authenticate (rosauth's MAC, the `auth` op): on hosts
the test makes (network namespaces), a client without it is refused and closed, one with a MAC from the secret
is served; without a secret the server will not listen beyond loopback at all."""

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fleet.ros.rosauth import AuthRequest, auth_problem, mac_of
from tests.fleet.hosts_apart.namespaces import NamespacesUnavailable, hosts_on_one_switch, processes_in
from tests.fleet.ros.rosbridge_session import ROS_CELL

ROOT = Path(__file__).resolve().parents[3]


def test_a_mac_authenticates_only_its_own_connection_and_time():
    now = 1_800_000_000
    good = AuthRequest(mac_of("s3cret", "10.0.0.2", "10.0.0.1", "r", now, "user", now + 60), "10.0.0.2",
                       "10.0.0.1", "r", now, "user", now + 60)  # fmt: skip
    assert auth_problem(good, "s3cret", "10.0.0.2", "10.0.0.1", now) == ""
    assert "does not match" in auth_problem(good, "other", "10.0.0.2", "10.0.0.1", now)
    assert "this connection is" in auth_problem(good, "s3cret", "10.0.0.3", "10.0.0.1", now)
    assert "end time has passed" in auth_problem(good, "s3cret", "10.0.0.2", "10.0.0.1", now + 120)
    assert "too far" in auth_problem(good, "s3cret", "10.0.0.2", "10.0.0.1", now - 3600)


@pytest.mark.slow
def test_beyond_loopback_only_an_authenticated_client_is_served(tmp_path):
    secret = tmp_path / "secret"
    secret.write_text("a-secret-for-this-test\n")
    try:
        with hosts_on_one_switch(["lab", "visitor"]) as hosts:
            lab, visitor = hosts["lab"], hosts["visitor"]
            line = subprocess.Popen(
                lab.run(sys.executable, "-m", "fleet", "run", ROS_CELL, "--mode", "realtime", "--duration", "90",
                        "--listen", "tcp/127.0.0.1:7447"),
                cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
            )  # fmt: skip
            plain = subprocess.run(
                lab.run(sys.executable, "-m", "fleet", "rosbridge", "--connect", "tcp/127.0.0.1:7447", "--host",
                        lab.address),
                cwd=ROOT, capture_output=True, text=True, timeout=60,
            )  # fmt: skip
            bridge = subprocess.Popen(
                lab.run(sys.executable, "-m", "fleet", "rosbridge", "--connect", "tcp/127.0.0.1:7447", "--host",
                        lab.address, "--secret-file", str(secret), "--wait", "60"),
                cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
            )  # fmt: skip
            try:
                time.sleep(1.0)
                visit = subprocess.run(
                    visitor.run(sys.executable, "-m", "tests.fleet.ros.rosauth_visitor", "--server", lab.address,
                                "--me", visitor.address, "--secret", "a-secret-for-this-test"),
                    cwd=ROOT, capture_output=True, text=True, timeout=120,
                )  # fmt: skip
            finally:
                for proc in (bridge, line):
                    proc.terminate()
                    proc.wait(60)
            assert visit.returncode == 0, visit.stderr[-2000:]
            seen = json.loads(visit.stdout.strip().splitlines()[-1])
            assert plain.returncode == 2 and "--secret-file" in plain.stderr, plain.stderr
            assert isinstance(seen["without"], str), ("roslibpy got no topics without authenticating", seen)
            assert seen["raw_answer"]["op"] == "status" and "authenticate first" in seen["raw_answer"]["msg"]
            assert seen["raw_closed"] == 1008, "and the connection was closed (policy violation)"
            assert "/joint_states" in seen["with"], seen
            for host in hosts.values():
                assert processes_in(host.netns) == [], f"processes left on {host.netns}"
    except NamespacesUnavailable as exc:
        pytest.skip(str(exc))
