"""What an engineer sees on the backup and audit pages in chromium at 1440x900 and 1024x768:
the whole result text of an audit row, the reason a device has nothing to back up, no
uploader placeholder, and the risk of restoring SettingsRemoveMagnet = 1.

The app runs on the demo plant with a data folder prepared beforehand: an audit row with a
long result and a door-1 backup whose SettingsRemoveMagnet is 1.
"""

from __future__ import annotations

import json
import os
import re
import time
import urllib.request
from pathlib import Path

import pytest
from webutil import demo_plant_text, free_port, start_app, stop_app, wait_http

from app import backup
from app.audit import AuditLog
from devices.hdlock.params import PARAMS
from devices.params import backup_entry

CHROMIUM = Path("/usr/bin/chromium")
if not CHROMIUM.exists():
    pytest.skip(f"{CHROMIUM} is not installed", allow_module_level=True)

from playwright.sync_api import expect, sync_playwright  # noqa: E402
from conftest import TEST_SHOTS, shot

pytestmark = pytest.mark.timeout(120)

SHOTS = Path("/tmp/commission-shots")
LONG = ("refused: SettingsRemoveMagnet = 1 needs a confirmation: Security risk: with SettingsRemoveMagnet = 1 the bolt "
        "retracts as soon as the magnetic field of the strike plate weakens, even while locking is requested. The lock "
        "can then be unlocked from outside by manipulating the magnetic field (END)")


def _prepare(data_dir: Path) -> None:
    data_dir.mkdir(mode=0o700)
    log = AuditLog(data_dir / "audit.sqlite")
    log.record(user="anna", role="engineer", device="door-1", action="write SettingsRemoveMagnet",
               parameter="SettingsRemoveMagnet", old="Off (secure) (0)", new="Retract when magnet removed (1)", result=LONG)
    log.close()
    entries = [backup_entry(p, 1 if p.name == "SettingsRemoveMagnet" else (p.default if p.default is not None else 0))
               for p in PARAMS]
    document = backup.make_document("demo", "door-1", "hdlock", "line1", {}, entries, user="anna", role="engineer")
    (data_dir / "backups").mkdir(mode=0o700)
    (data_dir / "backups" / "door-1-magnet.json").write_text(json.dumps(document))


def _door_online(url: str, timeout: float = 20) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        with urllib.request.urlopen(url + "/api/devices", timeout=2) as response:
            if any(d["name"] == "door-1" and d["status"] == "online" for d in json.load(response)):
                return
        time.sleep(0.2)
    raise TimeoutError("door-1 did not come online")


def _inside(page, locator) -> None:
    """The element is on the screen horizontally and shows its whole text (not cut, not scrolled away)."""
    box = locator.bounding_box()
    width = page.viewport_size["width"]
    assert box is not None and box["x"] >= 0 and box["x"] + box["width"] <= width, (box, width)
    clipped = locator.evaluate("e => e.scrollWidth > e.clientWidth + 1")
    assert not clipped, "the text is cut off"


def test_backup_and_audit_pages_show_everything(tmp_path: Path):
    data_dir = tmp_path / "data"
    _prepare(data_dir)
    plant = tmp_path / "plant.toml"
    plant.write_text(demo_plant_text(free_port()))
    port = free_port()
    url = f"http://127.0.0.1:{port}"
    env_before = os.environ.get("COMMISSION_DATA_DIR")
    os.environ["COMMISSION_DATA_DIR"] = str(data_dir)  # start_app copies os.environ
    try:
        proc = start_app(plant, port, tmp_path / "app.log")
    finally:
        if env_before is None:
            os.environ.pop("COMMISSION_DATA_DIR", None)
        else:
            os.environ["COMMISSION_DATA_DIR"] = env_before
    errors: list[str] = []
    try:
        wait_http(url + "/api/devices", proc, timeout=30)
        _door_online(url)
        SHOTS.mkdir(parents=True, exist_ok=True)
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=str(CHROMIUM),
                                        args=["--no-sandbox", "--disable-gpu", "--disable-background-networking"])
            try:
                for width, height in ((1440, 900), (1024, 768)):
                    page = browser.new_page(viewport={"width": width, "height": height})
                    page.set_default_timeout(10_000)
                    page.on("pageerror", lambda exc: errors.append(str(exc)))

                    page.goto(url + "/audit")
                    cell = page.locator("td", has_text="(END)")
                    expect(cell).to_have_count(1)
                    expect(cell).to_have_text(LONG)
                    cell.scroll_into_view_if_needed()
                    expect(cell).to_be_visible()
                    _inside(page, cell)
                    shot(page, str(SHOTS / f"audit-{width}x{height}.png"))

                    page.goto(url + "/backup")
                    reason = page.get_by_text("heater-hm (m3io): nothing to back up")
                    expect(reason).to_be_visible()
                    expect(reason).to_contain_text("addressed mode")
                    assert reason.inner_text().count("nothing to back up") == 1, reason.inner_text()
                    expect(page.get_by_test_id("restore-upload")).to_be_visible()
                    assert "0.0B" not in page.locator("body").inner_text()
                    row = page.locator("tbody tr", has_text="door-1-magnet.json")
                    expect(row).to_contain_text("anna (engineer)")
                    row.get_by_role("button", name="Restore").click()
                    # the restore opens below the file list: it is brought into sight by itself (issue 32.13)
                    card = page.get_by_test_id("restore-card")
                    page.wait_for_function(
                        "() => { const e = document.querySelector('[data-testid=restore-card]'); if (!e) return false;"
                        " const r = e.getBoundingClientRect(); return r.top >= 0 && r.top < window.innerHeight / 3; }")
                    expect(page.get_by_test_id("restore-compare")).to_be_in_viewport()
                    page.get_by_test_id("restore-compare").click()
                    risk = page.get_by_test_id("restore-risk")
                    expect(risk).to_have_count(1)
                    expect(risk).to_contain_text("unlocked from outside")
                    risk.scroll_into_view_if_needed()
                    expect(risk).to_be_visible()
                    _inside(page, risk)
                    # differing rows are coloured, the same ones not (issue 32.13)
                    differs = card.locator("tbody tr", has_text="SettingsRemoveMagnet")
                    expect(differs).to_have_class(re.compile("restore-differs"))
                    colour = differs.locator("td").nth(1).evaluate("e => getComputedStyle(e).backgroundColor")
                    same = card.locator("tbody tr").filter(has_not_text="differs").first
                    assert colour != same.locator("td").nth(1).evaluate("e => getComputedStyle(e).backgroundColor")
                    if TEST_SHOTS:
                        page.wait_for_timeout(2300)  # the progress bar glides to its value before the picture
                    page.evaluate("window.scrollTo(0, 0)")  # a full-page shot draws the fixed header where the page is
                    shot(page, str(SHOTS / f"backup-{width}x{height}.png"), full_page=True)
                    page.close()
            finally:
                browser.close()
    except BaseException:
        print((tmp_path / "app.log").read_text(errors="replace")[-3000:])
        raise
    finally:
        stop_app(proc)
    assert not errors, f"JavaScript errors on the page: {errors}"
