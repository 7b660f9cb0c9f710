"""Electrak HD checkout against its twin network (two actuators on a virtual CAN bus)."""

from __future__ import annotations

import pytest

from tests.recordutil import demo_runtime, run_checkout

pytestmark = pytest.mark.timeout(120)


async def test_electrak_checkout_passes_and_an_overload_fails_with_the_reason(tmp_path):
    async with demo_runtime(tmp_path, ("lift",)) as runtime:
        result = await run_checkout(runtime, "lift")
        assert result["status"] == "passed", [(s["name"], s["reason"]) for s in result["steps"]]
        out = next(s for s in result["steps"] if s["name"] == "Move out")
        assert {v["name"] for v in out["values"]} >= {"Position", "Peak current", "Error flags"}
        assert any(f["id"] == 0x06 and f["dir"] == "tx" for f in out["evidence"]["frames"]), "control telegrams kept"
        assert runtime.worker.adapters["lift"].controller is None, "control released"
        asked = [a["question"] for s in result["steps"] for a in s.get("answers", ())]
        assert len(asked) == 1 and "area is clear" in asked[0], asked  # Go's area-clear question, asked once first

        runtime.twins["lift"].set_load(30.0)
        result = await run_checkout(runtime, "lift")
        assert result["status"] == "failed"
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert "overload" in step["reason"].lower() or "current" in step["reason"].lower(), step["reason"]
        assert runtime.worker.adapters["lift"].controller is None
