"""Electrak HD checkout against its twin network (two actuators on a virtual CAN bus)."""

from __future__ import annotations

import pytest

from conftest import running_plant, wait_for
from plants import electrak_bus, plant_text

from app.plant import parse_plant
from devices.electrak import codec
from tests.recordutil import demo_runtime, run_checkout

pytestmark = pytest.mark.timeout(120)


async def test_electrak_checkout_passes_and_an_overload_fails_with_the_reason(tmp_path):
    async with demo_runtime(tmp_path, ("lift",)) as runtime:
        result = await run_checkout(runtime, "lift")
        assert result["status"] == "passed", [(s["name"], s["reason"]) for s in result["steps"]]
        out = next(s for s in result["steps"] if s["name"] == "Move out")
        assert {v["name"] for v in out["values"]} >= {"Position", "Peak current after start-up", "Error flags",
                                                      "Saturated, longest time on"}
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


def network(*actuators: tuple[str, str]) -> str:
    return plant_text(electrak_bus(actuators=[{"model": m, "gearing": g, "stroke_mm": 300} for m, g in actuators]))


@pytest.mark.parametrize("actuators", [(("HD24", "B100"),), (("HD48", "B160"), ("HD48", "B160")), (("MD12", "B017"),)])
def test_the_speed_and_current_come_from_the_networks_own_gearing_and_model(actuators):
    """HD24/B100 accepts 2..9 mm/s and an HD48 6.5 A at most: a fixed 15 mm/s and 8 A failed or passed wrongly."""
    from devices.electrak.checkout import SETTINGS, limits_of

    options = {"actuators": [{"model": m, "gearing": g, "stroke_mm": 300} for m, g in actuators]}
    speed, current = limits_of(options, SETTINGS)
    low, high = codec.SPEED_RANGE_MM_S[actuators[0][1]]
    assert low <= speed <= high and current == codec.CURRENT_LIMIT_A[actuators[0][0]]


async def test_a_slow_gearing_passes_at_its_own_speed(tmp_path):
    async with running_plant(parse_plant(network(("HD24", "B100")))) as runtime:
        assert await wait_for(lambda: runtime.store.devices["lift"].status == "online", 10)
        result = await run_checkout(runtime, "lift", settings={"distance_mm": 5.0})
        assert result["status"] == "passed", [(s["name"], s["reason"]) for s in result["steps"]]


async def test_the_start_up_current_is_not_counted(tmp_path):
    """An MD12 with a 5 A load runs at 6.2 A; its inrush peaks at twice that: not a failure (document: Strombegrenzung)."""
    async with running_plant(parse_plant(network(("MD12", "B026")))) as runtime:
        assert await wait_for(lambda: runtime.store.devices["lift"].status == "online", 10)
        runtime.twins["lift"].set_load(5.0)
        result = await run_checkout(runtime, "lift", settings={"distance_mm": 10.0})
        assert result["status"] == "passed", [(s["name"], s["reason"]) for s in result["steps"]]
        out = next(s for s in result["steps"] if s["name"] == "Move out")
        peak = next(v for v in out["values"] if v["name"] == "Peak current after start-up")
        assert peak["value"] < 9, peak


async def test_a_network_stuck_saturated_fails_the_move_with_the_reason(tmp_path):
    async with demo_runtime(tmp_path, ("lift",)) as runtime:
        runtime.twins["lift"].set_load(8.0)  # the load takes the top speed below the commanded one: Saturated stays on
        result = await run_checkout(runtime, "lift", settings={"speed_mm_s": 32.0, "distance_mm": 60.0})
        assert result["status"] == "failed"
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert step["name"] == "Move out" and "Saturated stayed on" in step["reason"], step["reason"]
