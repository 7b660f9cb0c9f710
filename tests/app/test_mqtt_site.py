"""A site of two ``commission`` instances publishing to one Mosquitto and a third running ``commission view``.

Instance ``cab-a`` runs the demo plant (every device type); ``cab-b`` one HD-Lock line whose twin
runs in a ``commission sim`` process of its own, so the test can take the device away. The
view's API must show both plants' devices with live values, a device going offline within
``OFFLINE_BOUND_S``, and the devices of a SIGKILLed instance as vanished through its last will.
"""

from __future__ import annotations

import asyncio
import json
import os
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import aiomqtt
import pytest
from plants import modbus_line, plant_text
from test_mqtt_helpers import running_broker
from webutil import ROOT, demo_plant_text, free_port, stop_app, wait_http

pytestmark = pytest.mark.timeout(90)

# the adapter's offline verdict (timeout 0.2 s, no retry) + one sampling period (0.5 s) + the broker hop
OFFLINE_BOUND_S = 3.0
VANISH_BOUND_S = 2.0  # the broker sends the last will when the dead instance's socket closes

def plant_b(broker_url: str) -> str:
    """Instance B of the site: one simulated lock, published to the broker at ``broker_url``."""
    return plant_text(modbus_line((("door-9", 1),), name="line9", poll_period=0.2), name="cab-b",
                      head=f'[mqtt]\nurl = "{broker_url}"\nsite = "hall-3"\nheartbeat = 2\n\n')


def _spawn(args: list[str], log: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "NICEGUI_STORAGE_PATH": str(log.parent / f"{log.stem}-storage")}
    env.pop("NICEGUI_USER_SIMULATION", None)
    env.pop("PYTEST_CURRENT_TEST", None)
    with open(log, "wb") as out:
        return subprocess.Popen([sys.executable, "-m", "app.cli", *args], cwd=ROOT, env=env, stdout=out,
                                stderr=subprocess.STDOUT, start_new_session=True)


def _site(view: str) -> dict:
    with urllib.request.urlopen(f"{view}/api/site", timeout=2) as response:
        return json.load(response)


def _devices(view: str) -> dict[str, dict]:
    return {d["name"]: d for s in _site(view)["sites"] for d in s["devices"]}


def _until(check, timeout: float, what: str):
    end = time.monotonic() + timeout
    while True:
        try:
            result = check()
            if result:
                return result
        except (AssertionError, KeyError, OSError):
            if time.monotonic() > end:
                raise
        if time.monotonic() > end:
            raise AssertionError(f"not within {timeout} s: {what}")
        time.sleep(0.1)


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    folder = tmp_path_factory.mktemp("site")
    with running_broker(folder, free_port()) as broker:
        a = demo_plant_text(free_port()).replace('name = "demo"', f'name = "cab-a"\n\n[mqtt]\nurl = "{broker.url}"\nsite = "hall-3"\nheartbeat = 2', 1)
        (folder / "a.toml").write_text(a)
        (folder / "b.toml").write_text(plant_b(broker.url))
        ports = {"a": free_port(), "b": free_port(), "view": free_port()}
        procs = {
            "sim-b": _spawn(["sim", "--plant", str(folder / "b.toml")], folder / "sim-b.log"),
            "a": _spawn(["--plant", str(folder / "a.toml"), "--port", str(ports["a"]), "--data-dir", str(folder / "da")], folder / "a.log"),
            "b": _spawn(["--plant", str(folder / "b.toml"), "--no-sim", "--port", str(ports["b"]), "--data-dir", str(folder / "db")],
                        folder / "b.log"),
            "view": _spawn(["view", "--broker", broker.url, "--port", str(ports["view"])], folder / "view.log"),
        }
        try:
            view = f"http://127.0.0.1:{ports['view']}"
            wait_http(f"{view}/api/site", procs["view"])
            yield {"broker": broker, "procs": procs, "view": view, "folder": folder, "ports": ports}
        finally:
            for proc in procs.values():
                stop_app(proc)


def test_view_shows_both_plants_devices_with_live_values(site):
    view = site["view"]

    def both_live():
        devices = _devices(view)
        for name in ("door-1", "lift", "heater-hm", "lift-1", "barrier-in", "door-9"):
            assert name in devices, f"{name} not in the view yet"
        assert devices["door-9"]["instance"] == "cab-b" and devices["door-1"]["instance"] == "cab-a"
        for name in ("door-1", "door-9"):
            assert devices[name]["view_status"] == "online", devices[name]["view_status"]
            assert isinstance(devices[name]["values"]["BoltPosition"]["value"], int)
        return devices

    try:
        _until(both_live, 30, "both instances' devices live in the view")
    except AssertionError as exc:  # say what the instances said, so a failure under load can be read afterwards
        logs = {n: (site["folder"] / f"{n}.log").read_text(errors="replace")[-1500:] for n in ("a", "b", "sim-b", "view")
                if (site["folder"] / f"{n}.log").exists()}
        raise AssertionError(f"{exc}; {site['procs']['b'].poll()=}; logs: {logs}") from None
    snap = _site(view)
    assert [s["site"] for s in snap["sites"]] == ["hall-3"]
    assert {i["name"]: i["state"] for i in snap["sites"][0]["instances"]} == {"cab-a": "online", "cab-b": "online"}
    assert snap["broker"]["connected"]
    with urllib.request.urlopen(f"{view}/", timeout=5) as page:  # the page is served too
        assert page.status == 200


async def _state_messages(port: int, timeout: float = 15.0) -> dict[str, dict]:
    """The newest state payload of one device per type, {type: payload}, once each carries its expected values."""
    found: dict[str, dict] = {}
    names = {name: t for t, (name, _values) in EXPECTED.items()}
    async with aiomqtt.Client("127.0.0.1", port) as client:
        await client.subscribe("commission/hall-3/+/state")
        try:
            async with asyncio.timeout(timeout):
                async for message in client.messages:
                    data = json.loads(message.payload)
                    if data["device"] in names:
                        found[data["type"]] = data
                    if len(found) == len(EXPECTED) and all(set(EXPECTED[t][1]) <= set(p["values"]) for t, p in found.items()):
                        return found
        except TimeoutError:
            pass
    return found


EXPECTED = {  # one device of each type in the demo plant, and values its payload must carry (docs/mqtt.md)
    "hdlock": ("door-1", {"BoltPosition": int, "LockStatus": int}),
    "m3io": ("heater-hm", {"E1": bool, "TEMP1": (float, type(None))}),
    "electrak": ("lift", {"Position": (float, int), "Devices heard": int}),
    "scu": ("lift-1", {"Session": str}),
    "mo64": ("barrier-in", {"Serial number": int}),
}


@pytest.mark.parametrize("device_type", list(EXPECTED))
def test_payload_schema_per_device_type(site, device_type):
    _until(lambda: "barrier-in" in _devices(site["view"]), 30, "the demo instance publishes")
    found = asyncio.run(_state_messages(site["broker"].port))
    payload = found[device_type]
    name, values = EXPECTED[device_type]
    assert set(payload) == {"schema", "version", "instance", "device", "type", "bus", "status", "time", "values"}
    assert (payload["schema"], payload["version"], payload["instance"], payload["device"]) == ("commission-state", 1, "cab-a", name)
    assert payload["status"] in ("online", "stale", "offline", "unknown")
    for item in payload["values"].values():
        assert {"value", "unit", "quality", "time", "text"} <= set(item)
        assert item["quality"] in ("good", "stale", "offline", "unknown")
    for key, typ in values.items():
        assert key in payload["values"], f"{key} missing in {sorted(payload['values'])}"
        value = payload["values"][key]["value"]
        assert isinstance(value, typ), (key, value)


def test_device_going_offline_shows_offline_in_the_view(site):
    view = site["view"]
    _until(lambda: _devices(view)["door-9"]["view_status"] == "online", 30, "door-9 online")
    gone = time.monotonic()
    stop_app(site["procs"]["sim-b"])  # the twin of door-9 goes away: its line stays silent
    _until(lambda: _devices(view)["door-9"]["view_status"] == "offline", OFFLINE_BOUND_S + 5, "door-9 offline in the view")
    took = time.monotonic() - gone
    print(f"door-9 offline in the view {took:.2f} s after its twin stopped")
    assert took <= OFFLINE_BOUND_S
    assert _devices(view)["door-1"]["view_status"] == "online"  # the other instance is not affected


def test_sigkill_of_an_instance_marks_its_devices_vanished(site):
    view = site["view"]
    _until(lambda: _devices(view)["door-1"]["view_status"] == "online", 30, "door-1 online")
    killed = time.monotonic()
    os.killpg(site["procs"]["a"].pid, signal.SIGKILL)
    site["procs"]["a"].wait(timeout=5)

    def vanished():
        devices = _devices(view)
        return all(d["view_status"] == "vanished" for d in devices.values() if d["instance"] == "cab-a")

    _until(vanished, VANISH_BOUND_S + 5, "cab-a's devices vanished")
    assert time.monotonic() - killed <= VANISH_BOUND_S
    snap = _site(view)
    insts = {i["name"]: i for i in snap["sites"][0]["instances"]}
    assert insts["cab-a"]["state"] == "vanished" and "last will" in insts["cab-a"]["reason"]
    assert insts["cab-b"]["state"] == "online"
