"""The overview and the plant view in chromium: equal tiles, names on one line, every plant tile on a
1024x768 screen, M3IO temperatures, CAN counters, and a frame's value pushed to the plant view.

One app: the demo plant plus a ``udp_multicast`` CAN bus with two locks nobody simulates: one that
is never heard (offline, with a long name) and one whose status frames this test sends.
"""

from __future__ import annotations

import json
import time
import urllib.request
from pathlib import Path

import pytest
from conftest import free_udp_port, wait_devices_online
from webutil import demo_plant_text, free_port, running_app

GROUP = "239.74.163.12"
HEARD_ID, SILENT_ID = 660200, 660201
SIZES = [(1440, 900), (1024, 768), (768, 1024)]


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    port = free_udp_port()
    text = demo_plant_text(free_port()) + f"""
[[bus]]
name = "udp-can"
type = "can"
interface = "udp_multicast"
channel = "{GROUP}"
port = {port}
bitrate = 250000
poll_period = 1.0
timeout = 0.2

[[device]]
name = "frame-lock"
type = "hdlock"
bus = "udp-can"
device_id = {HEARD_ID}

[[device]]
name = "door-22"
type = "hdlock"
bus = "udp-can"
device_id = {SILENT_ID}
"""
    with running_app(text, tmp_path_factory.mktemp("overview-plant")) as url:
        wait_devices_online(url, ["door-1", "gate-1", "lift", "heater-hm", "heater-hmr"], timeout=40)
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
@pytest.mark.parametrize("width,height", SIZES, ids=[f"{w}x{h}" for w, h in SIZES])
def test_tiles_equal_named_on_one_line_and_plant_fits(app, chromium, tmp_path: Path, width: int, height: int):
    url, _port = app
    page = chromium.new_page(viewport={"width": width, "height": height})
    try:
        page.goto(url + "/plant")
        offline = page.locator('[data-plant-tile="door-22"]')
        offline.get_by_text("offline", exact=True).wait_for(timeout=15_000)
        page.locator('[data-plant-tile="heater-hm"]').get_by_text("T1", exact=False).wait_for(timeout=10_000)
        page.screenshot(path=str(tmp_path / f"plant-{width}.png"))
        tiles = _tile_boxes(page, "[data-plant-tile]")
        with urllib.request.urlopen(url + "/api/devices", timeout=5) as response:
            assert len(tiles) == len(json.load(response))
        _grid_widths_equal(tiles)
        wrapped = [t["name"] for t in tiles if not (t["nameOneLine"] and t["badgeOneLine"])]
        assert wrapped == [], f"names or badges wrapped: {wrapped}"
        assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
        below = [t["name"] for t in tiles if t["bottom"] > height + 0.5]
        if (width, height) == (1024, 768):  # a landscape tablet sees every tile of the demo plant without scrolling
            assert set(below) <= {"frame-lock", "door-22"}, f"demo tiles below the screen at 1024x768: {below}"
        more = page.locator("[data-plant-more]")
        if below:  # the layout says how to page
            more.get_by_text(f"{len(below)} more below: scroll down").wait_for(timeout=5_000)
        else:
            assert not more.is_visible()
        assert "T1" in page.locator('[data-plant-tile="heater-hmr"]').inner_text()

        page.goto(url + "/")
        page.locator('[data-device="gate-1"] [data-tile-counters]').get_by_text("frames heard", exact=False).wait_for(timeout=10_000)
        page.screenshot(path=str(tmp_path / f"overview-{width}.png"), full_page=True)
        tiles = _tile_boxes(page, "[data-device]")
        _grid_widths_equal(tiles)
        assert [t["name"] for t in tiles if not t["nameOneLine"]] == []
        assert page.evaluate("document.documentElement.scrollWidth <= window.innerWidth")
        for name in ("gate-1", "lift", "heater-hm"):  # CAN devices: no request counters
            counters = page.locator(f'[data-device="{name}"] [data-tile-counters]').inner_text()
            assert "frames heard" in counters and "req" not in counters, (name, counters)
        assert "req " in page.locator('[data-device="door-1"] [data-tile-counters]').inner_text()
        assert "T1" in page.locator('[data-device="heater-hm"]').inner_text()
        # issue 32.7: every device at a glance in one dense table in sight without scrolling, tiles are links
        # (open in a new tab), and the tiles use the width instead of one short row per bus
        with urllib.request.urlopen(url + "/api/devices", timeout=5) as response:
            names = {d["name"] for d in json.load(response)}
        page.locator('[data-glance="door-22"]').get_by_text("offline").wait_for(timeout=10_000)
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
        # one wording for an Electrak network nobody controls, on both pages
        assert "idle (no controller)" in page.locator('[data-device="lift"]').inner_text()
        page.goto(url + "/plant")
        page.locator('[data-plant-tile="lift"]').get_by_text("idle (no controller)").wait_for(timeout=5_000)
    finally:
        page.close()


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
            tile.get_by_text("bolt 40 Inc", exact=True).wait_for(timeout=10_000)
            # mark the tile's line elements: updated in place, they keep the mark
            page.evaluate("""() => document.querySelectorAll('[data-plant-tile="frame-lock"] .q-card__section, '
                              + '[data-plant-tile="frame-lock"] div').forEach(e => e.__kept = true)""")
            for value in (77, 91, 12):
                sent = time.monotonic()
                send(value)
                tile.get_by_text(f"bolt {value} Inc", exact=True).wait_for(timeout=5_000)
                assert time.monotonic() - sent < 1.0, f"bolt {value} Inc shown after {time.monotonic() - sent:.2f} s"
            rebuilt = page.evaluate("""() => [...document.querySelectorAll('[data-plant-tile="frame-lock"] div')]
                                          .filter(e => !e.__kept).length""")
            assert rebuilt == 0, f"{rebuilt} elements of the tile were rebuilt"
    finally:
        page.close()
