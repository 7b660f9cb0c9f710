"""An SCU that answers single data IDs only (issue 25.5): every live value reaches the JSON API
/api/devices with its quality, as from a unit that takes groups; positions in mm from the unit's
conversion factors 0x1011.. where the plant file gives no scale."""

from __future__ import annotations

import asyncio

import pytest
import plants
from conftest import free_port
from plants import scu_line
from webutil import simulated_user

from app.plant import parse_plant
from app.runtime import Runtime

pytestmark = pytest.mark.timeout(60)

# what the page and the API show of a two-actuator unit: positions, status 1 and 2 (and their bits),
# currents, speeds, error code and bits, supply, I/O, keys
LIVE = ("A1 position", "A2 position", "A1 position mm", "A2 position mm", "A1 status 1", "A2 status 1",
        "A1 status 2", "A2 status 2", "A1 motion", "A2 initialised", "A1 current", "A2 current", "A1 speed",
        "A2 speed", "Error code", "Error bit 22", "Error history 1", "Mains", "Battery voltage",
        "Binary Output Status", "Keys", "Analogue input 1", "Session", "RC period")


def plant_text(port: int, actuators) -> str:
    return plants.plant_text(scu_line("scu", port=port, actuators=actuators, baudrate=38400), name=None)


async def values_until(client, check, timeout: float) -> dict:
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while True:
        response = await client.get("/api/devices/scu")
        assert response.status_code == 200, response.text
        values = response.json()["values"]
        if check(values) or loop.time() > end:
            return values
        await asyncio.sleep(0.2)


@pytest.mark.parametrize("strict", [{}, {"single_ids_only": True}], ids=["groups", "single-ids-only"])
async def test_every_live_value_of_the_scu_reaches_the_api_within_15_s(tmp_path, strict):
    runtime = Runtime(parse_plant(plant_text(free_port(), 2)), simulate=True, data_dir=tmp_path / "data")
    twin = runtime.twins["scu"]
    for key, value in strict.items():
        setattr(twin.strict, key, value)  # before the first byte: the unit refuses groups from the start
    async with simulated_user(runtime) as user:
        values = await values_until(user.http_client, lambda v: all(k in v and v[k]["quality"] == "good" for k in LIVE), 15)
        missing = sorted(k for k in LIVE if k not in values or values[k]["quality"] != "good")
        assert not missing, {k: values.get(k, {}).get("quality") for k in missing}
        for key in LIVE:
            assert {"value", "unit", "time", "quality", "raw", "text"} <= set(values[key]), key
        adapter = runtime.worker.adapters["scu"]
        assert bool(adapter.single_ids) == bool(strict) and twin.session_lost_count == 0


async def test_positions_in_mm_from_the_units_conversion_factors(tmp_path):
    """No scale in the plant file: counts per mm from 0x1011/0x1012 (table 6); the twin answers 12.5 and
    8.0 counts per mm, so 1500 counts are 120 mm on A1 and 187.5 mm on A2."""
    runtime = Runtime(parse_plant(plant_text(free_port(), 2)), simulate=True,
                      data_dir=tmp_path / "data")
    twin = runtime.twins["scu"]
    twin.actuators[1].counts_per_mm = 8.0  # what the unit reports in 0x1012
    for act in twin.actuators:
        act.position = 1500.0
    async with simulated_user(runtime) as user:
        values = await values_until(user.http_client, lambda v: "A2 position mm" in v and "A1 position mm" in v, 15)
        assert values["A1 conversion factor"]["value"] == 12.5 and values["A2 conversion factor"]["value"] == 8.0
        assert values["A1 position mm"]["value"] == 120.0 and values["A1 position mm"]["unit"] == "mm"
        assert values["A2 position mm"]["value"] == 187.5
        assert "= 187.5 mm" in values["A2 position"]["text"]
        adapter = runtime.worker.adapters["scu"]
        assert [s.counts_per_mm for s in adapter.scales] == [12.5, 8.0]
