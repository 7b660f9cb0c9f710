"""Real-browser tests: Debian's chromium, driven by playwright, on ``python -m app.cli``.

The app runs as a separate process on a copy of the demo plant whose simulated RTU line
listens on a free port; the HD-Lock twins are polled over real Modbus RTU frames.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from conftest import CHROMIUM, inside_viewport, shot, wait_devices_online
from webutil import at_size, click_until, demo_app_serving

if not CHROMIUM.exists():
    pytest.skip(f"{CHROMIUM} is not installed", allow_module_level=True)

from playwright.sync_api import Browser, Page, expect  # noqa: E402
from playwright.sync_api import TimeoutError as PlaywrightTimeout  # noqa: E402

pytestmark = pytest.mark.timeout(60)  # includes starting the app for the first test

STEP_MS = 10_000  # longest wait for one visible step (page timers tick every 0.5-1 s)


@pytest.fixture(scope="module")
def app_url(tmp_path_factory: pytest.TempPathFactory):
    """The GUI on the demo plant (line1 on a free port), until the module's tests are done."""
    with demo_app_serving(tmp_path_factory.mktemp("browser-app"), ("door-1", "door-2"), online_within_s=15) as url:
        yield url


@pytest.fixture
def page(chromium: Browser):
    context = chromium.new_context(viewport={"width": 1400, "height": 1800})
    page = context.new_page()
    page.set_default_timeout(STEP_MS)
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        yield page
    finally:
        context.close()
    assert not errors, f"JavaScript errors on the page: {errors}"


def lamp(page: Page, name: str):
    return page.locator(f'[data-lamp="{name}"]')


def register_value(page: Page, name: str) -> str:
    """Text of the Value cell of the row named ``name`` in the visible register table."""
    row = page.locator(".q-tab-panel:visible tr", has=page.locator("td", has_text=re.compile(rf"^\s*{re.escape(name)}\s*$")))
    expect(row).to_have_count(1)
    return row.locator("td").nth(2).inner_text().strip()


def bolt_position(page: Page) -> int:
    text = register_value(page, "BoltPosition")
    match = re.fullmatch(r"(-?\d+) Inc", text)
    assert match, f"BoltPosition shows {text!r}"
    return int(match.group(1))


def save_shot(page: Page, tmp_path: Path, name: str, full_page: bool = True) -> Path:
    """A screenshot for a person to look at, under the test's own temporary folder."""
    path = tmp_path / name
    shot(page, str(path), full_page=full_page)
    return path


BOLT_OUT = re.compile(r"^\s*(10[1-9]|1[1-9]\d|[2-9]\d\d|\d{4,}) Inc\s*$")  # more than 100 Inc


def test_closing_the_door_locks_the_bolt(app_url: str, page: Page, tmp_path: Path):
    page.goto(app_url + "/device/door-1")
    expect(page.get_by_text("HD-Lock door-1", exact=True).first).to_be_visible()
    expect(page.locator(".q-badge", has_text=re.compile(r"^\s*online\s*$")).first).to_be_visible()

    # the door of door-1 starts open: bolt retracted, nothing in position
    expect(lamp(page, "BoltUnlocked")).to_have_attribute("data-on", "1")
    expect(lamp(page, "DoorInPosition")).to_have_attribute("data-on", "0")
    expect(lamp(page, "BoltLocked")).to_have_attribute("data-on", "0")
    expect(page.locator('[data-value="DoorState"]')).not_to_have_text("-")
    assert bolt_position(page) == 0

    page.get_by_test_id("sim-close").click()

    expect(lamp(page, "DoorInPosition")).to_have_attribute("data-on", "1")
    expect(lamp(page, "BoltLocked")).to_have_attribute("data-on", "1")
    expect(lamp(page, "BoltUnlocked")).to_have_attribute("data-on", "0")
    bolt_row = page.locator(".q-tab-panel:visible tr", has=page.locator("td", has_text=re.compile(r"^\s*BoltPosition\s*$")))
    expect(bolt_row.locator("td").nth(2)).to_have_text(BOLT_OUT)
    assert bolt_position(page) > 100
    expect(page.locator('[data-value="StateMachineState"]')).not_to_have_text("-")

    # the live chart shows the stroke: a trace with several samples, the last one out (> 100 Inc)
    page.wait_for_function(
        """() => [...document.querySelectorAll('.js-plotly-plot')].some(p => (p.data || []).some(
               t => t.y && t.y.length >= 3 && Math.max(...t.y.filter(v => v !== null)) > 100))""",
        timeout=STEP_MS,
    )
    inside_viewport(page, lamp(page, "BoltLocked"))
    save_shot(page, tmp_path, "device-door-1-locked.png")


def test_overview_tiles_online_and_open_device(app_url: str, page: Page, tmp_path: Path):
    page.goto(app_url + "/")
    for name in ("door-1", "door-2"):
        tile = page.locator(f'[data-device="{name}"]')
        expect(tile).to_be_visible()
        expect(tile).to_contain_text(name)
        expect(tile).to_contain_text("HD-Lock on line1")
        expect(tile.locator(".q-badge:not(.drift-badge)")).to_have_text(re.compile(r"^\s*online\s*$"))
        expect(tile).to_contain_text(re.compile(r"req \d+"))
        inside_viewport(page, tile)
    save_shot(page, tmp_path, "overview.png")

    page.locator('[data-device="door-2"]').click()
    expect(page).to_have_url(re.compile(r"/device/door-2$"))
    expect(page.get_by_text("HD-Lock door-2", exact=True).first).to_be_visible()
    # door-2 starts with its door closed: its bolt is out
    expect(lamp(page, "BoltLocked")).to_have_attribute("data-on", "1")


HEADER_SIZES = ((1440, 900), (1024, 768), (768, 1024))
_HEADER_LINE_JS = """() => { const h = document.querySelector('[data-testid=header]');
    const r = h.getBoundingClientRect(); const title = h.querySelector('a').getBoundingClientRect();
    return {height: r.height, title: title.height}; }"""


def test_header_on_one_line_with_pages_and_account_reachable(app_url: str, chromium: Browser, tmp_path: Path):
    """Issue 32.16: the header is one line down to 1024 px (it wrapped to 2-3): the page links fold into a
    menu on a narrow window; every page stays one click away and the account stays in sight. The page is loaded
    once and made each size in turn; the last one follows a link of the menu."""
    context = chromium.new_context(viewport={"width": HEADER_SIZES[0][0], "height": HEADER_SIZES[0][1]})
    try:
        page = context.new_page()
        page.goto(app_url + "/device/door-1")
        header = page.get_by_test_id("header")
        expect(header.get_by_text("local engineer")).to_be_visible()
        names = ("Overview", "Plant view", "Backup", "Audit", "Record")
        for width, height in HEADER_SIZES:
            with at_size(page, width, height):
                try:  # the header fits its bus list once a second besides on a resize: one line once it has
                    page.wait_for_function(f"() => {{ const line = ({_HEADER_LINE_JS})();"
                                           " return line.height < 2 * line.title + 16; }", timeout=5_000)
                except PlaywrightTimeout:
                    pass  # said below with the heights
                line = page.evaluate(_HEADER_LINE_JS)
                assert line["height"] < 2 * line["title"] + 16, f"the header takes {line} at {width} px"
                inside_viewport(page, header.get_by_text("local engineer"))
                if width >= 1440:
                    for name in names:
                        link = header.locator("a", has_text=re.compile(f"^{name}$"))
                        expect(link).to_be_visible()
                        inside_viewport(page, link)
                    save_shot(page, tmp_path, f"header-{width}.png", full_page=False)
                    continue
                menu = page.get_by_test_id("nav-menu")
                expect(menu).to_be_visible()
                inside_viewport(page, menu)
                # opened again if a header drawn anew on a loaded machine closed it before it showed
                click_until(menu, page.locator(".q-menu a", has_text=re.compile("^Overview$")))
                for name in names:
                    expect(page.locator(".q-menu a", has_text=re.compile(f"^{name}$"))).to_be_visible()
                save_shot(page, tmp_path, f"header-menu-{width}.png", full_page=False)
                if (width, height) != HEADER_SIZES[-1]:
                    page.keyboard.press("Escape")  # closed again for the next size
                    expect(page.locator(".q-menu")).to_have_count(0)
                    save_shot(page, tmp_path, f"header-{width}.png", full_page=False)
                    continue
                page.locator(".q-menu a", has_text=re.compile("^Backup$")).click()
                page.wait_for_url(re.compile(r"/backup$"))
                save_shot(page, tmp_path, f"header-{width}.png", full_page=False)
    finally:
        context.close()


def _field(page: Page, testid: str):
    """The text input inside the NiceGUI input/number with ``data-testid``."""
    element = page.locator(f'[data-testid="{testid}"]')
    inner = element.locator("input")
    return inner if inner.count() else element


def test_broadcast_address_change_asks_with_the_number_of_locks(app_url: str, chromium: Browser, tmp_path: Path):
    """Section 4.3, address 255: the confirmation names how many locks of the line may take the address (asked at
    1440x900 and again with the page made 1024x768)."""
    context = chromium.new_context(viewport={"width": 1440, "height": 900})
    page = context.new_page()
    page.set_default_timeout(STEP_MS)
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    try:
        page.goto(app_url + "/device/door-1")
        expect(page.get_by_text("HD-Lock door-1", exact=True).first).to_be_visible()
        card = page.get_by_text("Set Modbus Address on every lock of line1 (broadcast 255)")
        card.scroll_into_view_if_needed()
        expect(page.locator('[data-testid="bc-known"]')).to_contain_text("2 locks known on line1 (2 in the plant")
        _field(page, "bc-address").fill("9")
        # BoltMovingIn must be set: no lock meets it, whatever the earlier tests did to the doors
        _field(page, "bc-p1").fill("0x0800")
        _field(page, "bc-p2").fill("0x0800")
        expect(page.locator('[data-testid="bc-known"]')).to_contain_text("none would take it")
        for width, height in ((1440, 900), (1024, 768)):
            with at_size(page, width, height):
                send = page.locator('[data-testid="bc-send"]')
                send.scroll_into_view_if_needed()
                inside_viewport(page, send)
                save_shot(page, tmp_path, f"device-door-1-{width}x{height}.png", full_page=False)
                send.click()
                dialog = page.locator(".q-dialog")
                expect(dialog).to_contain_text("Up to 2 locks on line1 may take address 9")
                expect(dialog).to_contain_text("door-1, door-2")
                cancel = dialog.get_by_role("button", name="Cancel")
                expect(cancel).to_be_visible()
                expect(dialog.get_by_role("button", name="Send to all (2)")).to_be_visible()
                page.wait_for_function("() => !document.querySelector('.q-dialog .q-transition--scale-enter-active, "
                                       ".q-dialog .q-transition--fade-enter-active')")  # the dialog has faded in
                inside_viewport(page, dialog.locator(".q-card").first)
                save_shot(page, tmp_path, f"broadcast-confirm-{width}x{height}.png", full_page=False)
                cancel.click()
                expect(dialog).to_have_count(0)
    finally:
        context.close()
    assert not errors, f"JavaScript errors on the page: {errors}"


def test_the_stop_bar_stays_pressable_above_a_confirmation(app_url: str, chromium: Browser, tmp_path: Path):
    """Issue 32.11: a confirmation's backdrop must not cover the STOP bar. The SCU's Go asks first; with
    its dialog open, STOP is still the element a click there lands on, and pressing it answers."""
    wait_devices_online(app_url, ("lift-1",), timeout=30)
    context = chromium.new_context(viewport={"width": 1440, "height": 900})
    page = context.new_page()
    page.set_default_timeout(STEP_MS)
    try:
        page.goto(app_url + "/device/lift-1")
        page.get_by_test_id("take-control").click()
        go = page.get_by_test_id("go")
        expect(go).to_be_enabled()
        go.click()
        dialog = page.locator(".q-dialog")
        expect(dialog).to_contain_text("Check that the area is clear")
        stop = page.get_by_test_id("big-stop")
        box = stop.bounding_box()
        on_top = page.evaluate("([x, y]) => !!document.elementFromPoint(x, y)?.closest('[data-testid=big-stop]')",
                               [box["x"] + box["width"] / 2, box["y"] + box["height"] / 2])
        save_shot(page, tmp_path, "stop-above-dialog.png", full_page=False)
        assert on_top, "the dialog's backdrop covers the STOP button"
        stop.click()
        expect(page.get_by_text("stop (RS)", exact=False).first).to_be_visible()
    finally:
        context.close()
