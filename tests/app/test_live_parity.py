"""Every value a device page shows reaches the JSON API and the MQTT payload (issue 27).

The page is built by NiceGUI's simulated user against the device's twin; every name it reads from
the device's live record (``live``, ``point``, ``entry``) is recorded. Pages read nothing else of a
device (tests/app/test_layering.py: no adapter, no twin, no ``info``), so what the page shows is these
values plus the summary (status, age, last error, counters). Each must be in ``/api/devices/{name}``
and in the MQTT ``state`` and ``status`` payloads, with the same value. One device type per row: a
family is switched on here when its page is moved to the store.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import pytest
from plants import can_bus, device, electrak_bus, hdlock_can, modbus_line, mo64_tcp, plant, scu_line
from webutil import eventually, simulated_user

from app.mqtt import state_payload, status_payload
from app.plant import Plant
from app.runtime import Runtime

pytestmark = pytest.mark.timeout(60)


def mo64_plant() -> Plant:
    return plant(mo64_tcp())


def hdlock_plant() -> Plant:
    # the line's answers wait on this process's loop, where the twin runs too: on a loaded machine the lines' usual
    # 0.2 s (tests/plants.py) left every poll of a cycle failing for 45 s (2026-11-29); parity is the subject here
    return plant(modbus_line(timeout=1.0))


def hdlock_can_plant() -> Plant:
    return plant(can_bus(hdlock_can("gate-1", 11)))


def scu_plant() -> Plant:
    return plant(scu_line())


def electrak_plant() -> Plant:
    return plant(electrak_bus(bitrate=None))


def m3io_plant() -> Plant:
    return plant(can_bus(device("heater-hmr", "m3io", "can3", variant="HMR", sw1=0xCA, master="always"),
                         name="can3", bitrate=500000))


NOT_MOVED = "its page still reads adapters or info (tests/app/test_layering.py STORE_ONLY_PENDING)"
FAMILIES = [
    pytest.param("mo64", "gate", mo64_plant, id="mo64"),
    pytest.param("hdlock", "door-1", hdlock_plant, id="hdlock"),
    pytest.param("hdlock", "gate-1", hdlock_can_plant, id="hdlock-can"),
    pytest.param("electrak", "lift", electrak_plant, id="electrak"),
    pytest.param("m3io", "heater-hmr", m3io_plant, id="m3io"),
    pytest.param("scu", "lift", scu_plant, id="scu"),
]


def record_reads(state, monkeypatch) -> set[str]:
    """The names the page reads from ``state`` from now on."""
    read: set[str] = set()
    for method in ("live", "point", "entry"):
        original = getattr(state, method)

        def reading(name, *args, _original: Callable = original, **kwargs):
            read.add(name)
            return _original(name, *args, **kwargs)

        monkeypatch.setattr(state, method, reading)
    return read


@pytest.mark.parametrize(("device_type", "device", "plant"), FAMILIES)
async def test_api_and_mqtt_carry_every_value_the_page_shows(device_type, device, plant, monkeypatch):
    runtime = Runtime(plant(), simulate=True)
    async with simulated_user(runtime) as user:
        state = runtime.store.devices[device]
        assert state.type == device_type
        read = record_reads(state, monkeypatch)
        await user.open(f"/device/{device}")
        assert read, "the page read nothing from the store"
        # every value the page reads is published (the page shows it, not '-')
        await eventually(lambda: all(state.points.get(n) is not None or state.live(n) is not None for n in read),
                         timeout=45, what=f"published: {sorted(n for n in read if state.live(n) is None)}")
        shown = sorted(read)
        api = (await user.http_client.get(f"/api/devices/{device}")).json()
        now = time.time()
        mqtt = state_payload(state, "cab", now)["values"]
        status = status_payload(state, "cab", now)
        missing_api = [n for n in shown if n not in api["values"]]
        missing_mqtt = [n for n in shown if n not in mqtt]
        assert missing_api == [] and missing_mqtt == []
        for name in shown:  # one shape: the same keys; the value of a fact read once is the same in both
            assert set(mqtt[name]) <= set(api["values"][name]), name
            point = state.points.get(name)
            same_reading = api["values"][name].get("time") == mqtt[name].get("time")  # not changed between the two
            if point is not None and not point.periodic and same_reading:
                assert api["values"][name]["value"] == mqtt[name]["value"], name
        for key in ("status", "last_error", "counters"):  # the page's badge, error line and counter line
            assert key in api and key in status, key
        assert set(api["counters"]) == set(status["counters"])
        assert {"Error memory levels", "Levels set by this tool", "Connection", "Gate state"} <= read or device_type != "mo64"
        levels = api["values"].get("Error memory levels") if device_type == "mo64" else None
        assert levels is None or all(set(e) == {"level", "flags", "timestamp_h"} for e in levels["value"])
