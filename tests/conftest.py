"""Suite-wide: robots a test registers (a robot file, a tuning candidate) are gone after it, so that no test sees
another's robots (a scene error lists the valid models); the lines tests run in this process fork their nodes from
one kept node factory, as a sweep's worker does (a run's own factory costs ~2 s of imports, and the suite runs
dozens of lines); the tests that need a Ray cluster share one head, in a network namespace whose only interface is
loopback (each a head of its own cost ~9 s).

The suite runs on two workers (pytest-xdist, `addopts` in pyproject.toml), a test file to a worker. A test that runs
against the wall clock (a realtime line, a browser, a watchdog, a wait in wall time, a plug-in's time budget) could
turn flaky beside another test's line, so it runs alone on the machine: it takes a lock both workers share
exclusively, every other test takes it shared (`WALL_TIME`)."""

import fcntl
import os
import shutil
import tempfile
from pathlib import Path

import pytest

import robots.registry
from fleet.run.node_factory import close_kept_factory, keep_factory
from tests.ray_namespace import loopback_namespace, start_head

# test files (or folders) that run against the wall clock: alone on the machine under xdist
WALL_TIME = (
    "tests/fleet/monitor/",  # browsers, a realtime line, the monitor's pacing
    "tests/fleet/ros/",  # realtime lines served to ROS clients
    "tests/fleet/hosts_apart/",
    "tests/fleet/record/",  # a recorder tapping a running line, Ctrl-C
    "tests/fleet/nodes/",  # watchdogs, faults in wall time, processes killed mid-run
    "tests/fleet/run/",  # the node factory's processes, killed launchers
    "tests/fleet/bus/test_session.py",
    "tests/fleet/bus/test_faults.py",
    "tests/fleet/bus/test_lockstep.py",
    "tests/fleet/bus/test_router_audit.py",
    "tests/fleet/env/test_distributed.py",
    "tests/fleet/env/test_watch.py",
    "tests/fleet/test_run.py",  # realtime pacing, hung and killed nodes, the e-stop
    "tests/fleet/test_pipelined_run.py",  # three lines at once must never wait out a lockstep step
    "tests/fleet/test_allocator_plugins.py",  # a plug-in's 50 ms budget
    "tests/fleet/test_goal_storm.py",
    "tests/fleet/test_secure_bus.py",
    "tests/fleet/test_bus_lies.py",
    "tests/fleet/test_rightful_lies.py",
    "tests/fleet/test_bus_fuzz.py",
)
ROOT = Path(__file__).resolve().parents[1]


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if item.path.relative_to(ROOT).as_posix().startswith(WALL_TIME):
            item.add_marker(pytest.mark.wall_time)


LOCKS = "CLAWFLEET_TEST_LOCKS"  # the folder of the workers' lock, made by the xdist controller for its workers


def pytest_configure(config: pytest.Config) -> None:
    if not hasattr(config, "workerinput") and config.getoption("numprocesses", None):
        os.environ[LOCKS] = tempfile.mkdtemp(prefix="clawfleet-tests-")  # the workers start after this


def pytest_unconfigure(config: pytest.Config) -> None:
    if not hasattr(config, "workerinput") and LOCKS in os.environ:
        shutil.rmtree(os.environ.pop(LOCKS), ignore_errors=True)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None):
    """Under xdist: a wall-time test (setup, call, teardown) holds the workers' lock alone, any other shares it."""
    if not hasattr(item.config, "workerinput") or LOCKS not in os.environ:
        yield
        return
    folder = Path(os.environ[LOCKS])
    with open(folder / "run.lock", "a") as lock, open(folder / "turnstile.lock", "a") as turn:
        # the turnstile: a wall-time test waiting for the lock holds it, so the other worker's next test waits
        # behind it instead of taking the lock shared again and again
        fcntl.flock(turn, fcntl.LOCK_EX)
        fcntl.flock(lock, fcntl.LOCK_EX if item.get_closest_marker("wall_time") else fcntl.LOCK_SH)
        fcntl.flock(turn, fcntl.LOCK_UN)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


@pytest.fixture(autouse=True, scope="session")
def lines_fork_their_nodes_from_one_kept_factory():
    keep_factory()
    yield
    close_kept_factory()


@pytest.fixture(autouse=True)
def robots_registered_by_a_test_stay_in_it(monkeypatch):
    robots.registry._load_entry_points()  # the installed packages' robots belong to every test
    monkeypatch.setattr(robots.registry, "_REGISTRY", dict(robots.registry._REGISTRY))


@pytest.fixture(scope="session")
def ray_head() -> str:
    """The address of a Ray head in the loopback namespace, started when a test first asks for it."""
    pytest.importorskip("ray")
    with loopback_namespace():
        yield start_head()
