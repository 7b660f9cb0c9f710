"""Overview and plant-view tiles: the freshest source of a value, M3IO temperatures, counters that fit the bus."""

from __future__ import annotations

import time
from types import SimpleNamespace

from app.plant import DeviceConfig
from devices.hdlock import STATUS_FRAME_BOLT, codec
from devices.hdlock.can_adapter import HdLockCanAdapter
from devices.live import DeviceState
from devices.registry import DEVICE_TYPES
from pages.overview import counters_text

NOW = 1_000_000.0


def point(value, *, time=NOW - 0.2, text=None, unit="", fields=None, name=None) -> dict:
    entry = {"value": value, "unit": unit, "time": time, "quality": "good", "raw": None, "text": text}
    if fields is not None:
        entry["fields"] = fields
    if name is not None:
        entry["name"] = name
    return entry


def test_lock_bar_shows_the_status_frame_when_it_is_fresher_than_the_register_poll():
    spec = DEVICE_TYPES["hdlock"].tile
    polled = {"BoltPosition": point(0, time=NOW - 1.9, unit="Inc")}
    assert spec.evaluate(polled.get, NOW)["bar"] == (0.0, "bolt 0 Inc")  # a Modbus lock: the register
    heard = polled | {STATUS_FRAME_BOLT: point(115, time=NOW - 0.05, unit="Inc")}
    assert spec.evaluate(heard.get, NOW)["bar"] == (1.0, "bolt 115 Inc")
    older = polled | {STATUS_FRAME_BOLT: point(115, time=NOW - 2.5, unit="Inc")}
    assert spec.evaluate(older.get, NOW)["bar"] == (0.0, "bolt 0 Inc")  # the newest value wins, whatever its source


class FakeCanBus:
    name = "can1"
    options = {"bitrate": 250_000}

    def __init__(self):
        self.handlers = {}

    def subscribe(self, is_extended, arbitration_id, handler):
        self.handlers[(is_extended, arbitration_id)] = handler


def test_can_lock_publishes_motor_pos_of_each_status_frame_with_its_arrival_time():
    bus = FakeCanBus()
    state = DeviceState("gate-1", "hdlock", "can1")
    HdLockCanAdapter(DeviceConfig("gate-1", "hdlock", "can1", {"device_id": 660100}), state, bus)
    handler = bus.handlers[(True, 660100)]
    arrived = time.time() - 0.3
    handler(SimpleNamespace(data=codec.encode_status(codec.StatusFrame(0x0117, 57, 20, 4)), timestamp=arrived))
    entry = state.entry(STATUS_FRAME_BOLT)
    assert entry["value"] == 57 and entry["time"] == arrived and entry["unit"] == "Inc"
    assert state.counters.responses == 1  # a frame heard
    handler(SimpleNamespace(data=codec.encode_status(codec.StatusFrame(0x0117, 58, 20, 4)), timestamp=0.0))
    assert state.entry(STATUS_FRAME_BOLT)["value"] == 58
    assert abs(state.entry(STATUS_FRAME_BOLT)["time"] - time.time()) < 1  # no usable interface time: now
    tile = DEVICE_TYPES["hdlock"].tile.evaluate(state.entry, time.time())
    assert tile["bar"][1] == "bolt 58 Inc"


def test_m3io_tile_lists_the_temperatures_heard():
    spec = DEVICE_TYPES["m3io"].tile
    points = {"LED": point(False), "TEMP1": point(21.5, unit="°C", text="21.5 °C"),
              "TEMP4": point(None, unit="°C", text="out of range (-5.0)")}
    lines = [line.replace("\u00a0", " ") for line in spec.evaluate(points.get, NOW)["lines"]]
    assert lines == ["outputs on: none", "T1 21.5 °C · T4 out of range (-5.0)"]
    assert spec.evaluate({"LED": point(False)}.get, NOW)["lines"] == ["outputs on: none"]  # a KM: no temperature line


def test_tile_counters_mean_something_on_the_devices_bus():
    counters = {"requests": 0, "responses": 412, "timeouts": 0, "crc_errors": 0, "exceptions": 0, "write_errors": 0,
                "malformed": 1}
    can = counters_text(counters, "can", 0.2)
    assert "req" not in can and "timeouts" not in can and "CRC" not in can
    assert can == "frames heard 412 · malformed 1 · last frame just now"
    assert "timeouts 3" in counters_text(counters | {"timeouts": 3}, "can", 0.2)  # register reads of a CAN lock that failed
    for bus_type in ("modbus-rtu", "serial", "logited-tcp", "logited-rs485"):
        text = counters_text(counters | {"requests": 168, "timeouts": 2, "crc_errors": 1}, bus_type, 3.0)
        assert text.startswith("req 168 · timeouts 2 · CRC 1") and "frames heard" not in text and text.endswith("last answer 3 s ago")


def test_an_overview_tile_says_the_bar_s_quantity_once():
    """An MO 64's tile: "0 % open" on its bar, not "position: 0 %" beside it (issue 42 item 13)."""
    from pages.plant_view import fresh_evaluate_tile

    points = {"Position": point(0, unit="%", text="0 %"), "Gate state": point(5, text="closed")}
    state = SimpleNamespace(type="mo64", online=True, entry=lambda name, now: points.get(name))
    tile = fresh_evaluate_tile(state)
    assert tile["bar"] == (0.0, "0 % open")
    assert not any("position" in line for line in tile["lines"]), tile["lines"]
    points.pop("Position")  # no position heard: no bar, and no line of it either
    assert fresh_evaluate_tile(state)["bar"] is None
