"""In chromium: the project against the devices reconciled per row (apply, update), a swapped lock shown
as "replaced?" on the overview and restored by the replacement assistant, a batch from a sibling with
per-device results. One app, two HD-Locks on a simulated Modbus line, five page loads."""

from __future__ import annotations

import json
import urllib.request
from pathlib import Path

import pytest
from conftest import CHROMIUM, CHROMIUM_ARGS, shot, wait_devices_online
from plants import bus, device, plant_text
from webutil import free_port, running_app

if not CHROMIUM.exists():
    pytest.skip(f"{CHROMIUM} is not installed", allow_module_level=True)

from playwright.sync_api import expect, sync_playwright  # noqa: E402

pytestmark = pytest.mark.timeout(180)
SHOTS = Path("/tmp/shots")

def fleet_plant() -> str:
    """Two HD-Locks on a simulated RTU line, each with its serial and a project."""
    locks = (device("door-1", "hdlock", "line1", address=1, serial=660020, project={"LockRequestDelay": 350}),
             device("door-2", "hdlock", "line1", address=2, serial=660021,
                    project={"LockRequestDelay": 200, "SettingsProximityOffsetRight": 9}))
    return plant_text(bus("line1", "modbus-rtu", *locks, port=f"socket://127.0.0.1:{free_port()}", timeout=0.3, retries=0,
                          poll_period=0.2, simulate=True), name="fleet")


def _value(url: str, device: str, name: str):
    with urllib.request.urlopen(f"{url}/api/devices/{device}", timeout=2) as response:
        return json.load(response)["values"][name]["value"]


def _shots(page, name: str) -> None:
    SHOTS.mkdir(exist_ok=True)
    for width, height in ((1440, 900), (768, 1024)):
        page.set_viewport_size({"width": width, "height": height})
        shot(page, str(SHOTS / f"{name}-{width}x{height}.png"), full_page=True)
    page.set_viewport_size({"width": 1440, "height": 900})


def test_project_replacement_and_batch_in_the_browser(tmp_path: Path):
    with running_app(fleet_plant(), tmp_path) as url, sync_playwright() as pw:
        wait_devices_online(url, ("door-1", "door-2"), timeout=20)
        browser = pw.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1440, "height": 900})
        try:
            # 1. the project against each device, reconciled per row
            page.goto(url + "/backup")
            card = page.get_by_test_id("project-card")
            card.get_by_test_id("project-compare").click()
            expect(card.locator('[data-project-apply="holding:3000"]')).to_be_visible()
            expect(card.get_by_test_id("project-summary")).to_contain_text("door-1: 1 of 1 project entry differs")
            card.locator('[data-project-apply="holding:3000"]').click()
            page.get_by_role("button", name="Write", exact=True).click()
            expect(card.get_by_test_id("project-summary")).to_contain_text("device and project agree")
            assert _value(url, "door-1", "LockRequestDelay") == 350
            card.get_by_test_id("project-device").click()
            page.get_by_role("option", name="door-2").click()
            card.get_by_test_id("project-compare").click()
            expect(card.get_by_test_id("project-summary")).to_contain_text("door-2: 1 of 2 project entries differs")
            _shots(page, "backup-project")
            card.locator('[data-project-update="holding:3008"]').click()
            expect(card.get_by_test_id("project-summary")).to_contain_text("device and project agree")
            assert "SettingsProximityOffsetRight = 0 }" in (tmp_path / "plant.toml").read_text()
            assert _value(url, "door-2", "SettingsProximityOffsetRight") == 0  # nothing written to the device

            # the project's write to door-1 ended with its save step: the record takes a snapshot by itself, the set
            # the replacement below is compared with (taken after the swap, it would be the new lock's own)
            page.goto(url + "/record/door-1")
            expect(page.get_by_role("cell", name="snapshot", exact=True).first).to_be_visible(timeout=15_000)

            # 2. door-1 swapped for a new lock: "replaced?" on the overview, restored by the assistant
            page.goto(url + "/replace/door-1")
            expect(page.get_by_test_id("replace-state")).to_contain_text("identity as known: serial 660020")
            page.get_by_test_id("sim-new-serial").fill("770077")
            page.get_by_test_id("sim-swap").click()
            expect(page.get_by_test_id("replace-state")).to_contain_text("replaced? known serial 660020")
            expect(page.get_by_test_id("replace-state")).to_contain_text("now serial 770077")
            page.goto(url + "/")
            expect(page.locator('[data-replaced="door-1"]')).to_contain_text("replaced? serial 660020 → 770077")
            expect(page.locator('[data-replaced="door-2"]')).to_be_hidden()
            expect(page.locator('[data-drift="door-1"]')).to_be_hidden()
            _shots(page, "overview-replaced")
            page.locator('[data-glance-replaced="door-1"]').click()
            page.get_by_test_id("replace-compare").click()
            expect(page.get_by_test_id("replace-note").first).to_contain_text("serial number 660020 -> 770077")
            row = page.locator("tr", has_text="LockRequestDelay")
            expect(row).to_contain_text("200 ms")
            expect(row).to_contain_text("350 ms")
            _shots(page, "replace-diff")
            assert _value(url, "door-1", "LockRequestDelay") == 200  # the new lock: nothing written before the go
            page.get_by_test_id("replace-write").click()
            page.get_by_test_id("restore-confirm-ok").click()
            expect(page.get_by_test_id("replace-report")).to_contain_text("1 written", timeout=15000)
            expect(page.get_by_test_id("replace-report")).to_contain_text("Save-Settings done")
            expect(page.get_by_test_id("replace-state")).to_contain_text("identity as known: serial 770077")
            expect(page.get_by_test_id("replace-checkout")).to_be_visible()
            assert _value(url, "door-1", "LockRequestDelay") == 350

            # 3. a batch from a sibling: door-1's set to both locks, each checked and compared first
            page.goto(url + "/fleet")
            page.get_by_test_id("fleet-source").click()
            page.get_by_role("option", name="door-1 as it is now (sibling)").click()
            page.get_by_test_id("fleet-compare").click()
            expect(page.get_by_test_id("fleet-summary")).to_contain_text("ready: door-1 0 to write, door-2 1 to write",
                                                                         timeout=15000)
            expect(page.locator('[data-fleet-result="door-2"]')).to_contain_text("LockRequestDelay: 200 ms → 350 ms")
            page.get_by_test_id("fleet-apply").click()
            page.get_by_role("button", name="Apply", exact=True).click()
            expect(page.get_by_test_id("fleet-summary")).to_contain_text("door-1 unchanged, door-2 written", timeout=15000)
            _shots(page, "fleet")
            assert _value(url, "door-2", "LockRequestDelay") == 350
        finally:
            browser.close()
