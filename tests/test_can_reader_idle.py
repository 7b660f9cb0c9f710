"""A quiet CAN bus costs nothing: its reader thread waits until a frame comes (no timeout to wake on), and
the bus closing ends that wait at once."""

from __future__ import annotations

import uuid

import can
import pytest
from conftest import wait_for

from app import can_bus as cb
from app.can_bus import CanBus, CanBusState


@pytest.fixture
def recv_calls(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, float | None]]:
    """Every ``recv(timeout)`` of a python-can bus: (bus class, timeout)."""
    calls: list[tuple[str, float | None]] = []
    original = can.BusABC.recv

    def recording(self, timeout=None):
        calls.append((type(self).__name__, timeout))
        return original(self, timeout)

    monkeypatch.setattr(can.BusABC, "recv", recording)
    return calls


async def _quiet_then_one_frame(options: dict, sender_options: dict, calls: list) -> None:
    state = CanBusState("q", "can", "")
    bus = CanBus("q", options, state)
    await bus.start()
    try:
        assert await wait_for(lambda: state.connected and bus._thread is not None, timeout=5)
        thread = bus._thread
        with can.Bus(**sender_options) as sender:
            sender.send(can.Message(arbitration_id=0x123, is_extended_id=False, data=b"\x01\x02"))
            assert await wait_for(lambda: state.rx_frames == 1, timeout=5)
        waits = [timeout for _name, timeout in calls]
        # never a wait that ends by itself while the bus is quiet: blocking (None), or a read of what is there (0)
        assert waits and all(t is None or t == 0.0 for t in waits), waits
    finally:
        await bus.stop()
    assert not thread.is_alive()  # the closing ended the wait


async def test_a_quiet_virtual_bus_reader_waits_for_a_frame_without_a_timeout(recv_calls):
    channel = f"quiet-{uuid.uuid4().hex[:10]}"
    await _quiet_then_one_frame({"interface": "virtual", "channel": channel, "bitrate": 500000},
                                {"interface": "virtual", "channel": channel}, recv_calls)
    assert {name for name, _ in recv_calls} == {"VirtualBus"}
    assert [t for _, t in recv_calls[:1]] == [None]


async def test_a_quiet_udp_multicast_bus_reader_waits_on_its_socket(recv_calls):
    pytest.importorskip("msgpack")
    from webutil import free_port

    port = free_port()
    options = {"interface": "udp_multicast", "channel": "239.74.163.7", "port": port}
    await _quiet_then_one_frame({**options, "bitrate": 500000}, options, recv_calls)
    # the reader reads only when its socket has a frame: non-blocking reads, none before the frame came
    assert recv_calls and all(t == 0.0 for _, t in recv_calls), recv_calls


def test_interfaces_without_a_wake_up_wait_a_bounded_time():
    assert cb.READ_WAIT_S >= 0.5  # at most two wake-ups a second on a quiet bus, and a close within that
