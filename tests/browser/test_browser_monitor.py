"""The bus monitor in a real browser (Debian's chromium through playwright) on the app as a subprocess.

The app runs the demo plant with its Modbus line on a free port and its CAN bus on a
virtual channel of its own; recordings and screenshots go to the test's temporary folder.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import can
import pytest
from conftest import CHROMIUM, shot
from webutil import page_at
from demo_app import demo_app

pytest.importorskip("playwright")
from playwright.sync_api import Browser, Page, expect
GATE1 = "0x000A1284 (ext)"  # demo plant gate-1: extended device ID 660100
GATE2 = "0x00B"  # demo plant gate-2: standard device ID 11

pytestmark = [
    pytest.mark.skipif(not CHROMIUM.exists(), reason="needs Debian's chromium at /usr/bin/chromium"),
    pytest.mark.timeout(120),
]


@pytest.fixture
def app_url(tmp_path: Path) -> Iterator[str]:
    """``python -m app.cli`` on the demo plant, moved to free ports and virtual channels of its own."""
    with demo_app(tmp_path, "browser-monitor", COMMISSION_RECORDINGS_DIR=str(tmp_path / "recordings")) as url:
        yield url


def count_cell(page: Page, can_id: str):
    row = page.locator("[data-monitor=overwrite] tbody tr").filter(has=page.locator("td", has_text=re.compile(rf"^{re.escape(can_id)}$")))
    return row.locator("td").nth(3)  # ID, Dir, Device, Count


def count_of(page: Page, can_id: str) -> int:
    return int(count_cell(page, can_id).inner_text().strip())


def wait_count_grows(page: Page, can_id: str) -> None:
    """Wait until the overwrite view's count of ``can_id`` is above what it shows now."""
    before = count_of(page, can_id)
    expect(count_cell(page, can_id)).not_to_have_text(re.compile(rf"^\s*{before}\s*$"))
    assert count_of(page, can_id) > before


# the live frame table shows only rows whose ID cell (Time, Dir, ID, ...) is the argument, and at least one
ONLY_ID_JS = r"""id => { const cells = [...document.querySelectorAll('[data-monitor=frames] tbody tr td:nth-child(3)')];
    return cells.length > 0 && cells.every(c => c.innerText.trim() === id); }"""
# the record status: recording for at least 2 s (two status frames of each lock, section "alle 1000 ms") and 3 frames
RECORDED_JS = r"""() => { const m = /: (\d+\.\d) s, (\d+) frames/.exec(document.querySelector('[data-monitor=record-status]').innerText);
    return m !== null && parseFloat(m[1]) >= 2.0 && parseInt(m[2]) >= 3; }"""


def test_can_monitor_in_browser(app_url: str, chromium: Browser, tmp_path: Path):
    page = chromium.new_page(viewport={"width": 1500, "height": 1150}, accept_downloads=True)
    page.set_default_timeout(15_000)
    page.goto(f"{app_url}/monitor/can1")
    expect(page.get_by_text("Bus monitor can1")).to_be_visible()

    # live frames, decoded
    frames = page.locator("[data-monitor=frames] tbody tr")
    expect(frames.filter(has_text="HD-Lock Status").first).to_be_visible()
    assert frames.count() <= 200
    expect(page.get_by_text("error-active")).to_be_visible()
    expect(page.get_by_text(re.compile(r"rx \d+ · tx \d+ · error frames 0"))).to_be_visible()

    # overwrite view: one row per lock ID, counts growing with the status every second
    overwrite = page.locator("[data-monitor=overwrite] tbody tr")
    expect(overwrite.filter(has_text=GATE1).first).to_be_visible()
    expect(overwrite.filter(has_text=GATE2).first).to_be_visible()
    wait_count_grows(page, GATE1)
    assert overwrite.filter(has_text=GATE1).first.locator(".byte").count() in (6, 8)  # status or register answer

    # ID range filter: only gate-2 (0x00B)
    page.get_by_label("ID from (hex)").fill("B")
    page.get_by_label("ID to (hex)").fill("B")
    expect(frames.first).to_contain_text(GATE2)
    page.wait_for_function(ONLY_ID_JS, arg=GATE2)
    ids = frames.locator("td:nth-child(3)").all_inner_texts()
    assert ids and set(ids) == {GATE2}, set(ids)
    page.get_by_label("ID from (hex)").fill("")
    page.get_by_label("ID to (hex)").fill("")
    expect(frames.filter(has_text=GATE1).first).to_be_visible()
    expect(frames.filter(has_text=GATE2).first).to_be_visible()
    shot(page, str(tmp_path / "monitor.png"))

    # record in .blf for a few seconds, download it
    page.get_by_label("Format").click()
    page.get_by_role("option", name="Vector .blf").click()
    page.get_by_role("button", name="Record", exact=True).click()
    status = page.locator("[data-monitor=record-status]")
    expect(status).to_contain_text(re.compile(r"recording can1-.*\.blf: .* s, \d+ frames"))
    page.wait_for_function(RECORDED_JS)
    page.get_by_role("button", name="Stop", exact=True).click()
    expect(page.get_by_text(re.compile(r"Saved \d+ frames to can1-.*\.blf"))).to_be_visible()
    recordings = sorted((tmp_path / "recordings").glob("can1-*.blf"))
    assert len(recordings) == 1
    recorded = recordings[0]
    reader = can.LogReader(recorded)
    try:
        messages = list(reader)
    finally:
        reader.stop()
    assert len(messages) >= 3 and any(m.is_extended_id and m.arbitration_id == 660100 for m in messages)
    with page.expect_download() as info:
        page.get_by_role("button", name="Download", exact=True).click()
    downloaded = tmp_path / "downloaded.blf"
    info.value.save_as(downloaded)
    assert downloaded.read_bytes() == recorded.read_bytes()

    # open the recorded file: same decoding, relative time
    page.get_by_role("tab", name="Recorded file").click()
    upload_input = page.locator("[data-monitor=upload] input[type=file]")
    upload_input.set_input_files(str(recorded))
    expect(page.get_by_text(f"Opened {recorded.name}")).to_be_visible()
    file_rows = page.locator("[data-monitor=file-frames] tbody tr")
    expect(file_rows.first.locator("td").first).to_have_text("0.000")
    assert file_rows.count() == min(200, len(messages))
    headers = [h.strip() for h in page.locator("[data-monitor=file-frames] thead th").all_inner_texts()]
    decoded = file_rows.locator(f"td:nth-child({headers.index('Decoded') + 1})").all_inner_texts()
    assert decoded and all(d.startswith("HD-Lock") for d in decoded), [d for d in decoded if not d.startswith("HD-Lock")][:3]
    # a register read burst can fill a page: look for the locks' status page by page
    pages = -(-len(messages) // 200)
    for number in range(2, pages + 1):
        if file_rows.filter(has_text="HD-Lock Status").count():
            break
        page.locator("[data-monitor=file-pages] button", has_text=re.compile(rf"^{number}$")).click()
        expect(file_rows.first.locator("td").first).not_to_have_text("0.000")
    expect(file_rows.filter(has_text="HD-Lock Status").first).to_be_visible()
    shot(page, str(tmp_path / "monitor-file.png"))

    # a broken file: a message, and the page still works
    broken = tmp_path / "broken.blf"
    broken.write_bytes(b"this is not a BLF file" * 20)
    upload_input.set_input_files(str(broken))
    expect(page.locator("[data-monitor=file-info]")).to_contain_text("broken.blf: cannot open as .blf file")
    page.get_by_role("tab", name="Live").click()
    wait_count_grows(page, GATE2)
    page.close()


def test_modbus_monitor_in_browser(app_url: str, chromium: Browser, tmp_path: Path):
    page = page_at(chromium, f"{app_url}/monitor/line1", 1500, 900)
    expect(page.get_by_text("Bus monitor line1")).to_be_visible()
    rows = page.locator(".q-table tbody tr")
    expect(rows.filter(has_text="read ").first).to_be_visible()
    expect(page.get_by_text(re.compile(r"\d+ transactions buffered"))).to_be_visible()
    shot(page, str(tmp_path / "monitor-line1.png"))
    page.close()


def test_monitor_names_devices_and_decodes_values_in_browser(app_url: str, chromium: Browser, tmp_path: Path):
    """Decoded columns by name with signed values, and the Device column, on a CAN bus with locks,
    a CAN bus with M3IO modules and the Modbus line; screenshots at 1440x900 and 1024x768."""
    page = page_at(chromium, f"{app_url}/monitor/can1")
    frames = page.locator("[data-monitor=frames] tbody tr")
    answer = frames.filter(has_text="SettingsProximityThresholdLock = -60").first
    expect(answer).to_be_visible()
    assert answer.locator("td").nth(3).inner_text().strip() in ("gate-1", "gate-2")
    gate1 = page.locator("[data-monitor=overwrite] tbody tr").filter(has_text=GATE1).first
    expect(gate1.locator("td").nth(2)).to_have_text("gate-1")
    shot(page, str(tmp_path / "monitor-names-1440.png"))
    page.set_viewport_size({"width": 1024, "height": 768})
    # the Device column is on screen at 1024 px: measured across only, and without scrolling to the row,
    # which the live list moves down with every new frame (it is never still long enough to scroll to)
    device = None
    for _ in range(20):
        device = answer.locator("td").nth(3).bounding_box()
        if device is not None:
            break
        page.wait_for_timeout(100)
    assert device is not None and 0 <= device["x"] and device["x"] + device["width"] <= 1024, device
    shot(page, str(tmp_path / "monitor-names-1024.png"))

    # (the M3IO modules of can3 send their TEMP frames only while served: tests/app/test_monitor.py decodes them)
    page.set_viewport_size({"width": 1440, "height": 900})
    page.goto(f"{app_url}/monitor/line1")
    rows = page.locator(".q-table tbody tr")
    named = rows.filter(has_text="door-1 (unit 1)").filter(has_text="SettingsProximityThresholdLock = -60").first
    expect(named).to_be_visible()
    shot(page, str(tmp_path / "monitor-line1-1440.png"))
    page.set_viewport_size({"width": 1024, "height": 768})
    expect(named).to_be_visible()
    shot(page, str(tmp_path / "monitor-line1-1024.png"))
    page.close()
