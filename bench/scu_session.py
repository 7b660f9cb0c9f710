"""The SCU keep-alive and live-data cycle against the twin, against the RS232 wire's limit.

Drives the worker's own SCU adapter and serial line (pyserial ``socket://``) against the
simulated unit, first with the twin answering after the wire time of 38400 baud 8N1 (10 bits
per character), then with no emulated delay to show the pure software time. One cycle is one
``poll()``: the RC keep-alive that brings positions and status back through the cyclic object,
plus one RG of a value read in turn. The watchdog of the unit needs an RC within 500 ms; the
worker sends one every 200 ms. Last line: ``overhead_ratio: X`` = measured time per cycle /
pure wire time of the same frames.
"""

from __future__ import annotations

import argparse
import asyncio
import socket
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from app.plant import parse_plant  # noqa: E402
from app.runtime import SimulatedPlant  # noqa: E402
from app.worker import Worker  # noqa: E402

BAUD = 38400
BITS_PER_CHAR = 10  # start + 8 data + stop
WATCHDOG_S = 0.5


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def plant_text(port: int, wire_delay: bool) -> str:
    return (
        f'[[bus]]\nname = "rs1"\ntype = "serial"\nport = "socket://127.0.0.1:{port}"\nbaudrate = {BAUD}\n'
        f"simulate = true\nwire_delay = {str(wire_delay).lower()}\ntimeout = 0.5\n"
        '[[device]]\nname = "scu"\ntype = "scu"\nbus = "rs1"\nactuators = 2\n'
    )


async def measure(wire_delay: bool, cycles: int) -> tuple[float, float, int, float]:
    """(seconds per cycle, wire seconds per cycle, transactions per cycle, longest RC gap)."""
    plant = parse_plant(plant_text(free_port(), wire_delay))
    sim = SimulatedPlant(plant)
    await sim.start()
    worker = Worker(plant)  # not started: the benchmark drives the adapter itself
    adapter = worker.adapters["scu"]
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


async def run(cycles: int) -> None:
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
