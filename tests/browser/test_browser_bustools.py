"""The engineer's bus tools in a real browser (Debian's chromium through playwright): transmit list, Modbus poll.

The app runs the demo plant as a subprocess, on free ports and CAN channels of its own, with a
data folder of the test's own. Screenshots at 1440x900 and 1024x768 land in /tmp/commission-shots.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from demo_app import demo_app
from webutil import page_at

pytest.importorskip("playwright")
from playwright.sync_api import Browser, Page, expect, sync_playwright
from conftest import shot

CHROMIUM = Path("/usr/bin/chromium")
SHOTS = Path("/tmp/commission-shots")

pytestmark = [
    pytest.mark.skipif(not CHROMIUM.exists(), reason="needs Debian's chromium at /usr/bin/chromium"),
    pytest.mark.timeout(120),
]


@pytest.fixture(scope="module")
def app_url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with demo_app(tmp_path_factory.mktemp("bustools"), "bustools") as url:
        yield url


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=str(CHROMIUM), args=["--no-sandbox", "--disable-gpu", "--disable-background-networking"]
        )
        try:
            yield browser
        finally:
            browser.close()


def shoot(page: Page, name: str) -> None:
    SHOTS.mkdir(exist_ok=True)
    for width, height in ((1440, 900), (1024, 768)):
        page.set_viewport_size({"width": width, "height": height})
        shot(page, str(SHOTS / f"{name}-{width}x{height}.png"), full_page=True)


@pytest.mark.alone  # a cyclic row sends only while its page beats (dead-man): a browser beside it delays the beats
def test_transmit_list(app_url: str, browser: Browser):
    page = page_at(browser, f"{app_url}/monitor/can1/transmit")
    expect(page.get_by_text("Transmit list · can1")).to_be_visible()
    page.get_by_label("ID (hex)").fill("321")
    page.get_by_label("Data (hex bytes)").fill("AA 55")
    page.get_by_label("Send", exact=True).click()
    page.get_by_role("option", name="cyclic").click()
    page.get_by_label("Cycle ms", exact=True).fill("50")
    page.get_by_test_id("transmit-add").click()
    table = page.get_by_test_id("transmit-table")
    row = table.locator("tbody tr").filter(has_text="0x321")
    expect(row).to_contain_text("every 50 ms")
    row.get_by_role("button", name="Start").click()
    expect(row).to_contain_text("running")
    expect(row.locator("td").nth(5)).to_have_text(re.compile(r"^[1-9]\d+$"))  # frames sent, counting
    # the count moves in place: the table (and its Stop button) is never replaced by a new one, so a
    # click on Stop cannot land on a table the page has just thrown away, and be lost
    element = table.get_attribute("id")
    sent = int(row.locator("td").nth(5).inner_text())
    expect(row.locator("td").nth(5)).not_to_have_text(str(sent))
    sent = int(row.locator("td").nth(5).inner_text())
    expect(row.locator("td").nth(5)).not_to_have_text(str(sent))
    assert table.get_attribute("id") == element
    # a forbidden frame is refused by name
    page.get_by_label("ID (hex)").fill("706")
    page.get_by_label("Data (hex bytes)").fill("00 00 00 00 00 00")
    page.get_by_label("DLC").fill("6")
    page.get_by_label("Send", exact=True).click()
    page.get_by_role("option", name="once").click()
    page.get_by_test_id("transmit-add").click()
    expect(page.get_by_text(re.compile("FWU erase sector.*firmware-update"))).to_be_visible()
    page.get_by_role("button", name="OK").click()
    shoot(page, "transmit")
    row.get_by_role("button", name="Stop").click()
    expect(row).not_to_contain_text("running")
    page.close()


def _ask(page, window, start: str, count: str, period: str, function: str | None = None) -> None:
    """Fill a poll window's request (``window`` the page itself while it has one window)."""
    if function is not None:
        window.get_by_label("Function").click()
        page.get_by_role("option", name=function).click()
    for label, value in (("Start address", start), ("Count", count), ("Period s", period)):
        window.get_by_label(label).fill(value)
        expect(window.get_by_label(label)).to_have_value(value)  # a redraw did not put the old value back


def test_modbus_poll(app_url: str, browser: Browser):
    page = page_at(browser, f"{app_url}/monitor/line1/poll")
    expect(page.get_by_text("Modbus poll · line1")).to_be_visible()
    _ask(page, page, "104", "2", "0.5", function="04 Read Input Registers")
    page.get_by_test_id("poll-start").click()
    table = page.get_by_test_id("poll-table")
    first = table.locator("tbody tr").first
    expect(first).to_contain_text("SerialNumber")
    expect(page.get_by_test_id("poll-status")).to_contain_text(re.compile(r"[2-9] polls|\d\d+ polls"))
    shoot(page, "modbus-poll")
    # every poll changes the rows in place: the table stays the same element
    element = table.get_attribute("id")
    expect(page.get_by_test_id("poll-status")).to_contain_text(re.compile(r"([4-9]|\d\d+) polls"))
    assert table.get_attribute("id") == element
    header = table.locator("thead")
    expect(header).to_contain_text("uint32 ABCD")
    expect(header).to_contain_text("float32 CDAB")
    # in a 1024 px window one kind of 32-bit value fits: every column in sight, none scrolled off
    page.set_viewport_size({"width": 1024, "height": 768})
    page.get_by_label("32-bit values").click()
    page.get_by_role("option", name="float32", exact=True).click()
    expect(header).not_to_contain_text("uint32")
    expect(header).to_contain_text("float32 ABCD")
    expect(table.locator("tbody tr").first).to_contain_text("SerialNumber")
    expect(header).not_to_contain_text("float32 BADC")  # the byte-swapped orders only when chosen
    overflow = table.locator(".q-table__middle").evaluate("e => e.scrollWidth - e.clientWidth")
    assert overflow <= 1, f"the poll table is {overflow} px wider than its box at 1024 px"
    shoot(page, "modbus-poll-float32")
    page.get_by_label("Word orders").click()
    page.get_by_role("option", name="BADC, DCBA (bytes swapped)").click()
    expect(header).to_contain_text("float32 DCBA")
    expect(header).not_to_contain_text("float32 ABCD")
    overflow = table.locator(".q-table__middle").evaluate("e => e.scrollWidth - e.clientWidth")
    assert overflow <= 1, f"the poll table is {overflow} px wider than its box at 1024 px (byte-swapped orders)"
    page.set_viewport_size({"width": 1440, "height": 900})
    # a protected register is refused
    page.get_by_label("Address", exact=True).fill("10")
    page.get_by_label("Value(s)").fill("1")
    page.get_by_role("button", name="Write").click()
    expect(page.get_by_text(re.compile(r"MFR: not writable"))).to_be_visible()
    page.close()


@pytest.mark.alone  # beside another browser (twice on 2026-11-29, the app's loop stalling 130-140 ms) the second
# window's entries came back with the values it was built with after they were typed; the cause is not found yet
def test_modbus_poll_windows(app_url: str, browser: Browser):
    """Two poll windows at once, each with its own request and table; a reload of the tab brings them back."""
    page = page_at(browser, f"{app_url}/monitor/line1/poll")
    first = page.get_by_test_id("poll-window-1")
    expect(first).to_be_visible()
    _ask(page, first, "104", "2", "0.5", function="04 Read Input Registers")
    first.get_by_label("32-bit values").click()
    page.get_by_role("option", name="float32", exact=True).click()
    first.get_by_test_id("poll-start").click()
    page.get_by_test_id("poll-add").click()
    second = page.get_by_test_id("poll-window-2")
    expect(second).to_be_visible()
    _ask(page, second, "3000", "4", "0.3")
    second.get_by_label("32-bit values").click()
    page.get_by_role("option", name="none", exact=True).click()
    second.get_by_test_id("poll-start").click()
    # what each window polls, as the page took it (a typed entry that did not arrive would show here first)
    expect(first.get_by_test_id("poll-summary")).to_contain_text("104+2")
    expect(second.get_by_test_id("poll-summary")).to_contain_text("3000+4")
    expect(first.get_by_test_id("poll-table").locator("tbody tr").first).to_contain_text("SerialNumber")
    expect(second.get_by_test_id("poll-table").locator("tbody tr").first).to_contain_text("LockRequestDelay")
    expect(second.get_by_test_id("poll-status")).to_contain_text(re.compile(r"([2-9]|\d\d+) polls · 0 errors \(0 timeouts\)"))
    expect(second.get_by_test_id("poll-status")).to_contain_text("updated")
    SHOTS.mkdir(exist_ok=True)
    for width, height in ((1440, 900), (768, 1024)):
        page.set_viewport_size({"width": width, "height": height})
        expect(second.get_by_test_id("poll-table")).to_be_visible()
        shot(page, str(SHOTS / f"modbus-poll-windows-{width}x{height}.png"), full_page=True)
    page.set_viewport_size({"width": 1440, "height": 900})
    # a reload of the tab brings both windows back, each polling what it polled
    page.reload()
    expect(second.get_by_label("Start address")).to_have_value("3000")
    expect(first.get_by_test_id("poll-table").locator("tbody tr").first).to_contain_text("SerialNumber")
    expect(second.get_by_test_id("poll-table").locator("tbody tr").first).to_contain_text("LockRequestDelay")
    expect(first.get_by_test_id("poll-table").locator("thead")).to_contain_text("float32 ABCD")
    expect(first.get_by_test_id("poll-table").locator("thead")).not_to_contain_text("uint32")
    second.get_by_test_id("poll-remove").click()
    expect(second).to_have_count(0)
    first.get_by_test_id("poll-stop").click()
    expect(first.get_by_test_id("poll-status")).to_contain_text("stopped")
    page.close()
