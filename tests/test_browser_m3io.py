"""Real browser on the M3IO page: switch an SSR on, blow its fuse in the simulator, see the blown fuse."""

from __future__ import annotations

from pathlib import Path

import pytest
from webutil import running_app

CHROMIUM = Path("/usr/bin/chromium")
SHOTS = Path("/tmp/commission-shots")

pytestmark = pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed")

PLANT = """
name = "m3io-test"
[[bus]]
name = "can3"
type = "can"
interface = "virtual"
channel = "browser-m3io"
bitrate = 500000
simulate = true

[[device]]
name = "heater-hm"
type = "m3io"
bus = "can3"
variant = "HM"
sw1 = 0x1A
"""


@pytest.fixture
def app_url(tmp_path):
    with running_app(PLANT, tmp_path) as url:
        yield url


def test_blown_fuse_is_shown(app_url):
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=str(CHROMIUM), args=["--no-sandbox", "--disable-gpu", "--disable-background-networking"]
        )
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1100})
            page.goto(f"{app_url}/device/heater-hm")
            page.get_by_text("watchdog served: DigOut every 500 ms").wait_for(timeout=10_000)
            ssr1 = page.locator('[data-channel="SSR1"]')
            ssr1.get_by_text("load: present").wait_for(timeout=5_000)
            ssr1.locator(".q-toggle").click()
            page.get_by_text("switches mains voltage").wait_for(timeout=5_000)
            page.get_by_role("button", name="Switch on").click()
            ssr1.get_by_text("triac: ok").wait_for(timeout=5_000)
            page.get_by_test_id("sim-blow-fuse").click()
            ssr1.get_by_text("fuse: blown").wait_for(timeout=5_000)
            ssr1.get_by_text("replace fuse SI3 (10 A").wait_for(timeout=2_000)
            SHOTS.mkdir(parents=True, exist_ok=True)
            page.screenshot(path=str(SHOTS / "m3io.png"), full_page=True)
            page.get_by_test_id("all-off").click()
            page.wait_for_function("() => !document.querySelector('[data-channel=\"SSR1\"] .q-toggle__inner--truthy')", timeout=5_000)
        finally:
            browser.close()
