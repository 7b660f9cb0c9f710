"""Real browser on the MO 64 page: open the barrier (with the first-motion confirmation) and see
the gate go opening -> open and the position reach 100 %."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from conftest import free_port
from webutil import running_app

CHROMIUM = Path("/usr/bin/chromium")
SHOTS = Path("/tmp/commission-shots")
ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking"]
pytestmark = [pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed"), pytest.mark.timeout(90)]


def plant_text(port: int) -> str:
    return f"""
name = "mo64-test"
[[bus]]
name = "gate-tcp"
type = "logited-tcp"
host = "127.0.0.1"
port = {port}
poll_period = 0.3
simulate = true

[[device]]
name = "barrier-in"
type = "mo64"
bus = "gate-tcp"
"""


def test_open_the_barrier_and_see_it_open(tmp_path):
    from playwright.sync_api import expect, sync_playwright

    with running_app(plant_text(free_port()), tmp_path) as url, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            for width, height in ((1440, 900), (1024, 768)):
                page = browser.new_page(viewport={"width": width, "height": height})
                page.goto(f"{url}/device/barrier-in")
                gate = page.get_by_test_id("gate-state")
                expect(gate).to_have_text("gate state: closed", timeout=15_000)
                page.get_by_test_id("pulse-open").click()
                page.get_by_role("button", name="The area is clear: move").click()  # the first motion of the session
                seen = set()
                end = time.monotonic() + 20
                while time.monotonic() < end and "gate state: open" not in seen:
                    seen.add(gate.inner_text())
                    time.sleep(0.1)
                assert "gate state: open" in seen, seen
                assert any("opening" in s or "pre-warning" in s for s in seen), seen  # it went through opening
                expect(page.get_by_test_id("position")).to_have_text("position: 100 %", timeout=5_000)
                SHOTS.mkdir(exist_ok=True)
                page.screenshot(path=str(SHOTS / f"mo64-open-{width}.png"))
                page.get_by_test_id("pulse-close").click()  # no second question in this session
                expect(gate).to_have_text("gate state: closed", timeout=20_000)
                page.close()
        finally:
            browser.close()
