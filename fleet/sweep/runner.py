"""Running a sweep's cells: each one is a whole `fleet run` (its own sim, coordinator and controller processes),
on a local process pool (`jobs` at a time) or as Ray tasks on a cluster. Resumable: a finished run leaves
`DIR/runs/<run_id>.json` and is not run again; an interrupted one leaves nothing.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import signal
from collections.abc import Callable, Iterable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import asdict
from pathlib import Path

from fleet.common.processes import die_with_parent
from fleet.sweep.grid import RunCell, scenes_for

RUNS_DIR = "runs"


_POOL_PARENT: int | None = None  # in a local pool's worker: the sweep's pid
_INTERRUPTED = False  # in a local pool's worker: a Ctrl-C or SIGTERM came (or the sweep died): start no run after it


def _pool_worker_start() -> None:
    """A local pool worker: SIGTERM when the sweep dies (its run's launcher stops that run), and no new run after."""
    global _POOL_PARENT
    _POOL_PARENT = os.getppid()
    signal.signal(signal.SIGTERM, _interrupt)  # also while a run starts, before its launcher takes the signal
    signal.signal(signal.SIGINT, _interrupt)  # Ctrl-C reaches the sweep's whole group: workers stop too
    die_with_parent()


def _interrupt(_signum: int, _frame: object) -> None:
    global _INTERRUPTED
    _INTERRUPTED = True
    raise KeyboardInterrupt


def _sweep_gone() -> bool:
    return _POOL_PARENT is not None and os.getppid() != _POOL_PARENT


def run_cell(cell: RunCell, scene: str, run_id: str, scene_text: str | None = None) -> dict:
    """One run, exactly as `fleet run` would do it with these arguments; its summary. `scene_text`: the
    overridden scene file's text, written where this runs (a cluster node has no copy of the sweep's folder)."""
    if _sweep_gone():
        os._exit(0)  # the sweep died: a queued run is not started
    if _INTERRUPTED:  # the sweep is stopping (it waits for its workers): a run queued before that is not started
        raise KeyboardInterrupt("the sweep was interrupted")
    try:
        return _run_cell(cell, scene, run_id, scene_text)
    finally:
        if _sweep_gone():
            os._exit(0)  # its run was stopped with it; nobody is left to take a result


def _run_cell(cell: RunCell, scene: str, run_id: str, scene_text: str | None) -> dict:
    import tempfile

    from fleet.run.launcher import Launcher, RunOptions
    from fleet.run.node_factory import keep_factory

    with tempfile.TemporaryDirectory(prefix="clawfleet-sweep-") as tmp:
        if scene_text is not None:
            scene = str(Path(tmp) / Path(scene).name)
            Path(scene).write_text(scene_text)
        if cell.restore_from:  # a branch: the snapshot's line, this allocator, this seed's arrivals from there on
            from fleet.run.restore import restore_options

            options, _ = restore_options(
                cell.restore_from,
                Path(tmp) / "scene",
                cell.duration_s,
                dict(cell.overrides) or None,  # a field of the scene set otherwise from the snapshot on
                allocator=cell.allocator,
                run_id=run_id,
                reseed=cell.seed,
            )
        else:
            options = RunOptions(
                scene=scene,
                arms=cell.arms,
                duration_s=cell.duration_s,
                seed=cell.seed,
                allocator=cell.allocator,
                run_id=run_id,
                perception=cell.perception,
            )
        keep_factory()  # a worker's runs fork their nodes from one factory, kept from run to run
        with Launcher(options, on_message=lambda _text: None) as launcher:
            return launcher.run()


def result_path(out: Path, cell: RunCell) -> Path:
    return out / RUNS_DIR / f"{cell.run_id}.json"


def finished(out: Path, cells: Iterable[RunCell]) -> set[str]:
    """Run ids whose result is already in `out` (a run that was interrupted left none)."""
    return {c.run_id for c in cells if result_path(out, c).is_file()}


def save(out: Path, cell: RunCell, summary: dict) -> bool:
    """Keep a run's result (not an interrupted one: it runs again next time); whether it was kept."""
    if summary.get("status") == "interrupted":
        return False
    path = result_path(out, cell)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps({"cell": asdict(cell), "summary": summary}, sort_keys=True, default=str))
    tmp.replace(path)
    return True


def load_results(out: Path) -> list[dict]:
    """Every kept result: `{"cell": ..., "summary": ...}`."""
    return [json.loads(p.read_text()) for p in sorted((out / RUNS_DIR).glob("*.json"))]


def run_local(
    cells: list[RunCell],
    out: Path,
    jobs: int,
    on_done: Callable[[RunCell, dict], None],
    scenes: dict[str, str] | None = None,
) -> None:
    """`jobs` runs at a time in worker processes (spawned: no inherited bus state). `scenes`: `scenes_for(cells)`, if
    made already."""
    scenes = scenes or scenes_for(cells, out / "scenes")
    context = multiprocessing.get_context("spawn")
    # a worker dies with the sweep (SIGTERM, kill -9 alike): its run's launcher stops that run's processes
    with ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=_pool_worker_start) as pool:
        pending = {pool.submit(run_cell, c, scenes[c.run_id], c.run_id): c for c in cells}
        try:
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for future in done:
                    cell = pending.pop(future)
                    summary = future.result()
                    save(out, cell, summary)
                    on_done(cell, summary)
        except BaseException:
            for future in pending:
                future.cancel()
            raise


def run_ray(
    cells: list[RunCell],
    out: Path,
    address: str,
    on_done: Callable[[RunCell, dict], None],
    scenes: dict[str, str] | None = None,
) -> dict:
    """Each run a Ray task on the cluster at `address` (one CPU each; a run's processes live on the node that
    runs it). What Ray reported. No local Ray is started here: Ray's servers listen on every interface of the
    machine they run on (Ray 2.60, whatever `node_ip_address` says), so where to run one is the user's call."""
    import ray

    scenes = scenes or scenes_for(cells, out / "scenes")
    try:
        ray.init(address=address, log_to_driver=False)
    except (ConnectionError, RuntimeError) as exc:
        said = str(exc).strip().splitlines()
        hint = (
            " (a cluster with token authentication: set RAY_AUTH_MODE=token here too)"
            if "auth" in str(exc).lower()
            else ""
        )
        raise RuntimeError(
            f"cannot reach the Ray cluster at {address}: {said[-1] if said else type(exc).__name__}{hint}"
        ) from None
    try:
        task = ray.remote(num_cpus=1, max_retries=0)(run_cell)
        texts = {c.run_id: Path(scenes[c.run_id]).read_text() if c.overrides else None for c in cells}
        pending = {task.remote(c, scenes[c.run_id], c.run_id, texts[c.run_id]): c for c in cells}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                cell = pending.pop(ref)
                summary = ray.get(ref)
                save(out, cell, summary)
                on_done(cell, summary)
        return {"address": address, "nodes": len(ray.nodes())}
    finally:
        ray.shutdown()
