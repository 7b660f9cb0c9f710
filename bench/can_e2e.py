"""End to end on ``udp_multicast`` at the 1 Mbit/s frame limit: frames received, without and with
the bus monitor's per-frame work.

A second process sends standard 8-byte frames at ``--rate`` frames/s (9,009 = 1 Mbit/s with
111 bits each, no stuff bits) for ``--seconds``: a lock's status frames on its device ID and
frames of unknown IDs (offered to discovery). This process runs the worker's CAN bus with an
HD-Lock adapter (subscribed ID), once with no monitor page and once with ``--pages`` monitor
refreshes every 0.3 s (row building and serialising as pages/can_monitor.py does). Printed for
each: frames sent, handled, shed at the hand-over, dropped by the kernel (the socket's drop
counter), the socket's receive buffer, and the app's CPU per frame.

Last line: ``received_fraction: X`` = handled / sent with ``--pages`` monitor pages.
"""

from __future__ import annotations

import argparse
import asyncio
import multiprocessing as mp
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

GROUP = "239.74.163.9"
DEVICE_ID = 660100


def sender(port: int, rate: int, seconds: float, ready, sent) -> None:
    import can

    from devices.hdlock import codec

    status = codec.encode_status(codec.StatusFrame(0x0117, 5, 100, 4))
    msgs = [can.Message(arbitration_id=DEVICE_ID, is_extended_id=True, data=status) if i % 4 == 0 else
            can.Message(arbitration_id=0x300 + i % 50, is_extended_id=False, data=bytes([i % 256] * 8)) for i in range(200)]
    with can.Bus(interface="udp_multicast", channel=GROUP, port=port) as bus:
        ready.wait(10)
        n, step = 0, 0.005
        per_step = rate * step
        start = time.perf_counter()
        while time.perf_counter() - start < seconds:
            due = int((time.perf_counter() - start) / step + 1) * per_step
            while n < due:
                bus.send(msgs[n % len(msgs)])
                n += 1
            time.sleep(max(0.0, start + (n / rate) - time.perf_counter()))
    sent.value = n


async def run(rate: int, seconds: float, pages: int) -> float:
    from bench.can_ingest import MonitorRefresh
    from app.plant import parse_plant
    from app.worker import Worker
    from tests.webutil import free_port

    port = free_port()
    plant = parse_plant(f'[[bus]]\nname = "can1"\ntype = "can"\ninterface = "udp_multicast"\nchannel = "{GROUP}"\nport = {port}\n'
                        f'bitrate = 1000000\n[[device]]\nname = "gate-1"\ntype = "hdlock"\nbus = "can1"\ndevice_id = {DEVICE_ID}\n')
    worker = Worker(plant)
    can_bus = worker.can_buses["can1"]
    state = can_bus.state
    await can_bus.start()
    while not state.connected:
        await asyncio.sleep(0.05)
    ctx = mp.get_context("spawn")
    ready, sent = ctx.Event(), ctx.Value("q", 0)
    proc = ctx.Process(target=sender, args=(port, rate, seconds, ready, sent))
    proc.start()
    refreshes = [MonitorRefresh(worker, "can1") for _ in range(pages)]
    await asyncio.sleep(0.5)
    ready.set()
    cpu0, t0 = time.process_time(), time.perf_counter()
    while proc.is_alive():
        await asyncio.sleep(0.3)
        for refresh in refreshes:
            refresh()
    await asyncio.sleep(1.0)  # let the last frames arrive
    cpu = (time.process_time() - cpu0) / (time.perf_counter() - t0)
    await can_bus.link.count_interface_drops(asyncio.get_running_loop())
    handled = state.rx_frames  # frames dispatched (shed ones never are)
    await can_bus.stop()
    n = sent.value
    print(f"sent {n} frames in {seconds:.0f} s ({n / seconds:,.0f}/s; 1 Mbit/s limit 9,009/s), {pages} monitor pages")
    print(f"handled {handled}, shed at the hand-over {state.shed}, kernel socket drops {state.interface_dropped}, "
          f"receive buffer {state.rcvbuf} bytes; discovery skipped {can_bus.no_discovery_skipped} frames of unknown IDs")
    print(f"app CPU {cpu * 100:.0f} % of a core, {cpu / max(n / seconds, 1) * 1e6:.0f} us per frame")
    print(f"received fraction with {pages} monitor pages: {handled / max(n, 1):.4f}", flush=True)
    return handled / max(n, 1)


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rate", type=int, default=9_009)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--pages", type=int, default=3)
    args = parser.parse_args()
    asyncio.run(run(args.rate, args.seconds, 0))
    received = asyncio.run(run(args.rate, args.seconds, args.pages))
    print(f"received_fraction: {received:.4f}")
