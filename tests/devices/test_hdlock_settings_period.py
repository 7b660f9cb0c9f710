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


def test_can_poll_leaves_out_what_status_frames_carry_and_reads_identity_with_the_settings():
    from devices.hdlock.adapter import CAN_SETTINGS_BLOCKS, CAN_STATUS_BLOCKS, IDENTITY_BLOCK
    every = {(s, a) for s, start, n in CAN_STATUS_BLOCKS for a in range(start, start + n)}
    slow = {(s, a) for s, start, n in CAN_SETTINGS_BLOCKS for a in range(start, start + n)}
    assert not every & slow and IDENTITY_BLOCK in CAN_SETTINGS_BLOCKS
    assert (INPUT, 104) in slow and (INPUT, 0) in every and (INPUT, 57) in every
    assert (HOLDING, 1000) not in every and (HOLDING, 1001) not in every  # every status frame carries them
    assert (HOLDING, 1000) in slow and (HOLDING, 1001) in slow  # and the settings' read (a backup has them at once)
    assert (HOLDING, 1009) in every  # MotorCurrent, charted
    assert {(p.space, a) for p in PARAMS for a in p.addresses} <= every | slow


@pytest.mark.timeout(60)
async def test_can_settings_and_identity_read_slowly_then_after_a_write_and_a_gap(monkeypatch):
    from test_hdlock_can import can_plant

    from app.plant import parse_plant
    from devices.hdlock.adapter import IDENTITY_BLOCK

    monkeypatch.setattr(hdlock_adapter, "SETTINGS_PERIOD_S", 600.0)
    async with running_plant(parse_plant(can_plant())) as runtime:
        state = runtime.store.devices["gate-1"]
        adapter = runtime.worker.adapters["gate-1"]
        serial, setting = PARAMS.by_name["SerialNumber"], PARAMS.by_name["SettingsProximityThresholdUnlock"]
        assert await wait_for(lambda: state.status == "online" and None not in (state.raw(serial), state.raw(setting)))
        polls: list[list] = []
        read_blocks = adapter._read_blocks

        async def recorded(blocks):
            polls.append(list(blocks))
            await read_blocks(blocks)

        adapter._read_blocks = recorded
        assert await wait_for(lambda: len(polls) >= 3, timeout=10)
        assert all(IDENTITY_BLOCK not in p and ("holding", 3000, 9) not in p for p in polls)  # status only
        assert all(b[:2] != (HOLDING, 1000) for p in polls for b in p)
        assert state.param_quality(serial) == "good"  # aged by the settings' period, not the poll's
        assert (INPUT, 104) in state.register_every and (HOLDING, 1000) not in state.register_every

        polls.clear()
        await adapter.write_param(setting, -25)  # a write: identity and settings with the next poll
        assert await wait_for(lambda: any(IDENTITY_BLOCK in p for p in polls), timeout=5)
        n = len(polls)
        assert await wait_for(lambda: len(polls) >= n + 2, timeout=10)
        assert all(IDENTITY_BLOCK not in p for p in polls[n + 1:])

        polls.clear()
        adapter._last_status -= 10 * state.stale_after  # no status frame for a while: the next one comes after a gap
        assert await wait_for(lambda: any(IDENTITY_BLOCK in p for p in polls), timeout=5)
