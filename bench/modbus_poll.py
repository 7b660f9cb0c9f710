"""Full HD-Lock register poll over the localhost RTU socket, against the wire's physical limit.

Polls every register block of the lock (the worker's own adapter and line code) from
the twin, first with the twin emulating the wire time of 19200 baud 8E1 (11 bits per
character, 3.5-character gap after each frame), then with no emulated delay to show
the pure software time per transaction.

The emulated wire delay uses the same formula as the wire time it is compared with, so the
ratio of the two cannot fall below 1.0 and says little; it is printed for reference. The
figure that measures this program is the software time per transaction, with no wire delay.
Last line: ``software_ms_per_transaction: X``.
"""

from __future__ import annotations

import argparse
import asyncio
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import liveapp  # noqa: E402
from liveapp import bus, device, free_port  # noqa: E402

from app.plant import parse_plant  # noqa: E402
from app.runtime import SimulatedPlant  # noqa: E402
from app.worker import Worker  # noqa: E402

BAUD = 19200
BITS_PER_CHAR = 11  # start + 8 data + parity + stop


def plant_text(port: int, wire_delay: bool) -> str:
    return liveapp.plant_text(
        bus("line1", "modbus-rtu", device("door-1", "hdlock", "line1", address=1), port=f"socket://127.0.0.1:{port}",
            baudrate=BAUD, parity="E", simulate=True, wire_delay=wire_delay, timeout=1.0), name=None)


def wire_time_per_cycle(adapter) -> tuple[float, int, int]:
    """Seconds on the wire for one full poll: every request and answer plus 3.5-char gaps."""
    chars = 0
    frames = 0
    for blocks in adapter.blocks.values():
        for _start, count in blocks:
            chars += 8 + 5 + 2 * count  # request: addr fc start count crc; answer: addr fc n data crc
            frames += 2
    seconds = (chars + 3.5 * frames) * BITS_PER_CHAR / BAUD
    return seconds, frames // 2, chars


async def measure(wire_delay: bool, cycles: int) -> tuple[float, int, float]:
    plant = parse_plant(plant_text(free_port(), wire_delay))
    sim = SimulatedPlant(plant)
    await sim.start()
    worker = Worker(plant)  # not started: the benchmark drives the adapter itself
    adapter = worker.adapters["door-1"]
    try:
        await adapter.poll()  # connect and warm up
        start = time.perf_counter()
        for _ in range(cycles):
            await adapter.poll()
        elapsed = (time.perf_counter() - start) / cycles
        state = worker.store.devices["door-1"]
        assert state.counters.timeouts == 0 and state.status == "online", state.last_error
        wire, transactions, _chars = wire_time_per_cycle(adapter)
        return elapsed, transactions, wire
    finally:
        for line in worker.lines.values():
            line.close()
        await sim.stop()


async def run(cycles: int) -> None:
    soft_cycle, transactions, wire = await measure(False, cycles * 4)
    cycle, _, _ = await measure(True, cycles)
    print(f"register blocks per full poll: {transactions} transactions")
    print(f"pure wire time per poll at {BAUD} baud 8E1: {wire * 1000:.1f} ms")
    print(f"measured per poll, wire delay emulated: {cycle * 1000:.1f} ms")
    print(f"measured / wire time: {cycle / wire:.3f} (by construction at least 1.0: the emulated delay is the wire time)")
    print(f"software time per poll (no wire delay): {soft_cycle * 1000:.2f} ms, "
          f"{100 * soft_cycle / wire:.1f} % of the poll's wire time")
    print(f"software_ms_per_transaction: {soft_cycle / transactions * 1000:.3f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cycles", type=int, default=20)
    asyncio.run(run(parser.parse_args().cycles))
