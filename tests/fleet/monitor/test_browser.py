"""The monitor in a real browser: headless Chromium (Debian's package) driven by Playwright.

`fleet run --monitor` runs as a child process on free loopback ports; the page must draw the
arms, and its emergency-stop button must hold every arm still, as seen on the bus. Then the run
is stopped with Ctrl-C and nothing of it may be left.
"""

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState
from fleet.bus.session import BusEndpoints, Inbox, free_loopback_port, loopback_endpoint, open_session

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
BROWSER_ARGS = ["--enable-unsafe-swiftshader"]  # WebGL in software; no GPU on CI
PANEL_X = 930  # the page's control panel starts about here at a 1280 px wide viewport
NOTICE = (320, 160)  # Viser's "software WebGL" notice in the top-left corner


def wait_http(url: str, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(url, timeout=1):
                return
        except OSError:
            time.sleep(0.2)
    raise AssertionError(f"{url} did not answer within {timeout_s} s")


def arm_orange_pixels(png: Path) -> int:
    """Warm-tinted pixels in the 3D view (panel and notice masked): the arms' orange links. Software WebGL
    sometimes draws the whole scene washed out (pale, nearly grey), so any warm tint counts; the floor
    grid, the belt, shadows and labels are neutral grey, and the scene's axes add at most a few hundred."""
    from PIL import Image

    rgb = np.asarray(Image.open(png).convert("RGB")).astype(int)
    view = rgb[:, :PANEL_X].copy()
    view[: NOTICE[1], : NOTICE[0]] = 255
    return int((view[..., 0] - view[..., 2] >= 6).sum())


def states_after(session, keys: Keys, arms: list[str], seconds: float) -> dict[str, list[ArmState]]:
    inbox, decoder = Inbox(), Decoder(ArmState, DropCounter())
    sub = session.declare_subscriber(keys.all_arms("state"), inbox)
    try:
        time.sleep(seconds)
    finally:
        sub.undeclare()
    out: dict[str, list[ArmState]] = {a: [] for a in arms}
    for key, payload in inbox.drain():
        msg = decoder.decode(key, payload)
        if msg is not None:
            out[msg.arm].append(msg)
    return out


def arm_pixels_once_drawn(page, shot: Path, within_s: float) -> int:
    """Arm-coloured pixels in screenshots of `page`, taken until the arms show or `within_s` passes. The scene
    streams in after the canvas appears, and the first frame that draws it waits for software WebGL to compile its
    shaders: 22-29 s on a quiet 2-core machine (screenshots of `fleet run --monitor`'s page in a loop: that one
    takes 22-29 s, the others 2-7 s), past 30 s once in CI, so one shot may take most of the time given."""
    deadline = time.monotonic() + within_s
    while True:
        page.screenshot(path=str(shot), timeout=max(1.0, deadline - time.monotonic()) * 1000)
        orange = arm_orange_pixels(shot)
        if orange > 2000 or time.monotonic() > deadline:
            return orange
        time.sleep(1.0)


@pytest.mark.skipif(
    not os.path.exists(CHROMIUM), reason="needs Debian's chromium (apt-get install chromium; .ci/run does)"
)
def test_the_page_draws_the_arms_and_its_emergency_stop_holds_every_arm(tmp_path):
    from playwright.sync_api import sync_playwright

    page_port, bus = free_loopback_port(), loopback_endpoint(free_loopback_port())
    summary_file = tmp_path / "summary.json"
    run = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "fleet",
            "run",
            "--duration",
            "600",
            "--monitor",
            "--port",
            str(page_port),
            "--listen",
            bus,
            "--summary",
            str(summary_file),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    url = f"http://127.0.0.1:{page_port}"
    try:
        wait_http(url, 60)
        keys, arms = Keys("line"), ["arm_0", "arm_1", "arm_2"]
        with sync_playwright() as p, open_session(BusEndpoints(connect=(bus,))) as session:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=BROWSER_ARGS)
            try:
                page = browser.new_page(viewport={"width": 1280, "height": 800})
                page.goto(url)
                page.wait_for_selector("canvas", timeout=60_000)
                shot = tmp_path / "monitor.png"
                orange = arm_pixels_once_drawn(page, shot, within_s=150)
                assert orange > 2000, f"only {orange} arm-coloured pixels: the arms are not drawn (screenshot {shot})"
                moving = states_after(session, keys, arms, 0.5)
                assert all(moving[a] for a in arms), "every arm publishes its state"
                assert not any(s.held for a in arms for s in moving[a]), "nobody held before the e-stop"

                # a loaded 2-core machine once took > 30 s
                page.get_by_role("button", name="Emergency stop").click(timeout=90_000)
                held_by = time.monotonic() + 10
                while time.monotonic() < held_by:
                    latest = states_after(session, keys, arms, 0.2)
                    if all(latest[a] and latest[a][-1].held for a in arms):
                        break
                held = states_after(session, keys, arms, 1.0)
                for a in arms:
                    assert len(held[a]) >= 20 and all(s.held for s in held[a]), f"{a} is not held after the e-stop"
                    q = np.array([s.q for s in held[a]])[10:]  # 0.1 s of sim to come to rest
                    assert np.abs(q - q[0]).max() < 0.01, f"{a} moved {np.abs(q - q[0]).max():.4f} rad while held"
                    speed = np.abs(np.array([s.dq for s in held[a]])[10:]).mean()
                    # the drives' jitter is ~0.05
                    assert speed < 0.1, f"{a} still moves: mean joint speed {speed:.3f} rad/s"
                assert page.get_by_text("E-STOP").count() >= 1, "the page shows the e-stop"
                # this run has no --out folder: the sim hears the button and says it cannot write a snapshot
                page.get_by_role("button", name="Snapshot now").click(timeout=30_000)
            finally:
                browser.close()
    finally:
        if run.poll() is None:
            run.send_signal(signal.SIGINT)
        try:
            _, err = run.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            run.kill()
            _, err = run.communicate()
    assert run.returncode == 130, err[-2000:]
    summary = json.loads(summary_file.read_text())
    assert summary["monitor"]["url"] == url and summary["monitor"]["frames"] > 0
    assert "estop" in summary["monitor"]["controls_sent"] and "snapshot" in summary["monitor"]["controls_sent"]
    assert summary["snapshots_refused"] == ["monitor: this run writes no snapshots (fleet run --out DIR)"]
    assert {p["role"] for p in summary["processes"]} == {"sim", "coordinator", "controller", "monitor"}
    for p in summary["processes"]:
        with pytest.raises(ProcessLookupError):
            os.kill(p["pid"], 0)
    for port in (page_port, int(bus.rsplit(":", 1)[1])):
        with socket.socket() as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            s.bind(("127.0.0.1", port))
