"""The CAN bus's monitor figures: per-frame delta-t, per-ID cycle time (median of recent gaps,
bursts told apart), bus load and frames/s, lost frames reported by the interface, and
discovery offered unknown IDs once per period instead of once per frame."""

from __future__ import annotations

import asyncio
import time
import uuid

import can
import pytest

from app import can_bus as cb
from app.can_bus import CanBus, CanBusState, frame_bits
from devices.hdlock import codec as hdlock


def make_bus(**options) -> tuple[CanBus, CanBusState]:
    state = CanBusState("b", "can", "")
    opts = {"interface": "virtual", "channel": f"stats-{uuid.uuid4().hex[:10]}", **options}
    return CanBus("b", opts, state), state  # never opened: dispatch only


def status(i: int) -> bytes:
    return hdlock.encode_status(hdlock.StatusFrame(0x0117, i % 100, 5, 4))


def test_cycle_time_of_a_lock_id_with_status_frames_and_answer_bursts():
    """A lock's device ID carries its 1 s status (8 bytes) and, every 2 s, a burst of register answers
    (6 bytes, one per register, ms apart): the cycle times are 1 s and 2 s, not the gaps in a burst."""
    bus, state = make_bus()
    t0 = 1_000.0
    for i in range(12):
        bus.dispatch(can.Message(arbitration_id=660100, is_extended_id=True, data=status(i), timestamp=t0 + i))
        if i % 2 == 0:
            for j in range(12):
                answer = bytes([0, 1, j, 0x03, 0, 0])
                bus.dispatch(can.Message(arbitration_id=660100, is_extended_id=True, data=answer, timestamp=t0 + i + 0.3 + j * 0.002))
    cycles = {length: (cycle, burst) for length, _n, cycle, burst in state.ids[(True, 660100)].cycles()}
    assert cycles[8][0] == pytest.approx(1.0, abs=0.01) and cycles[8][1] == 1.0
    assert cycles[6][0] == pytest.approx(2.0, abs=0.01)
    assert cycles[6][1] == pytest.approx(12, abs=0.5)


def test_cycle_time_is_the_median_and_ignores_a_stray_gap():
    bus, state = make_bus()
    t = 0.0
    for i in range(40):
        t += 0.5 if i != 20 else 0.05  # one early frame (another sender's) among a 500 ms cycle
        bus.dispatch(can.Message(arbitration_id=0x422, is_extended_id=False, data=b"\x01", timestamp=10 + t))
    [(length, count, cycle, burst)] = state.ids[(False, 0x422)].cycles()
    assert (length, count, burst) == (1, 40, 1.0)
    assert cycle == pytest.approx(0.5, abs=0.001)


def test_frames_handed_over_in_a_batch_keep_their_own_gaps():
    """The gaps come from the interface's time stamps, not from when the loop handled the frames."""
    bus, state = make_bus()
    for i in range(5):
        bus.dispatch(can.Message(arbitration_id=0x7, is_extended_id=False, data=bytes(8), timestamp=100 + 0.1 * i))
    frames = list(state.frames)
    assert frames[0].dt is None
    assert [round(f.dt, 3) for f in frames[1:]] == [0.1, 0.1, 0.1, 0.1]
    assert state.ids[(False, 0x7)].cycles()[0][2] == pytest.approx(0.1)


def test_cycle_statistics_are_bounded_per_id():
    bus, state = make_bus()
    for i in range(2000):  # many lengths and frames on one ID
        bus.dispatch(can.Message(arbitration_id=0x100, is_extended_id=False, data=bytes(i % 9), timestamp=i * 0.01))
    stats = state.ids[(False, 0x100)]
    assert len(stats.streams) <= cb.CYCLE_STREAMS
    assert all(len(s.gaps) <= cb.CYCLE_GAPS and len(s.burst_gaps) <= cb.CYCLE_GAPS for s in stats.streams.values())


def test_bus_load_and_frames_per_second():
    bus, state = make_bus(bitrate=250_000)
    assert frame_bits(8, False) == 111 and frame_bits(8, True) == 131 and frame_bits(0, False) == 47
    bus.stats.load_mark = (time.monotonic() - 1.0, 0, 0)  # one second ago
    for i in range(500):
        bus.dispatch(can.Message(arbitration_id=0x7, is_extended_id=False, data=bytes(8), timestamp=i * 0.002))
    bus.stats.measure_load()
    assert state.frames_per_s == pytest.approx(500, rel=0.05)
    assert state.load_pct == pytest.approx(500 * 111 / 250_000 * 100, rel=0.05)  # 22 %


def test_unknown_ids_are_offered_to_discovery_once_per_period_not_per_frame():
    bus, state = make_bus()
    heard: list[int] = []
    bus.listeners.append(lambda msg: heard.append(msg.arbitration_id))
    for i in range(1000):
        bus.dispatch(can.Message(arbitration_id=0x321, is_extended_id=False, data=bytes([i % 256, 1]), timestamp=i * 0.001))
    assert heard.count(0x321) == 1  # the first frame; the negative result is remembered
    assert bus.no_discovery_skipped == 999
    for i in range(5):  # a lock's status frames on an unknown ID are offered every time
        bus.dispatch(can.Message(arbitration_id=660102, is_extended_id=True, data=status(i), timestamp=2 + i))
    assert heard.count(660102) == 5
    for n in range(cb.NO_DISCOVERY_IDS + 10):  # the table of negative results is bounded
        bus.dispatch(can.Message(arbitration_id=0x10000 + n, is_extended_id=True, data=b"\x01"))
    assert len(bus.link.no_discovery) == cb.NO_DISCOVERY_IDS
    assert state.rx_frames == 1005 + cb.NO_DISCOVERY_IDS + 10  # every frame still reaches the monitor


def test_a_negative_result_expires(monkeypatch: pytest.MonkeyPatch):
    bus, _ = make_bus()
    heard: list[int] = []
    bus.listeners.append(lambda msg: heard.append(1))
    clock = [100.0]
    monkeypatch.setattr(time, "monotonic", lambda: clock[0])
    bus.dispatch(can.Message(arbitration_id=0x321, is_extended_id=False, data=b"\x01"))
    bus.dispatch(can.Message(arbitration_id=0x321, is_extended_id=False, data=b"\x01"))
    clock[0] += cb.NO_DISCOVERY_S + 0.1
    bus.dispatch(can.Message(arbitration_id=0x321, is_extended_id=False, data=b"\x01"))
    assert len(heard) == 2


def _udp_options(port: int) -> dict:
    return {"interface": "udp_multicast", "channel": "239.74.163.2", "port": port, "bitrate": 1_000_000}


def test_udp_multicast_gets_a_big_receive_buffer_and_reports_kernel_drops():
    pytest.importorskip("msgpack")
    from webutil import free_port

    port = free_port()
    state = CanBusState("u", "can", "")
    small = CanBus("u", {**_udp_options(port), "rcvbuf": 4096}, state)
    small.bus = small.open()  # opened, but nobody reads: the kernel must drop
    try:
        assert cb.interface_drops(small.bus, small.options) == (0, "kernel socket drops")
        with can.Bus(**{k: v for k, v in _udp_options(port).items() if k != "bitrate"}) as sender:
            for _ in range(300):
                sender.send(can.Message(arbitration_id=0x100, is_extended_id=False, data=bytes(8)))
        count, source = cb.interface_drops(small.bus, small.options)
        assert count > 0 and source == "kernel socket drops"
    finally:
        small.bus.shutdown()

    big_state = CanBusState("u2", "can", "")
    big = CanBus("u2", _udp_options(free_port()), big_state)
    big.bus = big.open()
    try:
        assert big_state.rcvbuf is not None and big_state.rcvbuf >= 1_000_000  # the default is about 200 kB
    finally:
        big.bus.shutdown()


async def test_the_bus_shows_interface_drops_once_running():
    pytest.importorskip("msgpack")
    from webutil import eventually, free_port

    state = CanBusState("u", "can", "")
    bus = CanBus("u", _udp_options(free_port()), state)
    await bus.start()
    try:
        await eventually(lambda: state.connected and state.interface_dropped == 0, timeout=5)
        assert state.drop_source == "kernel socket drops"
    finally:
        await bus.stop()


def test_virtual_bus_does_not_claim_a_drop_count():
    bus, state = make_bus()
    assert state.interface_dropped is None
    assert cb.interface_drops(can.Bus(interface="virtual", channel=bus.options["channel"]), bus.options) is None


if __name__ == "__main__":
    asyncio.run(test_the_bus_shows_interface_drops_once_running())
