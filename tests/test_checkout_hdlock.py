"""HD-Lock checkout against its twins (Modbus RTU and CAN), through the real adapters."""

from __future__ import annotations

import pytest

from tests.conftest import wait_for
from tests.recordutil import demo_runtime, run_checkout

pytestmark = pytest.mark.timeout(120)


async def test_hdlock_checkout_passes_on_modbus_and_can(tmp_path):
    async with demo_runtime(tmp_path, ("door-2", "gate-2")) as runtime:
        for name in ("door-2", "gate-2"):
            result = await run_checkout(runtime, name)
            assert result["status"] == "passed", result
            steps = {s["name"]: s for s in result["steps"]}
            lock = steps["Lock"]
            assert any(v["name"].startswith("Lock time") and v["ok"] for v in lock["values"])
            assert steps["Door closed (asked)"]["answers"][0]["by"] == "anna"
            evidence = lock["evidence"]
            assert evidence["frames" if evidence["kind"] == "can" else "transactions"], "the step's traffic is kept"
            assert runtime.twins[name].holding[4] == 4  # the source the lock had (IrsNotLine), written back
        rows = await runtime.record.timeline("door-2", ("checkout",))
        assert rows and rows[0].data["status"] == "passed"


async def test_hdlock_checkout_fails_with_the_reason_when_the_door_is_open(tmp_path):
    async with demo_runtime(tmp_path, ("door-2",)) as runtime:
        runtime.twins["door-2"].open_door()
        state = runtime.store.devices["door-2"]
        assert await wait_for(lambda: state.value("Calculated proxi (normalized)") == 100, 10)  # wide open
        result = await run_checkout(runtime, "door-2", settings={"door_timeout_s": 2.0})
        assert result["status"] == "failed"
        door = next(s for s in result["steps"] if s["name"].startswith("Door in position"))
        assert door["status"] == "failed" and "not in position" in door["reason"]
        assert result["steps"][-1]["status"] == "skipped"
