"""Keep-alive periods whatever the event loop does (issue 28).

The Electrak control telegram 0x06 (every 100 ms; the actuators flag a message timeout after
250 ms), the SCU's RC (sent by its serial line's own thread; the unit ends remote mode after 500 ms
without one; phases (a), (b) and (d), heard by the twin on an event loop of its own) and the M3IO DigOut (every 100 ms while an engineer controls the module; the module's
watchdog switches its outputs off after 2 s) leave on python-can's cyclic task under a lease.
This benchmark measures their periods as a third node of each bus hears them, in four phases:

(a) idle: control held, nothing else to do;
(b) a flood of unknown extended IDs at 2x the frame limit of a 1 Mbit/s bus on a third bus of the
    same program (the receive path, discovery and the monitor take the CPU and the GIL);
(c) 20 pages open in chromium (overview, plant view and device pages, a mix): the app runs in a
    process of its own on ``udp_multicast`` buses and the keep-alives are heard from this one;
    skipped (and said so) without Debian's chromium and playwright;
(d) the event loop blocked for 1 s (a loop callback that sleeps) while a jog is held and a mains
    output is on: the keep-alives go on, and the stop form (enable cleared, SSR off) must be on
    the bus within 500 ms of the block.

Per telegram and phase: frames heard, p50 / p99 / max of the period error (gap minus the nominal
period), the worst gap over the nominal period, and whether a device's own timeout rose (the
Electrak's message-timeout flag in its status telegrams; the M3IO's watchdog, 2 s without DigOut).
Phases (a), (b) and (d) run the worker in this process on ``virtual`` buses, as the tests do.

Last line: ``keepalive_worst_gap_ratio: X`` = the largest gap / nominal period over every phase
and telegram (goal: <= 1.2).
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import sys
import tempfile
import threading
import time
import uuid
from pathlib import Path

import can

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from can_flood import flood_frames  # noqa: E402
from can_flood import sender as flood_sender  # noqa: E402
from can_listener import FrameListener  # noqa: E402

from app.plant import parse_plant  # noqa: E402
from app.runtime import Runtime, raise_priority  # noqa: E402
from devices.electrak import codec as electrak  # noqa: E402
from devices.m3io import codec as m3io  # noqa: E402
from devices.scu import codec as scu  # noqa: E402
from devices.scu.sim import ScuSim  # noqa: E402

BUS_LIMIT_FPS = 1_000_000 // 131  # 8-byte extended frames
DIGOUT_ID, DIGOUT_SSR1 = 0x422, 0x02  # M3IO HM, SW1 0x1A
TIMEOUT_BIT = 1 << 5  # Electrak status byte 7 bit 5: message timeout


def heard_on(bus: can.BusABC) -> FrameListener:
    """The keep-alives (and the Electrak's status telegrams) as a third node of ``bus`` hears them, with their
    interface time stamps (wall clock)."""
    return FrameListener(bus, sent_time=True, keep=lambda msg: not msg.is_extended_id and msg.arbitration_id in (
        electrak.CONTROL_ID, electrak.STATUS_ID, DIGOUT_ID))


def report(phase: str, heard: dict[str, FrameListener], start: float, end: float) -> float:
    """Print the figures of one phase; the worst gap ratio."""
    worst = 0.0
    for name, can_id, nominal in (("Electrak 0x06", electrak.CONTROL_ID, electrak.CONTROL_PERIOD_S), ("M3IO DigOut", DIGOUT_ID, m3io.DIGOUT_PERIOD_S)):
        times = [t for t, _ in heard[name].of(can_id, start, end)]
        gaps = [b - a for a, b in zip(times, times[1:], strict=False)]
        if not gaps:
            print(f"  {phase}: {name}: no telegrams heard")
            worst = float("inf")
            continue
        errors = sorted(abs(g - nominal) * 1000 for g in gaps)
        ratio = max(gaps) / nominal
        worst = max(worst, ratio)
        if name.startswith("Electrak"):
            flags = [d for _, d in heard[name].of(electrak.STATUS_ID, start + 0.3, end) if len(d) == 8 and d[7] & TIMEOUT_BIT]
            own = f"message-timeout flag {'ROSE (' + str(len(flags)) + ' status telegrams)' if flags else 'never'}"
        else:
            own = f"module watchdog {'RAN OUT' if max(gaps) > m3io.WATCHDOG_S else 'served'}"
        print(f"  {phase}: {name}: {len(times)} telegrams, period error p50 {statistics.median(errors):.1f} ms, "
              f"p99 {errors[min(len(errors) - 1, int(0.99 * len(errors)))]:.1f} ms, max {errors[-1]:.1f} ms; "
              f"worst gap {max(gaps) * 1000:.0f} ms = {ratio:.2f} x nominal; {own}")
    return worst


class ScuTwinThread:
    """The SCU twin on an event loop of its own (a real unit does not stall with this program): the RCs it
    received, with their arrival times, are what the unit's watchdog (500 ms) sees."""

    def __init__(self, plant):
        self.sim = ScuSim(plant.buses["rs1"], plant.devices_on("rs1"))
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, name="scu twin", daemon=True)

    def start(self) -> None:
        self.thread.start()
        asyncio.run_coroutine_threadsafe(self.sim.start(), self.loop).result(5)

    def stop(self) -> None:
        asyncio.run_coroutine_threadsafe(self.sim.stop(), self.loop).result(5)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)
        self.loop.close()

    def rc_times(self, start: float, end: float) -> list[float]:
        """Arrival times (wall clock) of the RCs between ``start`` and ``end`` (wall clock)."""
        shift = time.time() - time.monotonic()
        return [t + shift for t in list(self.sim.twin.rc_received) if start <= t + shift <= end]


def report_scu(phase: str, unit: ScuTwinThread, start: float, end: float) -> float:
    """The SCU RC's period as the unit received it; the worst gap ratio."""
    nominal = scu.KEEP_ALIVE_PERIOD_S
    times = unit.rc_times(start, end)
    gaps = [b - a for a, b in zip(times, times[1:], strict=False)]
    if not gaps:
        print(f"  {phase}: SCU RC: no RC received")
        return float("inf")
    errors = sorted(abs(g - nominal) * 1000 for g in gaps)
    trips = [t for t in unit.sim.twin.watchdog_trips if start <= t + time.time() - time.monotonic() <= end]
    print(f"  {phase}: SCU RC: {len(times)} received, period error p50 {statistics.median(errors):.1f} ms, "
          f"p99 {errors[min(len(errors) - 1, int(0.99 * len(errors)))]:.1f} ms, max {errors[-1]:.1f} ms; worst gap "
          f"{max(gaps) * 1000:.0f} ms = {max(gaps) / nominal:.2f} x nominal; unit watchdog (500 ms) {'TRIPPED' if trips else 'fed'}")
    return max(gaps) / nominal


def in_process_plant(lift: str, heater: str, flood: str, scu_port: int):
    return parse_plant(
        f'[[bus]]\nname = "rs1"\ntype = "serial"\nport = "socket://127.0.0.1:{scu_port}"\nbaudrate = 38400\n'
        'timeout = 0.3\npoll_period = 0.2\n'
        '[[device]]\nname = "scu"\ntype = "scu"\nbus = "rs1"\nactuators = 2\n'
        f'[[bus]]\nname = "can1"\ntype = "can"\ninterface = "virtual"\nchannel = "{flood}"\nbitrate = 1000000\n'
        f'[[bus]]\nname = "can2"\ntype = "can"\ninterface = "virtual"\nchannel = "{lift}"\nbitrate = 500000\nsimulate = true\n'
        f'[[bus]]\nname = "can3"\ntype = "can"\ninterface = "virtual"\nchannel = "{heater}"\nbitrate = 500000\nsimulate = true\n'
        '[[device]]\nname = "lift"\ntype = "electrak"\nbus = "can2"\n'
        'actuators = [{ model = "HD24", gearing = "B026", stroke_mm = 300 }, { model = "HD24", gearing = "B026", stroke_mm = 300 }]\n'
        '[[device]]\nname = "heater-hm"\ntype = "m3io"\nbus = "can3"\nvariant = "HM"\nsw1 = 0x1A\n'
    )


async def beat(runtime: Runtime, session: str) -> None:
    while True:
        runtime.worker.heartbeat(session)
        await asyncio.sleep(0.1)


async def in_process(seconds: float) -> float:
    lift_ch, heater_ch, flood_ch = (f"{k}-{uuid.uuid4().hex}" for k in ("lift", "heater", "flood"))
    raise_priority()  # as the GUI process does before its threads start (app/cli.py)
    plant = in_process_plant(lift_ch, heater_ch, flood_ch, free_tcp_port())
    unit = ScuTwinThread(plant)
    unit.start()
    runtime = Runtime(plant, simulate=True)
    heard = {"Electrak 0x06": heard_on(can.Bus(interface="virtual", channel=lift_ch)),
             "M3IO DigOut": heard_on(can.Bus(interface="virtual", channel=heater_ch))}
    await runtime.start()
    beating = asyncio.create_task(beat(runtime, "bench"))
    worst = 0.0
    try:
        lift, heater = runtime.worker.adapters["lift"], runtime.worker.adapters["heater-hm"]
        scu_adapter = runtime.worker.adapters["scu"]
        await lift.take_control("bench", "engineer")
        await heater.take_control("bench", "engineer")
        for _ in range(100):  # the SCU's remote session: RC every KEEP_ALIVE_PERIOD_S from the line's thread
            if scu_adapter.session == "open":
                break
            await asyncio.sleep(0.1)
        await scu_adapter.take_control("bench", "engineer")
        await asyncio.sleep(1.0)
        start = time.time()
        await asyncio.sleep(seconds)
        worst = max(worst, report("(a) idle", heard, start, time.time()), report_scu("(a) idle", unit, start, time.time()))

        stop = threading.Event()
        sender = threading.Thread(target=flood_sender, args=(flood_ch, flood_frames("unknown", 20_000), 2 * BUS_LIMIT_FPS, stop, [0]),
                                  daemon=True)
        sender.start()
        start = time.time()
        await asyncio.sleep(seconds)
        end = time.time()
        stop.set()
        sender.join()
        shed = runtime.store.buses["can1"].shed
        print(f"  (b) flood: {2 * BUS_LIMIT_FPS:,} unknown extended frames/s on can1, {runtime.store.buses['can1'].rx_frames:,} handled, {shed:,} shed")
        worst = max(worst, report("(b) 2x flood", heard, start, end), report_scu("(b) 2x flood", unit, start, end))
        await asyncio.sleep(1.0)

        lift.jog("bench", +1)
        heater.set_output("bench", "SSR1", True)
        await asyncio.sleep(0.5)
        blocked = time.time()
        asyncio.get_running_loop().call_soon(time.sleep, 1.0)
        await asyncio.sleep(0)
        end = blocked + 1.0
        worst = max(worst, report("(d) loop blocked 1 s", heard, blocked - 0.3, end))
        # the SCU under control but nothing running: RC goes on from the line's thread through the block
        report_scu("(d) loop blocked 1 s", unit, blocked - 0.3, end)
        stop_lift = [t for t, d in heard["Electrak 0x06"].of(electrak.CONTROL_ID, blocked, end) if not d[7] & 0x01]
        stop_heater = [t for t, d in heard["M3IO DigOut"].of(DIGOUT_ID, blocked, end) if not d[0] & DIGOUT_SSR1]
        for name, found in (("Electrak enable cleared", stop_lift), ("M3IO SSR1 off", stop_heater)):
            print(f"  (d) {name} on the bus {(found[0] - blocked) * 1000:.0f} ms after the block (bound 500 ms)" if found
                  else f"  (d) {name}: NOT on the bus during the block")
    finally:
        beating.cancel()
        await runtime.stop()
        unit.stop()
        for h in heard.values():
            h.close()
    return worst


def free_tcp_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


CHROMIUM_PLANT = """
name = "jitter"
[[bus]]
name = "can2"
type = "can"
interface = "udp_multicast"
channel = "239.74.163.9"
port = {lift}
bitrate = 500000
simulate = true

[[device]]
name = "lift"
type = "electrak"
bus = "can2"
actuators = [{{ model = "HD24", gearing = "B026", stroke_mm = 300 }}]

[[bus]]
name = "can3"
type = "can"
interface = "udp_multicast"
channel = "239.74.163.9"
port = {heater}
bitrate = 500000
simulate = true

[[device]]
name = "heater-hm"
type = "m3io"
bus = "can3"
variant = "HM"
sw1 = 0x1A
"""


def with_pages(seconds: float, pages: int) -> float | None:
    """(c): the app in a process of its own, ``pages`` chromium pages open, keep-alives heard from here."""
    sys.path.insert(0, str(ROOT / "bench"))
    from liveapp import free_udp_port, running_app  # the app in a process of its own, as the other benchmarks start it (no tests/)

    try:
        from playwright.sync_api import sync_playwright
    except ImportError as exc:
        print(f"  (c) skipped: {exc}")
        return None
    chromium = Path("/usr/bin/chromium")
    if not chromium.exists():
        print("  (c) skipped: Debian's chromium is not installed")
        return None
    lift_port, heater_port = free_udp_port(), free_udp_port()
    heard = {"Electrak 0x06": heard_on(can.Bus(interface="udp_multicast", channel="239.74.163.9", port=lift_port)),
             "M3IO DigOut": heard_on(can.Bus(interface="udp_multicast", channel="239.74.163.9", port=heater_port))}
    worst = None
    try:
        with tempfile.TemporaryDirectory() as folder, running_app(CHROMIUM_PLANT.format(lift=lift_port, heater=heater_port), Path(folder)) as url, \
                sync_playwright() as p:
            browser = p.chromium.launch(executable_path=str(chromium), args=["--no-sandbox", "--disable-gpu", "--disable-background-networking"])
            context = browser.new_context(viewport={"width": 1440, "height": 900})
            control = context.new_page()
            control.goto(f"{url}/device/lift")
            control.get_by_test_id("take-control").click()
            control.get_by_text("you hold control").wait_for(timeout=15_000)
            heater = context.new_page()
            heater.goto(f"{url}/device/heater-hm")
            heater.get_by_test_id("take-control").click()
            heater.get_by_test_id("controller").get_by_text("you control the module").wait_for(timeout=15_000)
            paths = ["/", "/plant", "/device/lift", "/device/heater-hm"]
            opened = []
            for i in range(pages - 2):
                page = context.new_page()
                page.goto(f"{url}{paths[i % len(paths)]}", wait_until="domcontentloaded")
                opened.append(page)
            start = time.time()
            for page in opened:  # the pages load and draw meanwhile; a few are reloaded, as people do
                page.wait_for_timeout(seconds * 1000 / len(opened))
            for page in opened[:4]:
                page.reload(wait_until="domcontentloaded")
            end = time.time()
            print(f"  (c) {pages} pages open in chromium ({', '.join(paths)}), 4 reloaded")
            worst = report("(c) 20 pages", heard, start, end)
            browser.close()
    finally:
        for h in heard.values():
            h.close()
    return worst


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=10.0, help="length of phases (a), (b) and (c)")
    parser.add_argument("--pages", type=int, default=20)
    parser.add_argument("--no-browser", action="store_true", help="skip phase (c)")
    args = parser.parse_args()
    print(f"Electrak control every {electrak.CONTROL_PERIOD_S * 1000:.0f} ms (timeout {electrak.DEFAULT_TIMEOUT_MS} ms); "
          f"M3IO DigOut every {m3io.DIGOUT_PERIOD_S * 1000:.0f} ms (watchdog {m3io.WATCHDOG_S:g} s)")
    worst = asyncio.run(in_process(args.seconds))
    if not args.no_browser:
        pages = with_pages(args.seconds, args.pages)
        if pages is not None:
            worst = max(worst, pages)
    print(f"keepalive_worst_gap_ratio: {worst:.2f}")


if __name__ == "__main__":
    main()
