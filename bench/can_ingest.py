"""CAN receive path throughput against the physical limit of a 1 Mbit/s bus.

Frames go through exactly the path the worker uses: python-can ``virtual`` bus ->
python-can's Notifier thread -> batched hand-over to the event loop -> dispatch by ID -> the
HD-Lock adapter's codec -> state store (registers, history) and the monitor's ring
buffer and per-ID overwrite statistics.

The frames are queued on the virtual bus first (python-can's virtual sender deep-copies
every message, which would measure the sender, not this program), then the receive
path drains them as fast as it can. A second run streams frames at a fixed rate while
the monitor page's refresh (row building for the frame list and the overwrite view,
a few times per second) runs, to report the CPU share the monitor adds.

What it leaves out: the frames are made and queued before the clock starts, all for one
known ID, on python-can's ``virtual`` interface. So it does not time an interface's receive
cost (a socket, msgpack on ``udp_multicast``), the making of each ``can.Message``, or the
discovery check for unknown IDs. The whole app, end to end, from a second process on
``udp_multicast`` with three quarters unknown IDs: ``bench/can_e2e.py``.

Last line: ``ingest_ratio: X`` = frames per second handled / the most frames of this kind a
1 Mbit/s bus carries (8-byte extended frames, 29-bit IDs: 131 bits each without stuffing,
7,634 frames/s).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
import threading
import time
from pathlib import Path

import can

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from app.plant import parse_plant  # noqa: E402
from app.worker import Worker  # noqa: E402
from devices.hdlock import codec  # noqa: E402

# 8-byte extended data frame: SOF 1, ID 11, SRR 1, IDE 1, ID 18, RTR 1, r1 r0 2, DLC 4, data 64,
# CRC 15, CRC delimiter 1, ACK 2, EOF 7, interframe space 3 = 131 bits (no stuff bits)
FRAME_BITS = 131
BUS_LIMIT_FPS = 1_000_000 / FRAME_BITS  # 7,634: the frames below are extended (the HD-Lock's 29-bit ID)
DEVICE_ID = 660100


def plant(channel: str):
    return parse_plant(
        f'[[bus]]\nname = "can1"\ntype = "can"\ninterface = "virtual"\nchannel = "{channel}"\nbitrate = 1000000\n'
        f'[[device]]\nname = "gate-1"\ntype = "hdlock"\nbus = "can1"\ndevice_id = {DEVICE_ID}\n'
    )


def frames(n: int) -> list[can.Message]:
    out = []
    for i in range(n):
        data = codec.encode_status(codec.StatusFrame(0x0117 if i % 2 else 0x0200, i % 116, i % 100, 4))
        out.append(can.Message(arbitration_id=DEVICE_ID, is_extended_id=True, data=data))
    return out


class MonitorRefresh:
    """What the monitor page does per refresh (pages/can_monitor.py, its rows from pages/can_trace.py): pick the newest 200 frames,
    decode and format them, build the overwrite view's rows, and serialise both tables as
    NiceGUI sends them to the browser."""

    def __init__(self, worker, bus: str):
        from app import recording as rec
        from pages.can_trace import frame_rows  # imports nicegui: done before measuring

        self.rec = rec
        self.frame_rows = frame_rows
        self.state = worker.store.buses[bus]
        self.decoder = rec.FrameDecoder(worker.known_ids(bus), rec.describers(worker, bus, ["hdlock"]))
        self.filter = rec.FrameFilter()

    def __call__(self) -> int:
        rec = self.rec
        rows = self.frame_rows(rec.newest(self.state.frames, self.filter, 200), self.decoder)
        ids = [
            {"id": rec.format_id(k[1], k[0]), "count": s.count, "data": rec.format_data(s.data),
             "bytes": rec.changed_bytes(s.data, s.changed), "decoded": self.decoder(k[1], k[0], s.data)}
            for k, s in list(self.state.ids.items())[:300]
        ]
        return len(json.dumps(rows)) + len(json.dumps(ids))


async def ingest(count: int) -> tuple[float, float, int, int]:
    channel = f"bench-{time.time_ns()}"
    worker = Worker(plant(channel))
    can_bus = worker.can_buses["can1"]
    can_bus.bus = can_bus.open()  # open first so the virtual queue exists
    with can.Bus(interface="virtual", channel=channel) as sender:
        for msg in frames(count):
            sender.send(msg)
    state = worker.store.buses["can1"]
    device = worker.store.devices["gate-1"]
    start, cpu0 = time.perf_counter(), time.process_time()
    await can_bus.start()
    # the notifier's thread drains the queue far faster than a bus delivers: while the hand-over is full it
    # pauses (app.can_bus.READER_BACKOFF_S), then sheds the oldest; done when every frame was handled or shed
    while state.rx_frames + state.shed < count and time.perf_counter() - start < 60:
        await asyncio.sleep(0.001)
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu0
    await asyncio.sleep(0.2)
    handled = state.rx_frames
    await can_bus.stop()
    assert device.value("LockStatus") in (0x0117, 0x0200)
    return elapsed, cpu, handled, count - handled


async def monitor_share(rate: int, seconds: float, with_monitor: bool) -> tuple[float, int]:
    """CPU seconds used per wall second while a sender streams ``rate`` frames/s."""
    channel = f"bench-m-{time.time_ns()}"
    worker = Worker(plant(channel))
    can_bus = worker.can_buses["can1"]
    await can_bus.start()
    await asyncio.sleep(0.3)
    stop = threading.Event()
    batch = frames(rate // 100)

    def send() -> None:
        with can.Bus(interface="virtual", channel=channel) as sender:
            next_t = time.perf_counter()
            while not stop.is_set():
                for msg in batch:
                    sender.send(msg)
                next_t += 0.01
                time.sleep(max(0.0, next_t - time.perf_counter()))

    thread = threading.Thread(target=send, daemon=True)
    thread.start()
    refreshes = 0
    refresh = MonitorRefresh(worker, "can1") if with_monitor else None
    cpu0, t0 = time.process_time(), time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        await asyncio.sleep(0.3)  # the monitor page's refresh period
        if with_monitor:
            refresh()
            refreshes += 1
    cpu = (time.process_time() - cpu0) / (time.perf_counter() - t0)
    stop.set()
    thread.join()
    await can_bus.stop()
    return cpu, refreshes


async def run(count: int, rate: int, seconds: float) -> None:
    elapsed, cpu, handled, lost = await ingest(count)
    fps = handled / elapsed
    print(f"frames queued: {count}, handled: {handled}, shed at the hand-over: {lost} "
          f"(the queue is drained at memory speed, faster than any bus delivers; the notifier pauses while the hand-over is full)")
    print(f"receive path: {fps:,.0f} frames/s ({elapsed * 1e6 / max(handled, 1):.1f} us per frame)")
    print(f"receive path CPU: {cpu * 1e6 / max(handled, 1):.1f} us per frame, {handled / max(cpu, 1e-9) / BUS_LIMIT_FPS:.2f}x the bus limit "
          f"per core (CPU time of this process's threads: less sensitive than the wall time to other programs of the machine)")
    print(f"1 Mbit/s bus limit: {BUS_LIMIT_FPS:,.0f} frames/s (8-byte extended frames, {FRAME_BITS} bits)")
    print("not timed here: the interface's receive cost, making each can.Message, discovery of unknown IDs; "
          "the whole app end to end: bench/can_e2e.py")
    try:
        base, _ = await monitor_share(rate, seconds, with_monitor=False)
        with_mon, refreshes = await monitor_share(rate, seconds, with_monitor=True)
        print(f"CPU at {rate} frames/s (sender thread included): {base * 100:.1f} % without the monitor, "
              f"{with_mon * 100:.1f} % with it ({refreshes} refreshes); the monitor adds {(with_mon - base) * 100:.1f} % of one core")
    except ImportError as exc:  # the page module needs nicegui
        print(f"monitor share not measured: {exc}")
    print(f"ingest_ratio: {fps / BUS_LIMIT_FPS:.2f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=200_000)
    parser.add_argument("--rate", type=int, default=7_634, help="frames/s for the monitor CPU measurement (the bus limit)")
    parser.add_argument("--seconds", type=float, default=4.0)
    args = parser.parse_args()
    asyncio.run(run(args.frames, args.rate, args.seconds))
