"""Suite-wide: robots a test registers (a robot file, a tuning candidate) are gone after it, so that no test sees
another's robots (a scene error lists the valid models); the lines tests run in this process fork their nodes from
one kept node factory, as a sweep's worker does (a run's own factory costs ~2 s of imports, and the suite runs
dozens of lines); the tests that need a Ray cluster share one head, in a network namespace whose only interface is
loopback (each a head of its own cost ~9 s).

The suite runs on two workers (pytest-xdist, `addopts` in pyproject.toml), a test file to a worker, and three locks
the workers share keep the tests that run against the wall clock (a realtime line, a watchdog, a wait in wall time,
a plug-in's time budget: `WALL_TIME`) from turning flaky beside another test's work. A wall-time test runs beside no
other test that runs a line or other processes (`slow`, or a file in `HEAVY`): those two kinds take the `lines` lock,
exclusively or shared. It may run beside a light test (one process on the other core). A browser test (`ALONE`)
runs alone on the machine: every other test shares the `machine` lock. `CLAWFLEET_TEST_TIMELINE=FILE` writes when
each test asked for its locks, got them and ended, per worker: where the suite's time goes."""

import fcntl
import os
import shutil
import tempfile
import time
from pathlib import Path

import pytest

import robots.registry
from fleet.run.node_factory import close_kept_factory, keep_factory
from tests.lock_scheduling import LockAwareScheduling, write_kinds
from tests.ray_namespace import loopback_namespace, start_head

# test files (or folders) that run against the wall clock: under xdist, beside no test that runs lines
WALL_TIME = (
    "tests/fleet/monitor/",  # browsers, a realtime line, the monitor's pacing
    "tests/fleet/ros/",  # realtime lines served to ROS clients
    "tests/fleet/foxglove/",  # a realtime line served to Foxglove's client
    "tests/fleet/hosts_apart/",
    "tests/fleet/record/",  # a recorder tapping a running line, Ctrl-C
    "tests/fleet/nodes/",  # watchdogs, faults in wall time, processes killed mid-run
    "tests/fleet/run/",  # the node factory's processes, killed launchers
    "tests/fleet/bus/test_session.py",
    "tests/fleet/bus/test_lockstep.py",
    "tests/fleet/bus/test_router_audit.py",
    "tests/fleet/env/test_watch.py",
    "tests/fleet/test_run.py",  # realtime pacing, hung and killed nodes, the e-stop
    "tests/fleet/test_pipelined_run.py",  # three lines at once must never wait out a lockstep step
    "tests/fleet/test_allocator_plugins.py",  # a plug-in's 50 ms budget
    "tests/fleet/test_goal_storm.py",
    "tests/fleet/test_secure_bus.py",
    "tests/fleet/test_bus_lies.py",
    "tests/fleet/test_rightful_lies.py",
    "tests/fleet/test_bus_fuzz.py",
    "tests/fleet/snapshot/test_snapshot_now.py",  # realtime lines
    # drivers wait about 34 ms for each servo's answer (LeRobot's, Feetech's SDK): a realtime line, nothing beside it
    "tests/fleet/twin/test_lerobot_so101.py",
    "tests/fleet/twin/test_serve_bus.py",
    "tests/fleet/twin/test_mirror.py",
    "tests/fleet/sim/test_realtime_clock.py",  # the pacing's sleeps, measured
)
# tests that run lines or other processes without the `slow` mark (beside them, both cores are busy)
HEAVY = (
    "tests/fleet/cli/test_cli.py",
    "tests/fleet/robot_tools/test_robots_cli.py",
    "tests/fleet/env/test_distributed.py",  # arm processes answering within 10 s (60 s to start): no wall-time test
    # rendering on the CPU: lavapipe's threads take both cores (a first frame compiles for about 6 s); beside a
    # wall-time test an arm of its lockstep line was lost twice in clean-clone CI
    "tests/fleet/sim/test_cameras.py",
    "tests/fleet/sim/test_camera_mirror.py",
    "tests/fleet/env/test_cameras.py",
    "tests/fleet/cli/test_cameras_cli.py",
    "tests/fleet/test_render.py",
    "tests/perception/test_detect.py",
    "tests/fleet/twin/test_mirror_cli.py",  # LeRobot's Python, started five times
)
# a browser (and a line for it to draw) runs alone on the machine
ALONE = (
    "tests/fleet/monitor/test_browser.py",
    "tests/fleet/monitor/test_replay_browser.py",
    "tests/fleet/ros/test_roslibjs_browser.py",
)
ROOT = Path(__file__).resolve().parents[1]


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        path = item.path.relative_to(ROOT).as_posix()
        for marker, paths in (("wall_time", WALL_TIME), ("heavy", HEAVY), ("alone", ALONE)):
            if path.startswith(paths):
                # a lockstep case in a wall-time file runs lines but no clock against the wall: heavy, not alone
                item.add_marker("heavy" if marker == "wall_time" and item.get_closest_marker("lockstep") else marker)
    if hasattr(config, "workerinput") and LOCKS in os.environ:  # for the scheduler (`tests/lock_scheduling.py`)
        kinds = {item.nodeid: kind_of(item) for item in items}
        write_kinds(Path(os.environ[LOCKS]), config.workerinput["workerid"], kinds)


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """The next test file for a worker is one that can run beside the other worker's (`LockAwareScheduling`)."""
    folder = Path(os.environ[LOCKS]) if LOCKS in os.environ else None
    return LockAwareScheduling(config, log, folder)


LOCKS = "CLAWFLEET_TEST_LOCKS"  # the folder of the workers' lock, made by the xdist controller for its workers
TIMELINE = "CLAWFLEET_TEST_TIMELINE"  # a file: each test's worker, when it asked for its locks, got them, ended


CACHE = "CLAWFLEET_CACHE_DIR"  # reach tables, measured reaches: a folder of the session's own, for all its lines
OWN_CACHE = "CLAWFLEET_TEST_OWN_CACHE"


def pytest_configure(config: pytest.Config) -> None:
    if hasattr(config, "workerinput"):
        return
    if config.getoption("numprocesses", None):
        os.environ[LOCKS] = tempfile.mkdtemp(prefix="clawfleet-tests-")  # the workers start after this
    if CACHE not in os.environ:  # not the user's tables: a run's outcome never depends on them, its time would
        os.environ[CACHE] = os.environ[OWN_CACHE] = tempfile.mkdtemp(prefix="clawfleet-cache-")


def pytest_unconfigure(config: pytest.Config) -> None:
    if hasattr(config, "workerinput"):
        return
    if LOCKS in os.environ:
        shutil.rmtree(os.environ.pop(LOCKS), ignore_errors=True)
    if OWN_CACHE in os.environ:
        shutil.rmtree(os.environ.pop(OWN_CACHE), ignore_errors=True)
        os.environ.pop(CACHE, None)


def kind_of(item: pytest.Item) -> str:
    """What a test excludes beside it (`tests.lock_scheduling.KINDS`): as its lock modes say."""
    machine_mode, lines_mode = lock_modes(item)
    if machine_mode == fcntl.LOCK_EX:
        return "alone"
    return {fcntl.LOCK_EX: "wall", fcntl.LOCK_SH: "heavy", None: "light"}[lines_mode]


def lock_modes(item: pytest.Item) -> tuple[int, int | None]:
    """The modes a test takes the `machine` and `lines` locks in (None: it does not take `lines`)."""
    if item.get_closest_marker("alone"):
        return fcntl.LOCK_EX, None
    if item.get_closest_marker("wall_time"):
        return fcntl.LOCK_SH, fcntl.LOCK_EX
    if item.get_closest_marker("slow") or item.get_closest_marker("heavy"):
        return fcntl.LOCK_SH, fcntl.LOCK_SH
    return fcntl.LOCK_SH, None


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None):
    """Under xdist: a test (setup, call, teardown) holds the workers' locks in its modes (`lock_modes`)."""
    if not hasattr(item.config, "workerinput") or LOCKS not in os.environ:
        yield
        return
    folder = Path(os.environ[LOCKS])
    machine_mode, lines_mode = lock_modes(item)
    with (
        open(folder / "machine.lock", "a") as machine,
        open(folder / "lines.lock", "a") as lines,
        open(folder / "turnstile.lock", "a") as turn,
    ):
        # the turnstile: a test waiting for a lock holds it, so the other worker's next test waits behind it
        # instead of taking the lock shared again and again; locks are always taken in one order (no deadlock)
        asked = time.time()
        fcntl.flock(turn, fcntl.LOCK_EX)
        fcntl.flock(machine, machine_mode)
        if lines_mode is not None:
            fcntl.flock(lines, lines_mode)
        fcntl.flock(turn, fcntl.LOCK_UN)
        started = time.time()
        try:
            yield
        finally:
            fcntl.flock(lines, fcntl.LOCK_UN)
            fcntl.flock(machine, fcntl.LOCK_UN)
            if timeline := os.environ.get(TIMELINE):
                with open(timeline, "a") as out:  # one short line per test: appends from two workers do not mix
                    worker = item.config.workerinput["workerid"]
                    out.write(f"{worker} {asked:.3f} {started:.3f} {time.time():.3f} {item.nodeid}\n")


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
