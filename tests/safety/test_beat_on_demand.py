"""Pages beat only while needed (dead-man rule, app/worker/deadman.py and pages/frame.py BEAT_JS).

A real browser on an M3IO module's page; the beats are counted in the websocket frames the page
sends (``BEAT_EVENT``). A page that holds nothing sends none; the page whose session switches a
mains output on beats and keeps it on for as long as it beats, stops beating a few seconds after the
output is off again, and a page that stops beating while it holds the output has it switched off
within the dead-man bound. A page whose connection drops while it holds idle control gets it back.
"""

from __future__ import annotations

import re
import time

import pytest
from conftest import CHROMIUM
from plants import can_bus, device, plant_text
from webutil import running_app

from app.browser import BEAT_EVENT
from app.worker import BEAT_RELEASE_S, BEAT_WINDOW_S, DEADMAN_BOUND_S

pytestmark = [pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed"), pytest.mark.timeout(120)]

PLANT = plant_text(can_bus(device("heater-hm", "m3io", "can3", variant="HM", sw1=0x1A),
                           name="can3", channel_name="browser-beat-on-demand", bitrate=500000), name="beat-test")
QUIET_S = 1.0  # no beat for this long: the page does not beat


@pytest.fixture(scope="module")
def app_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("beats")
    with running_app(PLANT, folder) as url:
        yield url, folder / "app.log"


class Beats:
    """The times (here) of the beats a page sends on its websocket."""

    def __init__(self, page):
        self.page = page
        self.times: list[float] = []
        page.on("websocket", lambda ws: ws.on("framesent", self._frame))

    def _frame(self, payload) -> None:
        if isinstance(payload, str) and f'"{BEAT_EVENT}"' in payload:
            self.times.append(time.monotonic())

    def count(self, since: float) -> int:
        return sum(1 for t in self.times if t >= since)

    def over(self, seconds: float) -> int:
        """Beats sent within the next ``seconds``."""
        start = time.monotonic()
        self.page.wait_for_timeout(seconds * 1000)  # the beats are counted over this stretch of real time
        return self.count(start)

    def wait_silent(self, timeout: float) -> float:
        """Wait until the page sent no beat for QUIET_S; returns when its last beat was sent."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            last = self.times[-1] if self.times else 0.0
            if time.monotonic() - last >= QUIET_S:
                return last
            self.page.wait_for_timeout(100)
        raise AssertionError(f"the page still beats {timeout} s later")

    def wait_beating(self, since: float, timeout: float = 5.0) -> None:
        end = time.monotonic() + timeout
        while self.count(since) < 3:
            assert time.monotonic() < end, "the page does not beat"
            self.page.wait_for_timeout(50)

    def wait_until(self, moment: float) -> None:
        self.page.wait_for_timeout(max(0.0, moment - time.monotonic()) * 1000)  # a stated window (BEAT_WINDOW_S) has to pass


def open_page(context, url: str):
    page = context.new_page()
    beats = Beats(page)
    page.goto(f"{url}/device/heater-hm")
    page.get_by_test_id("take-control").wait_for(timeout=10_000)
    page.wait_for_function("() => window.did_handshake && window.socket.connected", timeout=20_000)  # connected
    return page, beats


def take_control(page) -> None:
    page.get_by_test_id("take-control").click()
    page.get_by_test_id("controller").get_by_text("you control the module").wait_for(timeout=10_000)


def ssr1_on(page) -> bool:
    return page.locator('[data-channel="SSR1"] .q-toggle__inner--truthy').count() > 0


def switch_on_ssr1(page) -> None:
    row = page.locator('[data-channel="SSR1"]')
    row.get_by_text("load: present").first.wait_for(timeout=5_000)
    row.locator(".q-toggle").click()
    page.get_by_role("button", name="Switch on").click()
    page.locator('[data-channel="SSR1"] .q-toggle__inner--truthy').wait_for(timeout=5_000)


def test_a_page_beats_only_while_its_session_holds_something(app_run, chromium):
    url, log_file = app_run
    context = chromium.new_context(viewport={"width": 1440, "height": 900})
    try:
        page, beats = open_page(context, url)
        assert beats.over(2.0) == 0, "a page that holds nothing sends beats"

        take_control(page)
        switch_on_ssr1(page)
        touched = time.monotonic()  # the last interaction: it beats BEAT_WINDOW_S from here anyway
        beats.wait_until(touched + BEAT_WINDOW_S + 0.5)
        assert beats.over(1.0) >= 5, "the page holding a mains output stopped beating"
        assert ssr1_on(page), "the output went off while its page beat"
        assert "not confirmed it is alive" not in log_file.read_text()

        page.get_by_test_id("all-off").click()  # holds nothing from now on (control only)
        page.wait_for_function("() => !document.querySelector('[data-channel=\"SSR1\"] .q-toggle__inner--truthy')",
                               timeout=5_000)
        off = time.monotonic()
        last = beats.wait_silent(timeout=BEAT_WINDOW_S + BEAT_RELEASE_S + 3)
        assert last - off < BEAT_WINDOW_S + BEAT_RELEASE_S + 1

        # it holds the output again, then its page freezes (its tick worker ends, the socket stays open)
        switch_on_ssr1(page)
        beats.wait_beating(time.monotonic())
        assert ssr1_on(page)
        page.evaluate("window.commissionBeat.terminate()")
        page.wait_for_function("() => !document.querySelector('[data-channel=\"SSR1\"] .q-toggle__inner--truthy')",
                               timeout=5_000)
        silent = [int(m) for m in re.findall(r"not confirmed it is alive for (\d+) ms", log_file.read_text())]
        assert silent and max(silent) < DEADMAN_BOUND_S * 1000, silent
    finally:
        context.close()


def test_a_page_that_reconnects_keeps_its_idle_control(app_run, chromium):
    url, _log = app_run
    mine, other = (chromium.new_context(viewport={"width": 1440, "height": 900}) for _ in range(2))
    try:
        page, beats = open_page(mine, url)
        take_control(page)
        beats.wait_silent(timeout=BEAT_WINDOW_S + 3)  # idle control holds nothing: no beats
        before = time.monotonic()
        page.evaluate("window.socket.io.engine.close()")  # the connection drops; socket.io reconnects
        beats.wait_beating(before)  # the server asks the page back to beat: its first beat gives control back
        intruder, _ = open_page(other, url)
        intruder.get_by_test_id("take-control").click()
        intruder.get_by_text("controls the module since").first.wait_for(timeout=10_000)  # refused: still held
        assert intruder.get_by_test_id("controller").get_by_text("you control the module").count() == 0
        page.get_by_test_id("controller").get_by_text("you control the module").wait_for(timeout=2_000)
        beats.wait_silent(timeout=BEAT_RELEASE_S + 3)  # and stops again: it holds nothing
    finally:
        mine.close()
        other.close()
