"""The overview and the plant view in chromium: equal tiles, names on one line, every plant tile on a
1024x768 screen, CAN counters, and a frame's value pushed to the plant view.

One app: the demo plant plus a ``udp_multicast`` CAN bus with two locks nobody simulates: one that
is never heard (offline, with a long name) and one whose status frames this test sends.
"""

from __future__ import annotations

import json
import re
import time
import urllib.request
from pathlib import Path

import pytest
from conftest import free_udp_port, shot, wait_devices_online
from plants import bus, hdlock_can
from webutil import at_size, demo_plant_text, free_port, running_app

GROUP = "239.74.163.12"
HEARD_ID, SILENT_ID = 660200, 660201
SIZES = [(1440, 900), (1024, 768), (768, 1024)]


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    port = free_udp_port()
    locks = hdlock_can("frame-lock", HEARD_ID, "udp-can"), hdlock_can("door-22", SILENT_ID, "udp-can")
    text = demo_plant_text(free_port()) + "\n" + bus("udp-can", "can", *locks, interface="udp_multicast", channel=GROUP,
                                                     port=port, bitrate=250000, poll_period=1.0, timeout=0.2)
    with running_app(text, tmp_path_factory.mktemp("overview-plant")) as url:
        # the M3IO modules answer only while served (an engineer controls them): not waited for
        wait_devices_online(url, ["door-1", "gate-1", "lift", "lift-1", "barrier-in"], timeout=40)
        yield url, port


def _tile_boxes(page, selector: str) -> list[dict]:
    """Name, width, whether its name and badge stay on one line, and its bottom, of every tile."""
    return page.evaluate(
        """(sel) => [...document.querySelectorAll(sel)].map(t => {
              const r = t.getBoundingClientRect();
              const one = el => { if (!el) return true; const lh = parseFloat(getComputedStyle(el).lineHeight) || 20;
                                  return el.getBoundingClientRect().height < 1.6 * lh; };
              return {name: t.getAttribute(sel.slice(1, -1)), left: r.left, width: r.width, bottom: r.bottom,
                      nameOneLine: one(t.querySelector('.name, .tile-name')), badgeOneLine: one(t.querySelector('.q-badge'))};
           })""",
        selector,
    )


def _grid_widths_equal(tiles: list[dict]) -> None:
    widths = {round(t["width"]) for t in tiles}
    assert max(widths) - min(widths) <= 1, f"tiles of different widths: {tiles}"


@pytest.mark.timeout(120)
def test_tiles_equal_named_on_one_line_and_plant_fits(app, chromium, tmp_path: Path):
    """Each page loaded once at the first size and made each of SIZES in turn, checked once laid out anew."""
    url, _port = app
    page = chromium.new_page(viewport={"width": SIZES[0][0], "height": SIZES[0][1]})
    try:
        page.goto(url + "/plant")
        offline = page.locator('[data-plant-tile="door-22"]')
        offline.locator('[data-plant-state="offline"]').wait_for(timeout=15_000)
        page.locator('[data-plant-tile="gate-1"] .bar-label').get_by_text("% out", exact=False).wait_for()
        with urllib.request.urlopen(url + "/api/devices", timeout=5) as response:
            names = {d["name"] for d in json.load(response)}
        for width, height in SIZES:
            with at_size(page, width, height):
                _plant_fits(page, tmp_path, names, width, height)

        page.goto(url + "/")
        page.locator('[data-device="gate-1"] [data-tile-counters]').get_by_text("frames heard", exact=False).wait_for()
        page.locator('[data-glance="door-22"]').get_by_text("offline").wait_for()
        for width, height in SIZES:
            with at_size(page, width, height):
                _overview_fits(page, tmp_path, names, width, height)
        # one wording for an Electrak network nobody controls, on both pages
        assert "idle (no controller)" in page.locator('[data-device="lift"]').inner_text()
        page.goto(url + "/plant")
        page.locator('[data-plant-tile="lift"]').get_by_text("idle (no controller)").wait_for()
    finally:
        page.close()


def _plant_fits(page, tmp_path: Path, names: set[str], width: int, height: int) -> None:
    from playwright.sync_api import expect

    shot(page, str(tmp_path / f"plant-{width}.png"))
    tiles = _tile_boxes(page, "[data-plant-tile]")
    assert {t["name"] for t in tiles} == names
    _grid_widths_equal(tiles)
    wrapped = [t["name"] for t in tiles if not (t["nameOneLine"] and t["badgeOneLine"])]
    assert wrapped == [], f"names or badges wrapped: {wrapped}"
    assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
    below = [t["name"] for t in tiles if t["bottom"] > height + 0.5]
    if (width, height) == (1024, 768):  # a landscape tablet sees every tile of the demo plant without scrolling
        assert set(below) <= {"frame-lock", "door-22"}, f"demo tiles below the screen at 1024x768: {below}"
    more = page.locator("[data-plant-more]")
    if below:  # the layout says how to page (the note follows the window's resize)
        more.get_by_text(f"{len(below)} more below: scroll down").wait_for()
    else:
        expect(more).to_be_hidden()
    _plant_view_reads_at_arms_length(page, width, height)


def _overview_fits(page, tmp_path: Path, names: set[str], width: int, height: int) -> None:
    shot(page, str(tmp_path / f"overview-{width}.png"), full_page=True)
    tiles = _tile_boxes(page, "[data-device]")
    _grid_widths_equal(tiles)
    assert [t["name"] for t in tiles if not t["nameOneLine"]] == []
    assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
    for name in ("gate-1", "lift"):  # CAN devices: no request counters
        counters = page.locator(f'[data-device="{name}"] [data-tile-counters]').inner_text()
        assert "frames heard" in counters and "req" not in counters, (name, counters)
    assert "req " in page.locator('[data-device="door-1"] [data-tile-counters]').inner_text()
    # issue 32.7: every device at a glance in one dense table in sight without scrolling, tiles are links
    # (open in a new tab), and the tiles use the width instead of one short row per bus
    rows = page.evaluate("""() => [...document.querySelectorAll('[data-glance]')].map(r => ({
                               name: r.getAttribute('data-glance'), bottom: r.getBoundingClientRect().bottom}))""")
    assert {r["name"] for r in rows} == names
    assert [r["name"] for r in rows if r["bottom"] > height + 0.5] == [], f"table rows below the screen: {rows}"
    for name in ("gate-1", "door-1"):
        assert page.locator(f'a[href="/device/{name}"] [data-device="{name}"]').count() == 1, f"{name}'s tile is no link"
    if width >= 1440:
        glance = page.get_by_test_id("glance").bounding_box()
        rights = [t["left"] + t["width"] for t in tiles]
        assert glance["x"] + glance["width"] <= min(t["left"] for t in tiles), "the table is not beside the tiles"
        assert max(rights) > 0.8 * width, f"tiles end at {max(rights):.0f} px of {width}"


def _plant_view_reads_at_arms_length(page, width: int, height: int) -> None:
    """Issue 32.10: offline stands out (colour and words, the tile not faded), no text is cut, the store's
    words instead of raw codes, each value once, large values on a tablet."""
    page.locator('[data-plant-tile="lift-1"]').get_by_text("supply:", exact=False).wait_for()
    offline = page.locator('[data-plant-tile="door-22"] [data-plant-state]')
    assert offline.get_attribute("data-plant-state") == "offline"
    assert "OFFLINE" in offline.inner_text() and "never heard" in offline.inner_text()
    look = page.evaluate("""() => {
        const style = sel => { const e = document.querySelector(sel); const c = getComputedStyle(e);
                               return {bg: c.backgroundColor, color: c.color, opacity: c.opacity, filter: c.filter}; };
        return {offline: style('[data-plant-tile="door-22"] [data-plant-state]'),
                card: style('[data-plant-tile="door-22"]'),
                live: style('[data-plant-tile="door-1"] [data-plant-state]')}; }""")
    assert look["card"]["opacity"] == "1" and look["card"]["filter"] == "none", f"the offline tile is faded: {look}"
    red, green, blue = (int(c) for c in re.findall(r"\d+", look["offline"]["bg"])[:3])
    assert red > 150 and green < 60 and blue < 60, f"offline is not red: {look}"
    assert look["offline"]["bg"] != look["live"]["bg"]
    # nothing cut: every text of every tile shows whole (no ellipsis, nothing wider than its box)
    cut = page.evaluate("""() => [...document.querySelectorAll('[data-plant-tile] *')]
        .filter(e => e.children.length === 0 && e.textContent.trim() && e.offsetParent !== null)
        .filter(e => e.scrollWidth > e.clientWidth + 1 || getComputedStyle(e).textOverflow === 'ellipsis')
        .map(e => e.textContent)""")
    assert cut == [], f"texts cut: {cut}"
    texts = page.evaluate("""(names) => Object.fromEntries(names.map(n => {  // the words shown, not the icons' names
        const tile = document.querySelector(`[data-plant-tile="${n}"]`).cloneNode(true);
        tile.querySelectorAll('.q-icon').forEach(i => i.remove());
        return [n, tile.textContent]; }))""", ["door-1", "gate-2", "lift-1", "barrier-in", "lift"])
    for name, text in texts.items():
        for raw in ("0x", "_", " Inc", "counts", "CRC"):
            assert raw not in text, f"{name} shows {raw!r}: {text!r}"
    assert "supply: mains connected, battery connected, charge controller on" in texts["lift-1"]
    assert texts["barrier-in"].count("%") == 1, f"the position shown twice: {texts['barrier-in']!r}"
    assert texts["lift-1"].count("A1") == 1, f"A1 shown twice: {texts['lift-1']!r}"
    assert "bolt 100 % out" in texts["gate-2"] or "bolt 0 % out" in texts["gate-2"], texts["gate-2"]
    if (width, height) in ((768, 1024), (1024, 768)):
        sizes = page.evaluate("""() => [...document.querySelectorAll('[data-plant-tile] .value-line')]
                                     .filter(e => e.textContent.trim()).map(e => parseFloat(getComputedStyle(e).fontSize))""")
        assert sizes and min(sizes) >= 20, f"values at {sizes} px on a tablet"


@pytest.mark.timeout(90)
def test_a_status_frame_reaches_the_plant_view_and_tiles_are_not_rebuilt(app, chromium):
    import can

    from devices.hdlock import codec

    url, port = app
    page = chromium.new_page(viewport={"width": 1024, "height": 768})
    tile = page.locator('[data-plant-tile="frame-lock"]')
    try:
        with can.Bus(interface="udp_multicast", channel=GROUP, port=port) as bus:
            def send(motor_pos: int) -> None:
                data = codec.encode_status(codec.StatusFrame(0x0117, motor_pos, 20, 4))
                bus.send(can.Message(arbitration_id=HEARD_ID, is_extended_id=True, data=data))

            page.goto(url + "/plant")
            send(40)
            tile.get_by_text("bolt 35 % out", exact=True).wait_for()
            # mark the tile's line elements: updated in place, they keep the mark
            page.evaluate("""() => document.querySelectorAll('[data-plant-tile="frame-lock"] .q-card__section, '
                              + '[data-plant-tile="frame-lock"] div').forEach(e => e.__kept = true)""")
            for value, percent in ((77, 67), (91, 79), (12, 10)):
                sent = time.monotonic()
                send(value)
                tile.get_by_text(f"bolt {percent} % out", exact=True).wait_for()
                assert time.monotonic() - sent < 1.0, f"bolt {value} shown after {time.monotonic() - sent:.2f} s"
            rebuilt = page.evaluate("""() => [...document.querySelectorAll('[data-plant-tile="frame-lock"] div')]
                                          .filter(e => !e.__kept).length""")
            assert rebuilt == 0, f"{rebuilt} elements of the tile were rebuilt"
            # a fault stands out in colour and words (issue 32.10): the hall sensors overdriven
            bus.send(can.Message(arbitration_id=HEARD_ID, is_extended_id=True,
                                 data=codec.encode_status(codec.StatusFrame(0x0108, 115, 20, 4))))
            tile.get_by_text("hall sensors overdriven (magnet)", exact=False).wait_for()
            band = tile.locator("[data-plant-state]")
            assert band.get_attribute("data-plant-state") == "fault" and "FAULT" in band.inner_text()
            assert page.evaluate("""() => getComputedStyle(document.querySelector(
                '[data-plant-tile="frame-lock"] [data-plant-state]')).backgroundColor""") == "rgb(176, 0, 18)"
            send(12)
            tile.locator('[data-plant-state="good"]').wait_for()
    finally:
        page.close()
