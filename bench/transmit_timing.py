"""Timing of cyclic transmit rows: the period error of frames sent through the bus owner.

Starts cyclic rows of the engineer's transmit list (app.transmit) at 10 ms, 100 ms and 1 s on a
python-can virtual bus through the worker, receives them on a second virtual bus object and
prints, from the time stamps the bus gives each frame as it is sent, per period, the frames received, the mean and p99 of |interval - period| and the worst
interval; last, `cyclic_period_error_p99_ms` over all rows. Not a test: the numbers depend on
the machine's load.

    python bench/transmit_timing.py [--seconds 5]
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import sys
import tempfile
import time
import uuid
from pathlib import Path

import can

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from app.plant import parse_plant  # noqa: E402
from app.runtime import Runtime  # noqa: E402
from app.transmit import make_row, transmit_list  # noqa: E402

PERIODS_MS = (10, 100, 1000)
SESSION = "bench"


async def main(seconds: float) -> None:
    channel = f"tx-bench-{uuid.uuid4().hex[:8]}"
    plant = parse_plant(f'[[bus]]\nname = "can1"\ntype = "can"\ninterface = "virtual"\nchannel = "{channel}"\n')
    with tempfile.TemporaryDirectory() as folder:
        runtime = Runtime(plant, simulate=False, data_dir=folder)
        await runtime.start()
        listener = can.Bus(interface="virtual", channel=channel)
        tl = transmit_list(runtime.worker, "can1", Path(folder))
        await tl.load()
        ids = {}
        for n, period in enumerate(PERIODS_MS):
            row = await tl.add(make_row(0x100 + n, False, bytes([n]), period_ms=period), user="bench", role="engineer")
            ids[0x100 + n] = (period, row.key)

        async def beat() -> None:
            while True:
                runtime.worker.heartbeat(SESSION)
                await asyncio.sleep(0.1)

        beating = asyncio.create_task(beat())
        for _period, key in ids.values():
            await tl.start(key, user="bench", role="engineer", session=SESSION)
        stamps: dict[int, list[float]] = {i: [] for i in ids}
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            msg = listener.recv(0)
            if msg is None:
                await asyncio.sleep(0.0005)
            elif msg.arbitration_id in stamps:
                stamps[msg.arbitration_id].append(msg.timestamp)  # when the frame went onto the (virtual) bus
        tl.stop_all()
        beating.cancel()
        listener.shutdown()
        await runtime.stop()
    errors_all: list[float] = []
    for can_id, (period, _key) in ids.items():
        t = stamps[can_id]
        intervals = [(b - a) * 1000 for a, b in zip(t, t[1:])]
        errors = sorted(abs(i - period) for i in intervals)
        errors_all += errors
        if not errors:
            print(f"period {period} ms: {len(t)} frames")
            continue
        p99 = errors[min(len(errors) - 1, int(0.99 * len(errors)))]
        print(f"period {period:>5} ms: {len(t):>5} frames (expected {seconds * 1000 / period:.0f}), "
              f"mean error {statistics.mean(errors):.2f} ms, p99 error {p99:.2f} ms, worst interval {max(intervals):.1f} ms")
    errors_all.sort()
    p99_all = errors_all[min(len(errors_all) - 1, int(0.99 * len(errors_all)))] if errors_all else float("nan")
    print(f"cyclic_period_error_p99_ms: {p99_all:.2f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0)
    asyncio.run(main(parser.parse_args().seconds))
