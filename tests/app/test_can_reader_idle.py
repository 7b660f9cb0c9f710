"""A quiet CAN bus costs little: python-can's notifier waits in the interface's own ``recv`` for at most
``READ_WAIT_S`` at a time (``VIRTUAL_READ_WAIT_S`` on the in-process ``virtual`` bus; no shorter waits,
no busy reads), and the bus closing ends its thread."""

from __future__ import annotations

import asyncio
import uuid

import can
import pytest
from conftest import wait_for

from app import can_bus as cb
from app.can_bus import CanBus, CanBusState

QUIET_S = 1.2


@pytest.fixture
def recv_calls(monkeypatch: pytest.MonkeyPatch) -> list[tuple[can.BusABC, float | None]]:
    """Every ``recv(timeout)`` of a python-can bus in this process: (the bus, timeout)."""
    calls: list[tuple[can.BusABC, float | None]] = []
    original = can.BusABC.recv

    def recording(self, timeout=None):
        calls.append((self, timeout))
        return original(self, timeout)

    monkeypatch.setattr(can.BusABC, "recv", recording)
    return calls


async def _quiet_then_one_frame(options: dict, sender_options: dict, calls: list) -> None:
    state = CanBusState("q", "can", "")
    bus = CanBus("q", options, state)
    await bus.start()
    try:
        assert await wait_for(lambda: state.connected, timeout=5)
        with can.Bus(**sender_options) as sender:
            sender.send(can.Message(arbitration_id=0x123, is_extended_id=False, data=b"\x01\x02"))
            assert await wait_for(lambda: state.rx_frames == 1, timeout=5)
        thread = bus.link.handover.thread  # the notifier's thread, which handed the frame over
        assert thread is not None and thread.is_alive()
        calls.clear()
        await asyncio.sleep(QUIET_S)  # a quiet bus for QUIET_S: what the reader does when nothing comes
        # this bus's reads only: a test process may hold other buses of earlier tests still being closed
        waits = [timeout for reader, timeout in calls if reader is bus.link.bus]
        assert waits, "the reader of this bus waited in its recv"
        # every wait on a quiet bus is the longest one: never a busy read, at most one wake-up per wait
        wait = cb.read_wait_s(options)
        assert all(t == wait for t in waits), waits
        assert len(waits) <= QUIET_S / wait + 1, waits
    finally:
        await bus.stop()
    assert not thread.is_alive()  # the closing ended the notifier's thread


async def test_a_quiet_virtual_bus_is_read_with_the_longest_wait(recv_calls):
    channel = f"quiet-{uuid.uuid4().hex[:10]}"
    await _quiet_then_one_frame({"interface": "virtual", "channel": channel, "bitrate": 500000},
                                {"interface": "virtual", "channel": channel}, recv_calls)


async def test_a_quiet_udp_multicast_bus_is_read_with_the_longest_wait(recv_calls):
    pytest.importorskip("msgpack")
    from webutil import free_port

    port = free_port()
    options = {"interface": "udp_multicast", "channel": "239.74.163.7", "port": port}
    await _quiet_then_one_frame({**options, "bitrate": 500000}, options, recv_calls)


def test_interfaces_wait_a_bounded_time():
    assert cb.READ_WAIT_S >= 0.5  # at most two wake-ups a second on a quiet bus, and a close within that
    assert cb.read_wait_s({"interface": "socketcan", "channel": "can0"}) == cb.READ_WAIT_S
    assert 0.05 <= cb.read_wait_s({"interface": "virtual", "channel": "x"}) <= cb.READ_WAIT_S
