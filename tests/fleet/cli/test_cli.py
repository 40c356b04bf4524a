"""The `fleet` command as a user runs it: real subprocesses, exit codes and one-line errors."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from scenes import bundled_scene_names
from tests.fleet.in_process import fleet_in_process


def fleet(*args, timeout=300, env=None):
    return subprocess.run(
        [sys.executable, "-m", "fleet", *args], capture_output=True, text=True, timeout=timeout, env=env
    )


def test_check_prints_ok_for_bundled_scenes():
    for name in bundled_scene_names():
        code, stdout, stderr = fleet_in_process(["check", name])
        assert code == 0, (name, stderr)
        first, bound, *cameras = stdout.strip().splitlines()
        assert first == "ok" and bound.startswith("capacity: at best ") and "parts/min" in bound, name
        assert "stand idle" not in bound, name  # every bundled arm has work
        assert cameras[0].startswith("camera overhead: world, 160x120 px, 60 deg, 5 Hz, rgb+depth+segmentation"), name


def test_check_broken_scene_is_one_line_exit_2(tmp_path):
    path = tmp_path / "cell.yaml"
    path.write_text("name: cell\narms:\n  - {name: arm_0, model: openclaw, base: {xyz: [0, 0]}}\n")
    code, _, stderr = fleet_in_process(["check", str(path)])
    assert code == 2
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert str(path) in lines[0] and "arms.0.base.xyz" in lines[0]


def test_unknown_robot_exits_2_listing_valid_names():
    code, _, stderr = fleet_in_process(["trials", "--robot", "ur99", "--trials", "1"])
    assert code == 2 and "openclaw" in stderr and len(stderr.strip().splitlines()) == 1


def test_robots_and_scenes_list():
    code, robots, _ = fleet_in_process(["robots"])
    assert code == 0 and "openclaw" in robots
    code, scenes, _ = fleet_in_process(["scenes"])
    assert code == 0 and "sorting_line" in scenes


def test_scenes_without_the_models_extra_lists_every_scene_and_marks_what_it_cannot_run():
    result = subprocess.run(
        [sys.executable, str(Path(__file__).with_name("without_models.py")), "scenes"],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "COLUMNS": "300"},
    )
    assert result.returncode == 0, result.stderr
    rows = {line.split("│")[1].strip(): line for line in result.stdout.splitlines() if line.count("│") >= 3}
    assert set(bundled_scene_names()) <= set(rows), rows
    assert "cannot run here" in rows["mixed_fleet"] and "clawfleet[models]" in rows["mixed_fleet"]
    assert "cannot run here" not in rows["sorting_line"]


def test_fleet_run_names_every_client_login_it_wrote():
    """A user hands one of these to a client of their own: each config file named, with what it may do."""
    result = subprocess.run(
        [sys.executable, "-m", "fleet", "run", "pick_cell", "--duration", "1"],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "COLUMNS": "400"},
    )
    assert result.returncode == 0, result.stderr
    said = result.stdout + result.stderr
    logins = next(line for line in said.splitlines() if line.startswith("logins in "))
    for name in ("monitor.json5", "recorder.json5", "ros_client.json5"):
        assert name in logins, logins


def test_trials_json_last_line():
    result = fleet("trials", "--robot", "openclaw", "--trials", "2", "--seed", "7", "--json")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout.strip().splitlines()[-1])
    assert set(summary) == {"robot", "trials", "successes", "success_rate", "physics_hz", "solver_iterations"}
    assert summary["trials"] == 2 and summary["robot"] == "openclaw"
    assert summary["successes"] == 2
    assert (summary["physics_hz"], summary["solver_iterations"]) == (200.0, 20), "the trial cell's own physics"


def test_trials_refuse_a_physics_rate_the_servo_rate_does_not_divide_in_one_line():
    code, _, stderr = fleet_in_process(["trials", "--trials", "1", "--physics-hz", "250"])
    assert code != 0 and stderr.strip() == "fleet: error: scene: physics_hz must be a whole multiple of control_hz"


BAD_INPUT = [
    (["run", "no_such_scene"], "no such scene"),
    (["run", "sorting_line", "--arms", "25"], "arm_row.count"),
    (["run", "--allocator", "fastest"], "unknown allocator 'fastest'; valid allocators: optimal, auction, greedy"),
    (["run", "--allocator", "policy:/no/such.pt2"], "policy file /no/such.pt2: no such file"),
    (["sweep", "pick_cell", "--out", "o", "--allocator", "greedy", "policy:/no/such.pt2"], "/no/such.pt2: no such"),
    (["run", "--run-id", "BAD/ID"], "--run-id: run id 'BAD/ID' must be 1 to 40 lower-case"),
    (["run", "--run-id", "a" * 5000], "'... (5,000 characters) must be 1 to 40"),
    (["run", "--listen", "tcp/192.0.2.1:7447"], "--listen tcp/192.0.2.1:7447: this machine has no address 192.0.2.1"),
    (["run", "--connect", "tcp/127.0.0.1:1"], "--connect tcp/127.0.0.1:1: nothing answers there (connection refused)"),
    (["monitor", "--connect", "tcp/127.0.0.1:1", "--wait", "0.5"], "nothing answers there (connection refused)"),
    (["record", "--connect", "tcp/127.0.0.1:1", "--wait", "0", "x.mcap"], "--connect tcp/127.0.0.1:1: nothing answers"),
    (["ros2", "serve", "--connect", "tcp/127.0.0.1:1", "--wait", "0"], "--connect tcp/127.0.0.1:1: nothing answers"),
    (["rosbridge", "--connect", "tcp/127.0.0.1:1", "--wait", "nan"], "--wait nan: give seconds from 0 to 86,400"),
    (["monitor", "--run-id", "x" * 41, "--connect", "tcp/127.0.0.1:1"], "must be 1 to 40 lower-case letters"),
    (["run", "--listen", "garbage"], "argument --listen: 'garbage' is not an endpoint"),
    (["run", "--duration", "nan"], "--duration nan: give a positive number"),
    (["run", "--duration", "inf"], "--duration inf: give a positive number"),
    (["run", "--zenoh-config", "/dev/null"], "--zenoh-config /dev/null: not a readable file"),
    (["run", "--monitor", "--port", "99999"], "--port 99999: a TCP port is 0 to 65535"),
    (["run", "--rosbridge", "--rosbridge-port", "-1"], "--rosbridge-port -1: a TCP port is 0 to 65535"),
    (["run", "--loss", "1.5"], "--loss 1.5: Input should be less than 1"),
    (["run", "--latency-ms", "-5"], "--latency-ms -5: Input should be greater than or equal to 0"),
    (["check", "/dev/null"], "/dev/null: not a regular file"),
    (["tune", "--vary", "hover_m", "hover_height"], "cannot vary hover_height; valid values: arm_stiffness_scale"),
    (["check", "/"], "/: a directory, not a scene file"),
    (["run", "--seed", str(2**64)], "--seed: a seed is a whole number from 0 to 9,223,372,036,854,775,807"),
    (["sweep", "pick_cell", "--out", "o", "--seeds", f"0-{2**63 - 1}"], "9,223,372,036,854,775,808 seeds"),
    (["sweep", "pick_cell", "--out", "o", "--seeds", f"1,{2**70}"], "a seed is at most 9,223,372,036,854,775,807"),
]


def test_run_refuses_bad_input_with_one_line_and_starts_nothing():
    for args, says in BAD_INPUT:
        code, _, stderr = fleet_in_process(args)
        assert code == 2, (args, stderr)
        lines = stderr.strip().splitlines()
        assert says in lines[-1] and "Traceback" not in stderr, (args, stderr)
        assert "sim" not in stderr.split("error")[0], args  # no progress bar: nothing was started


def test_a_refusal_is_the_same_from_the_command_line():
    """The in-process checks above are the command's: the same refusal from a process of its own."""
    result = fleet("run", "--run-id", "BAD/ID")
    assert result.returncode == 2 and result.stderr.strip().splitlines() == [
        "fleet: error: --run-id: run id 'BAD/ID' must be 1 to 40 lower-case letters, digits and _ (starting with a "
        "letter)"
    ]


def started_by(pid: int) -> list[int]:
    """Processes still running that `pid` started through `fleet.common.processes` (its node factory among them)."""
    from fleet.common.processes import PARENT_ENV

    mark = f"{PARENT_ENV}={pid}".encode()
    left = []
    for environ in Path("/proc").glob("[0-9]*/environ"):
        try:
            if mark in environ.read_bytes().split(b"\0"):
                left.append(int(environ.parent.name))
        except OSError:
            pass  # gone, or not ours to read
    return left


@pytest.mark.parametrize(
    "args, code",
    [(["pick_cell", "--duration", "1"], 0), (["pick_cell", "--duration", "-1"], 2)],
    ids=["ran", "refused"],
)
def test_run_starts_its_node_factory_ahead_and_leaves_nothing_behind(args, code):
    """`fleet run` starts its node factory before its own imports and checks; run or refused, nothing stays."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "fleet", "run", *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == code, stderr
    assert started_by(proc.pid) == []


def test_only_a_line_of_fleet_run_starts_a_factory_ahead():
    from fleet.cli import starts_a_line

    assert starts_a_line(["run"]) and starts_a_line(["run", "sorting_line", "--arms", "4"])
    assert not starts_a_line(["run", "--help"]) and not starts_a_line(["sweep", "pick_cell"])
    assert not starts_a_line([])


def test_check_refuses_binary_and_oversized_files_at_once(tmp_path):
    binary, big = tmp_path / "binary.yaml", tmp_path / "big.yaml"
    binary.write_bytes(b"name: x\n\xff\xfe\x00junk")
    big.write_text("description: " + "x" * 1_200_000 + "\n")
    code, _, stderr = fleet_in_process(["check", str(binary)])
    assert code == 2 and stderr.strip() == f"fleet: error: {binary}: not UTF-8 text (byte 8: b'\\xff')"
    code, _, stderr = fleet_in_process(["check", str(big)])
    assert code == 2 and "larger than a scene can be (1,000,000 bytes at most)" in stderr
    assert stderr.count("\n") == 1


def test_monitor_needs_an_endpoint_and_says_so_in_one_line():
    code, _, stderr = fleet_in_process(["monitor"])
    assert code != 0 and stderr.strip().count("\n") == 0 and "--connect" in stderr


@pytest.fixture
def empty_bus():
    """The endpoint of a Zenoh session listening on loopback, with no line on it."""
    from fleet.bus.session import BusEndpoints, free_loopback_port, loopback_endpoint, open_session

    endpoint = loopback_endpoint(free_loopback_port())
    with open_session(BusEndpoints(listen=(endpoint,))):
        yield endpoint


def test_monitor_with_nobody_to_watch_fails_cleanly(empty_bus):
    result = fleet("monitor", "--connect", empty_bus, "--port", "0", "--wait", "2", timeout=120)
    assert result.returncode == 1
    assert "no sim of run 'line' answered" in result.stderr and "Traceback" not in result.stderr


@pytest.mark.parametrize(
    "args, says, code",
    [
        ([], "--connect", 1),
        (["--connect", "tcp/127.0.0.1:1", "--host", "0.0.0.0"], "beyond loopback", 2),
        (["--connect", "tcp/127.0.0.1:1", "--port", "70000"], "--port 70000", 1),
    ],
)
def test_rosbridge_refuses_what_it_cannot_do_with_one_line(args, says, code):
    returned, _, stderr = fleet_in_process(["rosbridge", *args])
    assert returned == code and says in stderr, stderr
    assert stderr.strip().count("\n") == 0


def test_rosbridge_with_no_line_to_serve_fails_cleanly(empty_bus):
    result = fleet("rosbridge", "--connect", empty_bus, "--port", "0", "--wait", "2")
    assert result.returncode == 1
    assert "no sim of run 'line' answered" in result.stderr and "Traceback" not in result.stderr


def test_run_refuses_bad_hosts_and_bus_config_flags_with_one_line(tmp_path):
    bus = tmp_path / "bus"
    made = ["bus-config", "--address", "127.0.0.1", "--port", "17463", "--scene", "pick_cell", "--out", str(bus)]
    assert fleet_in_process(made)[0] == 0
    hosts = tmp_path / "hosts.yaml"
    cases = [
        (["run", "--hosts", str(hosts)], "--hosts needs --bus-config"),
        (["run", "pick_cell", "--bus-config", str(bus), "--listen", "tcp/127.0.0.1:7447"], "leave out --listen"),
        (["run", "sorting_line", "--bus-config", str(bus)], "written for arms arm_0, the scene has arm_0, arm_1"),
        (["run", "pick_cell", "--bus-config", str(tmp_path)], "not a bus config directory"),
        (
            ["run", "pick_cell", "--bus-config", str(bus), "--hosts", str(hosts)],
            "nodes.arm_9: no such node; nodes: sim, coordinator, arm_0",
        ),
    ]
    hosts.write_text("nodes:\n  arm_9: somewhere\n")
    for args, says in cases:
        code, _, stderr = fleet_in_process(args)
        assert code == 2 and says in stderr and len(stderr.strip().splitlines()) == 1, (args, stderr)
    hosts.write_text("nodes:\n  sim: no_such_namespace\n")
    code, _, stderr = fleet_in_process(["run", "pick_cell", "--bus-config", str(bus), "--hosts", str(hosts)])
    assert code == 2 and "nodes.sim: no network namespace 'no_such_namespace'" in stderr


@pytest.mark.parametrize(
    "python, says", [(sys.executable, "robosuite cannot be imported"), ("/nonexistent/python3", "could not run")]
)
def test_bench_env_against_robosuite_without_it_is_one_line_before_any_env_runs(python, says):
    """This environment has no robosuite (it cannot: docs/benchmarks.md makes a second one); the baseline runs
    first, so a wrong interpreter is said at once."""
    result = fleet(
        "bench", "env", "--arms", "2", "--scenarios", "reach", "--steps", "2000", "--robosuite", python, timeout=120
    )
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and says in lines[0] and python in lines[0], result.stderr
    assert "agent-steps/s" not in result.stdout  # no env row was timed


def test_bench_decisions_times_every_built_in_allocator_on_a_long_line():
    result = fleet("bench", "decisions", "--arms", "6", "--pending", "10", "--decisions", "10", "--json", timeout=120)
    assert result.returncode == 0, result.stderr
    rows = json.loads(result.stdout.strip().splitlines()[-1])  # the table, then the rows as one JSON line
    assert [r["allocator"] for r in rows] == ["optimal", "auction", "greedy"]
    assert all(r["decisions"] == 8 and 0 < r["p50_ms"] <= r["p99_ms"] for r in rows)


@pytest.mark.slow  # a whole run: not in the quick set
def test_reach_fills_a_scenes_tables_so_that_no_decision_of_a_run_waits_on_ik(tmp_path):
    tables = {**os.environ, "CLAWFLEET_CACHE_DIR": str(tmp_path)}
    first = fleet("reach", "pick_cell", "--jobs", "2", "--quiet", env=tables)
    assert first.returncode == 0 and first.stdout.startswith("reach tables of pick_cell: "), first.stderr
    assert int(first.stdout.split(": ")[1].split()[0]) > 1000  # the belt and the bin, every part height
    again = fleet("reach", "pick_cell", "--quiet", env=tables)
    assert again.stdout.startswith("reach tables of pick_cell: 0 cells worked out"), again.stdout
    run = fleet("run", "pick_cell", "--duration", "20", "--json", env=tables)
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    assert summary["status"] == "ok" and summary["parts_completed"] >= 1
    assert summary["decision_wall_ms"]["reach_cells"] == 0, "every cell the run asked was in the table"
    off = fleet("reach", "pick_cell", env={**os.environ, "CLAWFLEET_CACHE_DIR": "off"})
    assert off.returncode == 2 and off.stderr.strip().count("\n") == 0 and "off" in off.stderr
