"""A flooded CAN bus sheds frames visibly and does not stall the keep-alives of another bus (issue 14, item 1)."""

from __future__ import annotations

import asyncio
import threading
import time
import uuid

import can
import pytest
from can_flood import control_listener
from conftest import wait_for
from plants import ELECTRAK_ACTUATORS, can_bus, electrak_bus, hdlock_can, plant

import app.can_bus
from app.can_bus import CanBus, CanBusState, open_error
from app.runtime import Runtime

SAFETY_GAP_S = 0.25  # Electrak: control telegram timeout 250 ms (message-timeout flag)


def _plant(flooded: str, lift: str):
    return plant(can_bus(hdlock_can("gate-1", 660100), channel_name=flooded, bitrate=1000000),
                 electrak_bus(channel_name=lift, actuators=ELECTRAK_ACTUATORS[:1]), name=None)


def _flood(channel: str, stop: threading.Event, sent: list[int]) -> None:
    """Bursts of unknown extended IDs whose data start 00 00 (2x the 1 Mbit/s limit), beyond what the hand-over holds."""
    burst = [can.Message(arbitration_id=0x100000 + i, is_extended_id=True, data=bytes(8)) for i in range(1000)]
    with can.Bus(interface="virtual", channel=channel) as bus:
        while not stop.is_set():
            for msg in burst:
                bus.send(msg)
            sent[0] += len(burst)
            time.sleep(0.05)


@pytest.fixture
def own_heap():
    """The app runs in a process of its own; this test runs after a thousand others in one process.
    Their objects are moved out of the collector's way (``gc.freeze``), so a full collection of the
    suite's leftovers is not counted as a stall of the keep-alive under test."""
    import gc

    gc.collect()
    gc.freeze()
    yield
    gc.unfreeze()


async def test_flood_is_shed_and_counted_and_the_other_bus_keeps_its_keepalive(monkeypatch: pytest.MonkeyPatch, own_heap):
    monkeypatch.setattr(app.can_bus, "INBOX_FRAMES", 256)  # a small hand-over: bursts must overflow it
    flooded, lift = f"flood-{uuid.uuid4().hex}", f"lift-{uuid.uuid4().hex}"
    runtime = Runtime(_plant(flooded, lift), simulate=True)
    await runtime.start()
    stop, times, sent = threading.Event(), [], [0]
    threads = [threading.Thread(target=control_listener, args=(lift, stop, times), daemon=True),
               threading.Thread(target=_flood, args=(flooded, stop, sent), daemon=True)]
    try:
        adapter = runtime.worker.adapters["lift"]
        assert await wait_for(lambda: runtime.store.devices["lift"].status == "online", timeout=4)
        await adapter.take_control("s1", "engineer")
        threads[0].start()
        await asyncio.sleep(0.3)  # the first flood runs alone for a while before the second starts
        threads[1].start()
        bus: CanBus = runtime.worker.can_buses["can1"]
        state: CanBusState = runtime.store.buses["can1"]
        largest_inbox = 0
        end = time.monotonic() + 3.0
        while time.monotonic() < end:
            largest_inbox = max(largest_inbox, len(bus.link.handover.other))
            await asyncio.sleep(0.02)
        stop.set()
        for thread in threads:
            thread.join(2)
        assert await wait_for(lambda: not bus.link.handover.other and not bus.link.handover.known, timeout=5)
        gaps = [b - a for a, b in zip(times, times[1:], strict=False)]
        assert len(times) >= 25 and max(gaps) < SAFETY_GAP_S, f"largest control gap {max(gaps) * 1000:.0f} ms"
        assert largest_inbox <= 256
        assert state.shed > 0 and state.dropped >= state.shed
        handled = sum(stats.count for (ext, ident), stats in state.ids.items() if ext and 0x100000 <= ident < 0x100000 + 1000)
        assert handled + state.shed == sent[0]  # every flood frame was handled or counted as shed
        assert runtime.store.devices["gate-1"].status == "online"  # its frames go first
    finally:
        stop.set()
        await asyncio.wait_for(runtime.stop(), 5)



@pytest.mark.parametrize("error", [OSError(97, "Address family not supported by protocol"),
                                   can.CanInitializationError("[Errno 97] Address family not supported by protocol", 97),
                                   OSError(19, "No such device")])
def test_socketcan_error_says_what_it_needs(error: Exception):
    text = open_error({"interface": "socketcan", "channel": "can0", "bitrate": 500000}, error)
    assert "Address family" in text or "No such device" in text  # python-can's own words stay
    assert "SocketCAN needs Linux" in text and "ip link set can0 up type can bitrate 500000" in text


def test_other_open_errors_are_unchanged():
    assert open_error({"interface": "pcan", "channel": "PCAN_USBBUS1"}, OSError("no driver")) == "cannot open pcan PCAN_USBBUS1: no driver"
