"""No automatic full collection holds the interpreter lock while a keep-alive sends (app/realtime.py)."""

from __future__ import annotations

import asyncio
import gc
import sys
import time

import pytest

from app import realtime
from app.can_bus import CanBus, CanBusState
from devices.lease import Lease


@pytest.fixture
def thresholds():
    saved = gc.get_threshold()
    gc.set_threshold(700, 10, 10)
    yield
    gc.set_threshold(*saved)


async def _connected_bus(prefix: str) -> CanBus:
    """A started virtual CAN bus of its own channel, once it is connected."""
    bus = CanBus("can9", {"interface": "virtual", "channel": f"{prefix}-{time.time_ns()}"}, CanBusState("can9", "can", ""))
    await bus.start()
    for _ in range(200):
        if bus.state.connected:
            break
        await asyncio.sleep(0.01)
    return bus


def test_a_hold_puts_off_the_full_collection_until_the_last_release(thresholds):
    realtime.hold_full_collections()
    realtime.hold_full_collections()
    assert gc.get_threshold() == (700, 10, realtime.FULL_MANAGED) and realtime.full_collections_held()
    realtime.release_full_collections()
    assert gc.get_threshold()[2] == realtime.FULL_MANAGED  # one sender still runs
    realtime.release_full_collections()
    assert gc.get_threshold() == (700, 10, 10) and not realtime.full_collections_held()
    realtime.release_full_collections()  # one release too many changes nothing
    assert gc.get_threshold() == (700, 10, 10)


def test_a_program_that_schedules_full_collections_itself_is_left_to_do_so(thresholds):
    gc.set_threshold(700, 10, realtime.FULL_MANAGED)  # as app.runtime.FullCollections sets it
    realtime.hold_full_collections()
    realtime.release_full_collections()
    assert gc.get_threshold() == (700, 10, realtime.FULL_MANAGED)


async def test_a_periodic_keepalive_holds_while_it_runs(thresholds):
    bus = await _connected_bus("gc")
    try:
        bus.start_periodic("control", 0.1, 0x100, bytes(8))
        assert bus.cyclic_running("control") and gc.get_threshold()[2] == realtime.FULL_MANAGED
        bus.start_periodic("control", 0.1, 0x100, bytes(8))  # started again: still one hold
        bus.stop_cyclic("control")
        assert gc.get_threshold() == (700, 10, 10)
        bus.start_periodic("control", 0.1, 0x100, bytes(8))
    finally:
        await bus.stop()  # closing the bus ends its keep-alives and their holds
    assert gc.get_threshold() == (700, 10, 10) and not realtime.full_collections_held()


@pytest.fixture
def switch_interval():
    saved = sys.getswitchinterval()
    sys.setswitchinterval(0.005)  # CPython's default
    yield
    sys.setswitchinterval(saved)


def test_a_hold_lowers_the_switch_interval_until_the_last_release(switch_interval, thresholds):
    realtime.hold_keepalive()
    realtime.hold_keepalive()
    assert sys.getswitchinterval() == pytest.approx(realtime.KEEPALIVE_SWITCH_S, abs=1e-6)
    realtime.release_keepalive()
    assert sys.getswitchinterval() == pytest.approx(realtime.KEEPALIVE_SWITCH_S, abs=1e-6)  # one sender still runs
    realtime.release_keepalive()
    assert sys.getswitchinterval() == pytest.approx(0.005)


def test_an_interval_set_lower_or_changed_meanwhile_is_left_as_it_is(switch_interval, thresholds):
    sys.setswitchinterval(realtime.KEEPALIVE_SWITCH_S / 2)
    realtime.hold_keepalive()
    assert sys.getswitchinterval() == pytest.approx(realtime.KEEPALIVE_SWITCH_S / 2, abs=1e-6)
    realtime.release_keepalive()
    assert sys.getswitchinterval() == pytest.approx(realtime.KEEPALIVE_SWITCH_S / 2, abs=1e-6)
    sys.setswitchinterval(0.005)
    realtime.hold_keepalive()
    sys.setswitchinterval(0.002)  # somebody else's choice while the keep-alive ran
    realtime.release_keepalive()
    assert sys.getswitchinterval() == pytest.approx(0.002)


async def test_the_switch_interval_is_lowered_only_while_a_periodic_keepalive_runs(switch_interval, thresholds):
    bus = await _connected_bus("sw")
    try:
        assert sys.getswitchinterval() == pytest.approx(0.005)  # a bus without keep-alives leaves it
        bus.start_periodic("idle", 0.5, 0x101, bytes(8))  # no lease (an I/O module served idle): left as well
        assert sys.getswitchinterval() == pytest.approx(0.005)
        lease = Lease()
        lease.grant()
        bus.start_periodic("control", 0.1, 0x100, bytes(8), lease=lease)  # guards a motion
        assert sys.getswitchinterval() == pytest.approx(realtime.KEEPALIVE_SWITCH_S, abs=1e-6)
        bus.stop_cyclic("control")
        assert sys.getswitchinterval() == pytest.approx(0.005)
        bus.start_periodic("control", 0.1, 0x100, bytes(8), lease=lease)
    finally:
        await bus.stop()
    assert sys.getswitchinterval() == pytest.approx(0.005)
