"""Chromium on the lift (Electrak), SCU and MO 64 pages at 1440x900 and 1024x768: an out-of-range entry is
kept and marked with its range; no STOP covers another button; each actuator's numbers are shown; a silent
network greys its values and disables its start buttons with the reason while STOP stays enabled."""

from __future__ import annotations

import pytest
from conftest import CHROMIUM, inside_viewport, shot
from plants import motion_plant_text
from webutil import running_app

pytestmark = [pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed"), pytest.mark.timeout(150)]

SIZES = ((1440, 900), (1024, 768))


def plant_text() -> str:
    return motion_plant_text("motion-browser", scu={"bus_name": "rs232-1", "timeout": None, "poll_period": None},
                             mo64={"bus_name": "gate-tcp", "timeout": None, "poll_period": 0.3, "travel_s": None})


# every visible, enabled button scrolled to the middle of the screen (or as far as the page goes) must be the
# element found at its own centre: nothing (a floating STOP, a bar) lies on top of it
COVERED_JS = """() => {
  const out = [];
  for (const b of document.querySelectorAll('button')) {
    const r0 = b.getBoundingClientRect();
    if (!r0.width || !r0.height || b.disabled || b.closest('.q-dialog, .q-menu, .q-tooltip, .modebar')) continue;
    b.scrollIntoView({block: 'center', inline: 'center'});
    const r = b.getBoundingClientRect();
    const x = r.left + r.width / 2, y = r.top + r.height / 2;
    if (x < 0 || y < 0 || x > innerWidth || y > innerHeight) continue;
    const hit = document.elementFromPoint(x, y);
    if (!hit || !b.contains(hit)) out.push(`${b.innerText.trim() || b.getAttribute('aria-label')} under ${hit && (hit.closest('button') || hit).innerText.trim().slice(0, 30)}`);
  }
  window.scrollTo(0, 0);
  return out;
}"""


def open_page(page, url: str) -> None:
    """Go to ``url`` and wait until the page's websocket is connected (the first HTML is shown before it)."""
    page.goto(url)
    page.wait_for_function("() => window.socket && window.socket.connected && window.did_handshake", timeout=15_000)


def take_control(page) -> None:
    """Take control, pressing again if the first press went out while the page's websocket reconnected
    (taking control is idempotent)."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    for _ in range(3):
        page.get_by_test_id("take-control").click()
        try:
            page.get_by_text("you hold control").wait_for()
            return
        except PlaywrightTimeout:
            continue
    raise AssertionError("control not taken after three presses")


def overlaps(a: dict, b: dict) -> bool:
    return a["x"] < b["x"] + b["width"] and b["x"] < a["x"] + a["width"] and a["y"] < b["y"] + b["height"] and b["y"] < a["y"] + a["height"]


def check_layout(page, tmp_path, name: str) -> None:
    """At both sizes: nothing sticks out sideways, no button is covered, the big STOP (if any) is in sight and
    overlaps no other button; a screenshot of each."""
    for width, height in SIZES:
        page.set_viewport_size({"width": width, "height": height})
        page.evaluate("window.scrollTo(0, 0)")
        # nothing sticks out sideways (once the charts have followed the new width)
        page.wait_for_function(f"() => document.documentElement.scrollWidth <= {width}")
        assert page.evaluate(COVERED_JS) == [], f"{name} at {width}x{height}"
        stop = page.get_by_test_id("big-stop")
        if stop.count():
            for where in ("0", "document.body.scrollHeight"):
                page.evaluate(f"window.scrollTo(0, {where})")
                inside_viewport(page, stop)
                box = stop.bounding_box()
                # (a chart's mode bar shows only while the pointer is on the chart: not a button a person sees)
                others = [b for b in page.get_by_role("button").all() if b.is_visible()
                          and b.get_attribute("data-testid") != "big-stop" and not b.evaluate("e => !!e.closest('.modebar')")]
                hits = [b.inner_text() for b in others if (ob := b.bounding_box()) and overlaps(box, ob)]
                assert hits == [], f"{name}: the big STOP overlaps {hits} at {width}x{height}"
        page.evaluate("window.scrollTo(0, 0)")
        shot(page, str(tmp_path / f"{name}-{width}x{height}.png"), full_page=True)


@pytest.fixture(scope="module")
def app_url(tmp_path_factory):
    with running_app(plant_text(), tmp_path_factory.mktemp("motion")) as url:
        yield url


def test_lift_entry_numbers_stop_layout_and_silence(app_url, chromium, tmp_path):
    from playwright.sync_api import expect

    page = chromium.new_page(viewport={"width": 1440, "height": 900})
    try:
        open_page(page, f"{app_url}/device/lift")
        page.get_by_text("actuators heard per 100 ms: 2 of 2 configured").wait_for(timeout=15_000)
        for i in (1, 2):  # each actuator's position, current and speed as numbers
            for what, unit in (("position", "mm"), ("current", "A"), ("speed", "mm/s")):
                expect(page.get_by_test_id(f"actuator-{i}-{what}")).to_contain_text(f" {unit}")
        take_control(page)
        sent = page.get_by_text("0x006:")
        before = sent.inner_text()
        speed = page.get_by_label("Speed [mm/s]")
        speed.fill("50")
        page.get_by_test_id("apply").click()
        expect(page.get_by_role("alert").filter(has_text="out of range: allowed 6 .. 32 mm/s")).to_be_visible()
        speed.blur()
        assert float(speed.input_value()) == 50  # kept as typed, not clamped to 32
        assert sent.inner_text() == before  # nothing sent
        assert page.locator(".q-notification").count() == 0  # no toast over the chart
        check_layout(page, tmp_path, "lift")
        # the network falls silent: values greyed, start buttons disabled with the reason, STOP enabled
        page.get_by_role("button", name="Release").click()
        page.get_by_text("nobody controls the network").wait_for()
        for i in (1, 2):
            page.get_by_role("switch", name=f"actuator {i} connected").click()
        take = page.get_by_test_id("take-control")
        expect(take).to_be_disabled(timeout=15_000)
        assert "does not answer" in take.get_attribute("data-disabled-reason")
        expect(page.get_by_test_id("go")).to_be_disabled()
        expect(page.get_by_test_id("big-stop")).to_be_enabled()
        expect(page.get_by_test_id("stop")).to_be_enabled()
        assert page.get_by_test_id("network-position").get_attribute("data-quality") == "offline"
        expect(page.get_by_test_id("events").locator("tbody tr").first).to_contain_text("error")
        shot(page, str(tmp_path / "lift-offline.png"), full_page=True)
        for i in (1, 2):
            page.get_by_role("switch", name=f"actuator {i} connected").click()
        expect(take).to_be_enabled(timeout=15_000)
    finally:
        page.close()


def test_scu_and_mo64_entries_and_layout(app_url, chromium, tmp_path):
    from playwright.sync_api import expect

    page = chromium.new_page(viewport={"width": 1440, "height": 900})
    try:
        open_page(page, f"{app_url}/device/scu")
        expect(page.get_by_test_id("session")).to_contain_text("open", timeout=15_000)
        take_control(page)
        speed = page.get_by_test_id("remote-speed")
        speed.fill("5000")
        page.get_by_test_id("set-speed").click()
        expect(page.get_by_role("alert").filter(has_text="out of range: allowed 0 .. 100 ")).to_be_visible()
        assert speed.input_value() == "5000"
        check_layout(page, tmp_path, "scu")
        page.get_by_role("button", name="Release control").click()

        open_page(page, f"{app_url}/device/gate")
        expect(page.get_by_test_id("gate-state")).to_have_text("gate state: closed", timeout=15_000)
        t_open = page.get_by_test_id("entry-t_open")
        t_open.fill("700")
        page.get_by_test_id("write-t_open").click()
        expect(page.get_by_role("alert").filter(has_text="out of range: allowed 0 .. 655 s")).to_be_visible()
        assert t_open.input_value() == "700"
        assert page.locator(".q-dialog").count() == 0  # no EEPROM question: nothing sent
        check_layout(page, tmp_path, "mo64")
    finally:
        page.close()
