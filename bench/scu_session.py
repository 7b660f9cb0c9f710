"""The SCU keep-alive and live-data cycle against the twin, against the RS232 wire's limit.

Drives the worker's own SCU adapter and serial line (pyserial ``socket://``) against the
simulated unit, first with the twin answering after the wire time of 38400 baud 8N1 (10 bits
per character), then with no emulated delay to show the pure software time. One cycle is one
``poll()``: the RC keep-alive that brings positions and status back through the cyclic object,
plus one RG of a value read in turn. The watchdog of the unit needs an RC within 500 ms; the
worker sends one every 200 ms.

Then the RC keep-alive as the program runs it: from the serial line's own thread, with the twin on
an event loop of its own in another thread, and the RC arrivals counted at the twin: the period
p50/p99/max while idle and with the program's event loop blocked for 1 s, and with a jog held
through a 2 s block: when the actuator stopped (the lease lapses, the line's thread sends RS).
Last line: ``overhead_ratio: X`` = measured time per cycle / pure wire time of the same frames.
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import liveapp  # noqa: E402
from liveapp import bus, device, free_port  # noqa: E402

from app.plant import parse_plant  # noqa: E402
from app.runtime import SimulatedPlant  # noqa: E402
from app.worker import Worker  # noqa: E402

BAUD = 38400
BITS_PER_CHAR = 10  # start + 8 data + stop
WATCHDOG_S = 0.5


def plant_text(port: int, wire_delay: bool) -> str:
    return liveapp.plant_text(
        bus("rs1", "serial", device("scu", "scu", "rs1", actuators=2), port=f"socket://127.0.0.1:{port}", baudrate=BAUD,
            simulate=True, wire_delay=wire_delay, timeout=0.5), name=None)


async def measure(wire_delay: bool, cycles: int) -> tuple[float, float, int, float]:
    """(seconds per cycle, wire seconds per cycle, transactions per cycle, longest RC gap)."""
    plant = parse_plant(plant_text(free_port(), wire_delay))
    sim = SimulatedPlant(plant)
    await sim.start()
    worker = Worker(plant)  # not started: the benchmark drives the adapter itself
    adapter = worker.adapters["scu"]
    adapter.rc_on_line_thread = False  # RC in every poll: one cycle is the whole load the line carries
    line = worker.lines["rs1"]
    try:
        loop = asyncio.get_running_loop()
        end = loop.time() + 10
        while adapter.session != "open" and loop.time() < end:
            await adapter.poll()
            await asyncio.sleep(0.01)
        if adapter.session != "open":
            raise SystemExit(f"the SCU session did not open: {worker.store.devices['scu'].last_error}")
        await adapter.poll()  # warm up
        line.state.transactions.clear()
        rc_times = []
        start = time.perf_counter()
        for _ in range(cycles):
            rc_times.append(time.perf_counter())
            await adapter.poll()
        elapsed = (time.perf_counter() - start) / cycles
        log = list(line.state.transactions)
        errors = [t.error for t in log if t.error]
        if errors:
            raise SystemExit(f"{len(errors)} failed transactions, e.g. {errors[0]}")
        chars = sum(len(bytes.fromhex(t.request_hex)) + len(bytes.fromhex(t.response_hex)) for t in log)
        wire = chars * BITS_PER_CHAR / BAUD / cycles
        gaps = [b - a for a, b in zip(rc_times, rc_times[1:])]
        return elapsed, wire, round(len(log) / cycles), max(gaps, default=0.0)
    finally:
        for serial_line in worker.lines.values():
            serial_line.close()
        await sim.stop()


def _pct(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


async def rc_thread_figures(idle_s: float) -> dict:
    """RC arrivals at a twin on its own loop and thread, the worker running for real."""
    from devices.scu import codec
    from devices.scu.sim import ScuSim

    plant = parse_plant(plant_text(free_port(), True))
    sim = ScuSim(plant.buses["rs1"], plant.devices_on("rs1"))
    twin = sim.twin
    twin_loop = asyncio.new_event_loop()
    thread = threading.Thread(target=twin_loop.run_forever, daemon=True)
    thread.start()
    asyncio.run_coroutine_threadsafe(sim.start(), twin_loop).result(5)
    worker = Worker(plant)
    await worker.start()
    adapter = worker.adapters["scu"]
    loop = asyncio.get_running_loop()

    async def beat():
        while True:
            worker.heartbeat("bench")
            await asyncio.sleep(0.1)

    beating = asyncio.create_task(beat())

    def gaps(since: float, until: float) -> list[float]:
        times = [t for t in list(twin.rc_received) if since <= t <= until]
        return [b - a for a, b in zip(times, times[1:])]

    try:
        end = loop.time() + 10
        while adapter.session != "open" and loop.time() < end:
            await asyncio.sleep(0.05)
        start = time.monotonic()
        await asyncio.sleep(idle_s)
        idle = gaps(start, time.monotonic())
        blocked = time.monotonic()
        loop.call_soon(time.sleep, 1.0)
        await asyncio.sleep(0)
        stalled = gaps(blocked - 0.2, blocked + 1.0)
        await adapter.take_control("bench", "bench")
        await adapter.jog("bench", int(codec.Function.F1), +1)
        await asyncio.sleep(0.6)
        moving_before = twin.actuators[0].moving
        blocked = time.monotonic()
        stop_at: list[float] = []

        def watch() -> None:
            while time.monotonic() < blocked + 2.0 and not stop_at:
                if not twin.actuators[0].moving:
                    stop_at.append(time.monotonic())
                time.sleep(0.002)

        watcher = threading.Thread(target=watch, daemon=True)
        watcher.start()
        loop.call_soon(time.sleep, 2.0)
        await asyncio.sleep(0)
        watcher.join(3)
        await adapter.jog("bench", int(codec.Function.F1), 0)
        return {"idle": idle, "stalled": stalled, "moving_before": moving_before,
                "stop_ms": (stop_at[0] - blocked) * 1000 if stop_at else None,
                "trips": twin.session_lost_count}
    finally:
        beating.cancel()
        await worker.stop()
        asyncio.run_coroutine_threadsafe(sim.stop(), twin_loop).result(5)
        twin_loop.call_soon_threadsafe(twin_loop.stop)
        thread.join(5)


async def run(cycles: int) -> None:
    figures = await rc_thread_figures(5.0)
    for name in ("idle", "stalled"):
        g = [x * 1000 for x in figures[name]]
        what = "idle" if name == "idle" else "event loop blocked 1 s"
        print(f"RC period from the line's thread, {what}: p50 {statistics.median(g):.1f} ms, "
              f"p99 {_pct(g, 0.99):.1f} ms, max {max(g):.1f} ms ({len(g)} periods; watchdog {WATCHDOG_S * 1000:.0f} ms)")
    stop = figures["stop_ms"]
    print(f"jog held, event loop blocked 2 s: actuator stopped {stop:.0f} ms after the block (bound 500 ms)"
          if stop is not None and figures["moving_before"] else "jog held, event loop blocked 2 s: not measured")
    worst = max(figures["idle"] + figures["stalled"])
    print(f"scu_rc_worst_gap_ratio: {worst / 0.2:.2f}")
    soft, _wire, _n, _gap = await measure(False, cycles * 4)
    cycle, wire, transactions, gap = await measure(True, cycles)
    print(f"transactions per cycle (RC with the cyclic object, one RG in turn): {transactions}")
    print(f"pure wire time per cycle at {BAUD} baud 8N1: {wire * 1000:.2f} ms")
    print(f"measured per cycle, wire delay emulated: {cycle * 1000:.2f} ms")
    print(f"software time per cycle (no wire delay): {soft * 1000:.2f} ms")
    print(f"cycles that fit into the 500 ms watchdog: {WATCHDOG_S / cycle:.0f} (the worker runs one every 200 ms)")
    print(f"longest gap between keep-alives, back to back: {gap * 1000:.1f} ms")
    print(f"overhead_ratio: {cycle / wire:.3f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cycles", type=int, default=50)
    asyncio.run(run(parser.parse_args().cycles))
