"""Ray for tests, in a network namespace of the test's own whose only interface is loopback: Ray's servers
listen on every interface of their host, and there that is 127.0.0.1 alone."""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

NETNS = f"clawfleet_ray_{os.getpid()}"  # a test session's own (two xdist workers may each have one)
RAY_TOKEN = secrets.token_hex(32)  # the test cluster's own: a fresh machine has no ~/.ray/auth_token
HEAD = "127.0.0.1:6390"
# the head's files: a session's own (`ray start` takes a head whose address file it finds in its temp dir, and whose
# GCS process it sees on the machine, for one already running, whatever the namespace)
RAY_TEMP = f"/tmp/ray_{os.getpid()}"


def in_netns(*argv: str) -> list[str]:
    """Run in the test's namespace, with the token the test's Ray head and its drivers share (Ray 2.60 asks for one)."""
    return ["ip", "netns", "exec", NETNS, "env", "RAY_AUTH_MODE=token", f"RAY_AUTH_TOKEN={RAY_TOKEN}", *argv]


@contextlib.contextmanager
def loopback_namespace() -> Iterator[None]:
    """The namespace, with its loopback up (skips the test where namespaces cannot be made)."""
    made = subprocess.run(["ip", "netns", "add", NETNS], capture_output=True, text=True)
    if made.returncode != 0 and "File exists" in made.stderr and not _pids_in_namespace():
        # left by a run that was killed: nothing runs in it
        subprocess.run(["ip", "netns", "del", NETNS], capture_output=True)
        made = subprocess.run(["ip", "netns", "add", NETNS], capture_output=True, text=True)
    if made.returncode != 0:
        pytest.skip(f"cannot make a network namespace here: {made.stderr.strip()}")
    try:
        subprocess.run(in_netns("ip", "link", "set", "lo", "up"), check=True)
        yield
    finally:
        # what runs in the namespace is Ray's and the test's: killed there (`ray stop` would stop every Ray on the
        # machine, and waits for each to exit)
        kill_namespace_processes()
        subprocess.run(["ip", "netns", "del", NETNS], capture_output=True)
        shutil.rmtree(RAY_TEMP, ignore_errors=True)


def kill_namespace_processes(timeout_s: float = 30.0) -> None:
    """SIGKILL every process in the namespace, until none is left."""
    deadline = time.monotonic() + timeout_s
    while (pids := _pids_in_namespace()) and time.monotonic() < deadline:
        for pid in pids:
            with contextlib.suppress(ProcessLookupError, ValueError):
                os.kill(int(pid), signal.SIGKILL)
        time.sleep(0.05)


def _pids_in_namespace() -> list[str]:
    listed = subprocess.run(["ip", "netns", "pids", NETNS], capture_output=True, text=True)
    return listed.stdout.split()


def start_head() -> str:
    """A Ray head in the namespace (2 CPUs, no dashboard); its address."""
    started = subprocess.run(
        in_netns(
            sys.executable,
            "-m",
            "ray.scripts.scripts",
            "start",
            "--head",
            "--node-ip-address",
            "127.0.0.1",
            "--port",
            HEAD.rsplit(":", 1)[1],
            "--num-cpus",
            "2",
            "--include-dashboard",
            "false",
            "--disable-usage-stats",
            "--temp-dir",
            RAY_TEMP,
        ),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert started.returncode == 0, started.stderr[-2000:]
    return HEAD
