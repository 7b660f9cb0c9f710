"""A CAN bus stops its periodic senders before the bus itself shuts down (issue 28).

python-can's cyclic thread that sends on a bus already shut down logs a traceback every period
("Cannot operate on a closed bus"); the headless commands showed it when they ended.
"""

from __future__ import annotations

import asyncio
import logging
import time
import uuid

import pytest

from app.can_bus import CanBus, CanBusState, PeriodicSender
from webutil import eventually


async def _open_bus(channel: str) -> CanBus:
    bus = CanBus("can-t", {"interface": "virtual", "channel": channel, "bitrate": 500000},
                 CanBusState("can-t", "can", channel))
    await bus.start()
    for _ in range(200):
        if bus.bus is not None and bus.state.connected:
            return bus
        await asyncio.sleep(0.01)
    raise AssertionError("the virtual bus did not open")


@pytest.mark.asyncio
async def test_periodic_senders_end_before_the_bus_shuts_down(caplog, monkeypatch):
    caplog.set_level(logging.DEBUG)
    before_send = PeriodicSender.before_send

    def slow_before_send(self, msg):  # the sender passed its check and waits for the interpreter, as under load
        time.sleep(0.005)  # a sender delayed inside its send, as under load
        before_send(self, msg)

    monkeypatch.setattr(PeriodicSender, "before_send", slow_before_send)
    for _ in range(5):
        bus = await _open_bus(f"shutdown-{uuid.uuid4().hex}")
        bus.start_periodic("a", 0.001, 0x123, b"\x01\x02")
        bus.start_periodic("b", 0.0013, 0x124, b"\x03")
        await asyncio.sleep(0.05)
        threads = [p.task.thread for p in bus.senders.periodic.values()]
        assert all(t.is_alive() for t in threads)
        await bus.stop()
        # each thread ends (a loaded machine may hold one past its join's bound: it then sends on the closed bus,
        # which the log check below finds)
        await eventually(lambda: not any(t.is_alive() for t in threads), 10.0, what="every sender's thread ended")
    failures = [r for r in caplog.records if "closed bus" in r.getMessage() or (r.exc_info and r.levelno >= logging.ERROR)]
    assert not failures, [r.getMessage() for r in failures]


@pytest.mark.asyncio
async def test_a_reopened_bus_starts_its_periodic_senders_again():
    bus = await _open_bus(f"reopen-{uuid.uuid4().hex}")
    try:
        bus.start_periodic("a", 0.02, 0x123, b"\x01")
        await asyncio.sleep(0.05)  # a few periods of the 20 ms sender
        await asyncio.get_running_loop().run_in_executor(None, bus.link.close)  # as the supervisor does on a failure
        assert not bus.cyclic_running("a")
        bus.bus = bus.open()
        bus.senders.restart(bus.bus)
        await asyncio.sleep(0.05)  # a few periods of the 20 ms sender
        assert bus.cyclic_running("a")
    finally:
        await bus.stop()
