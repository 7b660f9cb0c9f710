"""Real browser: an SCU emergency stop is seen at once, in red, on the device page and on its overview tile,
with who pressed it and when (issue 42 item 1); it stays until its release."""

from __future__ import annotations

import pytest
from conftest import CHROMIUM, shot
from test_browser_scu import scu_page

pytestmark = [pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed"), pytest.mark.timeout(90)]


def test_an_emergency_stop_is_red_on_the_page_and_the_tile(tmp_path, chromium):
    from playwright.sync_api import expect

    with scu_page(chromium, tmp_path) as (url, page):
        banner = page.get_by_test_id("estop-banner")
        expect(banner).to_be_hidden()
        page.get_by_test_id("emergency-stop").click()  # no control needed, no question
        expect(banner).to_be_visible()
        expect(banner).to_contain_text("EMERGENCY STOP")
        expect(banner).to_contain_text("confirmed by the unit")
        expect(banner).to_contain_text("pressed by local")  # the account (on loopback: "local"), not a page
        shot(page, str(tmp_path / "scu-estop-1440.png"))
        page.set_viewport_size({"width": 768, "height": 1024})
        shot(page, str(tmp_path / "scu-estop-768.png"))
        page.goto(f"{url}/")
        expect(page.get_by_text("EMERGENCY STOP (F20)").first).to_be_visible()
        shot(page, str(tmp_path / "overview-estop-768.png"))
