"""Electrak HD service telegrams: every actuator's answer, save forms, the bit-rate sequence, the timeout floor."""

from __future__ import annotations

import asyncio
from types import SimpleNamespace

import pytest
from conftest import wait_for
from test_electrak import lift  # noqa: F401 (fixture)

from devices.electrak import codec
from devices.electrak.adapter import CommandError
from devices.electrak.params import BITRATE_NAMES, PARAMS, TIMEOUT_MIN_MS, refusal

SOFT_START = PARAMS.by_name["Soft start time"]
BIT_RATE = PARAMS.by_name["Bit rate"]
TIMEOUT = PARAMS.by_name["Timeout"]

# -- golden vectors: the bit-rate table ("Wert / Baudrate") and its telegrams -------------------


@pytest.mark.parametrize(("code", "bitrate", "name"), [
    (0, 1_000_000, "1 Mbit/s"), (2, 500_000, "500 kbit/s"), (3, 250_000, "250 kbit/s"), (4, 125_000, "125 kbit/s"),
])
def test_bitrate_table(code, bitrate, name):
    assert codec.BITRATES[code] == bitrate and codec.bitrate_code(bitrate) == code
    assert BITRATE_NAMES[code] == name and BIT_RATE.display(code) == f"{name} ({code})"


def test_bitrate_table_has_no_value_1():
    assert 1 not in codec.BITRATES
    with pytest.raises(codec.CodecError, match="not one of"):
        codec.bitrate_code(800_000)
    with pytest.raises(ValueError, match="not one of"):
        BIT_RATE.validate(1)


@pytest.mark.parametrize(("message", "data"), [
    (codec.password_request(0x9A8B7C6D), "01 FF 04 00 6D 7C 8B 9A"),  # unlock bit rate and timeout
    (codec.write_request(0x04, 1, 3), "01 04 01 00 03 00 00 00"),  # bit rate 250 kbit/s
    (codec.read_request(0x04, 1), "00 04 01 00 00 00 00 00"),  # read it back
    (codec.ServiceMessage(codec.ServiceType.READ_RESPONSE, 0x04, 1, 2), "10 04 01 00 02 00 00 00"),  # 500 kbit/s
])
def test_bitrate_telegrams(message, data):
    assert message.encode() == bytes.fromhex(data)
    assert codec.ServiceMessage.decode(bytes.fromhex(data)) == message
    assert codec.ServiceMessage.decode(message.encode()).encode() == message.encode()


def test_save_forms():
    """The table's form first, the example's ("02 F0 01 ..." with 0x02 sent as 0x01, SPEC-NOTES) on WRONG_SIZE."""
    for length, data in ((4, "01 F0 04 00 00 00 00 00"), (1, "01 F0 01 00 00 00 00 00")):
        message = codec.save_request(length)
        assert message.encode() == bytes.fromhex(data)
        assert codec.ServiceMessage.decode(bytes.fromhex(data)) == message


def test_save_example_is_no_defined_type():
    example = codec.ServiceMessage.decode(bytes.fromhex("02 F0 01 00 00 00 00 00"))  # as printed
    assert example.type not in codec.ServiceType._value2member_map_ and example.specifier == codec.SAVE_SPECIFIER
    assert codec.SAVE_LENGTHS == (4, 1)  # the table's length first, the example's on WRONG_SIZE


# -- the parameters' own value type: 1 or 2 bytes, little-endian, in the payload ("Service-Telegramm") ------
@pytest.mark.parametrize(("name", "value", "data"), [
    ("Soft start time", 500, "F4 01"),  # the document's example: 0x01 0x01 0x02 0x00 0xF4 0x01 0x00 0x00
    ("Soft start time", 65535, "FF FF"),
    ("Soft stop distance", 12.3, "7B 00"),  # 0.1 mm units
    ("Soft stop distance", 25.6, "00 01"),
    ("Bit rate", 2, "02"),  # 500 kbit/s ("Wert / Baudrate")
    ("Bit rate", 4, "04"),
    ("Timeout", 250, "FA 00"),
    ("Timeout", 0x0102, "02 01"),
    ("Speed", 6553.5, "FF FF"),  # 0.1 mm/s units
    ("Speed", 1.1, "0B 00"),
])
def test_service_param_value_type_byte_table(name, value, data):
    param = PARAMS.by_name[name]
    vtype, wire = param.value_type, bytes.fromhex(data)
    assert vtype.size == int(param.extra["length"])
    assert vtype.decode(wire) == value
    assert vtype.encode(value) == wire
    assert vtype.encode(vtype.decode(wire)) == wire
    if param.enum is not None:
        assert vtype.decode(wire).name == param.enum[value]
    # the payload of a write request carries the same bytes from byte 4 on, zero-padded to 4 bytes
    raw = param.encode(value)
    assert codec.write_request(param.address, len(wire), raw).encode()[4:4 + len(wire)] == wire
    assert vtype.decode(codec.write_request(param.address, len(wire), raw).encode()[4:8], allow_excess=True) == value


def test_service_param_value_type_refuses_what_does_not_fit():
    with pytest.raises(ValueError, match="outside"):
        PARAMS.by_name["Timeout"].value_type.encode(65536)
    with pytest.raises(ValueError, match="not one of"):
        BIT_RATE.value_type.encode(1)  # no value 1 in the bit-rate table
    assert BIT_RATE.value_type.encode("250 kbit/s") == b"\x03"


# -- owns_frame: the bus monitor's device column and filter ("Das Netzwerk im Überblick") ---------------
class _QuietBus:
    """A CAN transport that records subscriptions and sends nothing."""

    name, options = "can-test", {"bitrate": 500_000}
    state = SimpleNamespace(connected=True, last_error="", reconnects=0)

    def subscribe(self, is_extended, arbitration_id, handler): ...
    def unsubscribe(self, is_extended, arbitration_id, handler): ...
    def send(self, arbitration_id, data, is_extended_id=False): return True
    def start_cyclic(self, key, period_s, make): ...
    def stop_cyclic(self, key): ...
    def cyclic_running(self, key): return False


@pytest.mark.parametrize(("arbitration_id", "is_extended", "owned"), [
    (codec.CONTROL_ID, False, True), (codec.STATUS_ID, False, True),
    (codec.SERVICE_REQUEST_ID, False, True), (codec.SERVICE_RESPONSE_ID, False, True),
    (0x600, False, True), (0x6FF, False, True),  # the actuators' internal traffic is the network's too
    (0x06, True, False), (0x07, True, False), (0x0A, True, False),  # extended IDs: not the SY2 protocol
    (0x05, False, False), (0x08, False, False), (0x0C, False, False), (0x5FF, False, False), (0x700, False, False),
])
def test_owns_frame(arbitration_id, is_extended, owned):
    from devices.electrak.adapter import ElectrakAdapter
    from devices.live import DeviceState

    config = SimpleNamespace(name="lift", options={"actuators": [{"model": "HD24", "gearing": "B026", "stroke_mm": 150}]})
    adapter = ElectrakAdapter(config, DeviceState("lift", "electrak", "can-test"), _QuietBus())
    assert adapter.owns_frame(arbitration_id, is_extended, bytes(8)) is owned
    assert adapter.owns_frame(arbitration_id, is_extended, b"") is owned  # the ID decides, not the payload


def test_answer_problems_in_words():
    read = codec.read_request(0x01, 2)
    ok = codec.ServiceMessage(codec.ServiceType.READ_RESPONSE, 0x01, 2, 300)
    other = codec.ServiceMessage(codec.ServiceType.READ_RESPONSE, 0x01, 2, 400)
    error = codec.ServiceMessage(codec.ServiceType.ERROR_RESPONSE, 0x01, 2, codec.ERROR_PERMISSION)
    assert codec.answer_problems(read, [ok, ok], 2) == []
    assert codec.answer_problems(read, [ok], 2) == ["1 of 2 actuators did not answer"]
    assert codec.answer_problems(read, [ok, ok, ok], 2) == ["3 answers, but 2 actuators are configured"]
    assert codec.answer_problems(read, [ok, other], 2) == ["the actuators disagree: answer 1: 300, answer 2: 400"]
    assert codec.answer_problems(read, [ok, error], 2) == ["answer 2: error INCORRECT_PERMISSION"]
    assert codec.belongs_to(read, error) and codec.belongs_to(read, ok)
    assert not codec.belongs_to(read, codec.ServiceMessage(codec.ServiceType.READ_RESPONSE, 0x02, 2, 300))


# -- every actuator's answer --------------------------------------------------------------------


async def test_read_reports_every_actuator(lift):  # noqa: F811
    _runtime, adapter, state, _twin = lift
    assert await adapter.read_param(SOFT_START) == 300
    report = next(r for r in state.live("Service reports").value if r.key == SOFT_START.key)
    assert report.ok and list(report.answers) == ["value 300", "value 300"]


async def test_read_fails_when_the_actuators_disagree(lift):  # noqa: F811
    _runtime, adapter, state, twin = lift
    twin.actuators[1].service.values[0x01] = 400
    with pytest.raises(CommandError, match="disagree.*300.*400"):
        await adapter.read_param(SOFT_START)
    report = next(r for r in state.live("Service reports").value if r.key == SOFT_START.key)
    assert not report.ok and sorted(report.answers) == ["value 300", "value 400"]
    assert state.raw(SOFT_START) is None  # no single value to show


async def test_read_fails_when_an_actuator_is_missing(lift):  # noqa: F811
    _runtime, adapter, _state, twin = lift
    twin.actuators[0].service_silent = True
    loop = asyncio.get_running_loop()
    started = loop.time()
    with pytest.raises(CommandError, match="1 of 2 actuators did not answer"):
        await adapter.read_param(SOFT_START)
    assert loop.time() - started < 1.5  # bounded: one service timeout per telegram


async def test_write_fails_when_an_actuator_errs(lift):  # noqa: F811
    _runtime, adapter, state, twin = lift
    twin.actuators[1].service_error = codec.ERROR_PERMISSION
    with pytest.raises(CommandError, match="INCORRECT_PERMISSION"):
        await adapter.write_param(SOFT_START, 500)
    assert twin.actuators[0].service.values[0x01] == 300  # stopped at the password: nothing written
    assert SOFT_START.key not in state.unsaved


async def test_write_fails_when_an_actuator_reads_back_another_value(lift):  # noqa: F811
    _runtime, adapter, state, twin = lift
    twin.actuators[1].service_stuck.add(0x01)  # confirms the write, keeps its value
    with pytest.raises(CommandError, match="read back.*500.*300|300.*500"):
        await adapter.write_param(SOFT_START, 500)
    assert state.counters.write_errors == 1
    assert SOFT_START.key in state.unsaved  # one actuator did change: the reminder stays


async def test_write_and_save_on_every_actuator(lift):  # noqa: F811
    _runtime, adapter, state, twin = lift
    assert await adapter.write_param(SOFT_START, 500) == 500
    assert [a.service.values[0x01] for a in twin.actuators] == [500, 500]
    form = await adapter.save_parameters()
    assert form == codec.SAVE_FORMS[4] and state.live("Save form").value == form
    assert [a.service.saved[0x01] for a in twin.actuators] == [500, 500] and not state.unsaved


# -- save: table's form, example's on WRONG_SIZE -----------------------------------------------


def sent_service(runtime) -> list[str]:
    frames = runtime.store.buses["can2"].frames
    return [f.data.hex(" ").upper() for f in frames if f.direction == "tx" and f.arbitration_id == codec.SERVICE_REQUEST_ID]


async def test_save_retries_once_with_the_example_form(lift):  # noqa: F811
    runtime, adapter, state, twin = lift
    for a in twin.actuators:
        a.save_lengths = {1}
    await adapter.write_param(SOFT_START, 450)
    form = await adapter.save_parameters()
    assert form == codec.SAVE_FORMS[1]
    saves = [f for f in sent_service(runtime) if f.startswith("01 F0")]
    assert saves == ["01 F0 04 00 00 00 00 00", "01 F0 01 00 00 00 00 00"]
    assert all(a.service.saved[0x01] == 450 for a in twin.actuators) and not state.unsaved
    assert any("1-byte form" in e.text for e in state.events)


async def test_save_reports_a_mixed_network(lift):  # noqa: F811
    _runtime, adapter, _state, twin = lift
    twin.actuators[1].save_lengths = {1}
    form = await adapter.save_parameters()
    assert "1 actuator" in form and "4-byte" in form and "1-byte" in form
    assert all(a.service.saves == 1 for a in twin.actuators)


async def test_save_fails_when_an_actuator_accepts_neither(lift):  # noqa: F811
    runtime, adapter, state, twin = lift
    await adapter.write_param(SOFT_START, 450)
    twin.actuators[0].save_lengths = set()
    with pytest.raises(CommandError, match="WRONG_SIZE"):
        await adapter.save_parameters()
    assert SOFT_START.key in state.unsaved
    assert len([f for f in sent_service(runtime) if f.startswith("01 F0")]) == 2  # retried once, not more


# -- the bit rate: write, read back, save; the bus and the actuators switch at power-up ----------


async def test_bitrate_is_read_back_and_saved_then_applies_at_power_up(lift):  # noqa: F811
    runtime, adapter, state, twin = lift
    assert await adapter.write_param(BIT_RATE, 3, confirmed=True) == 3
    assert [f for f in sent_service(runtime) if f.startswith("00 04")] == ["00 04 01 00 00 00 00 00"]  # read back
    assert BIT_RATE.key in state.unsaved and state.live("Bit rate change").value.raw == 3
    await asyncio.sleep(0.3)  # three status periods (0x07 every 100 ms) at the old bit rate
    assert state.live("Devices heard").value == 2  # still on this bus until they are powered up again
    await adapter.save_parameters()
    assert not state.unsaved and state.live("Bit rate change").value.saved
    assert all(a.service.saved[0x04] == 3 for a in twin.actuators)
    twin.power_cycle()
    assert await wait_for(lambda: state.live("Devices heard").value == 0 or state.status != "online", timeout=3)
    assert all(a.bitrate == 250_000 for a in twin.actuators)


async def test_unsaved_bitrate_is_lost_at_power_up(lift):  # noqa: F811
    _runtime, adapter, state, twin = lift
    await adapter.write_param(BIT_RATE, 4, confirmed=True)
    twin.power_cycle()
    await asyncio.sleep(0.3)  # three status periods (0x07 every 100 ms) after the power-up: both still heard
    assert state.live("Devices heard").value == 2 and all(a.bitrate == 500_000 for a in twin.actuators)


# -- the timeout floor ------------------------------------------------------------------------------


def test_timeout_below_the_control_period_is_refused_with_the_reason():
    assert "control period" in refusal(TIMEOUT, 99) and "timeout flag" in refusal(TIMEOUT, "50")
    assert refusal(TIMEOUT, TIMEOUT_MIN_MS) == "" and refusal(SOFT_START, 5) == ""
    with pytest.raises(ValueError):
        TIMEOUT.validate(50)


async def test_adapter_refuses_a_timeout_below_100_ms(lift):  # noqa: F811
    runtime, adapter, _state, twin = lift
    with pytest.raises(CommandError, match="control period of 100 ms"):
        await adapter.write_param(TIMEOUT, 50)
    assert not [f for f in sent_service(runtime) if f.startswith("01 06")]  # nothing reached the bus
    assert await adapter.write_param(TIMEOUT, 220) == 220  # above the floor (twice the period), below the default
    assert all(a.service.values[0x06] == 220 for a in twin.actuators)


def test_timeout_bounded_above_the_control_period_and_confirmed_above_the_default():
    """Issue 26.5: 100 ms (the tool's own period) is refused; 65535 ms is refused; above 250 ms asks first."""
    from devices.electrak.params import TIMEOUT_DEFAULT_MS, TIMEOUT_MAX_MS

    assert refusal(TIMEOUT, 100)  # the control period itself: the flag would be set between telegrams
    with pytest.raises(ValueError):
        TIMEOUT.validate(100)
    with pytest.raises(ValueError):
        TIMEOUT.validate(65535)
    assert TIMEOUT.validate(TIMEOUT_MAX_MS) == TIMEOUT_MAX_MS
    assert TIMEOUT.needs_confirmation(TIMEOUT_DEFAULT_MS) == ""
    assert "keep moving" in TIMEOUT.needs_confirmation(TIMEOUT_DEFAULT_MS + 1)


async def test_the_twins_declared_disagree_switch_makes_reads_fail(lift):  # noqa: F811
    """The simulation card's "last actuator disagrees" is a declared action of the twin (no page writes the twin)."""
    _runtime, adapter, state, twin = lift
    controls = twin.controls()
    assert {"extra load", "actuator 1 connected", "actuator 2 connected", "last actuator disagrees",
            "power cycle"} <= {a.name for a in controls.actions}
    controls.invoke("last actuator disagrees", {"on": True})
    assert controls.action("last actuator disagrees").state()
    with pytest.raises(CommandError, match="disagree"):
        await adapter.read_param(SOFT_START)
    controls.invoke("last actuator disagrees", {"on": False})
    assert await adapter.read_param(SOFT_START) == 300
    report = next(r for r in state.live("Service reports").value if r.key == SOFT_START.key)
    assert report.ok and state.live("Last service telegram").value == report
