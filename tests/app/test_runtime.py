"""What the runtime keeps across a restart and watches while it runs: unsaved device changes,
the accounts file, the event loop."""

from __future__ import annotations

import asyncio
import json
import time

from conftest import modbus_plant, wait_for

from app.runtime import Runtime
from app.users import UserStore
from app.worker import IDLE_PERIOD_S, STALL_S


async def test_unsaved_changes_survive_a_restart(tmp_path):
    plant = modbus_plant(locks=(("door-1", 1),))
    runtime = Runtime(plant, simulate=False, data_dir=tmp_path)
    await runtime.start()
    try:
        runtime.store.devices["door-1"].unsaved.add("holding:3000")
        assert await wait_for(lambda: (tmp_path / "unsaved.json").exists(), timeout=3)
    finally:
        await runtime.stop()
    stored = json.loads((tmp_path / "unsaved.json").read_text())
    assert stored[plant.name] == {"door-1": ["holding:3000"]}
    again = Runtime(plant, simulate=False, data_dir=tmp_path)
    state = again.store.devices["door-1"]
    assert state.unsaved == {"holding:3000"}
    assert any("not saved in the device yet" in e.text for e in state.events)
    await again.start()
    try:
        state.unsaved.clear()  # Save-Settings took them
        assert await wait_for(lambda: json.loads((tmp_path / "unsaved.json").read_text())[plant.name] == {}, timeout=3)
    finally:
        await again.stop()


async def test_accounts_file_changes_are_picked_up_while_running(tmp_path):
    runtime = Runtime(modbus_plant(locks=(("door-1", 1),)), simulate=False, data_dir=tmp_path)
    await runtime.start()
    try:
        UserStore(tmp_path / "users.toml").add("anna", "engineer", "correct horse")  # another process
        assert await wait_for(lambda: "anna" in runtime.users.users, timeout=3)
    finally:
        await runtime.stop()


async def test_a_blocked_event_loop_is_measured_and_counted(tmp_path, caplog):
    runtime = Runtime(modbus_plant(locks=(("door-1", 1),)), simulate=False, data_dir=tmp_path)
    await runtime.start()
    try:
        await asyncio.sleep(0.3)  # the runtime runs a few ticks before the block is measured
        before = runtime.worker.loop_health.stalls
        # a blocking call on the loop, as a locked database once was; no page is connected, so the tick comes
        # every IDLE_PERIOD_S and measures at least the block less one period
        time.sleep(0.2 + IDLE_PERIOD_S)
        assert await wait_for(lambda: runtime.worker.loop_health.stalls > before, timeout=2)
        summary = runtime.worker.loop_health.summary()
        assert summary["worst_ms"] >= 200 and summary["last_stall"] is not None
        assert "event loop stalled" in caplog.text and STALL_S == 0.1
    finally:
        await runtime.stop()
