"""The dead-man bound with a real, frozen browser.

Chromium drives an Electrak jog (hold-to-run, the mouse button stays down) and switches an
M3IO mains output on; then the whole browser is frozen with SIGSTOP (as a hung tab, a closed
laptop lid or a lost network leave it: no close, no disconnect). The test listens on the same
CAN buses from its own process (python-can udp_multicast) and measures how long after the
freeze the stopping telegrams go out: the control telegram with enable cleared, the DigOut
with the output off. The stated bound is app.worker.DEADMAN_BOUND_S (0.5 s) from the last
sign of life; the freeze comes after that sign, so freeze -> stop must be below it too.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import time
import urllib.request
from pathlib import Path

import can
import pytest
from conftest import CHROMIUM, free_port, free_udp_port, inside_viewport, shot
from can_listener import FrameListener
from plants import ELECTRAK_ACTUATORS, can_bus, electrak_bus, m3io_can, plant_text
from webutil import running_app

from app.worker import DEADMAN_BOUND_S, DEADMAN_TIMEOUT_S

pytestmark = [pytest.mark.skipif(not CHROMIUM.exists(), reason="Debian's chromium is not installed"), pytest.mark.timeout(120)]

GROUP = "239.74.163.9"
CONTROL_ID, DIGOUT_ID = 0x006, 0x422  # Electrak control; M3IO DigOut of SW1 0x1A (0x3A0 + 5 * 0x1A)


def deadman_plant(port_lift: int, port_heater: int) -> str:
    """An Electrak network of one actuator and an M3IO HM heater, each on a udp_multicast bus of its own (ports)."""
    multicast = {"interface": "udp_multicast", "channel_name": GROUP, "bitrate": 500000}
    return plant_text(electrak_bus(actuators=ELECTRAK_ACTUATORS[:1], port=port_lift, **multicast),
                      can_bus(m3io_can("heater-hm"), name="can3", port=port_heater, **multicast), name="deadman")


class Listener(FrameListener):
    """Every frame of one udp_multicast bus with the time it arrived here."""

    def __init__(self, port: int):
        super().__init__(can.Bus(interface="udp_multicast", channel=GROUP, port=port, receive_own_messages=False))


def start_chromium(folder: Path) -> tuple[subprocess.Popen, int]:
    """Chromium as a process of its own (not conftest's ``chromium`` fixture): the test freezes
    that very process with SIGSTOP, which a browser launched inside playwright's driver does not allow.
    With the switches playwright's own launch gives every chromium: a page in a background tab keeps its
    timers (the heater's page is behind the lift's here), as in the other browser tests."""
    port = free_port()
    proc = subprocess.Popen(
        [str(CHROMIUM), "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-background-timer-throttling", "--disable-renderer-backgrounding",
         "--disable-backgrounding-occluded-windows",
         f"--remote-debugging-port={port}", f"--user-data-dir={folder / 'profile'}", "--window-size=1440,900", "about:blank"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )
    end = time.monotonic() + 20
    while time.monotonic() < end:
        try:
            urllib.request.urlopen(f"http://127.0.0.1:{port}/json/version", timeout=1).read()
            return proc, port
        except OSError:
            time.sleep(0.1)
    proc.kill()
    raise TimeoutError("chromium did not open its debugging port")


def test_frozen_browser_stops_motion_and_mains_outputs_within_the_bound(tmp_path):
    from playwright.sync_api import sync_playwright

    port_lift, port_heater = free_udp_port(), free_udp_port()
    lift_bus, heater_bus = Listener(port_lift), Listener(port_heater)
    chromium, debug_port = start_chromium(tmp_path)
    frozen = False
    try:
        with running_app(deadman_plant(port_lift, port_heater), tmp_path) as url, sync_playwright() as p:
            browser = p.chromium.connect_over_cdp(f"http://127.0.0.1:{debug_port}")
            context = browser.contexts[0]

            heater = context.new_page()
            heater.goto(f"{url}/device/heater-hm")
            heater.get_by_text("belong to the page").first.wait_for(timeout=10_000)  # the stop rule is stated
            heater.get_by_test_id("take-control").click()  # this tool serves the module's watchdog only then
            heater.get_by_test_id("controller").get_by_text("you control the module").wait_for(timeout=10_000)
            row = heater.locator('[data-channel="SSR1"]')
            row.get_by_text("load: present").first.wait_for(timeout=10_000)
            row.locator(".q-toggle").click()
            heater.get_by_role("button", name="Switch on").click()
            switched_on = heater_bus.first(DIGOUT_ID, lambda d: d[0] & 0x02, timeout=5)
            assert switched_on, "SSR1 was not switched on"

            lift = context.new_page()
            lift.goto(f"{url}/device/lift")
            lift.get_by_text(re.compile(r"[Mm]otion stops")).first.wait_for(timeout=10_000)  # the stop rule is stated
            lift.get_by_test_id("take-control").click()
            lift.get_by_text("you hold control").wait_for(timeout=10_000)
            lift.get_by_test_id("jog-out").click()  # the first press asks that the area is clear and arms the jog
            lift.locator(".q-dialog").get_by_role("button", name="The area is clear").click()
            lift.get_by_test_id("jog-armed").get_by_text("jog armed").wait_for(timeout=10_000)
            lift.get_by_test_id("jog-out").scroll_into_view_if_needed()
            inside_viewport(lift, lift.get_by_test_id("jog-out"))
            # photographed armed, before the jog: a screenshot holds the browser up for a while, and the beats with it
            shot(lift, str(tmp_path / "deadman-lift-armed.png"))
            box = lift.get_by_test_id("jog-out").bounding_box()
            lift.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
            lift.mouse.down()  # hold-to-run: held, never released
            assert lift_bus.first(CONTROL_ID, lambda d: d[7] & 0x01, timeout=5), "the jog did not start"
            jog_started = time.monotonic()
            # moving: the worker keeps sending enabled control telegrams while the browser's beats arrive
            assert lift_bus.first(CONTROL_ID, lambda d: d[7] & 0x01, since=jog_started + 0.3, timeout=5), "the jog stopped by itself"

            # both are still running at the moment of the freeze (not stopped earlier by a false trip):
            # the newest DigOut (every 100 ms) has SSR1 on, the newest control telegram has enable set
            before = time.monotonic()
            last_digout = [f for f in heater_bus.frames if f[1] == DIGOUT_ID][-1]
            last_control = [f for f in lift_bus.frames if f[1] == CONTROL_ID][-1]
            assert last_digout[2][0] & 0x02 and before - last_digout[0] < 0.3, "SSR1 was off before the freeze"
            assert last_control[2][7] & 0x01 and before - last_control[0] < 0.3, "the jog had stopped before the freeze"
            assert not [f for f in heater_bus.frames if f[1] == DIGOUT_ID and f[0] > switched_on and not f[2][0] & 0x02], \
                "SSR1 went off while its page was alive (opening the second page tripped it)"
            os.killpg(chromium.pid, signal.SIGSTOP)  # the whole browser freezes: no mouseup, no close
            frozen = True
            freeze = time.monotonic()
            lift_stop = lift_bus.first(CONTROL_ID, lambda d: not d[7] & 0x01, since=freeze, timeout=5)
            heater_stop = heater_bus.first(DIGOUT_ID, lambda d: not d[0] & 0x02, since=freeze, timeout=5)
            assert lift_stop is not None, "the Electrak kept its enable bit after the browser froze"
            assert heater_stop is not None, "SSR1 stayed on after the browser froze"
            lift_ms, heater_ms = (lift_stop - freeze) * 1000, (heater_stop - freeze) * 1000
            print(f"frozen browser -> enable cleared {lift_ms:.0f} ms, SSR1 off {heater_ms:.0f} ms "
                  f"(timeout {DEADMAN_TIMEOUT_S * 1000:.0f} ms, bound {DEADMAN_BOUND_S * 1000:.0f} ms)")
            assert lift_ms < DEADMAN_BOUND_S * 1000 and heater_ms < DEADMAN_BOUND_S * 1000
            # nothing enables the actuators again while the browser stays frozen
            time.sleep(0.5)
            assert not [f for f in lift_bus.frames if f[0] > lift_stop and f[1] == CONTROL_ID and f[2][7] & 0x01]
            log = (tmp_path / "app.log").read_text()
            silent = [int(m) for m in re.findall(r"not confirmed it is alive for (\d+) ms", log)]
            assert silent and max(silent) < DEADMAN_BOUND_S * 1000  # stop sent within the bound of the last beat
    finally:
        if frozen:
            os.killpg(chromium.pid, signal.SIGCONT)
        os.killpg(chromium.pid, signal.SIGKILL)
        chromium.wait(10)
        lift_bus.close()
        heater_bus.close()
