"""SCU checkout against its twin (RS232 line as a TCP socket), through the real adapter."""

from __future__ import annotations

import pytest

from tests.recordutil import demo_runtime, run_checkout

pytestmark = pytest.mark.timeout(120)


def await_no_open_re(twin) -> bool:
    """No RE left without its RS, but the one whose session the unit's watchdog ended on purpose (the trip test)."""
    return twin.re_without_rs <= len(twin.watchdog_trips) and not twin.open_re


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
        assert watchdog["status"] == "passed", watchdog["reason"]  # the unit's own watchdog stopped the drive
        assert twin.watchdog_trips, "RC was not withheld"
        values = {v["name"]: v for v in watchdog["values"]}
        assert values["Error bit 22 (remote communication timeout) reported"]["value"] is True
        assert await_no_open_re(twin), "every RE was followed by its RS (the watchdog's too, after reopening)"
        assert runtime.worker.adapters["lift-1"].controller is None, "control released"

        twin.add_load(1, 20.0)  # above the twin's peak current: the actuator trips (error bits 15..20)
        result = await run_checkout(runtime, "lift-1")
        assert result["status"] == "failed"
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert step["name"] == "A1 out and back" and "error bits during the move" in step["reason"], step["reason"]
        assert "bit 15" in step["reason"], step["reason"]
        assert runtime.worker.adapters["lift-1"].controller is None
        assert not twin.open_re


async def test_scu_checkout_passes_after_a_line_drop_left_error_bit_22(tmp_path):
    """Bit 22 (and 14-21) clear with the next movement (table 10): set before the run, it is no failure."""
    from devices.scu import codec

    async with demo_runtime(tmp_path, ("lift-1",)) as runtime:
        twin = runtime.twins["lift-1"]
        twin.raise_error(codec.REMOTE_TIMEOUT_MASK | codec.ERROR_BITS[15].mask)  # a lost session, an overload
        result = await run_checkout(runtime, "lift-1")
        steps = {s["name"]: s for s in result["steps"]}
        assert steps["Take control, no error bits"]["status"] == "passed", steps["Take control, no error bits"]["reason"]
        assert steps["A1 out and back"]["status"] == "passed", steps["A1 out and back"]["reason"]


async def test_scu_checkout_fails_a_unit_whose_watchdog_stops_nothing(tmp_path):
    async with demo_runtime(tmp_path, ("lift-1",)) as runtime:
        twin = runtime.twins["lift-1"]
        twin.strict.ignores_watchdog = True
        result = await run_checkout(runtime, "lift-1")
        steps = {s["name"]: s for s in result["steps"]}
        watchdog = steps["Watchdog trip (RC withheld)"]
        assert watchdog["status"] == "failed", watchdog
        moved = next(v for v in watchdog["values"] if "last movement after RC withheld" in v["name"])
        assert moved["value"] > 0.7, moved  # the drive went on until the reopened session's RS stopped it
        assert await_no_open_re(twin) or not any(a.moving for a in twin.actuators)
