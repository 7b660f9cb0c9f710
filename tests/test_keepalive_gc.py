"""No automatic full collection holds the interpreter lock while a keep-alive sends (app/realtime.py)."""

from __future__ import annotations

import asyncio
import gc
import time

import pytest

from app import realtime
from app.can_bus import CanBus, CanBusState


@pytest.fixture
def thresholds():
    saved = gc.get_threshold()
    gc.set_threshold(700, 10, 10)
    yield
    gc.set_threshold(*saved)


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
    bus = CanBus("can9", {"interface": "virtual", "channel": f"gc-{time.time_ns()}"}, CanBusState("can9", "can", ""))
    await bus.start()
    try:
        for _ in range(200):
            if bus.state.connected:
                break
            await asyncio.sleep(0.01)
        bus.start_periodic("control", 0.1, 0x100, bytes(8))
        assert bus.cyclic_running("control") and gc.get_threshold()[2] == realtime.FULL_MANAGED
        bus.start_periodic("control", 0.1, 0x100, bytes(8))  # started again: still one hold
        bus.stop_cyclic("control")
        assert gc.get_threshold() == (700, 10, 10)
        bus.start_periodic("control", 0.1, 0x100, bytes(8))
    finally:
        await bus.stop()  # closing the bus ends its keep-alives and their holds
    assert gc.get_threshold() == (700, 10, 10) and not realtime.full_collections_held()
