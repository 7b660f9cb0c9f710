"""The plant view of the demo plant in chromium with a German browser (issue 47): every tile in German with no text
of the English catalog, decimal commas, Quasar's language, and the tiles fitting a tablet; an English browser
gets English. The header of every page follows the browser too."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from conftest import shot, wait_devices_online
from test_i18n_pages import english_patterns
from webutil import at_size, demo_plant_text, free_port, running_app, settled

SIZES = [(1440, 900), (768, 1024)]
SHOWN = ["door-1", "gate-1", "lift", "lift-1", "barrier-in", "barrier-out-1"]


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    with running_app(demo_plant_text(free_port()), tmp_path_factory.mktemp("i18n")) as url:
        # the M3IO modules answer only while served (an engineer controls them): not waited for
        wait_devices_online(url, SHOWN, timeout=40)
        yield url


def english_in(texts: list[str]) -> list[tuple[str, str]]:
    patterns = english_patterns()
    lines = [line.strip() for text in texts for line in text.split("\n") if line.strip()]
    return [(line, message) for line in lines for message, pattern in patterns if pattern.fullmatch(line)]


def tile_texts(page) -> list[str]:
    return page.eval_on_selector_all("[data-plant-tile]", "tiles => tiles.map(t => t.innerText)")


@pytest.mark.browser
@pytest.mark.timeout(120)
def test_the_plant_view_in_german(app, chromium, tmp_path: Path):
    """Loaded once at 1440x900 and made 768x1024: at each size no English, and the tiles fit."""
    context = chromium.new_context(viewport={"width": SIZES[0][0], "height": SIZES[0][1]}, locale="de-DE")
    try:
        page = context.new_page()
        page.goto(f"{app}/plant")
        for name in SHOWN:  # every device answers: its tile says so in German (live, or a fault the device reports:
            # the SCU drops its remote mode when a keep-alive comes late on a loaded machine, and says so)
            page.locator(f'[data-plant-tile="{name}"]').locator('[data-plant-state="good"], [data-plant-state="fault"]').get_by_text(
                re.compile(r"^(aktuell|STÖRUNG)$")).wait_for(timeout=15_000)
        page.get_by_text("Torzustand: Schranke ist", exact=False).first.wait_for()
        page.get_by_text("Remote-Betrieb:", exact=False).first.wait_for()
        assert page.evaluate("document.documentElement.lang") == "de-DE"  # Quasar's own components in German
        for width, height in SIZES:
            with at_size(page, width, height):
                texts = tile_texts(page) + [page.inner_text("header")]
                assert english_in(texts) == [], english_in(texts)
                every = "\n".join(texts)
                assert "Anlage demo" in every
                assert re.search(r"\b\d+,\d von 300 mm", every), every  # the Electrak's position with a decimal comma
                assert not any(line.strip().endswith("ago") for line in every.split("\n"))
                # the tiles fit the width of the screen (German words are longer): nothing scrolls sideways
                fits(page, f"the plant view at {width}x{height}")
                overflowing = page.eval_on_selector_all("[data-plant-tile]", """tiles => tiles.filter(t => [...t.querySelectorAll(
                    '.bar-label, .value-line, .alarm-text')].some(e => e.getBoundingClientRect().right > t.getBoundingClientRect().right + 1))
                    .map(t => t.getAttribute('data-plant-tile'))""")
                assert overflowing == [], f"texts run out of their tiles: {overflowing}"
                shot(page, str(tmp_path / f"plant-de-{width}x{height}.png"), full_page=True)
    finally:
        context.close()


@pytest.mark.browser
@pytest.mark.timeout(120)
def test_an_english_browser_gets_english_and_the_header_follows(app, chromium):
    context = chromium.new_context(viewport={"width": 1440, "height": 900}, locale="en-US")
    try:
        page = context.new_page()
        page.goto(f"{app}/plant")
        page.locator('[data-plant-tile="door-1"]').get_by_text("live", exact=True).wait_for(timeout=15_000)
        assert english_in(tile_texts(page)), "an English page is seen as English"
        assert page.evaluate("document.documentElement.lang") == "en-GB"
    finally:
        context.close()
    context = chromium.new_context(viewport={"width": 1440, "height": 900}, locale="de-DE")
    try:
        page = context.new_page()
        page.goto(f"{app}/")
        header = page.locator("[data-testid=header]")
        header.get_by_text("Anlagenansicht").wait_for(timeout=15_000)
        assert "Übersicht" in header.inner_text() and "Anlage: demo" in header.inner_text()
        # the switch: English for this browser from now on, on every page
        page.locator("[data-testid=language] [data-lang=en]").click()
        page.locator("[data-testid=header]").get_by_text("Plant view").wait_for(timeout=15_000)
        page.goto(f"{app}/plant")
        page.get_by_text("Plant demo").wait_for(timeout=15_000)
        for selector in ("button", "input", "select", ".q-toggle"):  # the switch is two links: nothing to press
            assert page.locator(selector).count() == 0, selector
    finally:
        context.close()


@pytest.mark.browser
@pytest.mark.timeout(120)
def test_a_number_entry_in_german_takes_the_decimal_comma(app, chromium):
    """The browser's number entry drops a comma it does not expect ("12,5" became 125): in German the comma typed
    or pasted is the decimal point."""
    context = chromium.new_context(viewport={"width": 1440, "height": 900}, locale="de-DE")
    try:
        page = context.new_page()
        page.goto(f"{app}/device/lift")
        field = page.locator("input[type=number]").first
        field.wait_for(timeout=15_000)
        field.fill("")
        field.type("12,5")
        assert field.input_value() == "12.5"
        assert page.evaluate("(e) => e.valueAsNumber", field.element_handle()) == 12.5
    finally:
        context.close()


def fits(page, what: str) -> None:
    """Nothing of ``page`` scrolls sideways, once its components have followed a new size (within 5 s)."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    try:
        page.wait_for_function("() => document.documentElement.scrollWidth <= window.innerWidth + 1", timeout=5_000)
    except PlaywrightTimeout:
        raise AssertionError(f"{what} scrolls sideways") from None


BUS_TOOLS = [("/monitor/line1", "Nur Fehler"), ("/monitor/rs232-1", "Nur Fehler"), ("/monitor/can1", "Überschreibansicht"),
             ("/monitor/line1/poll", "Fenster 1"), ("/monitor/can1/transmit", "Frame als Bytes"),
             ("/monitor/can1/replay", "Wiedergabe starten")]
# the page's own texts: what the lines and buses carried (transactions and frames, decoded in the devices' words) and
# the icons' names left out
OWN_TEXTS_JS = """() => { const c = document.querySelector('.nicegui-content').cloneNode(true);
  c.querySelectorAll('[data-monitor=transactions] tbody, [data-monitor=frames] tbody, [data-monitor=overwrite] tbody, '
   + '.q-icon').forEach(e => e.remove());  /* an icon's text is its name (close, send) */
  document.body.appendChild(c); const text = c.innerText; c.remove(); return text; }"""


@pytest.mark.browser
@pytest.mark.timeout(180)
def test_the_bus_tools_in_german(app, chromium):
    """The bus monitors (a Modbus line, an SCU's RS232 line, a CAN bus), the Modbus poll, the transmit list and the
    replay page with a German browser: no text of the English catalog, nothing scrolls sideways at either size (each
    page loaded once, at 1440x900, then made 768x1024)."""
    context = chromium.new_context(viewport={"width": SIZES[0][0], "height": SIZES[0][1]}, locale="de-DE")
    try:
        page = context.new_page()
        for path, text in BUS_TOOLS:
            page.set_viewport_size({"width": SIZES[0][0], "height": SIZES[0][1]})
            page.goto(f"{app}{path}")
            page.get_by_text(text).first.wait_for(timeout=15_000)
            settled(page)  # the first refresh of the lists and counters
            assert english_in([page.evaluate(OWN_TEXTS_JS)]) == [], path
            for width, height in SIZES:
                page.set_viewport_size({"width": width, "height": height})
                fits(page, f"{path} at {width}x{height}")
    finally:
        context.close()
