"""Replay in the browser: a recorded run played into the monitor (the same view code as live), its sim-time
slider moved from a real headless Chromium; the page jumps there and draws each arm as the recording has it."""

import os
import threading
import time

import numpy as np
import pytest

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import LineView
from fleet.bus.session import BusEndpoints, free_loopback_port, open_listening_session
from fleet.common.processes import StopFlag
from fleet.monitor.app import Monitor
from fleet.monitor.replay_panel import ReplayPanel
from fleet.record.mcap_file import Recording
from fleet.record.replay import Player
from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.monitor.test_browser import BROWSER_ARGS, CHROMIUM, wait_http

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out


def frame_at(recording: Recording, t_s: float) -> LineView:
    """The newest recorded frame at or before `t_s`."""
    decoder, newest = Decoder(LineView, DropCounter()), None
    for m in recording.raw_messages([Keys(recording.run_id).frame]):
        if m.stamp_ns > round(t_s * 1e9):
            break
        newest = m
    return decoder.decode(newest.key, newest.payload)


def drawn_q(monitor: Monitor, arm: str) -> np.ndarray | None:
    model = monitor.view.arms[arm]
    return None if model._last_q is None else np.asarray(model._last_q)


def wait_for(condition, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(0.1)


@pytest.mark.skipif(
    not os.path.exists(CHROMIUM), reason="needs Debian's chromium (apt-get install chromium; .ci/run does)"
)
def test_the_replay_slider_jumps_to_a_time_and_the_page_draws_the_arms_there(tmp_path):
    from playwright.sync_api import sync_playwright

    path = tmp_path / "run.mcap"
    with Launcher(RunOptions(duration_s=10.0, record=str(path), seed=3)) as launcher:
        assert launcher.run()["status"] == "ok"
    recording = Recording(path)
    keys, port, stop = Keys("line"), free_loopback_port(), StopFlag(watch_parent=False)
    session, _ = open_listening_session(BusEndpoints())
    with (
        session,
        Player(recording, session, keys) as player,
        Monitor(session, keys, recording.scene, "127.0.0.1", port) as monitor,
    ):
        panel = ReplayPanel(monitor.server, player)
        monitor.extras.append(panel)
        player.clock.playing = False  # paused at the start: only the slider moves it
        threads = [
            threading.Thread(target=player.run, args=(stop, False)),
            threading.Thread(target=monitor.run, args=(stop,)),
        ]
        for t in threads:
            t.start()
        try:
            wait_http(monitor.url, 30)
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=BROWSER_ARGS)
                try:
                    page = browser.new_page(viewport={"width": 1280, "height": 800})
                    page.goto(monitor.url)
                    page.wait_for_selector("canvas", timeout=60_000)
                    slider = page.get_by_role("slider").first  # the Replay folder comes first on the panel
                    slider.wait_for(timeout=60_000)
                    for key, t_s in (("End", player.clock.end_s), ("Home", player.clock.start_s)):
                        seeks = panel.seeks
                        slider.focus()
                        page.keyboard.press(key)
                        wait_for(
                            lambda seeks=seeks: panel.seeks > seeks,
                            30,
                            f"the page's {key} on the slider did not reach the player",
                        )
                        wait_for(
                            lambda t_s=t_s: abs(player.clock.position_s - t_s) < 0.1,
                            10,
                            f"{key} on the slider did not seek to {t_s:.1f} s",
                        )
                        want = frame_at(recording, player.clock.position_s)
                        for arm_state in want.arms:
                            expected = np.round(np.concatenate([arm_state.q, arm_state.gripper_q]), 4)
                            wait_for(
                                lambda arm_state=arm_state, expected=expected: (
                                    drawn_q(monitor, arm_state.arm) is not None
                                    and np.allclose(drawn_q(monitor, arm_state.arm), expected, atol=1e-3)
                                ),
                                30,
                                f"{arm_state.arm} is not drawn as recorded at {t_s:.1f} s",
                            )
                        page.get_by_text(f"{player.clock.position_s:.1f}", exact=True).first.wait_for(timeout=30_000)
                finally:
                    browser.close()
        finally:
            stop.reason = "test over"
            for t in threads:
                t.join(timeout=10)
    assert panel.seeks == 2
    start, end = frame_at(recording, 0.0), frame_at(recording, recording.end_ns / 1e9)
    assert not np.allclose(start.arms[0].q, end.arms[0].q, atol=1e-3), "the two times show arm_0 in different poses"
