"""Words people see in chromium, at 1440x900 and 768x1024 on the demo plant (issue 42 items 8 and 13): every bus
in the header is named (on a tablet in small type under its icon), the overview table keeps each device's name
on one line, the CAN monitor's tables keep their Decoded column in sight, and the M3IO header names the DigOut period it is sent at."""

from __future__ import annotations

import pytest
from conftest import wait_devices_online
from webutil import demo_plant_text, free_port, running_app

SIZES = [(1440, 900), (768, 1024)]


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    with running_app(demo_plant_text(free_port()), tmp_path_factory.mktemp("labels")) as url:
        wait_devices_online(url, ["door-1", "heater-hm", "barrier-out-1"], timeout=40)
        yield url


@pytest.mark.timeout(120)
@pytest.mark.parametrize("width,height", SIZES, ids=[f"{w}x{h}" for w, h in SIZES])
def test_bus_names_table_names_and_the_digout_period(app, chromium, width: int, height: int):
    page = chromium.new_page(viewport={"width": width, "height": height})
    try:
        page.goto(app + "/")
        page.wait_for_selector("[data-glance='barrier-out-1']")
        bus_names = """() => [...document.querySelectorAll('.hdr-bus')].map(link => {
            const name = link.querySelector('.hdr-bus-name'); const r = name.getBoundingClientRect();
            return {bus: link.dataset.bus, text: name.innerText, visible: r.width > 0 && r.height > 0,
                    inside: r.right <= window.innerWidth && r.bottom <= link.closest('header, .q-header, .hdr').getBoundingClientRect().bottom};
        })"""
        try:  # the header fits itself once a second: while the page still lays out, the names may give way to icons
            page.wait_for_function(f"({bus_names})().every(n => n.visible && n.inside)", timeout=30000)
        except Exception:  # noqa: BLE001 - said below with the names and what else the header showed
            pass
        names = page.evaluate(bus_names)
        assert names and all(n["inside"] and n["text"] == n["bus"] for n in names), names
        if not all(n["visible"] for n in names):
            # the one thing the names give way to on a tablet: the event-loop figure, shown only while it is not
            # grey (the loop lagged in the last minute; on these loaded cores it may), never the page links or account
            lag = page.get_by_test_id("loop-lag")
            assert width < 900 and lag.is_visible() and "text-grey-5" not in (lag.get_attribute("class") or ""), (
                names, page.locator(".hdr").first.inner_text())
        lines = page.evaluate("""() => [...document.querySelectorAll('[data-glance] td:first-child a')].map(a => {
            const lh = parseFloat(getComputedStyle(a).lineHeight) || 20;
            return {name: a.innerText, oneLine: a.getBoundingClientRect().height < 1.6 * lh};
        })""")
        assert lines and all(line["oneLine"] for line in lines), lines
        page.goto(app + "/monitor/can1")  # the CAN monitor's tables fit: Decoded in sight without scrolling sideways
        page.wait_for_function("document.querySelectorAll('.can-table tbody tr').length >= 2")
        widths = """() => [...document.querySelectorAll('.can-table .q-table__middle')]
            .filter(m => m.offsetParent !== null).map(m => [m.scrollWidth, m.clientWidth])"""
        try:  # the rows drawn and laid out (bounded)
            page.wait_for_function(f"({widths})().every(([s, c]) => s <= c + 1)")
        except Exception:  # noqa: BLE001 - said below with the widths
            pass
        overflow = page.evaluate(widths)
        assert overflow and all(scroll <= client + 1 for scroll, client in overflow), overflow
        page.goto(app + "/device/heater-hm")
        page.get_by_text("DigOut every 500 ms").first.wait_for()
        assert page.get_by_text("DigOut every 100 ms").count() == 0
    finally:
        page.close()
