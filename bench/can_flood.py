"""A flooded CAN bus must not stall the others (issue 14, item 1).

The plant: ``can1`` (1 Mbit/s, an HD-Lock and its twin) and ``can2`` (500 kbit/s, an
Electrak and its twin), both python-can ``virtual`` buses in this process, run by the
worker exactly as in the GUI. The Electrak is under control (its control telegram is
due every 100 ms; the actuators raise the message-timeout flag after 250 ms without
one); it leaves on python-can's cyclic task, a thread of its own, not on the event loop. A sender thread floods ``can1`` for ``--seconds`` per phase at 1x and 2x the
frame limit of a 1 Mbit/s bus (9,009 8-byte standard frames/s), first with unknown
IDs (extended, data starting ``00 00``: the worst case for discovery), then with the
lock's own status ID (every frame decoded by its adapter).

Per phase: frames sent and handled per second, frames shed at the hand-over, loop lag
p99 and worst (a 20 ms probe), RSS growth, the largest gap between two control
telegrams on ``can2`` (send times, as a third node on that bus sees them), whether the
message-timeout flag rose and whether the lock stayed online.

Two ways of flooding, both printed (``--via``):

* ``thread`` (the figure this benchmark always gave): the sender is a thread of this process on
  ``virtual`` buses. It shares the interpreter lock with the receive path and the keep-alive
  sender, and python-can's virtual bus deep-copies every frame for each receiver in it (15-30 % of
  a core at 1x-2x, all of it under the lock); the lock's twin receives the flood too. Pessimistic
  against a real interface, whose frames come from another node through the kernel.
* ``process``: a second process floods ``can1`` on python-can's ``udp_multicast`` interface (frames
  through the kernel, as from another node; ``can1`` is then a udp_multicast bus, the lock's twin on it
  as well, and this process's own frames come back and are filtered); ``can2`` stays as above. Not
  lighter for this machine: the sender process takes a share of its two cores (printed), and here
  two readers (the worker's and the lock twin's) unpack every flood frame from its datagram. Where
  permitted the sender runs real-time (as this process's threads do while a keep-alive runs, see
  app/realtime.py), so it keeps its rate as another node would, not behind them.

Per phase also the CPU this process's threads got and the time they waited for a CPU (the other
programs of the machine: a thread holding the interpreter lock that waits for a CPU holds up the
keep-alive sender as long).

Last line: ``worst_keepalive_gap_ms: X``, the worst over all phases of both ways (target below 150);
the line before it gives each way's figure.
"""

from __future__ import annotations

import argparse
import asyncio
import multiprocessing as mp
import os
import sys
import threading
import time
import uuid
from pathlib import Path

import can

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from liveapp import free_udp_port  # noqa: E402

from app import realtime  # noqa: E402
from app.plant import parse_plant  # noqa: E402
from app.runtime import Runtime  # noqa: E402
from devices.electrak import codec as electrak  # noqa: E402
from devices.hdlock import codec as hdlock  # noqa: E402

BUS_LIMIT_FPS = 1_000_000 // 111  # 8-byte standard frames, 111 bits each, no stuffing
LOCK_ID = 660100
MESSAGE_TIMEOUT = 1 << 5  # Electrak status error bit 5


GROUP = "239.74.163.10"  # udp_multicast group of the flooded bus in the ``process`` way


def plant(flooded: str, lift: str, port: int | None = None):
    can1 = (f'interface = "udp_multicast"\nchannel = "{GROUP}"\nport = {port}' if port is not None else
            f'interface = "virtual"\nchannel = "{flooded}"')
    return parse_plant(
        f'[[bus]]\nname = "can1"\ntype = "can"\n{can1}\nbitrate = 1000000\nsimulate = true\n'
        f'[[bus]]\nname = "can2"\ntype = "can"\ninterface = "virtual"\nchannel = "{lift}"\nbitrate = 500000\nsimulate = true\n'
        f'[[device]]\nname = "gate-1"\ntype = "hdlock"\nbus = "can1"\ndevice_id = {LOCK_ID}\n'
        '[[device]]\nname = "lift"\ntype = "electrak"\nbus = "can2"\n'
        'actuators = [{ model = "HD24", gearing = "B026", stroke_mm = 300 }, { model = "HD24", gearing = "B026", stroke_mm = 300 }]\n'
    )


def flood_frames(kind: str, n: int) -> list[can.Message]:
    if kind == "unknown":
        return [can.Message(arbitration_id=0x1000000 + i * 7919 % 0xFFFFFF, is_extended_id=True,
                            data=bytes([0, 0, i & 0xFF, i >> 8 & 0xFF, 0, 0, 0, 0])) for i in range(n)]
    status = [hdlock.encode_status(hdlock.StatusFrame(0x0200, i % 116, i % 100, 4)) for i in range(n)]
    return [can.Message(arbitration_id=LOCK_ID, is_extended_id=True, data=data) for data in status]


def sender(channel: str, frames: list[can.Message], rate: int, stop: threading.Event, sent: list[int]) -> None:
    """``rate`` frames/s in 10 ms slices, cycling through ``frames``."""
    per_slice = max(1, rate // 100)
    with can.Bus(interface="virtual", channel=channel) as bus:
        i, due = 0, time.perf_counter()
        while not stop.is_set():
            for _ in range(per_slice):
                bus.send(frames[i])
                i = (i + 1) % len(frames)
            sent[0] += per_slice
            due += 0.01
            time.sleep(max(0.0, due - time.perf_counter()))


def process_sender(port: int, kind: str, rate: int, ready, stop, sent, cpu) -> None:
    """In a second process: ``rate`` frames/s on ``udp_multicast`` in 10 ms slices until ``stop``; ``cpu``: the
    share of a core it used."""
    frames = flood_frames(kind, 5_000)
    per_slice = max(1, rate // 100)
    try:  # another node's frames do not wait for this machine's CPUs: as the GUI's threads do while a keep-alive runs
        os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(realtime.HOLDER_PRIORITY))
    except (OSError, AttributeError):  # not permitted: an ordinary process (it may fall short of its rate; printed)
        pass
    with can.Bus(interface="udp_multicast", channel=GROUP, port=port) as bus:
        ready.set()
        cpu0, t0 = time.process_time(), time.perf_counter()
        i, n, due = 0, 0, time.perf_counter()
        while not stop.is_set():
            for _ in range(per_slice):
                bus.send(frames[i])
                i = (i + 1) % len(frames)
            n += per_slice
            sent.value = n
            due += 0.01
            time.sleep(max(0.0, due - time.perf_counter()))
        cpu.value = (time.process_time() - cpu0) / (time.perf_counter() - t0)


class Flood:
    """The flood of one phase: a thread of this process on the virtual bus, or a second process on udp_multicast."""

    def __init__(self, via: str, channel: str, port: int | None, kind: str, frames: list[can.Message], rate: int):
        self.via = via
        if via == "thread":
            self.stop, self.count = threading.Event(), [0]
            self.worker = threading.Thread(target=sender, args=(channel, frames, rate, self.stop, self.count), daemon=True)
        else:
            ctx = mp.get_context("spawn")
            self.stop, self.ready, self.count, self.cpu = ctx.Event(), ctx.Event(), ctx.Value("q", 0), ctx.Value("d", 0.0)
            self.worker = ctx.Process(target=process_sender, args=(port, kind, rate, self.ready, self.stop, self.count, self.cpu),
                                      daemon=True)

    async def start(self) -> None:
        self.worker.start()
        if self.via == "process":  # its interpreter starts first: the phase's clock starts with its frames
            while not self.ready.is_set():
                await asyncio.sleep(0.05)

    def finish(self) -> None:
        self.stop.set()
        self.worker.join()

    def sender_cpu(self) -> str:
        """What the flood's sender itself cost this machine (after :meth:`finish`)."""
        return "" if self.via == "thread" else f"; the sender process used {self.cpu.value * 100:.0f} % of a core of this machine"

    @property
    def sent(self) -> int:
        return self.count[0] if self.via == "thread" else self.count.value


def cpu_of_threads() -> tuple[int, int]:
    """(ns on a CPU, ns waiting for one) summed over this process's threads (Linux schedstat; zeros elsewhere)."""
    ran = waited = 0
    try:
        for tid in os.listdir("/proc/self/task"):
            try:
                with open(f"/proc/self/task/{tid}/schedstat") as f:
                    run, wait, _ = f.read().split()
            except OSError:
                continue
            ran, waited = ran + int(run), waited + int(wait)
    except OSError:
        pass
    return ran, waited


def control_listener(channel: str, stop: threading.Event, times: list[float]) -> None:
    """Send times of the control telegrams on the lift's bus, as a third node hears them (until ``stop``)."""
    with can.Bus(interface="virtual", channel=channel) as bus:
        while not stop.is_set():
            msg = bus.recv(0.05)
            if msg is not None and msg.arbitration_id == electrak.CONTROL_ID and not msg.is_extended_id:
                times.append(msg.timestamp)


def rss_mb() -> float:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return 0.0


async def phase(runtime: Runtime, flood: Flood, kind: str, factor: int, seconds: float, times: list[float]) -> float:
    loop = asyncio.get_running_loop()
    state = runtime.store.buses["can1"]
    lift, lock = runtime.store.devices["lift"], runtime.store.devices["gate-1"]
    rate = BUS_LIMIT_FPS * factor
    await flood.start()
    rx0, shed0, rss0, first = state.rx_frames, state.shed, rss_mb(), len(times)
    rss_peak, lags, timeout_flag, lock_offline = rss0, [], False, False
    cpu0 = cpu_of_threads()
    start = loop.time()
    while loop.time() - start < seconds:
        t = loop.time()
        await asyncio.sleep(0.02)
        lags.append((loop.time() - t - 0.02) * 1000)
        flags = lift.live("Error flags")
        timeout_flag |= bool((flags.value if flags is not None else 0) & MESSAGE_TIMEOUT)
        lock_offline |= lock.status != "online"
        rss_peak = max(rss_peak, rss_mb())
    elapsed = loop.time() - start
    ran, waited = (b - a for a, b in zip(cpu0, cpu_of_threads(), strict=True))
    sent = flood.sent
    flood.finish()
    handled, shed = state.rx_frames - rx0, state.shed - shed0
    stamps = times[first:]
    gap_ms = max((b - a for a, b in zip(stamps, stamps[1:], strict=False)), default=float("inf")) * 1000
    lags.sort()
    p99 = lags[min(len(lags) - 1, int(0.99 * len(lags)))]
    print(f"{flood.via:>7}: {kind:>7} IDs at {factor}x ({rate:,} frames/s asked, {sent / elapsed:,.0f} sent): "
          f"handled {handled / elapsed:,.0f} frames/s, shed {shed:,}, loop lag p99 {p99:.0f} ms (worst {lags[-1]:.0f}), "
          f"RSS {rss0:.0f} -> peak {rss_peak:.0f} MB (+{rss_peak - rss0:.0f}), "
          f"control telegrams {len(stamps)} in {elapsed:.1f} s, largest gap {gap_ms:.0f} ms, "
          f"message-timeout flag {'ROSE' if timeout_flag else 'never'}, lock {'went OFFLINE' if lock_offline else 'online'}; "
          f"this process's threads (summed) ran {ran / 1e7 / elapsed:.0f} % of a core and waited {waited / 1e7 / elapsed:.0f} % for a CPU"
          f"{flood.sender_cpu()}")
    await asyncio.sleep(1.0)  # let the hand-over drain before the next phase
    return gap_ms


async def run_via(via: str, seconds: float, factors: list[int]) -> float:
    floods = {kind: flood_frames(kind, 50_000) for kind in ("unknown", "known")} if via == "thread" else {"unknown": [], "known": []}
    flooded, lift_channel = f"flood-{uuid.uuid4().hex}", f"lift-{uuid.uuid4().hex}"
    port = free_udp_port() if via == "process" else None
    runtime = Runtime(plant(flooded, lift_channel, port), simulate=True)
    await runtime.start()
    stop, times = threading.Event(), []
    listener = threading.Thread(target=control_listener, args=(lift_channel, stop, times), daemon=True)
    worst = 0.0
    try:
        lift, lock = runtime.store.devices["lift"], runtime.store.devices["gate-1"]
        end = time.monotonic() + 10
        while (lift.status != "online" or lock.status != "online") and time.monotonic() < end:
            await asyncio.sleep(0.05)
        listener.start()
        await runtime.worker.adapters["lift"].take_control("bench", "engineer")
        await asyncio.sleep(0.5)
        print(f"flood from {'a thread of this process (virtual)' if via == 'thread' else 'a second process (udp_multicast)'}: "
              f"1 Mbit/s bus limit: {BUS_LIMIT_FPS:,} frames/s; Electrak control every {electrak.CONTROL_PERIOD_S * 1000:.0f} ms, "
              f"timeout {electrak.DEFAULT_TIMEOUT_MS} ms; {seconds:.0f} s per phase")
        for kind, frames in floods.items():
            for factor in factors:
                flood = Flood(via, flooded, port, kind, frames, BUS_LIMIT_FPS * factor)
                worst = max(worst, await phase(runtime, flood, kind, factor, seconds, times))
    finally:
        stop.set()
        await runtime.stop()
    return worst


async def run(seconds: float, factors: list[int], ways: list[str]) -> None:
    worst = {via: await run_via(via, seconds, factors) for via in ways}
    print("worst keep-alive gap: " + ", ".join(f"{w:.0f} ms with the flood from {'a thread of this process' if via == 'thread' else 'a second process'}"
                                               for via, w in worst.items()))
    print(f"worst_keepalive_gap_ms: {max(worst.values()):.0f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=10.0, help="flood duration per phase")
    parser.add_argument("--factors", default="1,2", help="flood rates as multiples of the bus limit, e.g. 1,2,8 (beyond 2 it is overload: frames are shed)")
    parser.add_argument("--via", default="thread,process", help="where the flood comes from: thread (this process, virtual), process (a second one, udp_multicast), or both")
    args = parser.parse_args()
    asyncio.run(run(args.seconds, [int(f) for f in args.factors.split(",")], args.via.split(",")))
