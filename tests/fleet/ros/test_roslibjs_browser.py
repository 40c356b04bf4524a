"""roslibjs (npm `roslib`, from tests/clients) in a real browser, as a web dashboard uses it: a page served on
loopback connects to the line's rosbridge, subscribes to `/joint_states` and shows the arms' joints as they move."""

import functools
import json
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.line_beside import run_beside
from tests.fleet.monitor.test_browser import BROWSER_ARGS, CHROMIUM
from tests.fleet.ros.rosbridge_session import rosbridge_port

pytestmark = pytest.mark.slow  # a realtime line and a browser

CLIENTS = Path(__file__).resolve().parents[2] / "clients"


class Quiet(SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:  # the page's requests are not the test's output
        pass


def shown_in_browser(ws_url: str, messages: int = 5) -> dict:
    """What the page shows once roslibjs has had `messages` joint states (or after 60 s)."""
    from playwright.sync_api import sync_playwright

    if not (CLIENTS / "node_modules" / "roslib" / "build" / "roslib.min.js").is_file():
        pytest.fail("roslibjs is missing: npm ci --prefix tests/clients (scripts/install-system-packages)")
    handler = functools.partial(Quiet, directory=str(CLIENTS))
    with ThreadingHTTPServer(("127.0.0.1", 0), handler) as http, sync_playwright() as p:
        threading.Thread(target=http.serve_forever, daemon=True).start()
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=BROWSER_ARGS)
        try:
            page = browser.new_page()
            page.goto(f"http://127.0.0.1:{http.server_port}/roslibjs_page.html?ws={ws_url}")
            page.wait_for_function(
                f"() => JSON.parse(document.getElementById('joints').textContent || '{{}}').count >= {messages}",
                timeout=60_000,
            )
            return json.loads(page.inner_text("#joints")) | {"status": page.inner_text("#status")}
        finally:
            browser.close()
            http.shutdown()


def test_a_page_using_roslibjs_shows_the_line_s_joint_states_as_they_move():
    def user(launcher: Launcher, seen: dict) -> None:
        seen.update(shown_in_browser(f"ws://127.0.0.1:{rosbridge_port(launcher)}"))

    options = RunOptions(scene="pick_cell", duration_s=120.0, mode="realtime", rosbridge_port=0)
    _, seen, _ = run_beside(options, user)
    assert "error" not in seen, seen["error"]
    assert seen["status"] == "connected" and seen["count"] >= 5
    assert seen["name"] and all(n.startswith("arm_0/") for n in seen["name"]), seen["name"]
    assert len(seen["position"]) == len(seen["name"]) and seen["stamp"]["sec"] >= 0
