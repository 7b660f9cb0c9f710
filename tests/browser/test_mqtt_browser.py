"""The plant-wide view's page in chromium: tiles of a publishing instance, grouped by site, no controls."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from test_mqtt_helpers import running_broker
from test_mqtt_site import _devices, _spawn, _until
from webutil import demo_plant_text, free_port, stop_app, wait_http
from conftest import TEST_SHOTS, shot

pytestmark = pytest.mark.timeout(90)

SHOTS = Path(os.environ.get("COMMISSION_SHOTS", "")) if os.environ.get("COMMISSION_SHOTS") else None


def test_view_page_shows_site_tiles_without_controls(tmp_path):
    playwright = pytest.importorskip("playwright.sync_api")
    with running_broker(tmp_path, free_port()) as broker:
        plant = demo_plant_text(free_port()).replace('name = "demo"', f'name = "cab-a"\n\n[mqtt]\nurl = "{broker.url}"\nsite = "hall-3"', 1)
        (tmp_path / "a.toml").write_text(plant)
        view_port = free_port()
        procs = [_spawn(["--plant", str(tmp_path / "a.toml"), "--port", str(free_port()), "--data-dir", str(tmp_path / "da")], tmp_path / "a.log"),
                 _spawn(["view", "--broker", broker.url, "--port", str(view_port)], tmp_path / "view.log")]
        try:
            view = f"http://127.0.0.1:{view_port}"
            wait_http(f"{view}/api/site", procs[1])
            _until(lambda: _devices(view).get("door-1", {}).get("view_status") == "online", 30, "door-1 online in the view")
            with playwright.sync_playwright() as p:
                browser = p.chromium.launch(executable_path="/usr/bin/chromium",
                                            args=["--no-sandbox", "--disable-gpu", "--disable-background-networking"])
                try:
                    for width, height in ((1440, 900), (1024, 768)):
                        page = browser.new_page(viewport={"width": width, "height": height})
                        page.goto(view)
                        page.wait_for_selector('[data-site-tile="hall-3/door-1"]')
                        page.wait_for_selector('[data-instance="hall-3/cab-a"]')
                        assert page.locator("text=Site hall-3").count() == 1
                        assert page.locator("[data-site-tile]").count() == 11
                        assert page.locator("button, input, textarea, select").count() == 0  # read-only by construction
                        assert "broker connected" in page.locator("[data-testid=broker-state]").inner_text()
                        if TEST_SHOTS:
                            page.wait_for_timeout(1200)  # one refresh of the tiles, for the picture
                        shot(page, str((SHOTS or tmp_path) / f"site-view-{width}x{height}.png"), full_page=False)
                        page.close()
                finally:
                    browser.close()
        finally:
            for proc in procs:
                stop_app(proc)
