"""The line's cameras on the monitor's page, in a real browser (headless Chromium through Playwright): an image
panel per camera that shows what the camera sees, not its grey placeholder."""

import os
import subprocess
import sys
import time

import pytest

from fleet.bus.session import free_loopback_port
from tests.fleet.monitor.test_browser import BROWSER_ARGS, CHROMIUM, wait_http

pytestmark = pytest.mark.slow  # a whole run and a browser

# the panel's image drawn into a canvas: its size, and how far its pixels spread (the placeholder is one grey)
READ_IMAGE = """(img) => {
  const canvas = document.createElement("canvas");
  canvas.width = img.naturalWidth; canvas.height = img.naturalHeight;
  const context = canvas.getContext("2d");
  context.drawImage(img, 0, 0);
  const data = context.getImageData(0, 0, canvas.width, canvas.height).data;
  let low = 255, high = 0;
  for (let i = 0; i < data.length; i += 4) { low = Math.min(low, data[i + 1]); high = Math.max(high, data[i + 1]); }
  return [img.naturalWidth, img.naturalHeight, high - low];
}"""


@pytest.mark.skipif(not os.path.exists(CHROMIUM), reason="needs Debian's chromium (scripts/install-system-packages)")
def test_the_page_shows_each_rendered_camera_in_a_panel_of_its_own():
    from playwright.sync_api import sync_playwright

    port = free_loopback_port()
    command = [sys.executable, "-m", "fleet", "run", "pick_cell", "--duration", "600", "--mode", "realtime"]
    run = subprocess.Popen(
        [*command, "--cameras", "overhead", "--monitor", "--port", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        url = f"http://127.0.0.1:{port}"
        wait_http(url, 90)
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=BROWSER_ARGS)
            try:
                page = browser.new_page(viewport={"width": 1280, "height": 800})
                page.goto(url)
                page.get_by_text("overhead").first.wait_for(timeout=60_000)
                deadline, seen = time.monotonic() + 60, []
                while time.monotonic() < deadline:
                    seen = [page.evaluate(READ_IMAGE, img) for img in page.query_selector_all("img")]
                    if any(size[:2] == [160, 120] and size[2] > 40 for size in seen):
                        break
                    time.sleep(1.0)
                assert any(size[:2] == [160, 120] and size[2] > 40 for size in seen), seen
                assert not any(size[:2] == [128, 96] for size in seen), "the wrist camera, not rendered, has no panel"
            finally:
                browser.close()
    finally:
        run.send_signal(2)
        run.wait(60)
