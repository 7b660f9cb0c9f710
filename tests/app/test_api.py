"""JSON API for every device type against the demo plant's twins: named values with quality,
history as JSON and CSV, and the OpenAPI description of every endpoint.

Each test gets its own NiceGUI app (reset globals) and the demo plant on private endpoints
(a free localhost port for the RTU line, private virtual CAN channels).
"""

from __future__ import annotations

import csv
import io
from collections.abc import AsyncIterator
from dataclasses import dataclass

import httpx
import pytest
from webutil import demo_user, eventually

from app.runtime import Runtime
from devices.electrak.params import PARAMS as ELECTRAK_PARAMS

pytestmark = pytest.mark.timeout(40)

QUALITIES = {"good", "stale", "offline", "unknown"}


@dataclass
class Api:
    client: httpx.AsyncClient
    runtime: Runtime

    async def values(self, name: str) -> dict:
        response = await self.client.get(f"/api/devices/{name}")
        assert response.status_code == 200, response.text
        return response.json()["values"]

    async def until(self, name: str, check, what: str, timeout: float = 8.0) -> dict:
        """The device's values once ``check(values)`` holds (bounded)."""
        seen: dict = {}

        async def probe():
            seen["values"] = await self.values(name)
            return check(seen["values"])

        await eventually_async(probe, timeout, what)
        return seen["values"]


async def eventually_async(probe, timeout: float, what: str) -> None:
    import asyncio

    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while not await probe():
        if loop.time() > end:
            raise AssertionError(f"not within {timeout} s: {what}")
        await asyncio.sleep(0.1)


@pytest.fixture
async def api(tmp_path) -> AsyncIterator[Api]:
    async with demo_user(tmp_path, f"api-{tmp_path.name}") as (user, runtime):
        yield Api(user.http_client, runtime)


def good(values: dict, *names: str) -> bool:
    return all(n in values and values[n]["quality"] == "good" for n in names)


def all_offline(values: dict) -> bool:
    return bool(values) and all(v["quality"] == "offline" for v in values.values())


def assert_records(values: dict) -> None:
    for name, v in values.items():
        assert {"value", "unit", "time", "quality", "raw", "text"} <= set(v), name
        assert v["quality"] in QUALITIES, name


# -- values per device type ---------------------------------------------------------------------


@pytest.mark.parametrize("name", ["door-1", "gate-1"], ids=["modbus", "can"])
async def test_hdlock_values_with_quality_then_offline(api: Api, name: str):
    values = await api.until(name, lambda v: good(v, "BoltPosition", "LockStatus", "SettingsProximityThresholdLock"),
                             "registers read")
    assert_records(values)
    threshold = values["SettingsProximityThresholdLock"]
    assert threshold["value"] == -60 and threshold["raw"] == 65476  # signed (3.2.7)
    assert values["LockStatus"]["fields"]["BoltUnlocked"] == 1
    assert isinstance(values["LockStatus"]["time"], float)
    if name == "gate-1":  # the status frame's third word (section 6.5)
        proximity = values["Proximity (status frame)"]
        assert proximity["unit"] == "Inc" and proximity["raw"] >> 6 == proximity["value"]
        assert "LockRequestSource (status frame, low 6 bits)" in values
    api.runtime.twins[name].silent = True
    values = await api.until(name, lambda v: v["BoltPosition"]["quality"] == "offline", "offline", timeout=10)
    assert all_offline(values)


async def test_electrak_network_values_then_offline(api: Api):
    adapter = api.runtime.worker.adapters["lift"]
    flags = ["Extending", "Retracting", "Saturated", "Waiting", "Parameter", "Current overload", "Voltage", "Temperature",
             "Backdrive", "Message timeout", "Severe fault", "Too few devices"]
    values = await api.until("lift", lambda v: good(v, "Position", "Current", "Speed", "Devices heard", *flags)
                             and v["Devices heard"]["value"] == 2, "status telegrams of both actuators")
    assert_records(values)
    assert values["Position"]["unit"] == "mm" and values["Current"]["unit"] == "A" and values["Speed"]["unit"] == "mm/s"
    assert len(values["Position"]["raw"]) == 2  # one raw word per status telegram heard (0.1 mm)
    assert values["Position"]["value"] == pytest.approx(sum(values["Position"]["raw"]) / 20, abs=0.06)
    assert values["Devices configured"]["value"] == 2
    assert all(values[f]["value"] in (True, False) for f in flags)
    assert values["Error flags"]["raw"] == sum(values[f]["raw"] << bit for bit, f in enumerate(flags[4:]))
    assert values["Target position"]["value"] == 0.0 and values["Enable"]["value"] is False
    # service parameters appear once read, and do not age while the network is online
    param = next(iter(ELECTRAK_PARAMS))
    assert (param.label or param.name) not in values
    raw = await adapter.read_param(param)
    values = await api.values("lift")
    entry = values[param.label or param.name]
    assert entry["raw"] == raw and entry["quality"] == "good"
    read_at = entry["time"]
    values = await api.until("lift", lambda v: v["Position"]["time"] > read_at + 1.5, "status goes on", timeout=5)
    assert values[param.label or param.name]["quality"] == "good"
    # the twin stops: every value offline
    for index in range(len(api.runtime.twins["lift"].actuators)):
        api.runtime.twins["lift"].remove(index)
    values = await api.until("lift", lambda v: v["Position"]["quality"] in ("stale", "offline"), "stale", timeout=3)
    values = await api.until("lift", all_offline, "offline", timeout=8)
    assert values[param.label or param.name]["quality"] == "offline"


@pytest.mark.parametrize("name", ["heater-hm", "heater-hmr"])
async def test_m3io_values_then_offline(api: Api, name: str):
    hmr = name == "heater-hmr"
    temps = ["TEMP1", "TEMP4", "TEMP5", "TEMP6"] if hmr else [f"TEMP{i}" for i in range(1, 7)]
    ssr = [f"SSR{i} {bit}" for i in range(1, 7) for bit in ("Last", "Si", "Triac")]
    values = await api.until(name, lambda v: good(v, *[f"E{i}" for i in range(1, 7)], *temps, *ssr),
                             "inputs and temperatures")
    assert_records(values)
    outputs = ["LED", "SSR1-3", "SSR4", "SSR5", "SSR6"] if hmr else ["LED"] + [f"SSR{i}" for i in range(1, 7)]
    assert all(values[o]["value"] is False for o in outputs)
    if hmr:
        assert "TEMP2" not in values and "TEMP3" not in values  # t2/t3 carry TEMP1 on the HMR (7.2.2)
    for t in temps:
        v = values[t]
        assert v["unit"] == "°C" and isinstance(v["raw"], int)
        assert v["value"] is None if "out of range" in v["text"] else isinstance(v["value"], float)
    assert values["SSR1 Si"]["value"] in ("ok", "blown", "unknown")
    assert values["Watchdog"]["value"] is True and values["Watchdog"]["quality"] == "good"
    # out of the measuring range: no temperature, but the word and the words "out of range"
    api.runtime.twins[name].set_temperature(4, -5.0)
    values = await api.until(name, lambda v: v["TEMP4"]["value"] is None, "TEMP4 out of range")
    assert "out of range" in values["TEMP4"]["text"]
    api.runtime.twins[name].set_temperature(4, 21.5)
    await api.until(name, lambda v: v["TEMP4"]["value"] == 21.5, "TEMP4 21.5")
    # a commanded output
    adapter = api.runtime.worker.adapters[name]
    await api.until(name, lambda v: v["Variant check"]["value"] != "unchecked", "variant checked")
    await adapter.take_control("test", "engineer")  # switching on needs control of the module
    adapter.set_output("test", outputs[-1], True)
    values = await api.values(name)
    assert values[outputs[-1]]["value"] is True
    adapter.set_output("test", outputs[-1], False)
    if hmr:  # identity and customer data once read (addressed mode)
        await adapter.read_identity()
        await adapter.read_customer(3)
        values = await api.values(name)
        assert values["Serial number"]["value"] == "42120023"
        assert values["Product code"]["text"].startswith("HMR")
        assert values["Customer data 3"]["quality"] == "good" and len(values["Customer data 3"]["raw"]) == 6
    else:
        assert "Serial number" not in values
    api.runtime.twins[name].powered = False
    values = await api.until(name, all_offline, "offline", timeout=8)
    assert values["E1"]["quality"] == values["Watchdog"]["quality"] == "offline"


# -- history and OpenAPI -------------------------------------------------------------------------


async def test_history_json_and_csv(api: Api):
    await api.until("door-1", lambda v: good(v, "BoltPosition"), "door-1 read")
    state = api.runtime.store.devices["door-1"]
    await eventually(lambda: len(state.history_since(10)) >= 3, what="three samples")
    response = await api.client.get("/api/devices/door-1/history?seconds=10")
    assert response.status_code == 200
    body = response.json()
    assert body["name"] == "door-1" and body["seconds"] == 10
    assert "BoltPosition" in body["series"]  # history keyed by the point's own name
    times = [s["time"] for s in body["samples"]]
    assert len(times) >= 3 and times == sorted(times)
    assert times[-1] - times[0] <= 10
    response = await api.client.get("/api/devices/door-1/history", params={"seconds": 10, "format": "csv"})
    assert response.status_code == 200 and response.headers["content-type"].startswith("text/csv")
    rows = list(csv.reader(io.StringIO(response.text)))
    assert rows[0] == ["time", *body["series"]]
    assert len(rows) - 1 >= len(times)
    float(rows[1][0])
    # every device type has history; bounds are checked
    for name in ("lift", "heater-hm"):
        await eventually(lambda n=name: len(api.runtime.store.devices[n].history) > 0, what=f"{name} history")
        body = (await api.client.get(f"/api/devices/{name}/history?seconds=5")).json()
        assert body["samples"] and body["series"]
    assert (await api.client.get("/api/devices/door-1/history?seconds=0")).status_code == 422
    assert (await api.client.get("/api/devices/door-1/history?seconds=100000")).status_code == 422
    assert (await api.client.get("/api/devices/door-1/history?format=xml")).status_code == 422
    assert (await api.client.get("/api/devices/nope/history")).status_code == 404


async def test_openapi_documents_every_endpoint_with_its_model(api: Api):
    spec = (await api.client.get("/openapi.json")).json()
    paths = spec["paths"]
    for path, model in (("/api/devices", None), ("/api/devices/{name}", "DeviceDetail"),
                        ("/api/devices/{name}/history", "History")):
        assert path in paths, path
        schema = paths[path]["get"]["responses"]["200"]["content"]["application/json"]["schema"]
        ref = schema.get("$ref") or schema.get("items", {}).get("$ref", "")
        assert ref.endswith(model or "DeviceSummary"), (path, schema)
    schemas = spec["components"]["schemas"]
    assert {"value", "unit", "time", "quality", "raw", "text"} <= set(schemas["Value"]["properties"])
    assert "text/csv" in paths["/api/devices/{name}/history"]["get"]["responses"]["200"]["content"]
    docs = await api.client.get("/docs")
    assert docs.status_code == 200 and "swagger" in docs.text.lower()
