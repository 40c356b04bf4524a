"""The page's side panel: the line's figures, live plots over sim time, and the controls.

Buttons call `LineControls`, which only publishes on the bus.
"""

from __future__ import annotations

from collections import deque

import numpy as np
import viser
import viser.uplot

from fleet.monitor.controls import LineControls
from fleet.monitor.feed import LineSight
from scenes.schema import Scene

PLOT_EVERY_S = 0.5  # sim seconds between plotted samples
PLOT_POINTS = 600


class History:
    """Samples of the line's figures over sim time, for the plots."""

    def __init__(self, arms: list[str]) -> None:
        self.arms = arms
        self.t = deque(maxlen=PLOT_POINTS)
        self.throughput = deque(maxlen=PLOT_POINTS)
        self.separation = deque(maxlen=PLOT_POINTS)
        self.utilisation = {a: deque(maxlen=PLOT_POINTS) for a in arms}

    def add(self, snap: LineSight) -> bool:
        """Take a sample if sim time moved on by `PLOT_EVERY_S`; True if it did."""
        t = snap.sim_time_s
        if snap.progress is None or snap.status is None or (self.t and t - self.t[-1] < PLOT_EVERY_S):
            return False
        self.t.append(t)
        self.throughput.append(snap.progress.parts_completed / (t / 60.0) if t > 0 else 0.0)
        seps = snap.separations.distances_m if snap.separations else ()
        self.separation.append(min(seps) if seps else np.nan)
        for a, u in zip(self.arms, snap.status.utilisation):
            self.utilisation[a].append(u)
        return True


def figures_markdown(snap: LineSight) -> str:
    """The figures as a small markdown table (what a line engineer reads first)."""
    st, pr = snap.status, snap.progress
    if st is None:
        return "waiting for the sim..."
    state = "E-STOP" if st.estop else ("paused" if st.paused else "running")
    rows = [
        (
            "sim time",
            f"{st.sim_time_s:.1f} s ({st.mode}, {state}" + (f", x{st.speed:g})" if st.mode == "realtime" else ")"),
        ),
    ]
    if pr is not None:
        minutes = max(pr.sim_time_s, 1e-9) / 60.0
        rows += [
            (
                "parts",
                f"{pr.parts_spawned} in · {pr.parts_completed} done · {pr.parts_missed} missed · {pr.parts_failed} "
                "failed",
            ),
            ("throughput", f"{pr.parts_completed / minutes:.2f} / min"),
            ("grants denied", str(pr.grants_denied)),
            ("min separation", f"{pr.min_separation_m * 100:.1f} cm" if pr.min_separation_m >= 0 else "-"),
        ]
    rows += [
        ("control latency p99", f"{st.latency_p99_ms:.2f} ms"),
        (
            "contacts",
            f"{st.contact_ticks} ticks"
            + (f" (last {', '.join(st.contact_pairs)} at {st.last_contact_s:.1f} s)" if st.contact_ticks else ""),
        ),
        ("arms lost", ", ".join(st.arms_lost) or "none"),
        ("dropped messages", str(st.dropped_messages)),
    ]
    return "| | |\n|---|---|\n" + "\n".join(f"| {k} | {v} |" for k, v in rows)


def utilisation_markdown(snap: LineSight, arms: list[str]) -> str:
    if snap.status is None:
        return ""
    return "\n".join(f"- **{a}** {u * 100:.0f} % busy" for a, u in zip(arms, snap.status.utilisation))


class Panel:
    """The GUI: figures, plots and controls; `show(sight)` refreshes the figures."""

    def __init__(self, server: viser.ViserServer, scene: Scene, controls: LineControls) -> None:
        self.gui, self.controls = server.gui, controls
        self.arms = [a.name for a in scene.arms]
        self.history = History(self.arms)
        self._build_controls()
        with self.gui.add_folder("Figures"):
            self.figures = self.gui.add_markdown("waiting for the sim...")
            self.utilisation = self.gui.add_markdown("")
        with self.gui.add_folder("Plots"):
            empty = np.zeros(0)
            self.throughput_plot = self.gui.add_uplot(
                (empty, empty),
                (viser.uplot.Series(label="sim s"), viser.uplot.Series(label="parts/min", stroke="#2070d0", width=2)),
                title="throughput",
                aspect=2.0,
            )
            self.separation_plot = self.gui.add_uplot(
                (empty, empty),
                (
                    viser.uplot.Series(label="sim s"),
                    viser.uplot.Series(label="min separation m", stroke="#d03020", width=2),
                ),
                title="closest arms",
                aspect=2.0,
            )
            self.utilisation_plot = self.gui.add_uplot(
                (empty,) * (len(self.arms) + 1),
                (viser.uplot.Series(label="sim s"), *(viser.uplot.Series(label=a, width=2) for a in self.arms)),
                title="utilisation",
                aspect=2.0,
            )

    def _build_controls(self) -> None:
        with self.gui.add_folder("Control"):
            self.status = self.gui.add_markdown("")
            estop = self.gui.add_button("Emergency stop", color="red", icon=viser.Icon.HAND_STOP)
            release = self.gui.add_button("Release e-stop")
            pause = self.gui.add_button("Pause")
            resume = self.gui.add_button("Resume")
            snapshot = self.gui.add_button("Snapshot now", icon=viser.Icon.CAMERA)
            speed = self.gui.add_slider("Speed (realtime)", min=0.1, max=10.0, step=0.1, initial_value=1.0)
            arm = self.gui.add_dropdown("Arm", tuple(self.arms))
            respawn = self.gui.add_button("Respawn controller")
        estop.on_click(lambda _: self.controls.emergency_stop(True))
        release.on_click(lambda _: self.controls.emergency_stop(False))
        pause.on_click(lambda _: self.controls.pause(True))
        resume.on_click(lambda _: self.controls.pause(False))
        snapshot.on_click(lambda _: self.controls.snapshot())
        speed.on_update(lambda _: self.controls.set_speed(float(speed.value)))
        respawn.on_click(lambda _: self.controls.respawn(str(arm.value)))

    def show(self, snap: LineSight) -> None:
        text = figures_markdown(snap)
        if self.figures.content != text:
            self.figures.content = text
        util = utilisation_markdown(snap, self.arms)
        if self.utilisation.content != util:
            self.utilisation.content = util
        sent = " · ".join(self.controls.sent[-3:])
        status = f"sent: {sent}" if sent else ""
        if self.status.content != status:
            self.status.content = status
        if self.history.add(snap):
            h = self.history
            t = np.asarray(h.t)
            self.throughput_plot.data = (t, np.asarray(h.throughput))
            self.separation_plot.data = (t, np.asarray(h.separation))
            self.utilisation_plot.data = (t, *(np.asarray(h.utilisation[a]) for a in self.arms))
