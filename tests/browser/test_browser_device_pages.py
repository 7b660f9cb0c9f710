"""HD-Lock and M3IO pages in chromium at 1440x900 and 1024x768: what is visible (issue 15 items 4, 6, 7, 10)."""

from __future__ import annotations

import json
import re
import urllib.request
from pathlib import Path

import pytest
from conftest import CHROMIUM, inside_viewport, shot, wait_devices_online
from webutil import at_size, charts_fit, demo_plant_text, eventually_sync, free_port, running_app

if not CHROMIUM.exists():
    pytest.skip(f"{CHROMIUM} is not installed", allow_module_level=True)

from playwright.sync_api import Browser, Page, expect  # noqa: E402

pytestmark = pytest.mark.timeout(90)
STEP_MS = 10_000
SIZES = [(1440, 900), (1024, 768)]


@pytest.fixture(scope="module")
def app_url(tmp_path_factory: pytest.TempPathFactory):
    with running_app(demo_plant_text(free_port()), tmp_path_factory.mktemp("device-pages")) as url:
        wait_devices_online(url, ("door-1", "heater-hm"), timeout=30)
        yield url


def open_page(chromium: Browser, url: str, size: tuple[int, int]) -> Page:
    page = chromium.new_context(viewport={"width": size[0], "height": size[1]}).new_page()
    page.set_default_timeout(STEP_MS)
    page.goto(url)
    return page


def page_with_chart(chromium: Browser, url: str, size: tuple[int, int], heading: str, drawn_js: str) -> Page:
    """:func:`open_page` once its ``heading`` is shown and a chart of it is drawn as ``drawn_js`` (a function of
    one plotly chart) tells."""
    page = open_page(chromium, url, size)
    try:
        expect(page.get_by_text(heading)).to_be_visible()
        page.wait_for_function(f"() => [...document.querySelectorAll('.js-plotly-plot')].some({drawn_js})")
    except BaseException:
        page.context.close()
        raise
    return page


def field(page: Page, testid: str):
    return page.locator(f'input[data-testid="{testid}"], [data-testid="{testid}"] input')


def lock_values(url: str) -> dict:
    with urllib.request.urlopen(url + "/api/devices/door-1", timeout=5) as response:
        return json.load(response)["values"]


def test_hdlock_entry_save_dialog_and_chart(app_url: str, chromium: Browser, tmp_path: Path):
    """Loaded once at 1440x900 and made 1024x768 (and for the register table 768x1024): at each size the chart, a
    refused address, a written parameter in the Save-Settings confirmation and the register table."""
    # the chart: increments on the left axis, mA on a right one, the last 30 s chosen
    page = page_with_chart(chromium, app_url + "/device/door-1", SIZES[0], "Modbus address 1 ·", "p => p.layout && "
                           "p.layout.yaxis2 && p.layout.yaxis2.overlaying === 'y' && p.layout.yaxis2.side === 'right'")
    try:
        for size in SIZES:
            with at_size(page, *size):
                _hdlock_entry_at(page, app_url, tmp_path, size)
    finally:
        page.context.close()


def _hdlock_entry_at(page: Page, app_url: str, tmp_path: Path, size: tuple[int, int]) -> None:
    page.evaluate("window.scrollTo(0, 0)")
    charts_fit(page)
    expect(page.locator("[data-chart-window] button[aria-pressed=true]")).to_have_text(re.compile(r"30 s"))
    expect(page.locator(".js-plotly-plot .y2title")).to_have_text("mA")  # each axis titled with its unit
    expect(page.locator(".js-plotly-plot .ytitle")).to_have_text("Inc")
    expect(page.locator(".js-plotly-plot .ytitle")).to_be_visible()
    page.wait_for_function("() => { const t = document.querySelector('.js-plotly-plot .ytitle');"
                           " return t && t.getBoundingClientRect().x >= 0; }")  # not clipped at the left edge
    shot(page, str(tmp_path / f"door-1-top-{size[0]}.png"))

    # address 300: kept as typed, marked with the range, Send off with the field's reason: nothing can be sent
    # (no confirmation, the lock keeps address 1)
    card = page.locator(".q-card", has_text="Set Modbus Address (command 3)")
    address = card.get_by_label("New address")
    address.scroll_into_view_if_needed()
    address.fill("300")
    address.press("Tab")  # the entry is taken on change, as a person leaves the field
    expect(card).to_contain_text("out of range: allowed 1 .. 254")
    expect(address).to_have_value("300")
    send = page.locator('[data-testid="sa-send"]')
    expect(send).to_be_disabled()
    expect(send).to_have_attribute("data-disabled-reason", "address 300 is refused: out of range: allowed 1 .. 254")
    expect(page.locator(".q-dialog")).to_have_count(0)
    expect(page.get_by_text("Modbus address 1 ·")).to_be_visible()
    inside_viewport(page, page.locator('[data-testid="sa-send"]'))
    shot(page, str(tmp_path / f"door-1-address-{size[0]}.png"))

    # a written parameter is listed by the Save-Settings confirmation
    delay = page.locator('input[data-param="LockRequestDelay"], [data-param="LockRequestDelay"] input')
    delay.scroll_into_view_if_needed()
    typed = 350 if size[0] == 1440 else 360
    delay.fill(str(typed))
    delay.press("Tab")
    page.locator('[data-write="LockRequestDelay"]').click()
    # written and read back (an earlier size's unsaved change may be listed already: wait for this one's value)
    eventually_sync(lambda: lock_values(app_url)["LockRequestDelay"]["value"] == typed, timeout=15, what="written")
    expect(page.get_by_text("unsaved change").first).to_be_visible()
    page.locator('[data-testid="save-settings"]').click()
    dialog = page.locator('[data-testid="save-dialog"]')
    expect(dialog).to_contain_text(f"LockRequestDelay (holding 3000) = {delay.input_value()} ms")
    inside_viewport(page, dialog)
    shot(page, str(tmp_path / f"door-1-save-{size[0]}.png"))
    dialog.get_by_role("button", name="Cancel").click()
    expect(dialog).to_have_count(0)
    assert lock_values(app_url)["SavedSettings"]["value"] == 0  # cancelled: the flash was not written

    # the register table shows every column, its Quality too, without scrolling sideways
    table = page.locator(".q-tab-panel .reg-table .q-table__middle").first
    table.scroll_into_view_if_needed()
    expect(table).to_contain_text("SystemCoreClock-Config")  # the longest value of the lock's input registers
    widths = [size[0]] + ([768] if size[0] == 1024 else [])  # and on a tablet held upright
    for width in widths:
        page.set_viewport_size({"width": width, "height": 1024 if width == 768 else size[1]})
        overflow = table.evaluate("e => e.scrollWidth - e.clientWidth")
        assert overflow <= 1, f"the register table is {overflow} px wider than its box at {width} px"


def test_hdlock_silent_lock_greys_lamps_ages_rows_and_disables_writes(app_url: str, chromium: Browser, tmp_path: Path):
    page = open_page(chromium, app_url + "/device/door-1", SIZES[0])
    try:
        expect(page.locator('[data-lamp="BoltUnlocked"]')).to_have_attribute("data-quality", "good")
        page.locator('[data-testid="sim-silent"]').click()
        lamp = page.locator('[data-lamp="BoltUnlocked"]')
        expect(lamp).to_have_attribute("data-quality", re.compile("stale|offline"), timeout=15_000)
        expect(lamp).to_have_css("filter", "grayscale(1)")
        expect(page.locator('[data-write="LockRequestDelay"]')).to_be_disabled(timeout=15_000)
        expect(page.locator('[data-write="LockRequestDelay"]')).to_have_attribute("title", re.compile("the device does not answer"))
        expect(page.locator('[data-testid="save-settings"]')).to_be_disabled()
        rows = page.locator(".q-tab-panel:visible tr.q-offline")
        expect(rows.first).to_contain_text(re.compile(r"offline, last \d+ s ago"))
        shot(page, str(tmp_path / "door-1-offline-1440.png"), full_page=True)
        page.locator('[data-testid="sim-silent"]').click()
        expect(page.locator('[data-write="LockRequestDelay"]')).to_be_enabled(timeout=15_000)
        expect(page.locator('[data-testid="events"] tbody tr').first).to_contain_text(re.compile("back online|answering again"))
    finally:
        page.context.close()


def test_m3io_page_record_entry_keeps_what_was_typed(app_url: str, chromium: Browser, tmp_path: Path):
    """The refused record entry, and the temperature chart beside the outputs from 1024 px and as wide as the page
    on an upright tablet: loaded once at 1440x900, made 1024x768 and then 768x1024."""
    page = page_with_chart(chromium, app_url + "/device/heater-hmr", SIZES[0], "CAN-M3IO heater-hmr (HMR)",
                           "p => (p.data || []).some(t => t.y && t.y.length >= 2)")
    try:
        record = field(page, "record")
        record.scroll_into_view_if_needed()
        record.fill("20")
        record.press("Tab")
        field(page, "record-bytes").fill("01 02")
        page.locator('[data-testid="record-write"]').click()
        card = page.locator(".q-card", has=field(page, "record"))
        expect(card).to_contain_text("out of range: allowed 1 .. 15")
        expect(record).to_have_value("20")
        expect(page.locator('[data-testid="events"] tbody tr').first).to_contain_text("refused")
        chart = page.locator(".js-plotly-plot").first
        for size in SIZES:
            with at_size(page, *size):
                charts_fit(page)
                expect(card).to_contain_text("out of range: allowed 1 .. 15")
                expect(record).to_have_value("20")
                shot(page, str(tmp_path / f"heater-hmr-{size[0]}.png"), full_page=True)
                assert chart.bounding_box()["width"] < size[0] / 2  # beside the outputs from 1024 px
        with at_size(page, 768, 1024):  # an upright tablet: the temperatures below the outputs, the chart as wide as the page
            charts_fit(page)
            expect(chart).to_be_visible()
            width = chart.bounding_box()["width"]
            assert width > 0.75 * 768, f"the temperature chart is {width:.0f} px wide on a 768 px tablet"
            shot(page, str(tmp_path / "heater-hmr-768.png"), full_page=True)
    finally:
        page.context.close()


def test_chart_in_a_hidden_page_draws_nothing_until_shown(app_url: str, chromium: Browser):
    """A page in a background tab or minimised window spends nothing on drawing: the samples wait,
    merged into one update per chart, and are drawn in one go when the page is shown again.

    The page is hidden by its ``document.hidden`` alone, so chromium goes on laying it out: the
    chart's own response to its size (plotly's autosize, 100 ms after it is first observed) may still
    draw, as it could not in a real background tab. So the drawings counted are the page's calls
    into plotly (extendTraces, react, newPlot), not every ``plotly_afterplot``."""
    page = open_page(chromium, app_url + "/device/heater-hm", (1440, 900))
    try:
        count = "() => document.querySelector('.js-plotly-plot').data[0].x.length"
        page.wait_for_function(f"() => document.querySelector('.js-plotly-plot')?.data && ({count})() > 0")
        page.evaluate("""() => {
            window.__draws = 0;
            const vm = getElement(document.querySelector('.js-plotly-plot'));
            for (const name of ['extendTraces', 'react', 'newPlot']) {
                const call = vm.Plotly[name];
                vm.Plotly[name] = function (...args) { window.__draws++; return call.apply(this, args); };
            }
            Object.defineProperty(document, 'hidden', {configurable: true, get: () => window.__hidden === true});
            window.__hidden = true;
            document.dispatchEvent(new Event('visibilitychange'));
        }""")
        before = page.evaluate(count)
        page.wait_for_function("() => Object.keys(window.__cx || {}).length > 0")  # new samples arrived meanwhile
        page.wait_for_timeout(2500)  # two more of the chart's sendings (one a second)
        assert page.evaluate("window.__draws") == 0
        assert page.evaluate("Object.keys(window.__cx).length") == 1  # merged: one waiting update for the one chart
        page.evaluate("() => { window.__hidden = false; document.dispatchEvent(new Event('visibilitychange')); }")
        page.wait_for_function("() => window.__draws > 0")
        assert page.evaluate(count) > before
        assert page.evaluate("Object.keys(window.__cx).length") == 0
    finally:
        page.context.close()
