"""The line cycle shown on the overview is the time of one poll round of the line's devices: steady at the
poll period, also across the lock's settings reads (every SETTINGS_PERIOD_S, fewer than every poll)."""

from __future__ import annotations

import asyncio
import time

import pytest

from app.runtime import Runtime
from devices.hdlock import adapter as hdlock_adapter
from tests.conftest import free_port, modbus_plant, wait_for


@pytest.mark.alone  # the measured cycle against the period: beside three other timed tests it once read 0.137 s for 0.2 s
@pytest.mark.timeout(30)
@pytest.mark.parametrize("poll", [0.2, 0.5])
async def test_the_cycle_stays_at_the_poll_period_across_settings_reads(monkeypatch, poll):
    monkeypatch.setattr(hdlock_adapter, "SETTINGS_PERIOD_S", 1.0)
    plant = modbus_plant(free_port(), poll_period=poll)
    runtime = Runtime(plant, simulate=True)
    line = runtime.worker.lines["line1"]
    line.attach_device(1, runtime.store.devices["door-1"])
    bus = runtime.store.buses["line1"]
    await runtime.start()
    try:
        assert await wait_for(lambda: runtime.store.devices["door-1"].status == "online", timeout=10)
        assert await wait_for(lambda: bus.cycle_s is not None, timeout=5)
        seen: list[float] = []
        end = time.monotonic() + max(3.0, 8 * poll)  # several settings reads
        while time.monotonic() < end:
            seen.append(bus.cycle_s)
            await asyncio.sleep(0.02)
        assert max(seen) <= 2 * poll, (poll, sorted(set(seen)))
        assert min(seen) >= 0.8 * poll, (poll, sorted(set(seen)))
        assert line.cycle_s == bus.cycle_s
    finally:
        await asyncio.wait_for(runtime.stop(), 10)
