"""Sweeps: the grid and its scene overrides, runs in parallel that give what `fleet run` gives, resuming after
Ctrl-C with nothing left behind, and the same results from a local Ray instance bound to loopback only."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from fleet.common.scene_overrides import scene_with
from fleet.run.launcher import Launcher, RunOptions
from fleet.sweep.grid import GridError, Override, grid, parse_seeds
from fleet.sweep.results import cell_rows, mean_ci, pair_rows, run_rows, write_results
from fleet.sweep.runner import load_results, run_local
from scenes.loader import SceneError, load_scene
from scenes.schema import MAX_SEED
from tests.fleet.in_process import fleet_in_process
from tests.ray_namespace import in_netns

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

SECONDS = 8.0
SAME = (
    "parts_spawned",
    "parts_completed",
    "parts_missed",
    "parts_failed",
    "inter_arm_contacts",
    "throughput_per_min",
    "goal_results",
    "grants_given",
    "min_separation_m",
)


def test_seeds_and_overrides_parse_and_a_bad_one_says_how():
    assert list(parse_seeds("0-3")) == [0, 1, 2, 3] and parse_seeds("1,4,9") == [1, 4, 9] and parse_seeds("7") == [7]
    for bad in ("5-2", "-3", "1,-2", "x"):
        with pytest.raises(GridError, match="--seeds"):
            parse_seeds(bad)


@settings(max_examples=300, deadline=None)
@given(low=st.integers(-(10**30), 10**30), high=st.integers(-(10**30), 10**30), listed=st.booleans())
def test_seeds_of_every_size_give_a_grid_or_one_line_and_nothing_else(low, high, listed):
    text = f"{low},{high}" if listed else f"{low}-{high}"
    try:
        seeds = parse_seeds(text)
    except GridError as e:
        assert "\n" not in str(e) and str(e).startswith("--seeds")
        return
    assert 0 <= min(seeds) and max(seeds) <= MAX_SEED and len(seeds) <= 100_000


def test_an_absurd_grid_is_refused_before_any_run_is_made():
    with pytest.raises(GridError, match="1,000,000,000 seeds; a sweep takes at most 100,000"):
        parse_seeds("0-999999999")  # counted, never spelt out
    with pytest.raises(GridError, match="9,223,372,036,854,775,808 seeds"):
        parse_seeds("0-9223372036854775807")  # past what len() of a range can say
    with pytest.raises(GridError, match="120,000 runs.*at most 100,000"):
        grid("sorting_line", parse_seeds("0-59999"), ["greedy", "optimal"], 10.0)
    assert Override.parse("conveyor.speed_m_per_s=0.05,0.1") == Override("conveyor.speed_m_per_s", (0.05, 0.1))
    assert Override.parse("randomise=none").values == (None,)
    with pytest.raises(GridError, match="FIELD.PATH=VALUE"):
        Override.parse("conveyor.speed_m_per_s")


@settings(max_examples=300, deadline=None)
@given(value=st.text(max_size=30))
def test_every_set_value_is_read_as_yaml_or_refused_in_one_line(value):
    """`--set FIELD=V`: V is one YAML flow sequence (`0.05,0.1` two values, `[0,0,0]` one list) or a `GridError`
    naming it; never another exception (a YAML parser's traceback)."""
    try:
        setting = Override.parse(f"arms.0.base.xyz={value}")
    except GridError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("--set")
        return
    assert setting.values


def test_a_list_value_is_one_value():
    assert Override.parse("arms.0.base.xyz=[0,0,0]").values == ([0, 0, 0],)
    assert Override.parse("a.b=[0, 1],[2, 3]").values == ([0, 1], [2, 3])
    with pytest.raises(GridError, match="is not a YAML value"):
        Override.parse("arms.0.base.xyz=[0,0")


def test_the_grid_covers_every_combination_seeds_innermost():
    cells = grid(
        "assembly_line",
        [0, 1],
        ["optimal", "greedy"],
        10.0,
        overrides=[Override("conveyor.speed_m_per_s", (0.05, 0.08))],
    )
    assert len(cells) == 8 and len({c.run_id for c in cells}) == 8
    assert [c.seed for c in cells[:4]] == [0, 0, 0, 0], "every group's first seed comes first"
    assert (
        cells[0].run_id
        == grid(
            "assembly_line",
            [0, 1],
            ["optimal", "greedy"],
            10.0,
            overrides=[Override("conveyor.speed_m_per_s", (0.05, 0.08))],
        )[0].run_id
    )


def test_perception_is_a_dimension_of_the_grid_and_a_run_on_the_truth_keeps_its_id():
    truth = grid("pick_cell", [0, 1], ["optimal"], 10.0)
    both = grid("pick_cell", [0, 1], ["optimal"], 10.0, perceptions=["truth", "cameras"])
    assert len(both) == 4 and {c.perception for c in both} == {"truth", "cameras"}
    assert {c.run_id for c in truth} < {c.run_id for c in both}, "a sweep on the truth resumes as before"
    assert [c.group.get("perception") for c in both[:2]] == ["cameras", None]


def test_a_sweep_that_would_see_a_scene_without_a_fixed_camera_is_one_line(tmp_path):
    from tests.fleet.test_run import QUICK_LINE

    code, _, stderr = fleet_in_process(
        ["sweep", QUICK_LINE, "--seeds", "0", "--perception", "cameras", "--out", str(tmp_path / "s")]
    )
    assert code == 2 and stderr.startswith("fleet: error: --perception cameras: the scene ") and stderr.count("\n") == 1


def test_an_override_is_checked_like_a_scene_file(tmp_path):
    path = scene_with(
        "assembly_line", {"conveyor.speed_m_per_s": 0.07, "feeders.0.arrival.rate_per_min": 2.0}, tmp_path
    )
    scene = load_scene(path)
    assert scene.conveyor.speed_m_per_s == 0.07 and scene.feeders[0].arrival.rate_per_min == 2.0
    with pytest.raises(
        SceneError, match=r"assembly_line.yaml with --set conveyor.speed_m_per_s=9.0: conveyor.speed_m_per_s: .*0.5"
    ):
        scene_with("assembly_line", {"conveyor.speed_m_per_s": 9.0}, tmp_path)
    with pytest.raises(SceneError, match=r"feeders.7: give a list index from 0 to"):
        scene_with("assembly_line", {"feeders.7.capacity": 3}, tmp_path)


def test_results_of_a_sweep_that_sets_a_mapping_are_written(tmp_path):
    cell = {"scene": "pick_cell", "seed": 0, "allocator": "optimal", "duration_s": 1.0, "arms": None}
    light = {"randomise.light_yaw_deg": {"uniform": [-60, 60]}}
    results = [
        {"cell": cell | {"overrides": light, "seed": s}, "summary": {"throughput_per_min": 1.0 + s}} for s in (0, 1)
    ]
    cells, written = write_results(results, tmp_path)
    assert len(cells) == 1 and cells[0]["set:randomise.light_yaw_deg"] == {"uniform": [-60, 60]}
    assert [p.name for p in written] == ["runs.csv", "cells.csv", "throughput.png"]


def test_mean_and_interval():
    mean, half = mean_ci([1.0, 2.0, 3.0])
    assert mean == 2.0 and half == pytest.approx(4.303 * 1.0 / 3**0.5, rel=1e-3)
    assert mean_ci([5.0])[1] != mean_ci([5.0])[1], "one run has no interval (NaN)"


def test_allocators_are_compared_pairwise_over_the_same_seeds():
    def row(allocator: str, seed: int, throughput: float, belt: float = 0.05) -> dict:
        return {
            "scene": "x",
            "arms": None,
            "allocator": allocator,
            "duration_s": 60.0,
            "seed": seed,
            "set:conveyor.speed_m_per_s": belt,
            "throughput_per_min": throughput,
        }

    rows = [row("optimal", s, 10.0 + s + 1.0) for s in range(4)] + [
        row("greedy", s, 10.0 + s + (0.5 if s % 2 else 1.5)) for s in range(4)
    ]
    rows += [row("greedy", 9, 3.0, belt=0.1)]  # another group with one allocator: no pair
    (pair,) = pair_rows(rows)
    assert (pair["first"], pair["second"], pair["seeds"]) == ("greedy", "optimal", 4)
    assert pair["difference_mean"] == 0.0 and pair["set:conveyor.speed_m_per_s"] == 0.05
    assert pair["p_value"] == pytest.approx(
        stats.ttest_rel([11.5, 11.5, 13.5, 13.5], [11, 12, 13, 14]).pvalue, abs=1e-5
    )
    assert pair["difference_ci95"] == pytest.approx(mean_ci([0.5, -0.5, 0.5, -0.5])[1], abs=1e-4)


def same_figures(summary: dict) -> dict:
    return {k: summary[k] for k in SAME}


def test_a_sweep_of_four_runs_on_two_jobs_gives_what_four_fleet_runs_give(tmp_path):
    cells = grid("assembly_line", [0, 1], ["optimal", "greedy"], SECONDS)
    run_local(cells, tmp_path, 2, lambda cell, summary: None)
    results = {(r["cell"]["seed"], r["cell"]["allocator"]): r["summary"] for r in load_results(tmp_path)}
    assert len(results) == 4 and all(s["status"] == "ok" for s in results.values())
    for seed, allocator in [(0, "optimal"), (1, "greedy")]:
        with Launcher(RunOptions(duration_s=SECONDS, seed=seed, allocator=allocator)) as launcher:
            alone = launcher.run()
        assert same_figures(results[(seed, allocator)]) == same_figures(alone)
    rows = run_rows(load_results(tmp_path))
    cells_out = cell_rows(rows)
    assert {c["allocator"]: c["runs"] for c in cells_out} == {"optimal": 2, "greedy": 2}
    _, written = write_results(load_results(tmp_path), tmp_path)
    documented = (Path(__file__).parents[3] / "docs" / "running.md").read_text()
    assert "pairs.csv" in {p.name for p in written}
    assert [p.name for p in written if f"`{p.name}`" not in documented] == [], "every file a sweep writes is documented"


MARK = f"CLAWFLEET_TEST_SWEEP={os.getpid()}"  # in the environment of this test's sweeps, inherited by all they start


def marked(pattern: str) -> set[int]:
    """Processes matching `pattern` that this test's sweeps started (their environment carries `MARK`): other
    fleet processes on the machine (another test run, a user's line) are not ours to count."""
    out = subprocess.run(["pgrep", "-f", pattern], capture_output=True, text=True).stdout
    ours = set()
    for pid in map(int, out.split()):
        try:
            if MARK.encode() in Path(f"/proc/{pid}/environ").read_bytes().split(b"\0"):
                ours.add(pid)
        except OSError:
            pass  # gone already
    return ours


def fleet_processes() -> set[int]:
    return marked("fleet.nodes")


def sweep_env() -> dict:
    name, value = MARK.split("=")
    return os.environ | {name: value}


def test_an_interrupted_sweep_leaves_nothing_running_and_runs_only_what_is_missing(tmp_path):
    before = fleet_processes()
    argv = [
        sys.executable,
        "-m",
        "fleet",
        "sweep",
        "assembly_line",
        "--seeds",
        "0-3",
        "--duration",
        str(SECONDS),
        "--jobs",
        "2",
        "--out",
        str(tmp_path),
    ]
    sweep = subprocess.Popen(
        argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True, env=sweep_env()
    )
    runs = tmp_path / "runs"
    deadline = time.monotonic() + 180
    while not (runs.is_dir() and list(runs.glob("*.json"))):
        assert time.monotonic() < deadline and sweep.poll() is None, "no run finished"
        time.sleep(0.2)
    os.killpg(sweep.pid, signal.SIGINT)  # Ctrl-C reaches the whole foreground group
    sweep.communicate(timeout=60)
    time.sleep(1.0)
    assert fleet_processes() - before == set(), "a run's processes outlived the sweep"
    kept = {p.name: p.stat().st_mtime for p in runs.glob("*.json")}
    assert 1 <= len(kept) < 4
    again = subprocess.run(argv, capture_output=True, text=True, timeout=300, env=sweep_env())
    assert again.returncode == 0, again.stderr[-2000:]
    assert f"({len(kept)} already in" in " ".join(again.stderr.split())  # rich wraps lines where there is no terminal
    assert len(list(runs.glob("*.json"))) == 4
    assert all((runs / name).stat().st_mtime == mtime for name, mtime in kept.items()), "a finished run was run again"
    assert (tmp_path / "cells.csv").is_file() and (tmp_path / "throughput.png").stat().st_size > 1000


def pool_workers() -> set[int]:
    return marked("multiprocessing.spawn")


def test_a_sweep_killed_by_sigterm_alone_leaves_no_worker_and_no_run_behind(tmp_path):
    before, workers_before = fleet_processes(), pool_workers()
    argv = [
        sys.executable,
        "-m",
        "fleet",
        "sweep",
        "assembly_line",
        "--seeds",
        "0-3",
        "--duration",
        "60",
        "--jobs",
        "2",
        "--out",
        str(tmp_path),
    ]
    sweep = subprocess.Popen(
        argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True, env=sweep_env()
    )
    deadline = time.monotonic() + 120
    while len(fleet_processes() - before) < 2:  # runs under way
        assert time.monotonic() < deadline and sweep.poll() is None, "no run started"
        time.sleep(0.2)
    os.kill(sweep.pid, signal.SIGTERM)  # the sweep's own process only, as a process manager stops it
    sweep.wait(timeout=30)
    deadline = time.monotonic() + 30
    while (fleet_processes() - before or pool_workers() - workers_before) and time.monotonic() < deadline:
        time.sleep(0.2)
    assert fleet_processes() - before == set(), "a run's processes outlived the sweep"
    assert pool_workers() - workers_before == set(), "a pool worker outlived the sweep"


def test_a_sweep_on_a_ray_cluster_gives_the_pools_results(tmp_path, ray_head):
    argv = [
        "sweep",
        "assembly_line",
        "--seeds",
        "2-3",
        "--duration",
        str(SECONDS),
        "--set",
        "conveyor.speed_m_per_s=0.05",
    ]
    pool = subprocess.run(
        [sys.executable, "-m", "fleet", *argv, "--jobs", "2", "--out", str(tmp_path / "pool")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert pool.returncode == 0, pool.stderr[-2000:]
    on_ray = subprocess.run(
        in_netns(sys.executable, "-m", "fleet", *argv, "--ray", ray_head, "--out", str(tmp_path / "ray")),
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert on_ray.returncode == 0, on_ray.stderr[-2000:]
    assert "on the Ray cluster at 127.0.0.1:6390" in " ".join(on_ray.stderr.split())
    figures = lambda folder: {r["cell"]["seed"]: same_figures(r["summary"]) for r in load_results(folder)}  # noqa: E731
    assert figures(tmp_path / "pool") == figures(tmp_path / "ray") and len(figures(tmp_path / "ray")) == 2


def test_a_bad_sweep_flag_is_one_line_and_runs_nothing(tmp_path):
    for extra, says in (
        (["--set", "conveyor.speed_m_per_s=3"], "conveyor.speed_m_per_s: Input should be less than or equal to 0.5"),
        (["--seeds", "4-1"], "--seeds '4-1'"),
        (["--set", "conveyor"], "FIELD.PATH=VALUE"),
        (["--jobs", "0", "--duration", "nan"], "--duration nan"),
    ):
        code, _, stderr = fleet_in_process(["sweep", "assembly_line", *extra, "--out", str(tmp_path / "out")])
        assert code == 2 and says in stderr and len(stderr.strip().splitlines()) == 1, stderr
    assert not (tmp_path / "out" / "runs").exists()
