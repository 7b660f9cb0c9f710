"""The CAN receive path's per-frame work (issue 28): one store notification per frame, every value kept.

A lock's status frame brings four live points and two registers; its readers (pages, history,
alarms, the monitor) must see each of them, but the store is told once per frame, not once per value.
Frames go through the worker's own path (``CanBus.dispatch`` -> the HD-Lock adapter) without a running loop.
"""

from __future__ import annotations

import time

import can
import pytest

from app.plant import parse_plant
from app.worker import Worker
from devices.hdlock import STATUS_FRAME_BOLT, codec
from devices.hdlock.adapter import P_FWU, P_PROXIMITY_FRAME, P_SOURCE_FRAME, P_STATUS_FRAME
from devices.hdlock.params import HOLDING
from devices.live import Point

DEVICE_ID = 660100


def worker(channel: str) -> Worker:
    return Worker(parse_plant(
        f'[[bus]]\nname = "can1"\ntype = "can"\ninterface = "virtual"\nchannel = "{channel}"\nbitrate = 1000000\n'
        f'[[device]]\nname = "gate-1"\ntype = "hdlock"\nbus = "can1"\ndevice_id = {DEVICE_ID}\n'))


def status(frame: codec.StatusFrame, stamp: float) -> can.Message:
    return can.Message(arbitration_id=DEVICE_ID, is_extended_id=True, data=codec.encode_status(frame), timestamp=stamp)


@pytest.fixture
def lock(request):
    """(worker, its CAN bus, the lock's record, the names the record told the store about)."""
    w = worker(f"rx-{request.node.name}-{time.time_ns()}")
    calls: list[str] = []
    store = w.store
    changed = store._changed

    def counting(name: str) -> None:
        calls.append(name)
        changed(name)

    store._changed = counting
    state = store.devices["gate-1"]
    assert state.on_change == store.changed  # a record tells its store through the one call every write ends with
    return w, w.can_buses["can1"], state, calls


def test_a_status_frame_is_one_change_for_the_readers(lock):
    _w, bus, state, calls = lock
    now = time.time()
    frames = [codec.StatusFrame(0x0117 if i % 2 else 0x0200, i % 116, i % 100, 4) for i in range(50)]
    bus.dispatch(status(frames[0], now))  # the first frame also publishes the firmware-update fact
    version, calls[:] = state.version, []
    for i, frame in enumerate(frames[1:], 1):
        bus.dispatch(status(frame, now + i * 0.001))
    assert state.version - version == 49  # one version bump per frame (it was seven)
    assert calls == ["gate-1"] * 49


def test_every_value_of_a_status_frame_reaches_the_store(lock):
    _w, bus, state, _calls = lock
    now = time.time()
    frame = codec.StatusFrame(0x0117, 77, 42, 4)
    bus.dispatch(status(frame, now))
    word = (42 << 6) + 4
    assert state.points[P_STATUS_FRAME].value == frame and state.points[P_STATUS_FRAME].time == now
    assert "motorPos 77 Inc" in state.points[P_STATUS_FRAME].text
    assert state.points[P_PROXIMITY_FRAME] == Point(42, "Inc", now, word)
    assert state.points[STATUS_FRAME_BOLT] == Point(77, "Inc", now, 77)
    assert (state.points[P_SOURCE_FRAME].value, state.points[P_SOURCE_FRAME].raw) == (4, word)
    assert state.points[P_SOURCE_FRAME].text == codec.LOCK_REQUEST_SOURCE[4]
    assert state.registers[(HOLDING, 1000)] == (0x0117, now) and state.registers[(HOLDING, 1001)] == (77, now)
    assert state.value("LockStatus") == 0x0117
    assert state.points[P_FWU].value is None and state.online is True and state.last_seen == now
    assert state.counters.responses == 1
    assert state.history[-1] == (now, {STATUS_FRAME_BOLT: 77, "MotorCurrent": None, P_PROXIMITY_FRAME: 42})
    assert bus.state.rx_frames == 1 and bus.state.ids[(True, DEVICE_ID)].count == 1  # the monitor saw it


def test_the_same_status_again_moves_the_times_on(lock):
    _w, bus, state, _calls = lock
    now = time.time()
    frame = codec.StatusFrame(0x0200, 5, 9, 4)
    bus.dispatch(status(frame, now - 1.0))
    version = state.version
    bus.dispatch(status(frame, now))
    assert state.version == version + 1
    assert all(state.points[n].time == now for n in (P_STATUS_FRAME, P_PROXIMITY_FRAME, STATUS_FRAME_BOLT, P_SOURCE_FRAME))
    assert state.registers[(HOLDING, 1001)] == (5, now) and state.last_seen == now
    assert [t for t, _ in state.history] == [now - 1.0, now]  # a second apart: both charted
    assert state.counters.responses == 2


def test_status_frames_are_charted_at_most_ten_a_second_and_a_malformed_one_is_counted(lock):
    _w, bus, state, _calls = lock
    now = time.time()
    for i in range(100):
        bus.dispatch(status(codec.StatusFrame(0x0200, i, 0, 4), now - 1.0 + i * 0.01))
    assert 9 <= len(state.history) <= 11
    bus.dispatch(can.Message(arbitration_id=DEVICE_ID, is_extended_id=True, data=bytes([0, 0, 1]), timestamp=now))
    assert state.counters.malformed == 1 and state.points[STATUS_FRAME_BOLT].value == 99


def test_firmware_update_status_then_status_frames_again(lock):
    _w, bus, state, _calls = lock
    now = time.time()
    frame = codec.StatusFrame(0x0200, 5, 9, 4)
    bus.dispatch(status(frame, now))
    fwu = codec.FwuStatusFrame(True, False)
    bus.dispatch(can.Message(arbitration_id=DEVICE_ID, is_extended_id=True, data=codec.encode_fwu_status(fwu), timestamp=now))
    assert state.points[P_FWU].value == fwu
    bus.dispatch(status(frame, now + 0.5))  # the same status as before the update: out of update mode again
    assert state.points[P_FWU].value is None and state.points[P_FWU].text == ""


def test_a_point_is_immutable():
    point = Point(1, "Inc", 2.0)
    with pytest.raises(AttributeError):
        point.value = 3  # type: ignore[misc]
    assert (point.unit, point.raw, point.text, point.periodic, point.every) == ("Inc", None, None, True, None)
