"""Issue 16 item 5: the stale threshold follows the line's measured cycle time (no flapping on a long line)."""

from __future__ import annotations

import asyncio
import time

import pytest

from app.modbus_line import STALE_CYCLES, STALE_MIN_S, stale_threshold
from app.runtime import Runtime
from tests.conftest import free_port, modbus_plant, wait_for

LOCKS = tuple((f"door-{n}", n) for n in range(1, 17))


def test_threshold_rule():
    assert stale_threshold(None) == STALE_MIN_S
    assert stale_threshold(0.4) == STALE_MIN_S
    assert stale_threshold(4.28) == pytest.approx(STALE_CYCLES * 4.28)


@pytest.mark.timeout(60)
async def test_sixteen_locks_at_19200_baud_do_not_flap():
    plant = modbus_plant(free_port(), locks=LOCKS, baudrate=19200, timeout=0.5, poll_period=0.5)
    plant.buses["line1"].options["wire_delay"] = True  # the twin answers after the 19200 baud 8E1 wire time
    runtime = Runtime(plant, simulate=True)
    line = runtime.worker.lines["line1"]
    for name, address in LOCKS:  # what the worker does for every device of a Modbus line
        line.attach_device(address, runtime.store.devices[name])
    states = [runtime.store.devices[name] for name, _a in LOCKS]
    await runtime.start()
    try:
        assert await wait_for(lambda: all(s.status == "online" for s in states), timeout=15)
        flips: dict[str, int] = {s.name: 0 for s in states}
        end = time.monotonic() + 10.0  # more than two cycles of the line
        while time.monotonic() < end:
            for s in states:
                if s.status != "online":
                    flips[s.name] += 1
            await asyncio.sleep(0.05)
        # the line takes seconds a cycle (2.7-3.3 s, by the machine and the Modbus library's own pace): a fixed stale
        # limit of 3 s flapped; the limit follows the cycle
        assert line.cycle_s is not None and line.cycle_s > 2.0
        assert all(s.stale_after > 3.0 * 2 for s in states)
        assert runtime.store.buses["line1"].cycle_s == line.cycle_s  # shown on the bus
        assert flips == {s.name: 0 for s in states}
        assert all(s.stale_after == pytest.approx(stale_threshold(line.cycle_s), rel=0.5) for s in states)
    finally:
        await asyncio.wait_for(runtime.stop(), 10)


async def test_a_silent_lock_still_goes_stale():
    plant = modbus_plant(free_port(), locks=(("door-1", 1), ("door-2", 2)))
    runtime = Runtime(plant, simulate=True)
    line = runtime.worker.lines["line1"]
    for name, address in (("door-1", 1), ("door-2", 2)):
        line.attach_device(address, runtime.store.devices[name])
    await runtime.start()
    try:
        state = runtime.store.devices["door-1"]
        assert await wait_for(lambda: state.status == "online", timeout=5)
        assert await wait_for(lambda: line.cycle_s is not None, timeout=5)
        assert state.stale_after == STALE_MIN_S  # a fast line keeps the 3 s floor
        runtime.twins["door-1"].silent = True
        assert await wait_for(lambda: state.status != "online", timeout=8)
    finally:
        await asyncio.wait_for(runtime.stop(), 10)
