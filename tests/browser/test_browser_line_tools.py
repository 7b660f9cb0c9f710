"""Issue 42 item 11 in a real browser (Debian's chromium through playwright), at 1440x900 and 768x1024: the RS232 and
LogiTed monitors in the words of their device pages with filters of their own kind, and a transmitted M3IO DigOut
that the tool's own keep-alive overrides, said before and after the send.

The app runs the demo plant as a subprocess, on free ports and CAN channels of its own.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

import pytest
from conftest import CHROMIUM, inside_viewport
from webutil import at_size, page_at
from demo_app import demo_app

pytest.importorskip("playwright")
from playwright.sync_api import Browser, Page, expect

pytestmark = [
    pytest.mark.skipif(not CHROMIUM.exists(), reason="needs Debian's chromium at /usr/bin/chromium"),
    pytest.mark.timeout(120),
]
SIZES = [(1440, 900), (768, 1024)]


@pytest.fixture(scope="module")
def app_url(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    with demo_app(tmp_path_factory.mktemp("linetools"), "linetools") as url:
        yield url


def rows(page: Page):
    return page.locator("[data-monitor=transactions] tbody tr")


def choose(page: Page, filter_key: str, option: str) -> None:
    """``option`` chosen in the monitor's filter ``filter_key``."""
    page.locator(f"[data-monitor=filter-{filter_key}]").click()
    page.get_by_role("option", name=option, exact=True).click()


def test_the_scu_monitor_names_telegrams_and_filters_by_command(app_url: str, chromium: Browser):
    """Loaded once at 1440x900 and made 768x1024: at each size the telegrams named, the decoded text in sight and the
    command filter (set back to any before the next size)."""
    page = page_at(chromium, f"{app_url}/monitor/rs232-1", *SIZES[0])
    expect(page.get_by_text("Bus monitor rs232-1")).to_be_visible()
    expect(page.locator("[data-monitor=filter-unit]")).to_have_count(0)
    for width, height in SIZES:
        with at_size(page, width, height):
            cyclic = rows(page).filter(has_text="RC keep-alive with CyclicObj 1").first
            expect(cyclic).to_contain_text("Actual_Position, all actuators: A1 ")
            expect(rows(page).filter(has_text=re.compile(r"ACK, \d+ data bytes"))).to_have_count(0)
            inside_viewport(page, cyclic.locator("td").nth(5))  # the decoded text is in sight on a tablet too
            choose(page, "command", "RG read data")
            first = rows(page).first
            expect(first.locator("td").nth(2)).to_have_text(re.compile(r"^RG 0x[0-9A-F]{4} \S"))
            expect(rows(page).filter(has_text="RC keep-alive")).to_have_count(0)
            choose(page, "command", "any")
    page.close()


def test_the_logited_monitor_names_another_masters_telegrams(app_url: str, chromium: Browser):
    """Loaded once at 1440x900 and made 768x1024: at each size the telegrams named and the telegram filter (set back
    to any before the next size)."""
    page = page_at(chromium, f"{app_url}/monitor/gates-485", *SIZES[0])
    expect(page.get_by_text("Bus monitor gates-485")).to_be_visible()
    for width, height in SIZES:
        with at_size(page, width, height):
            expect(rows(page).filter(has_text="Gate state = closed").first).to_be_visible()
            query = re.compile(r"master 0x01 -> barrier-out-\d: query gate state")
            expect(rows(page).filter(has_text=query).first).to_be_visible()
            expect(rows(page).filter(has_text="between others")).to_have_count(0)
            choose(page, "telegram", "another master's")
            expect(rows(page).first).to_contain_text("master 0x01")
            choose(page, "telegram", "any")
    page.close()


def test_a_digout_the_keepalive_overrides_says_so_before_and_after(app_url: str, chromium: Browser):
    page = page_at(chromium, f"{app_url}/monitor/can3/transmit")
    expect(page.get_by_text("Transmit list · can3")).to_be_visible()
    line = page.get_by_text("heater-hm DigOut", exact=True).locator("xpath=..")
    line.get_by_text("SSR1", exact=True).click()
    line.get_by_role("button", name="Add").click()
    row = page.get_by_test_id("transmit-table").locator("tbody tr").filter(has_text="heater-hm DigOut: SSR1")
    row.get_by_role("button", name="Send").click()
    dialog = page.locator(".q-dialog")
    expect(dialog).to_contain_text("mains voltage")
    expect(dialog).to_contain_text("heater-hm is served by this tool")
    expect(dialog).to_contain_text("sets heater-hm back to what its page shows")
    dialog.get_by_role("button", name="Send").click()
    expect(row.locator("td").nth(5)).to_have_text("1")
    expect(page.get_by_test_id("transmit-overridden")).to_contain_text("heater-hm is served by this tool")
    expect(page.get_by_text("Sent once, but it does not last")).to_be_visible()
    page.close()
