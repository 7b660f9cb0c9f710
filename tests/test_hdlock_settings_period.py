"""HD-Lock settings are read every SETTINGS_PERIOD_S, the status and identity every poll (issue 34)."""

from __future__ import annotations

import time

import pytest
from conftest import modbus_plant, running_plant, wait_for

from devices.hdlock import adapter as hdlock_adapter
from devices.hdlock.adapter import SETTINGS_BLOCKS, SETTINGS_PERIOD_S, STATUS_BLOCKS
from devices.hdlock.params import HOLDING, INPUT, PARAMS
from devices.live import DeviceState


def test_blocks_split_status_from_settings():
    status = {(s, a) for s, start, n in STATUS_BLOCKS for a in range(start, start + n)}
    settings = {(s, a) for s, start, n in SETTINGS_BLOCKS for a in range(start, start + n)}
    assert not status & settings
    assert {(p.space, a) for p in PARAMS for a in p.addresses} <= status | settings
    assert all((INPUT, a) in status for a in (0, 100, 104, 105))  # live status, firmware and serial every poll
    assert (HOLDING, 1000) in status and (HOLDING, 3004) in settings and (HOLDING, 103) in settings


def test_a_setting_ages_by_its_own_period():
    state = DeviceState("door-1", "hdlock", "line1", params=PARAMS)
    setting, status = PARAMS.by_name["SettingsProximityThresholdUnlock"], PARAMS.by_name["LockStatus"]
    state.register_every[(setting.space, setting.address)] = SETTINGS_PERIOD_S
    state.update_registers(HOLDING, setting.address, [1], now=100.0)
    state.update_registers(HOLDING, status.address, [1], now=100.0)
    assert state.param_quality(setting, 100.0 + 2 * SETTINGS_PERIOD_S) == "good"
    assert state.param_quality(status, 100.0 + 2 * SETTINGS_PERIOD_S) == "stale"
    assert state.param_quality(setting, 100.0 + 3 * SETTINGS_PERIOD_S) == "stale"
    assert state.live(setting.name, 100.0 + 2 * SETTINGS_PERIOD_S).quality == "good"


@pytest.mark.timeout(60)
async def test_settings_read_slowly_then_after_a_write_and_a_new_serial(monkeypatch):
    monkeypatch.setattr(hdlock_adapter, "SETTINGS_PERIOD_S", 3.0)
    async with running_plant(modbus_plant(locks=(("door-1", 1),))) as runtime:
        state = runtime.store.devices["door-1"]
        adapter, twin = runtime.worker.adapters["door-1"], runtime.twins["door-1"]
        setting, status = PARAMS.by_name["SettingsProximityThresholdUnlock"], PARAMS.by_name["LockStatus"]
        assert await wait_for(lambda: state.status == "online" and state.raw(setting) is not None)
        first = state.read_time(setting)
        assert await wait_for(lambda: state.read_time(status) > first + 1.0, timeout=5)
        assert state.read_time(setting) == first  # status polled on, the settings not yet
        assert state.param_quality(setting) == "good"
        assert await wait_for(lambda: state.read_time(setting) > first, timeout=8)  # read again when due

        monkeypatch.setattr(hdlock_adapter, "SETTINGS_PERIOD_S", 600.0)  # from now on only a write or a swap reads them
        twin.holding[3005] = (twin.holding[3005] + 1) & 0xFFFF  # changed behind the tool's back
        await adapter.write_param(setting, -25)  # a write: every setting read with the next poll
        wrote = time.time()
        other = PARAMS.by_name["SettingsRemoveMagnet"]
        assert await wait_for(lambda: (state.read_time(other) or 0) > wrote, timeout=3)
        assert state.raw(other) == twin.holding[3005]

        settled = state.read_time(other)
        assert await wait_for(lambda: state.read_time(status) > settled + 0.6, timeout=3)
        twin.input[105] ^= 0x0100  # another lock answers at this address
        twin.holding[3005] = (twin.holding[3005] + 1) & 0xFFFF
        swapped = time.time()
        assert await wait_for(lambda: (state.read_time(other) or 0) > swapped, timeout=5)  # with its serial
        assert state.raw(PARAMS.by_name["SerialNumber"]) == twin.serial
        assert state.raw(other) == twin.holding[3005]
