"""Real browser on the SCU page: take control, move actuator 1 to a remote position, watch the
position rise on the chart, stop, release."""

from __future__ import annotations

import re
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
name = "scu-test"
[[bus]]
name = "rs232-1"
type = "serial"
port = "socket://127.0.0.1:{port}"
simulate = true

[[device]]
name = "lift-1"
type = "scu"
bus = "rs232-1"
actuators = [{{ counts_per_mm = 10 }}, {{ stroke_mm = 300 }}]
"""


def counts(page) -> int:
    text = page.get_by_test_id("pos-A1").inner_text()
    match = re.search(r"(-?\d+) counts", text)
    assert match, text
    return int(match.group(1))


def test_move_actuator_1_to_a_remote_position_and_stop(tmp_path):
    from playwright.sync_api import expect, sync_playwright

    with running_app(plant_text(free_port()), tmp_path) as url, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=ARGS)
        try:
            page = browser.new_page(viewport={"width": 1440, "height": 900})
            page.goto(f"{url}/device/lift-1")
            expect(page.get_by_test_id("session")).to_contain_text("open", timeout=15_000)
            start = counts(page)
            page.get_by_test_id("take-control").click()
            expect(page.get_by_text("you hold control")).to_be_visible(timeout=10_000)
            target = page.get_by_test_id("remote-pos-A1")
            target.scroll_into_view_if_needed()
            target.fill("120")  # mm: 1200 counts at 10 counts per mm
            page.get_by_test_id("set-pos-A1").click()
            expect(page.get_by_text("remote position written and read back")).to_be_visible(timeout=10_000)
            page.get_by_test_id("go").click()
            end = time.monotonic() + 15
            while counts(page) < start + 100 and time.monotonic() < end:  # the position rises
                time.sleep(0.2)
            risen = counts(page)
            assert risen >= start + 100, f"actuator 1 did not move: {start} -> {risen}"
            page.get_by_test_id("stop").click()
            time.sleep(1.0)
            stopped = counts(page)
            time.sleep(1.0)
            assert abs(counts(page) - stopped) <= 20, "actuator 1 kept moving after Stop (RS)"
            expect(page.get_by_text("RS pending: none")).to_be_visible(timeout=5_000)
            SHOTS.mkdir(exist_ok=True)
            page.get_by_test_id("pos-A1").scroll_into_view_if_needed()
            page.screenshot(path=str(SHOTS / "scu-moved.png"))
            page.get_by_role("button", name="Release control").click()
            expect(page.get_by_text("nobody holds control")).to_be_visible(timeout=10_000)
        finally:
            browser.close()
