"""SCU checkout against its twin (RS232 line as a TCP socket), through the real adapter."""

from __future__ import annotations

import pytest

from tests.recordutil import demo_runtime, run_checkout

pytestmark = pytest.mark.timeout(120)


async def test_scu_checkout_moves_each_actuator_and_an_overload_fails_with_the_error_bits(tmp_path):
    async with demo_runtime(tmp_path, ("lift-1",)) as runtime:
        twin = runtime.twins["lift-1"]
        result = await run_checkout(runtime, "lift-1")
        assert result["status"] == "passed", [(s["name"], s["status"], s["reason"]) for s in result["steps"]]
        steps = {s["name"]: s for s in result["steps"]}
        for n in (1, 2):
            move = steps[f"A{n} out and back"]
            names = {v["name"] for v in move["values"]}
            assert {f"A{n} position out", f"A{n} position back", f"A{n} peak current out", "Error code"} <= names, names
            assert move["evidence"]["transactions"], "the step's serial traffic is kept"
            assert twin.actuators[n - 1].cumulated_stroke >= 190, "the actuator really moved out and back"
        watchdog = steps["Watchdog trip (RC withheld)"]
        assert watchdog["status"] == "not available" and "withhold RC" in watchdog["reason"]
        assert twin.re_without_rs == 0 and not twin.open_re, "every RE was followed by its RS"
        assert runtime.worker.adapters["lift-1"].controller is None, "control released"

        twin.add_load(1, 20.0)  # above the twin's peak current: the actuator trips (error bits 15..20)
        result = await run_checkout(runtime, "lift-1")
        assert result["status"] == "failed"
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert step["name"] == "A1 out and back" and "error bits during the move" in step["reason"], step["reason"]
        assert "bit 15" in step["reason"], step["reason"]
        assert runtime.worker.adapters["lift-1"].controller is None
        assert not twin.open_re
