"""Declared tiles (devices/registry.py TileSpec) and the quality marking of live values.

The first part evaluates each device type's declaration against hand-made points (pure);
the second renders the plant view, the overview and device pages with NiceGUI's simulated
user against the demo plant's twins, and stops twins to see the marking turn stale/offline.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from dataclasses import dataclass

import pytest
from nicegui import ui
from nicegui.testing import User
from webutil import demo_user, eventually

from app.runtime import Runtime
from devices.m3io import codec as m3io_codec
from devices.registry import DEVICE_TYPES, TileSpec

NOW = 1_000_000.0


def point(value, *, quality="good", time=NOW - 0.2, text=None, unit="", name=None, fields=None) -> dict:
    entry = {"value": value, "unit": unit, "time": time, "quality": quality, "raw": None, "text": text}
    if name is not None:
        entry["name"] = name
    if fields is not None:
        entry["fields"] = fields
    return entry


def evaluate(type_name: str, points: dict) -> dict:
    spec: TileSpec = DEVICE_TYPES[type_name].tile
    return spec.evaluate(points.get, NOW)


# -- declarations, evaluated (pure) ---------------------------------------------------------------


def lock_points(**status) -> dict:
    fields = {"BoltLocked": 0, "BoltUnlocked": 0, "BoltMovingOut": 0, "BoltMovingIn": 0, "ProximityOverrange": 0} | status
    return {
        "DoorState": point(3, name="door closed", text="door closed"),
        "LockStatus": point(0, fields=fields),
        "StateMachineState": point(4, name="Locked"),
        "BoltPosition": point(115, unit="Inc"),
    }


def test_hdlock_tile_door_bolt_bar_and_alarms():
    tile = evaluate("hdlock", lock_points(BoltLocked=1))
    assert tile["lines"] == ["door closed", "bolt locked"] and tile["icon"] == "lock"
    assert tile["bar"] == (1.0, "bolt 115 Inc") and tile["alarms"] == [] and tile["quality"] == "good"
    points = lock_points(BoltMovingIn=1, ProximityOverrange=1)
    points["StateMachineState"] = point(9, name="ErrorMotorBlocked")
    tile = evaluate("hdlock", points)
    assert tile["lines"][1] == "bolt moving" and tile["icon"] == "sync"
    assert tile["alarms"] == ["ErrorMotorBlocked", "hall sensors overdriven (magnet)"]
    tile = evaluate("hdlock", {})
    assert tile["lines"] == ["door: unknown", "bolt: unknown"] and tile["bar"] is None and tile["quality"] == "unknown"


def electrak_points(controlled_by=None, **flags) -> dict:
    names = ["Extending", "Retracting", "Parameter", "Current overload", "Voltage", "Temperature", "Backdrive",
             "Message timeout", "Severe fault", "Too few devices"]
    points = {n: point(bool(flags.get(n.replace(" ", "_").lower()))) for n in names}
    points.update({
        "Position": point(150.0, unit="mm"), "Stroke": point(300.0, unit="mm"),
        "Devices heard": point(2), "Devices configured": point(2),
        "Controlled by": point(controlled_by, text=None if controlled_by else "nobody"),
    })
    return points


def test_electrak_timeout_flag_is_no_alarm_while_nobody_controls():
    tile = evaluate("electrak", electrak_points(message_timeout=True))
    assert tile["alarms"] == [] and tile["lines"][0] == "idle (no controller)"
    assert tile["bar"] == (0.5, "150.0 of 300 mm") and tile["icon"] == "height"
    tile = evaluate("electrak", electrak_points("engineer", message_timeout=True, extending=True, backdrive=True))
    assert tile["alarms"] == ["Backdrive", "Message timeout"] and tile["lines"][0] == "moving: extending"
    assert "actuators heard: 2" in tile["lines"]


def test_m3io_outputs_faults_variant_and_bit_rate():
    points = {"LED": point(True), "SSR1": point(False), "SSR4": point(True),
              "SSR2 Si": point("blown"), "SSR5 Triac": point("defective"), "SSR1 Si": point("ok"),
              "Variant check": point("mismatch", text="variant mismatch: HMR on the bus, HM in the plant file"),
              "Bit rate check": point("mismatch", text="bit rate mismatch: module 500 kbit/s, bus 250 kbit/s")}
    tile = evaluate("m3io", points)
    assert tile["lines"] == ["outputs on: LED, SSR4"]
    assert tile["alarms"] == ["variant mismatch: HMR on the bus, HM in the plant file",
                              "bit rate mismatch: module 500 kbit/s, bus 250 kbit/s", "SSR2 fuse blown", "SSR5 triac defective"]
    points = {"SSR1-3": point(True), "SSR1-3 load check": point("fault", text="SSR1-3: 2 phases carry a load, 3 expected"),
              "Bit rate check": point("ok", text="500 kbit/s")}
    tile = evaluate("m3io", points)
    assert tile["lines"] == ["outputs on: SSR1-3"] and tile["alarms"] == ["SSR1-3: 2 phases carry a load, 3 expected"]
    assert evaluate("m3io", {"LED": point(False)})["lines"] == ["outputs on: none"]


def test_tile_quality_is_the_worst_of_its_points_and_age_the_oldest():
    points = lock_points(BoltLocked=1)
    points["BoltPosition"] = point(100, quality="stale", time=NOW - 12)
    tile = evaluate("hdlock", points)
    assert tile["quality"] == "stale" and tile["age"] == pytest.approx(12)
    points["DoorState"] = point(3, name="door closed", quality="offline", time=NOW - 30)
    assert evaluate("hdlock", points)["quality"] == "offline"


# -- rendered against the demo plant's twins ---------------------------------------------------------


@dataclass
class Env:
    user: User
    runtime: Runtime


@pytest.fixture
async def env(tmp_path) -> AsyncIterator[Env]:
    async with demo_user(tmp_path, f"tiles-{tmp_path.name}") as (user, runtime):
        yield Env(user, runtime)


def texts(user: User, prop: str, value: str) -> list[str]:
    """The label texts inside the element whose ``prop`` is ``value``."""
    found = [e for e in user.client.elements.values() if e.props.get(prop) == value]
    assert len(found) == 1, f"{prop}={value}: {len(found)} elements"
    return [e.text for e in found[0].descendants() if isinstance(e, ui.label | ui.badge)]


def quality_of(user: User, prop: str, value: str) -> str | None:
    found = [e for e in user.client.elements.values() if e.props.get(prop) == value]
    assert len(found) == 1, f"{prop}={value}: {len(found)} elements"
    return found[0].props.get("data-quality")


@pytest.mark.timeout(60)
async def test_plant_view_tiles_from_declarations_then_offline(env: Env):
    user = env.user
    await user.open("/plant")
    await user.should_see("Plant demo")

    def lines_shown() -> None:
        assert {"Door open", "bolt unlocked"} <= set(texts(user, "data-plant-tile", "door-1"))
        assert "bolt locked" in texts(user, "data-plant-tile", "door-2")
        assert "bolt locked" in texts(user, "data-plant-tile", "gate-2")
        lift = texts(user, "data-plant-tile", "lift")
        assert "idle (no controller)" in lift and "actuators heard: 2" in lift, lift
        assert any(t.endswith("of 300 mm") for t in lift), lift
        assert "⚠ Message timeout" not in lift  # nobody controls: the timeout flag is no alarm
        for heater in ("heater-hm", "heater-hmr"):
            assert "outputs on: none" in texts(user, "data-plant-tile", heater)
        for name in ("door-1", "lift", "heater-hm"):
            assert quality_of(user, "data-plant-tile", name) == "good"

    await eventually(lines_shown, timeout=15, what="declared tile lines")
    # a fault on an SSR channel raises the tile's alarm
    adapter, twin = env.runtime.worker.adapters["heater-hm"], env.runtime.twins["heater-hm"]

    def alive_and(check):  # the session that switched the output on confirms it is alive (dead-man)
        def probe():
            env.runtime.worker.heartbeat("test")
            return check()
        return probe

    env.runtime.worker.heartbeat("test")
    await adapter.take_control("test", "engineer")  # switching on needs control of the module
    adapter.set_output("test", "SSR2", True)
    await eventually(alive_and(lambda: adapter.channels[2].triac == "ok"), timeout=5, interval=0.05, what="SSR2 on")
    twin.ssr[2].fuse_ok = False  # the module latches Si = 0 until its 24 V are cut (7.2.3)
    await eventually(alive_and(lambda: "⚠ SSR2 fuse blown" in texts(user, "data-plant-tile", "heater-hm")), timeout=10, what="fuse alarm")
    adapter.set_output("test", "SSR2", False)

    # twins stop: their tiles are marked, with the age, and show no alarms of old data
    env.runtime.twins["door-1"].silent = True
    env.runtime.twins["heater-hm"].powered = False
    for index in range(len(env.runtime.twins["lift"].actuators)):
        env.runtime.twins["lift"].remove(index)

    def marked() -> None:
        for name in ("door-1", "lift", "heater-hm"):
            assert quality_of(user, "data-plant-tile", name) in ("stale", "offline"), name
        assert quality_of(user, "data-plant-tile", "door-2") == "good"
        assert not any(t.startswith("⚠") for t in texts(user, "data-plant-tile", "heater-hm"))

    await eventually(marked, timeout=10, what="stopped twins marked")
    await eventually(lambda: all(quality_of(user, "data-plant-tile", n) == "offline" for n in ("door-1", "lift", "heater-hm")),
                     timeout=10, what="offline")
    assert any(t.startswith("no answer, last heard") for t in texts(user, "data-plant-tile", "lift"))  # beside OFFLINE


@pytest.mark.timeout(60)
async def test_overview_tiles_and_device_pages_mark_stale_values(env: Env):
    user = env.user
    await user.open("/")
    await user.should_see("Overview")
    await eventually(lambda: "bolt locked" in texts(user, "data-device", "door-2") and
                     "idle (no controller)" in texts(user, "data-device", "lift"), timeout=15, what="overview tile lines")
    await eventually(lambda: env.runtime.store.devices["heater-hmr"].status == "online", timeout=15, what="heater-hmr online")
    env.runtime.twins["heater-hmr"].powered = False

    def heater_marked() -> None:
        card = [e for e in user.client.elements.values() if e.props.get("data-device") == "heater-hmr"][0]
        values = [e for e in card.descendants() if "data-tile-values" in e.props][0]
        assert values.props.get("data-quality") == "offline"
        assert any(t.startswith("offline, last") for t in texts(user, "data-device", "heater-hmr"))

    await eventually(heater_marked, timeout=10, what="overview tile offline")

    # the M3IO page: an out-of-range temperature carries its unit; a stopped module greys the values
    env.runtime.twins["heater-hm"].set_temperature(4, -5.0)
    await user.open("/device/heater-hm")
    await user.should_see("CAN-M3IO heater-hm (HM)")
    temp4 = [e for e in user.client.elements.values() if e.props.get("data-temp") == "4"][0]
    await eventually(lambda: temp4.text == "out of range (-5.0 °C)", timeout=10, what="TEMP4 out of range with its unit")
    assert quality_of(user, "data-temp", "1") == "good"
    env.runtime.twins["heater-hm"].powered = False
    await eventually(lambda: quality_of(user, "data-temp", "1") in ("stale", "offline") and quality_of(user, "data-lamp", "E1")
                     in ("stale", "offline"), timeout=10, what="M3IO page values marked")

    # the HD-Lock page: lamps, enum values and register rows
    await user.open("/device/door-1")
    await user.should_see("HD-Lock door-1")
    await eventually(lambda: quality_of(user, "data-lamp", "BoltUnlocked") == "good", timeout=10, what="lock values good")
    env.runtime.twins["door-1"].silent = True
    await eventually(lambda: quality_of(user, "data-lamp", "BoltUnlocked") in ("stale", "offline")
                     and quality_of(user, "data-value", "DoorState") in ("stale", "offline"), timeout=10, what="lock values marked")
    table = [e for e in user.client.elements.values() if isinstance(e, ui.table)][0]
    await eventually(lambda: all(r["quality_class"] in ("q-stale", "q-offline") for r in table.rows if r["raw"] != "-"),
                     timeout=10, what="register rows marked")


def test_temperature_text_has_the_unit_in_the_monitor_wording():
    from pages.m3io import temp_text

    hm, hmr = m3io_codec.Variant.HM, m3io_codec.Variant.HMR
    below = m3io_codec.TempWord.make(-50, False, False, False, False)
    assert not below.in_range
    assert temp_text(hm, 4, below) == "out of range (-5.0 °C)"
    assert f"TEMP4 {temp_text(hm, 4, below)}" in m3io_codec.describe_temp(hm, 4, below)  # the monitor's words
    assert temp_text(hmr, 1, m3io_codec.TempWord.make(215, True, True, True, False)) == "21.5 °C"


async def test_overview_says_when_a_bus_sheds_frames(env: Env):
    user = env.user
    env.runtime.store.buses["can1"].shed = 42  # the reader had to drop frames under a flood
    await user.open("/")
    await user.should_see("42 frames shed: more traffic than this program can handle", retries=30)
