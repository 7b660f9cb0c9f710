"""The plant view's words for an operator (issue 32.10): the store's own texts without codes and diagnoses."""

from __future__ import annotations

from pages.plant_view import operator_words, state_words


def _entry(value, text=None, name=None, unit=""):
    return {"value": value, "text": text, "name": name, "unit": unit, "quality": "good", "time": 0.0}


def test_a_bit_set_loses_its_code_and_underscores():
    words = operator_words(_entry(7, "0x7: mains, battery, charger_on"))
    assert words["text"] == "mains, battery, charger on"
    assert words["value"] == 7  # conditions of the tile still see the value


def test_a_state_word_loses_the_engineers_diagnosis():
    text = "lost: CRC 0x5100 received, 0xEE5B computed: 43 06 00 00 51"
    assert operator_words(_entry("lost", text))["text"] == "lost"
    assert operator_words(_entry("open", "open"))["text"] == "open"


def test_an_enum_shows_its_name_not_its_number():
    assert operator_words(_entry(1, "Door open (1)", name="Door open"))["text"] == "Door open"


def test_other_texts_are_kept():
    text = "bit rate mismatch: module 250 kbit/s, bus 500 kbit/s"
    assert operator_words(_entry("mismatch", text))["text"] == text
    assert operator_words(None) is None


def test_offline_and_stale_say_so_before_any_fault():
    assert state_words("offline", ["x"], None)[:2] == ("offline", "OFFLINE")
    assert "never heard" in state_words("offline", [], None)[2]
    assert state_words("stale", [], 63.0)[1:] == ("STALE", "last heard 63 s ago")
    assert state_words("good", ["hall sensors overdriven (magnet)"], 0.0)[:2] == ("fault", "FAULT")
    assert state_words("good", [], 0.0)[:2] == ("good", "live")


def test_an_alarm_the_store_found_is_worded_from_its_declaration_and_fields():
    """The plant view words what the store found (app/state.py RaisedAlarm); it evaluates no alarm itself."""
    from app.state import RaisedAlarm
    from devices.registry import TileAlarm, When
    from pages.plant_view import alarm_words

    bare = TileAlarm(When("CAN link", ("lost",)), "{text}")
    found = RaisedAlarm(bare, _entry("lost", "lost: CRC 0x5100 received"), "lost: CRC 0x5100 received")
    assert alarm_words(found) == "CAN link: lost"  # a bare state word, named by its point, without the diagnosis
    named = TileAlarm(When("StateMachineState", of="name", prefix="Error"), "{name}")
    assert alarm_words(RaisedAlarm(named, _entry(9, "ErrorMotorBlocked (9)", name="ErrorMotorBlocked"),
                                   "ErrorMotorBlocked")) == "ErrorMotorBlocked"
