"""HD-Lock adapter against its twin over a real pymodbus RTU conversation on a localhost socket."""

from __future__ import annotations

import asyncio

import pytest
from conftest import modbus_plant, wait_for

from app.modbus_line import LineException, LineTimeout
from app.runtime import Runtime
from app.worker import PermissionDenied
from devices.hdlock.adapter import CommandError, discover
from devices.hdlock.params import PARAMS


@pytest.fixture
async def running(plant):
    runtime = Runtime(plant, simulate=True)
    await runtime.start()
    try:
        yield runtime
    finally:
        await asyncio.wait_for(runtime.stop(), 5)


async def online(runtime, name="door-1"):
    state = runtime.store.devices[name]
    assert await wait_for(lambda: state.status == "online" and state.value("SerialNumber") is not None)
    return state


async def test_polling_reads_every_register(running):
    state = await online(running)
    values = state.values()
    assert values["SerialNumber"]["value"] == running.twins["door-1"].serial
    assert values["SettingsProximityThresholdUnlock"]["value"] == -30
    assert values["SettingsProximityThresholdUnlock"]["raw"] == 65506
    assert values["LockStatus"]["fields"]["BoltUnlocked"] == 1
    assert values["DoorState"]["name"] == "Door open"
    expected = {p.label or p.name for p in PARAMS}
    assert expected <= set(values)
    assert state.counters.timeouts == 0 and state.counters.exceptions == 0


async def test_door_closes_and_bolt_locks(running):
    state = await online(running)
    running.twins["door-1"].close_door()
    assert await wait_for(lambda: (state.value("LockStatus") or 0) & 0x0004, timeout=5)  # DoorInPosition
    assert await wait_for(lambda: (state.value("LockStatus") or 0) & 0x0100, timeout=5)  # BoltLocked
    # input registers are read before holding 1000 in a poll: BoltPosition follows one poll later
    assert await wait_for(lambda: state.value("BoltPosition") >= 100, timeout=2)
    assert await wait_for(lambda: state.value("StateMachineState") == 4, timeout=3)  # Locked
    assert any(sample["MotorCurrent [mA]"] for _, sample in state.history)


async def test_write_reads_back_and_marks_unsaved(running):
    state = await online(running)
    adapter = running.worker.adapters["door-1"]
    param = PARAMS.by_name["SettingsProximityThresholdUnlock"]
    assert await adapter.write_param(param, -25) == 65511
    assert running.twins["door-1"].holding[3004] == 65511
    assert state.value("SettingsProximityThresholdUnlock") == -25
    assert param.key in state.unsaved


async def test_save_and_restore(running):
    state = await online(running)
    adapter = running.worker.adapters["door-1"]
    twin = running.twins["door-1"]
    delay = PARAMS.by_name["LockRequestDelay"]
    await adapter.write_param(delay, 300)
    saves = twin.input[101]
    await adapter.save_settings()
    assert twin.input[101] == saves + 1 and not state.unsaved
    await adapter.write_param(delay, 999)
    await adapter.restore_settings()
    assert twin.holding[3000] == 300 and state.value("LockRequestDelay") == 300 and not state.unsaved
    twin.reset()  # power cycle keeps what was saved
    assert twin.holding[3000] == 300


async def test_refused_write_is_reported(running):
    state = await online(running)
    adapter = running.worker.adapters["door-1"]
    twin = running.twins["door-1"]
    twin.writable.discard(3000)  # this firmware protects the register: it acknowledges and keeps the value
    with pytest.raises(CommandError, match="refused by the firmware"):
        await adapter.write_param(PARAMS.by_name["LockRequestDelay"], 500)
    assert state.counters.write_errors == 1
    assert twin.holding[3000] == 200


async def test_invalid_entries_never_reach_the_bus(running):
    await online(running)
    adapter = running.worker.adapters["door-1"]
    requests = running.store.devices["door-1"].counters.requests
    with pytest.raises(CommandError, match="outside"):
        await adapter.write_param(PARAMS.by_name["LockRequestDelay"], 70000)
    with pytest.raises(CommandError, match="cannot be written"):
        await adapter.write_param(PARAMS.by_name["LockStatus"], 1)
    with pytest.raises(CommandError, match="cannot be written"):
        await adapter.write_param(PARAMS.get("holding", 32770), 1)
    with pytest.raises(CommandError, match="needs confirmation"):
        await adapter.write_param(PARAMS.by_name["SettingsRemoveMagnet"], 1)
    # only the poll loop's requests went out meanwhile, no write
    assert all("write" not in t.request for t in running.store.buses["line1"].transactions)
    assert running.twins["door-1"].holding[3005] == 0
    assert running.store.devices["door-1"].counters.requests >= requests


async def test_set_address_accepted(running):
    state = await online(running)
    twin = running.twins["door-1"]
    twin.close_door()
    assert await wait_for(lambda: (state.value("LockStatus") or 0) & 0x0104 == 0x0104, timeout=5)
    adapter = running.worker.adapters["door-1"]
    assert adapter.set_address_preview(0x010C, 0x0104)[0]
    assert await adapter.set_address(8, 0x010C, 0x0104) is True
    assert twin.address == 8 and adapter.address == 8
    state.online = None
    assert await online(running)


async def test_set_address_refused(running):
    state = await online(running)
    adapter = running.worker.adapters["door-1"]
    # BoltLocked must be set, but the door is open and the bolt in
    accepted, result, _status = adapter.set_address_preview(0x0100, 0x0100)
    assert not accepted and result == 0x0100
    assert await adapter.set_address(16, 0x0100, 0x0100) is False
    assert running.twins["door-1"].address == 1 and adapter.address == 1
    assert any("refused" in e.text for e in state.events)


async def test_timeout_when_twin_silent_and_recovery(running):
    state = await online(running)
    twin = running.twins["door-1"]
    twin.silent = True
    assert await wait_for(lambda: state.status == "offline", timeout=5)
    assert state.counters.timeouts > 0
    assert "no answer" in state.last_error
    assert running.store.devices["door-2"].status == "online"  # the other lock keeps going
    twin.silent = False
    assert await wait_for(lambda: state.status == "online", timeout=5)


async def test_twin_server_stopped_and_back(running):
    state = await online(running)
    await running.sim.stop()
    assert await wait_for(lambda: state.status == "offline", timeout=8)
    await running.sim.start()
    assert await wait_for(lambda: state.status == "online", timeout=15)


async def test_crc_error_is_counted(running):
    state = await online(running)
    running.sim.servers[0].corrupt_next = 1
    assert await wait_for(lambda: state.counters.crc_errors >= 1, timeout=5)
    assert await wait_for(lambda: state.status == "online", timeout=5)


async def test_modbus_exception_is_named(running):
    await online(running)
    line = running.worker.lines["line1"]
    counters = running.store.devices["door-1"].counters
    with pytest.raises(LineException, match="illegal data address"):
        await line.read_holding(1, 5, 1, counters)  # reserved register
    assert counters.exceptions == 1


async def test_unknown_address_times_out(running):
    line = running.worker.lines["line1"]
    with pytest.raises(LineTimeout):
        await line.read_holding(77, 103, 1)


async def test_viewer_cannot_write(running):
    await online(running)
    with pytest.raises(PermissionDenied):
        await running.worker.command(
            "door-1", lambda a: a.write_param(PARAMS.by_name["LockRequestDelay"], 300), role="viewer",
        )
    assert running.twins["door-1"].holding[3000] == 200


async def test_discover_broadcast_single_lock():
    plant = modbus_plant(locks=(("door-1", 7),))
    runtime = Runtime(plant, simulate=True)
    await runtime.sim.start()
    try:
        line = runtime.worker.lines["line1"]
        seen = []
        found = await discover(line, 1, 8, progress=lambda done, total: seen.append(done))
        assert {"address": 7, "via": "broadcast"} in found or found[0]["address"] == 7
        assert seen[-1] == 8
    finally:
        runtime.worker.lines["line1"].close()
        await runtime.sim.stop()


async def test_discover_scan_several_locks(running):
    await online(running)
    found = await running.worker.discover("line1", 1, 4)
    assert [f["address"] for f in found] == [1, 2]
    assert found[0]["serial"] == running.twins["door-1"].serial
