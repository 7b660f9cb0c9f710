""""Not saved yet" reminders are on disk before a write is reported done (issue 41, item 7): a crash
right after a confirmed write (kill -9 of the GUI, or of a CLI restore or apply) must not lose them."""

from __future__ import annotations

import json

import pytest
from conftest import modbus_plant, wait_for

from app.runtime import UNSAVED_FILE, Runtime
from devices.commands import WRITE_PARAMETER

pytestmark = pytest.mark.timeout(60)


async def test_the_reminder_is_on_disk_when_the_write_returns(tmp_path):
    runtime = Runtime(modbus_plant(), simulate=True, data_dir=tmp_path / "data")
    await runtime.start()
    try:
        assert await wait_for(lambda: runtime.store.devices["door-1"].status == "online", timeout=10)
        await runtime.worker.gate.invoke("door-1", WRITE_PARAMETER, {"param": "MaximumTimeLock", "value": 5},
                                         user="anna", role="engineer")
        key = next(iter(runtime.store.devices["door-1"].unsaved))
        # no wait: a process killed now keeps the reminder
        data = json.loads((tmp_path / "data" / UNSAVED_FILE).read_text())
        assert key in data[runtime.plant.name]["door-1"]
    finally:
        await runtime.stop()
