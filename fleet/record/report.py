"""A run's artefacts from its recording: time series (CSV) and the plots a line engineer looks at first.

- `arms.csv`: per arm and state (sim time): skill phase, task, busy, held, lost;
- `line.csv`: at the coordinator's rate (a one-arm line, with no separations: at the coordinator's progress reports, a
few a wall second): parts spawned / completed / missed / failed, throughput so far,
  the closest separation between arms now, the latest round-trip p99;
- `gantt.png` (every arm's phases and tasks over sim time), `line.png` (throughput and closest separation
  over time), `round_trip.png` (every state-to-answer round trip of the run, from the summary).
`fleet run --out DIR` and `fleet report FILE.mcap --out DIR` both write them from the recording.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, field
from itertools import groupby
from pathlib import Path

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, Progress, Separations, SimStatus
from fleet.record.mcap_file import Recording
from fleet.record.ros_types import deserialize
from robots.phase import Phase

PHASE_COLOURS = {
    Phase.APPROACH: "#4C72B0",
    Phase.DESCEND: "#55A868",
    Phase.CLOSE: "#2E8B57",
    Phase.LIFT: "#8172B2",
    Phase.STANDBY: "#E8A0A2",
    Phase.TRANSFER: "#C44E52",
    Phase.LOWER: "#CCB974",
    Phase.RELEASE: "#DD8452",
    Phase.RETREAT: "#64B5CD",
    Phase.HOME: "#8C8C8C",
    Phase.FAILED: "#000000",
}
HELD_COLOUR = "#BBBBBB"
ARM_FIELDS = ("sim_time_s", "arm", "phase", "task_id", "busy", "held", "lost")
LINE_FIELDS = (
    "sim_time_s",
    "parts_spawned",
    "parts_completed",
    "parts_missed",
    "parts_failed",
    "throughput_per_min",
    "closest_separation_m",
    "round_trip_p99_ms",
)


@dataclass
class RunSeries:
    """What the report draws, read from a recording."""

    arms: list[str]
    arm_rows: list[dict] = field(default_factory=list)
    line_rows: list[dict] = field(default_factory=list)
    margin_m: float | None = None
    summary: dict | None = None
    end_s: float = 0.0


def series_from_recording(recording: Recording) -> RunSeries:
    """Per-arm states (each tick once: re-sent states are skipped) and the line's figures over sim time."""
    keys = Keys(recording.run_id)
    arms = [a.name for a in recording.scene.arms]
    series = RunSeries(arms, end_s=recording.end_ns / 1e9)
    drops = DropCounter()
    decoders = {keys.arm_state(a): Decoder(ArmState, drops) for a in arms}
    decoders |= {
        keys.coord("progress"): Decoder(Progress, drops),
        keys.coord("separation"): Decoder(Separations, drops),
        keys.sim_status: Decoder(SimStatus, drops),
    }
    rows_on = Separations if keys.coord("separation") in recording.channels else Progress  # one arm: no separations
    last_tick: dict[str, int] = {}
    progress: Progress | None = None
    status: SimStatus | None = None
    for raw in recording.raw_messages([k for k in decoders if k in recording.channels]):
        msg = decoders[raw.key].decode(raw.key, raw.payload)
        if isinstance(msg, ArmState) and msg.tick > last_tick.get(msg.arm, -1):
            last_tick[msg.arm] = msg.tick
            busy = msg.phase not in (Phase.IDLE, Phase.DONE)
            series.arm_rows.append(
                dict(zip(ARM_FIELDS, (msg.sim_time_s, msg.arm, msg.phase, msg.task_id, busy, msg.held, msg.lost)))
            )
        elif isinstance(msg, Progress):
            progress = msg
            if rows_on is Progress:
                series.line_rows.append(_line_row(msg.sim_time_s, None, progress, status))
        elif isinstance(msg, SimStatus):
            status = msg
        elif isinstance(msg, Separations):
            series.margin_m = msg.margin_m
            series.line_rows.append(_line_row(msg.sim_time_s, min(msg.distances_m, default=None), progress, status))
    summary_topic = "/line/summary"
    if summary_topic in recording.channels:
        for _, message, schema in recording.messages([summary_topic]):
            series.summary = json.loads(deserialize(message.data, schema).data)
    return series


def _line_row(t: float, closest_m: float | None, progress: Progress | None, status: SimStatus | None) -> dict:
    done = progress.parts_completed if progress else 0
    return dict(
        zip(
            LINE_FIELDS,
            (
                t,
                progress.parts_spawned if progress else 0,
                done,
                progress.parts_missed if progress else 0,
                progress.parts_failed if progress else 0,
                round(done / (t / 60.0), 3) if t > 0 else 0.0,
                closest_m,
                status.latency_p99_ms if status else None,
            ),
        )
    )


def phase_segments(rows: list[dict], arm: str, end_s: float) -> list[tuple[float, float, str, int | None, bool]]:
    """(start, duration, phase, task, held) runs of one arm's consecutive states alike: what the Gantt chart draws.
    A state lasts until the next one; the last until the recording's end."""
    mine = [r for r in rows if r["arm"] == arm]
    ends = [r["sim_time_s"] for r in mine[1:]] + ([max(end_s, mine[-1]["sim_time_s"])] if mine else [])
    segments = []
    for key, run in groupby(
        zip(mine, ends), key=lambda pair: (pair[0]["phase"], pair[0]["task_id"], pair[0]["held"] or pair[0]["lost"])
    ):
        run = list(run)
        start = run[0][0]["sim_time_s"]
        segments.append((start, run[-1][1] - start, *key))
    return segments


def _write_csv(path: Path, fields: tuple[str, ...], rows: list[dict]) -> Path:
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)
    return path


def write_report(series: RunSeries, out_dir: str | Path) -> list[Path]:
    """The CSVs and PNGs into `out_dir`; the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = [
        _write_csv(out / "arms.csv", ARM_FIELDS, series.arm_rows),
        _write_csv(out / "line.csv", LINE_FIELDS, series.line_rows),
    ]
    written.append(_gantt(series, out / "gantt.png"))
    written.append(_line_plot(series, out / "line.png"))
    written.append(_round_trip_plot(series, out / "round_trip.png"))
    return written


def _gantt(series: RunSeries, path: Path) -> Path:
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    fig, ax = plt.subplots(figsize=(12, 1.0 + 0.6 * len(series.arms)))
    for row, arm in enumerate(series.arms):
        for start, length, phase, task, held in phase_segments(series.arm_rows, arm, series.end_s):
            if held:
                ax.broken_barh(
                    [(start, length)], (row - 0.4, 0.8), facecolors=HELD_COLOUR, hatch="//", edgecolor="#888888"
                )
            elif phase in PHASE_COLOURS:
                ax.broken_barh([(start, length)], (row - 0.4, 0.8), facecolors=PHASE_COLOURS[phase])
                if task is not None and phase == Phase.APPROACH and length > 0.02 * max(series.end_s, 1e-9):
                    ax.text(start, row, f" {task}", va="center", ha="left", fontsize=7, color="white")
    ax.set_yticks(range(len(series.arms)), series.arms)
    ax.invert_yaxis()
    ax.set_xlim(0, max(series.end_s, 1e-3))
    ax.set_xlabel("sim time (s)")
    title = "every arm's phases (task ids at each approach; blank: idle; hatched: held or lost)"
    ax.set_title(title, fontsize=10)
    handles = [Patch(facecolor=c, label=p) for p, c in PHASE_COLOURS.items()] + [
        Patch(facecolor=HELD_COLOUR, hatch="//", label="held")
    ]
    ax.legend(
        handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.25), ncol=len(handles), fontsize=7, frameon=False
    )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _line_plot(series: RunSeries, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    t = [r["sim_time_s"] for r in series.line_rows]
    top.plot(t, [r["parts_completed"] for r in series.line_rows], label="completed")
    top.plot(t, [r["parts_spawned"] for r in series.line_rows], label="arrived", linestyle="--")
    top.plot(t, [r["parts_missed"] for r in series.line_rows], label="missed", color="#C44E52")
    top.set_ylabel("parts")
    rate = top.twinx()
    rate.plot(
        t, [r["throughput_per_min"] for r in series.line_rows], color="#8172B2", alpha=0.6, label="throughput so far"
    )
    rate.set_ylabel("parts / sim minute")
    if series.summary and series.summary.get("throughput_bound_per_min"):
        rate.axhline(series.summary["throughput_bound_per_min"], color="#8172B2", linestyle=":", label="capacity bound")
    lines = top.get_legend_handles_labels()[0] + rate.get_legend_handles_labels()[0]
    top.legend(lines, [h.get_label() for h in lines], loc="upper left", fontsize=8)
    closest = [
        (r["sim_time_s"], r["closest_separation_m"]) for r in series.line_rows if r["closest_separation_m"] is not None
    ]
    if closest:
        bottom.plot(*zip(*closest), color="#4C72B0", label="closest arms")
    if series.margin_m is not None:
        bottom.axhline(series.margin_m, color="#C44E52", linestyle="--", label="guard margin")
    bottom.set_ylabel("separation (m)")
    bottom.set_xlabel("sim time (s)")
    if bottom.get_legend_handles_labels()[0]:
        bottom.legend(loc="upper right", fontsize=8)
    else:
        bottom.text(
            0.5,
            0.5,
            "one arm: no separation to draw",
            transform=bottom.transAxes,
            ha="center",
            va="center",
            color="#8C8C8C",
        )
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _round_trip_plot(series: RunSeries, path: Path) -> Path:
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    hist = (series.summary or {}).get("round_trip_histogram")
    if hist and sum(hist["counts"]):
        edges, counts = hist["edges_ms"], hist["counts"]
        ax.stairs(counts, edges, fill=True, color="#4C72B0")
        ax.set_xscale("log")
        ax.set_xlabel("state-to-answer round trip (ms, wall clock)")
        ax.set_ylabel("round trips")
        s = series.summary
        ax.set_title(f"p50 {s.get('latency_p50_ms')} ms, p99 {s.get('latency_p99_ms')} ms", fontsize=10)
    else:
        ax.text(
            0.5, 0.5, "no round trips in this recording's summary", ha="center", va="center", transform=ax.transAxes
        )
        ax.set_axis_off()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
