"""A sweep's tables and plots: `runs.csv` (one row per run: its arguments and the summary's figures),
`cells.csv` (per group of runs that differ only in seed: mean and 95% confidence interval of each figure),
`pairs.csv` (each pair of allocators over the same seeds and arguments: the paired difference in throughput
with its 95% interval and Student's paired t-test), `throughput.png` (per allocator and override),
`throughput_vs_<field>.png` for a numeric override; with offered loads (`--load`), the saturation curve
`throughput_vs_load.png` (and the line's capacity) with `parts_missed_vs_load.png` and
`utilisation_mean_vs_load.png`."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
from scipy import stats

FIGURES = (
    "throughput_per_min",
    "parts_completed",
    "parts_missed",
    "bound_fraction",
    "run_bound_fraction",
    "throughput_bound_per_min",
    "utilisation_mean",
    "inter_arm_contacts",
    "min_separation_m",
    "grants_denied",
    "wall_seconds",
    "seen_error_p95_mm",
    "seen_recall",
    "pick_success",
)


def _scalar(value: object) -> bool:
    return value is None or isinstance(value, (int, float, str, bool))


def run_rows(results: list[dict]) -> list[dict]:
    """One row per run: its arguments, then every scalar figure of its summary."""
    rows = []
    for r in results:
        cell, summary = r["cell"], r["summary"]
        row = {
            "run_id": _run_id(cell),
            "scene": cell["scene"],
            "arms": cell["arms"],
            "allocator": cell["allocator"],
            "seed": cell["seed"],
            "duration_s": cell["duration_s"],
        }
        if cell.get("restore_from"):
            row["from"] = Path(cell["restore_from"]).name  # a branch: every run from this snapshot
        if cell.get("perception", "truth") != "truth":
            row["perception"] = cell["perception"]
            row |= seen_figures(summary.get("perception") or {})
        row |= {f"set:{k}": v for k, v in sorted(cell["overrides"].items())}
        row |= {k: v for k, v in sorted(summary.items()) if _scalar(v) and k not in row}
        busy = [float(v) for v in (summary.get("utilisation") or {}).values() if isinstance(v, (int, float))]
        row["utilisation_mean"] = round(float(np.mean(busy)), 4) if busy else None  # the arms' mean busy share
        rows.append(row)
    return rows


def seen_figures(perception: dict) -> dict:
    """What seeing cost a run that worked from its cameras, as scalars: the p95 position error, the recall and the
    share of grasps that held."""
    scored = perception.get("scored") or {}
    return {
        "seen_error_p95_mm": scored.get("position_error_p95_mm"),
        "seen_recall": scored.get("recall"),
        "pick_success": (perception.get("picks") or {}).get("success"),
    }


def _run_id(cell: dict) -> str:
    from fleet.sweep.grid import RunCell

    return RunCell(**cell).run_id


def group_key(row: dict) -> tuple:
    return tuple(
        (k, json.dumps(row[k]))
        for k in sorted(row)
        if k in ("scene", "arms", "allocator", "duration_s", "from", "perception") or k.startswith("set:")
    )


def mean_ci(values: list[float]) -> tuple[float, float]:
    """Mean and the half-width of its 95% confidence interval (Student's t; NaN with one value)."""
    x = np.asarray([v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))], float)
    if x.size == 0:
        return math.nan, math.nan
    if x.size == 1:
        return float(x[0]), math.nan
    half = stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size)
    return float(x.mean()), float(half)


def cell_rows(rows: list[dict]) -> list[dict]:
    """Per group of runs differing only in seed: how many, and each figure's mean and 95% interval."""
    groups: dict[tuple, list[dict]] = {}
    for row in rows:
        groups.setdefault(group_key(row), []).append(row)
    out = []
    for key, members in groups.items():
        cell = {k: json.loads(v) for k, v in key} | {
            "runs": len(members),
            "seeds": " ".join(str(m["seed"]) for m in sorted(members, key=lambda m: m["seed"])),
        }
        for figure in FIGURES:
            mean, half = mean_ci([m.get(figure) for m in members])
            cell[f"{figure}_mean"], cell[f"{figure}_ci95"] = round(mean, 4), round(half, 4)
        out.append(cell)
    return sorted(
        out, key=lambda c: json.dumps([c.get(k) for k in sorted(c) if not k.endswith(("_mean", "_ci95"))], default=str)
    )


def pair_rows(rows: list[dict], figure: str = "throughput_per_min") -> list[dict]:
    """Each pair of allocators run over the same seeds with otherwise equal arguments: the mean of the per-seed
    differences (first minus second), its 95% interval and the paired t-test's p-value (scipy)."""
    groups: dict[tuple, dict[str, dict[int, float]]] = {}
    for row in rows:
        rest = tuple(item for item in group_key(row) if item[0] != "allocator")
        groups.setdefault(rest, {}).setdefault(row["allocator"], {})[row["seed"]] = row.get(figure)
    out = []
    for rest, by_allocator in groups.items():
        names = sorted(by_allocator)
        for i, a in enumerate(names):
            for b in names[i + 1 :]:
                seeds = sorted(set(by_allocator[a]) & set(by_allocator[b]))
                x = np.asarray([by_allocator[a][s] for s in seeds], float)
                y = np.asarray([by_allocator[b][s] for s in seeds], float)
                mean, half = mean_ci(list(x - y))
                p = float(stats.ttest_rel(x, y).pvalue) if len(seeds) > 1 and np.any(x != y) else math.nan
                out.append(
                    {k: json.loads(v) for k, v in rest}
                    | {
                        "first": a,
                        "second": b,
                        "seeds": len(seeds),
                        f"{figure}_first": round(float(x.mean()), 4) if seeds else math.nan,
                        f"{figure}_second": round(float(y.mean()), 4) if seeds else math.nan,
                        "difference_mean": round(mean, 4),
                        "difference_ci95": round(half, 4),
                        "p_value": round(p, 5),
                    }
                )
    return out


def write_csv(path: Path, rows: list[dict]) -> Path:
    fields: list[str] = []
    for row in rows:
        fields += [k for k in row if k not in fields]
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)
    return path


def label(cell: dict) -> str:
    sets = ", ".join(f"{k[4:]}={cell[k]}" for k in sorted(cell) if k.startswith("set:"))
    seeing = " seen by cameras" if cell.get("perception") == "cameras" else ""
    return f"{cell['allocator']}{seeing}" + (f" ({sets})" if sets else "")


def plot_throughput(cells: list[dict], path: Path) -> Path:
    """Mean throughput per group, with its 95% interval."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(max(5, 1.2 * len(cells)), 4))
    means = [c["throughput_per_min_mean"] for c in cells]
    errs = [0 if math.isnan(c["throughput_per_min_ci95"]) else c["throughput_per_min_ci95"] for c in cells]
    ax.bar(range(len(cells)), means, yerr=errs, capsize=4, color="#4C72B0")
    ax.set_xticks(range(len(cells)), [label(c) for c in cells], rotation=20, ha="right", fontsize=8)
    ax.set_ylabel("parts per sim minute (mean, 95% CI)")
    ax.set_title(f"{cells[0]['scene']}: {cells[0]['runs']} seeds per bar", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


FIGURE_LABELS = {
    "throughput_per_min": "parts per sim minute (mean, 95% CI)",
    "parts_missed": "parts missed per run (mean, 95% CI)",
    "utilisation_mean": "arms' mean busy share (mean, 95% CI)",
}


def plot_against(cells: list[dict], field: str, path: Path, figure: str = "throughput_per_min") -> Path:
    """A figure's mean against a numeric override, one line per allocator; against offered load, the throughput
    plot also draws the line's capacity (the nominal bound at load 1)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for allocator in sorted({c["allocator"] for c in cells}):
        mine = sorted((c for c in cells if c["allocator"] == allocator), key=lambda c: c[f"set:{field}"])
        ax.errorbar(
            [c[f"set:{field}"] for c in mine],
            [c[f"{figure}_mean"] for c in mine],
            yerr=[0 if math.isnan(c[f"{figure}_ci95"]) else c[f"{figure}_ci95"] for c in mine],
            capsize=4,
            marker="o",
            label=allocator,
        )
    at_one = [c["throughput_bound_per_min_mean"] for c in cells if c.get(f"set:{field}") == 1.0]
    if field == "load" and figure == "throughput_per_min" and at_one and not math.isnan(at_one[0]):
        ax.axhline(at_one[0], color="grey", linestyle="--", linewidth=1, label="capacity (load 1)")
    ax.set_xlabel("offered load (x capacity)" if field == "load" else field)
    ax.set_ylabel(FIGURE_LABELS.get(figure, figure))
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_results(results: list[dict], out: Path) -> tuple[list[dict], list[Path]]:
    """runs.csv, cells.csv and the plots; the cell rows and the files written."""
    rows = run_rows(results)
    cells = cell_rows(rows)
    written = [write_csv(out / "runs.csv", rows), write_csv(out / "cells.csv", cells)]
    pairs = pair_rows(rows)
    if pairs:
        written.append(write_csv(out / "pairs.csv", pairs))
    if cells:
        written.append(plot_throughput(cells, out / "throughput.png"))
        for key in sorted({k for c in cells for k in c if k.startswith("set:")}):
            values = [c[key] for c in cells]  # a value may be a list or a mapping (`--set randomise.x={uniform: ...}`)
            numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
            if numbers and len(set(values)) > 1:
                field = key[4:]
                written.append(plot_against(cells, field, out / f"throughput_vs_{field.replace('.', '_')}.png"))
                if field == "load":
                    for figure in ("parts_missed", "utilisation_mean"):
                        written.append(plot_against(cells, field, out / f"{figure}_vs_load.png", figure))
    return cells, written
