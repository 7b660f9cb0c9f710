"""Real browser on the MO 64 page: open the barrier (after its area-clear confirmation) and see the gate go
opening -> open and the position reach 100 %; the close after it asks again (issue 42 item 6)."""

from __future__ import annotations

import re

import pytest
from conftest import CHROMIUM, free_port, inside_viewport, shot
from plants import mo64_tcp, plant_text
from webutil import running_app

pytestmark = [pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed"), pytest.mark.timeout(90)]


def mo64_plant(port: int) -> str:
    return plant_text(mo64_tcp("barrier-in", "gate-tcp", port, travel_s=None, timeout=None, poll_period=0.3),
                      name="mo64-test")


def test_open_the_barrier_and_see_it_open(tmp_path, chromium):
    from playwright.sync_api import expect

    with running_app(mo64_plant(free_port()), tmp_path) as url:
        page = chromium.new_page(viewport={"width": 1440, "height": 900})
        page.goto(f"{url}/device/barrier-in")
        gate = page.get_by_test_id("gate-state")
        expect(gate).to_have_text("gate state: closed", timeout=15_000)
        page.get_by_test_id("pulse-open").click()
        page.get_by_role("button", name="Send").click()  # the declared risk, asked for every motion
        # it goes through opening (or the pre-warning before it), then stands open
        expect(gate).to_have_text(re.compile(r"gate state: (opening|pre-warning before opening)"))
        expect(gate).to_have_text("gate state: open", timeout=20_000)
        expect(page.get_by_test_id("position")).to_have_text("position: 100 %")
        for width, height in ((1440, 900), (1024, 768)):  # the open barrier's page at both sizes
            page.set_viewport_size({"width": width, "height": height})
            for testid in ("gate-state", "position", "pulse-close"):
                inside_viewport(page, page.get_by_test_id(testid))
            shot(page, str(tmp_path / f"mo64-open-{width}.png"))
        page.get_by_test_id("pulse-close").click()  # the second motion of the session asks again
        expect(page.get_by_text("nobody stands under it (the area is clear)")).to_be_visible()
        expect(gate).to_have_text("gate state: open")  # nothing sent before the answer
        page.get_by_role("button", name="Send").click()
        expect(gate).to_have_text("gate state: closed", timeout=20_000)
        page.close()
