"""The one live record (devices/live.py LiveValue), its JSON form, facts, history by point name, and the
declared simulation controls (devices/simcontrols.py)."""

from __future__ import annotations

import enum
import json
import math
from dataclasses import dataclass

import pytest

from devices.live import DeviceState, LiveValue, json_fields, jsonable, session_tag
from devices.params import Access, Param, ParamMap
from devices.simcontrols import SimAction, SimControls, SimParam


@dataclass(frozen=True, slots=True)
class Level:
    level: int
    flags: int


class Colour(enum.IntEnum):
    RED = 3


def test_jsonable_turns_records_and_odd_values_into_json():
    value = {"levels": (Level(0, 0x12), Level(1, 0)), "b": b"\x01\xff", "s": {3, 1}, "e": Colour.RED,
             "nan": math.nan, "inf": -math.inf, "n": None, "t": True, "f": 1.5}
    assert jsonable(value) == {"levels": [{"level": 0, "flags": 18}, {"level": 1, "flags": 0}], "b": "01 ff",
                               "s": [1, 3], "e": 3, "nan": None, "inf": None, "n": None, "t": True, "f": 1.5}
    json.dumps(jsonable(value), allow_nan=False)
    assert jsonable(object()).startswith("<object")


def test_a_point_reads_as_one_live_value_in_every_form():
    state = DeviceState("d", "t", "b")
    state.online = True
    state.publish("Error memory levels", (Level(0, 5),), text="1 level", periodic=False)
    live = state.live("Error memory levels")
    assert isinstance(live, LiveValue) and live.name == "Error memory levels" and live.quality == "good"
    assert live.value == (Level(0, 5),) and live.shown == "1 level"
    assert state.point("Error memory levels") == live.entry() == state.entry("Error memory levels")
    assert set(live.entry()) == {"value", "unit", "time", "quality", "raw", "text"}
    assert state.values_json()["Error memory levels"] == {
        "value": [{"level": 0, "flags": 5}], "unit": "", "time": live.time, "quality": "good", "raw": None, "text": "1 level"}
    with pytest.raises(AttributeError):
        live.value = 1  # frozen


def test_a_register_parameter_reads_as_a_live_value_with_its_register_keys():
    param = Param("Mode", "holding", 3000, access=Access.RW, enum={0: "off", 1: "on"})
    state = DeviceState("d", "t", "b", params=ParamMap([param]))
    state.online = True
    state.update_registers("holding", 3000, [1])
    live = state.live("Mode")
    assert (live.value, live.raw, live.enum, live.address, live.space, live.access) == (1, 1, "on", 3000, "holding", "RW")
    entry = state.entry("Mode")
    assert entry["name"] == "on" and entry["address"] == 3000 and "fields" not in entry
    assert state.values_json()["Mode"]["name"] == "on"


def test_the_json_form_is_declared_once_and_the_api_model_is_made_from_it():
    keys = [key for key, *_ in json_fields()]
    assert keys[:6] == ["value", "unit", "time", "quality", "raw", "text"]
    assert {"name", "fields", "address", "space", "access"} <= set(keys)
    from app.web import Value

    assert list(Value.model_fields) == keys
    assert Value.model_fields["quality"].is_required()


def test_a_fact_is_published_only_when_it_changes():
    state = DeviceState("d", "t", "b")
    state.fact("Connection", "connected")
    version, first = state.version, state.points["Connection"].time
    state.fact("Connection", "connected")
    assert state.version == version and state.points["Connection"].time == first
    state.fact("Connection", "released")
    assert state.version > version and state.live("Connection").value == "released"
    assert not state.points["Connection"].periodic  # a fact does not age


def test_history_recorded_by_point_name():
    state = DeviceState("d", "t", "b")
    state.publish("Position", 42, "%")
    state.record_history(("Position", "never published"), now=1000.0)
    assert list(state.history) == [(1000.0, {"Position": 42})]


def test_session_tag_hides_the_session_id():
    tag = session_tag("a5c1-client-id")
    assert tag == session_tag("a5c1-client-id") and "client" not in tag and len(tag) == 12


def test_sim_controls_check_and_describe_their_arguments():
    calls = []
    controls = SimControls("Simulated thing", (
        SimAction("fault", "Fault", lambda flags: calls.append(flags), params=(SimParam("flags", "flags", 1, 1, 0xFF, hex=True),)),
        SimAction("barrier", "Barrier", lambda on: calls.append(on), state=lambda: False),
    ))
    assert controls.describe("fault", {"flags": "0x10"}) == "fault flags=0x10"
    controls.invoke("fault", {"flags": "0x10"})
    controls.invoke("fault")
    controls.invoke("barrier", {"on": True})
    assert calls == [0x10, 1, True]
    for bad in ({"flags": 0x100}, {"flags": "x"}, {"flags": 1.5}, {"other": 1}):
        with pytest.raises(ValueError):
            controls.invoke("fault", bad)
    with pytest.raises(ValueError):
        controls.invoke("barrier", {"on": "yes"})
    with pytest.raises(KeyError):
        controls.action("nothing")
