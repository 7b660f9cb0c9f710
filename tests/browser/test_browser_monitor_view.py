"""What an engineer sees on the bus monitor in chromium at 1440x900 and 1024x768: the Modbus log's
RTT and Error columns on screen, a page of bounded height, CAN cycle times near the simulated
devices' documented periods, the whole buffer paged while paused, a frame's full decoding, a
recorded file opened with its progress, and the links to the bus tools. Screenshots land in
``/tmp/commission-shots``."""

from __future__ import annotations

import csv
import io
import re
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import can
import pytest
from demo_app import demo_app
from webutil import page_at

pytest.importorskip("playwright")
from playwright.sync_api import Browser, Page, expect, sync_playwright
from conftest import shot

CHROMIUM = Path("/usr/bin/chromium")
SHOTS = Path("/tmp/commission-shots")
GATE1 = "0x000A1284 (ext)"  # demo plant gate-1: extended device ID 660100, status every 1 s (section 6.5)
SIZES = ((1440, 900), (1024, 768))

pytestmark = [
    pytest.mark.skipif(not CHROMIUM.exists(), reason="needs Debian's chromium at /usr/bin/chromium"),
    pytest.mark.timeout(150),
]


@pytest.fixture(scope="module")
def app_url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    tmp = tmp_path_factory.mktemp("monitor-view")
    with demo_app(tmp, "monitor-view", COMMISSION_RECORDINGS_DIR=str(tmp / "recordings")) as url:
        yield url


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=["--no-sandbox", "--disable-gpu", "--disable-background-networking"])
        try:
            yield browser
        finally:
            browser.close()


def inside_viewport(page: Page, locator, width: int) -> None:
    box = None
    for _ in range(20):  # a row of the live log can be between two refreshes (replaced) when measured
        box = locator.bounding_box()
        if box is not None:
            break
        page.wait_for_timeout(100)
    assert box is not None, "not rendered"
    assert box["x"] >= 0 and box["x"] + box["width"] <= width + 1, f"{box} is outside a {width} px wide window"


def page_height(page: Page) -> int:
    return page.evaluate("document.documentElement.scrollHeight")


def test_modbus_log_fits_the_screen(app_url: str, browser: Browser):
    SHOTS.mkdir(parents=True, exist_ok=True)
    page = page_at(browser, f"{app_url}/monitor/line1")
    rows = page.locator("[data-monitor=transactions] tbody tr")
    expect(rows.nth(30)).to_be_visible(timeout=20_000)  # enough rows to make a tall table
    expect(page.locator("[data-monitor=tool-poll]")).to_be_visible()  # loopback: a local engineer
    for width, height in SIZES:
        page.set_viewport_size({"width": width, "height": height})
        header = page.locator("[data-monitor=transactions] thead th")
        for label in ("RTT ms", "Error", "Decoded"):
            inside_viewport(page, header.filter(has_text=re.compile(rf"^{label}$")), width)
        first = rows.first.locator("td")
        inside_viewport(page, first.nth(7), width)  # the Error cell of the newest transaction
        assert page.evaluate("document.documentElement.scrollWidth") <= width + 1, "the page scrolls sideways"
        assert page_height(page) <= 2 * height, f"page {page_height(page)} px tall at {width}x{height}"
        assert first.nth(1).inner_text().startswith("door-")  # the device by name
        # issue 32.14: hex never cut (wrapped between bytes), and a screen of transactions at 1440x900 (it held 7)
        cut = page.evaluate("""() => [...document.querySelectorAll('[data-monitor=transactions] td.hex')]
            .filter(td => td.scrollWidth > td.clientWidth + 1 || td.scrollHeight > td.clientHeight + 1
                          || getComputedStyle(td).textOverflow === 'ellipsis').map(td => td.textContent)""")
        assert cut == [], f"hex cut: {cut[:3]}"
        if width == 1440:
            visible = page.evaluate("""() => { const box = document.querySelector('[data-monitor=transactions-box]').getBoundingClientRect();
                return [...document.querySelectorAll('[data-monitor=transactions] tbody tr')].filter(r => {
                    const b = r.getBoundingClientRect(); return b.top >= box.top && b.bottom <= Math.min(box.bottom, innerHeight); }).length; }""")
            assert visible >= 12, f"{visible} transactions in sight at 1440x900"
        shot(page, str(SHOTS / f"monitor-modbus-{width}.png"))
    # the first answer carries the newest rows, not the whole table (it took 2.8-6.4 s to show a first value)
    expect(rows.nth(60)).to_be_visible(timeout=20_000)
    with urllib.request.urlopen(f"{app_url}/monitor/line1", timeout=10) as response:
        first_answer = response.read().decode()
    assert 1 <= first_answer.count('"tx":"') <= 40, f"{first_answer.count(chr(34) + 'tx' + chr(34))} rows in the first answer"
    # filter by unit, function and address, and export what is shown
    page.set_viewport_size({"width": 1440, "height": 900})
    page.locator("input[data-monitor=filter-unit], [data-monitor=filter-unit] input").fill("1")
    expect(rows.first.locator("td").nth(1)).to_have_text(re.compile(r"^door-1"))
    page.locator("input[data-monitor=filter-address], [data-monitor=filter-address] input").fill("3000-3001")
    expect(rows.first.locator("td").nth(2)).to_have_text(re.compile(r"^read holding 3000"))
    devices = rows.locator("td:nth-child(2)").all_inner_texts()
    assert devices and all(d.startswith("door-1") for d in devices), devices
    page.get_by_text("Pause").click()  # the table stands still while it is exported
    shown = rows.count()
    with page.expect_download() as download:
        page.locator("[data-monitor=export]").click()
    table = list(csv.reader(io.StringIO(Path(download.value.path()).read_text())))
    assert table[0][:4] == ["time", "device", "unit", "function"]
    assert len(table) - 1 == shown and all(r[2] == "1" and r[4].startswith("read holding 3000") for r in table[1:]), table[:3]
    page.close()


def test_can_cycle_times_paging_and_details(app_url: str, browser: Browser):
    page = page_at(browser, f"{app_url}/monitor/can1")
    expect(page.locator("[data-monitor=tool-transmit]")).to_be_visible()
    expect(page.locator("[data-monitor=tool-replay]")).to_be_visible()
    gate1 = page.locator("[data-monitor=overwrite] tbody tr").filter(has_text=GATE1).first

    def status_cycle() -> float:  # Cycle column: the 8-byte status stream's cycle, first or labelled "(8 B ...)"
        text = gate1.locator("td").nth(4).inner_text()
        parts = [p for p in text.split(" · ") if "8 B" in p] or [text]
        return float(parts[0].split()[0]) if parts[0].split()[0].replace(".", "").isdigit() else -1.0

    for _ in range(150):  # the status frames come every 1 s: a few of them make a median
        cycle = status_cycle()
        if 900 <= cycle <= 1100:
            break
        page.wait_for_timeout(100)
    assert 900 <= status_cycle() <= 1100, gate1.inner_text()  # the document's 1 s status period, not 0-2 ms
    expect(page.locator("[data-monitor=load]")).to_contain_text(
        re.compile(r"load \d+\.\d % of 250 kbit/s \(5 s average\), peak \d+\.\d % \(highest second of the last 10 s\) · \d+ frames/s"))
    expect(page.locator("[data-monitor=counters]")).to_contain_text("interface drops")
    for width, height in SIZES:
        page.set_viewport_size({"width": width, "height": height})
        inside_viewport(page, page.locator("[data-monitor=overwrite] thead th").filter(has_text=re.compile("^Last$")), width)
        overflow = page.locator("[data-monitor=overwrite-box]").evaluate("el => el.scrollWidth - el.clientWidth")
        assert overflow <= 1, f"the overwrite view is {overflow} px wider than its box: Last is cut off"
        assert page_height(page) <= 2 * height
        shot(page, str(SHOTS / f"monitor-can-{width}.png"))
    page.set_viewport_size({"width": 1440, "height": 900})

    # paused: the whole buffer in pages; a frame opened for its full decoding
    frames = page.locator("[data-monitor=frames] tbody tr")
    expect(frames.nth(50)).to_be_visible()
    page.locator("[data-monitor=pause]").click()
    pages = page.locator("[data-monitor=live-pages]")
    expect(pages).to_be_visible()
    info = page.locator("[data-monitor=frames-info]")
    expect(info).to_contain_text("paused: frames 1-")
    total = int(re.search(r"of (\d+) buffered", info.inner_text()).group(1))
    if total > 200:
        pages.get_by_role("button", name="2", exact=True).click()
        expect(info).to_contain_text("paused: frames 201-")
    newest_shown = frames.first.locator("td").first.inner_text()
    page.wait_for_timeout(700)  # two refresh periods: a paused list must not move
    assert frames.first.locator("td").first.inner_text() == newest_shown
    # a status frame of a lock of this bus (the demo's spare lock is heard but not in the plant)
    status_row = frames.filter(has_text="HD-Lock Status").filter(has_text=re.compile(r"gate-\d")).first
    if total > 200 and status_row.count() == 0:  # an older page of 200 frames may hold none (1 s apart among the bus's others)
        pages.get_by_role("button", name="1", exact=True).click()
        expect(info).to_contain_text("paused: frames 1-")
    status_row.click()
    details = page.locator("[data-monitor=frame-details]")
    expect(details).to_be_visible()
    expect(details).to_contain_text("gate-")
    expect(details).to_contain_text("HD-Lock Status")
    expect(details.locator("tbody tr")).to_have_count(8)  # every byte with hex, decimal, binary
    shot(page, str(SHOTS / "monitor-can-details-1440.png"))
    page.keyboard.press("Escape")
    page.close()


def test_a_large_recorded_file_opens_paged(app_url: str, browser: Browser, tmp_path: Path):
    path = tmp_path / "big.log"
    with can.CanutilsLogWriter(path, channel="can0") as writer:
        for i in range(100_000):
            writer.on_message_received(can.Message(timestamp=1_700_000_000 + i * 0.001, arbitration_id=0x100 + i % 7,
                                                   is_extended_id=False, data=bytes([i % 256] * 8)))
    bad = tmp_path / "bad.log"
    bad.write_text("(1700000000.000000) can0 123#0102\nthis is no candump line\n")
    page = browser.new_page(viewport={"width": 1440, "height": 900})
    page.set_default_timeout(30_000)
    page.goto(f"{app_url}/monitor/can1")
    page.get_by_role("tab", name="Recorded file").click()
    page.locator("[data-monitor=upload] input[type=file]").set_input_files(str(path))
    info = page.locator("[data-monitor=file-info]")
    expect(info).to_contain_text("100000 frames", timeout=60_000)
    expect(page.locator("[data-monitor=file-frames] tbody tr")).to_have_count(200)
    expect(page.locator("[data-monitor=file-pages]")).to_contain_text("500")
    assert page_height(page) <= 2 * 900
    shot(page, str(SHOTS / "monitor-file-1440.png"))
    page.locator("[data-monitor=upload] input[type=file]").set_input_files(str(bad))
    expect(info).to_contain_text("line 2")  # where the file broke
    page.close()
