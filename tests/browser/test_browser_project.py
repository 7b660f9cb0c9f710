"""In chromium: the project card on a device page (the differing entry applied through the gate) and the
project editor on a lock that never answered (edited, saved, shown again after a reload, an invalid entry
refused). One app, one simulated HD-Lock with a project and one on a line nothing answers on."""

from __future__ import annotations

import json
import urllib.request
from pathlib import Path

import pytest
from conftest import CHROMIUM, shot, wait_devices_online
from test_project_page import project_plant_text
from webutil import click_until, running_app

from app.plant import load_plant

if not CHROMIUM.exists():
    pytest.skip(f"{CHROMIUM} is not installed", allow_module_level=True)

from playwright.sync_api import expect  # noqa: E402

pytestmark = pytest.mark.timeout(120)
SHOTS = Path("/tmp/shots")


def _shots(page, name: str, part=None) -> None:
    """The page (or only ``part`` of it: a whole device page takes seconds to capture) at both widths."""
    SHOTS.mkdir(exist_ok=True)
    for width, height in ((1440, 900), (768, 1024)):
        page.set_viewport_size({"width": width, "height": height})
        path = str(SHOTS / f"{name}-{width}x{height}.png")
        if part is not None:
            shot(part, path)
        else:
            shot(page, path, full_page=True)
    page.set_viewport_size({"width": 1440, "height": 900})


def test_project_card_and_editor_in_the_browser(tmp_path: Path, chromium):
    with running_app(project_plant_text(), tmp_path) as url:
        wait_devices_online(url, ["door-1"])
        page = chromium.new_page(viewport={"width": 1440, "height": 900})
        try:
            # the device page: the one differing entry, applied through the gate
            page.goto(url + "/device/door-1")
            card = page.get_by_test_id("project-card")
            expect(card.get_by_test_id("project-summary")).to_contain_text("1 of 1 project entry differs")
            row = card.locator("tr", has_text="LockRequestDelay")
            expect(row).to_contain_text("350 ms")
            expect(row).to_contain_text("200 ms")
            _shots(page, "device-project", card)
            dialog = page.locator(".q-dialog")
            click_until(card.locator('[data-project-apply="holding:3000"]'), dialog)
            expect(dialog).to_contain_text("Write LockRequestDelay = 350 ms to door-1?")
            dialog.get_by_role("button", name="Write", exact=True).click()
            expect(card.get_by_test_id("project-summary")).to_contain_text("device and project agree")
            with urllib.request.urlopen(f"{url}/api/devices/door-1", timeout=5) as response:
                assert json.load(response)["values"]["LockRequestDelay"]["value"] == 350

            # the editor on the lock that never answered: refused, then saved and shown again after a reload
            page.goto(url + "/project/door-9")
            field = page.locator('[data-project-field="holding:3000"]')
            field.fill("70000")
            expect(page.get_by_text("70000 is outside 0 .. 65535 ms").first).to_be_visible()
            page.get_by_test_id("project-save").click()
            expect(page.get_by_test_id("project-status")).to_contain_text("Not saved: LockRequestDelay: 70000 is outside")
            field.fill("420")
            page.get_by_test_id("project-save").click()
            expect(page.get_by_test_id("project-status")).to_contain_text("Saved: LockRequestDelay - -> 420")
            page.reload()
            expect(page.locator('[data-project-field="holding:3000"]')).to_have_value("420")
            _shots(page, "project-editor")
            assert load_plant(tmp_path / "plant.toml").devices["door-9"].project == {"LockRequestDelay": 420}
        finally:
            page.close()
