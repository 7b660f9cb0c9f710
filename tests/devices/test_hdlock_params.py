"""Transcription checks for the HD-Lock register map (document section 3)."""

from __future__ import annotations

import pytest

from devices.hdlock import params as hd
from devices.params import Access, ParamError

PARAMS = hd.PARAMS

INPUT_ADDRESSES = set(range(0, 17)) | set(range(50, 64)) | set(range(100, 105))
HOLDING_ADDRESSES = (
    {0, 2, 3, 4}
    | set(range(10, 34))
    | {40, 41}
    | set(range(100, 104))
    | set(range(1000, 1011))
    | set(range(2000, 2004))
    | set(range(3000, 3009))
    | {32770}
)


def holding(address: int):
    param = PARAMS.get(hd.HOLDING, address)
    assert param is not None, f"holding {address} missing"
    return param


def test_input_addresses_exact():
    assert {p.address for p in PARAMS.space(hd.INPUT)} == INPUT_ADDRESSES


def test_holding_addresses_exact():
    assert {p.address for p in PARAMS.space(hd.HOLDING)} == HOLDING_ADDRESSES


def test_order_inputs_first_then_holdings_by_address():
    keys = [(p.space != hd.INPUT, p.address) for p in PARAMS]
    assert keys == sorted(keys)
    assert {p.space for p in PARAMS} == {hd.INPUT, hd.HOLDING}


def test_inputs_are_read_only():
    assert all(p.access is Access.R and not p.writable for p in PARAMS.space(hd.INPUT))


def test_access_classes():
    assert holding(0).access is Access.MFR and holding(0).never_write
    assert holding(4).access is Access.RW
    assert holding(1000).access is Access.RO
    assert holding(1002).access is Access.RW
    assert holding(3005).access is Access.RW
    assert all(holding(a).access is Access.MFR for a in range(10, 34))
    assert all(holding(a).access is Access.MFR for a in (40, 41, 100, 101, 102, 103))
    assert holding(32770).never_write
    assert all(holding(a).never_write for a in range(2000, 2004))


def test_writable_exactly():
    writable = {p.key for p in PARAMS if p.writable}
    expected = {f"holding:{a}" for a in (4, 1002, 1003, 1004, *range(3000, 3009))}
    assert writable == expected


@pytest.mark.parametrize(("space", "address", "name"), [
    (hd.INPUT, 7, "Calculated proxi (normalized)"), (hd.INPUT, 15, "SystemCoreClock-Config"),
    (hd.HOLDING, 30, "Lock/UnlockFailDelay1"), (hd.HOLDING, 40, "SettingsOutput1"), (hd.HOLDING, 3001, "SettingOutput1"),
    (hd.HOLDING, 3002, "SettingOutput2"), (hd.HOLDING, 2000, "Parameter 0"),
])
def test_names_verbatim(space, address, name):
    assert PARAMS.get(space, address).name == name


def test_duplicate_names_labelled():
    assert PARAMS.get(hd.INPUT, 2).label == ""
    assert PARAMS.get(hd.INPUT, 3).label == ""
    assert PARAMS.get(hd.INPUT, 57).label == ""
    assert holding(1002).label == ""
    assert PARAMS.get(hd.INPUT, 53).label == "MotorState (IR53)"
    assert PARAMS.get(hd.INPUT, 63).label == "ActCurrent (IR63)"
    assert holding(2).label == "BoltPosition (HR2)"
    assert holding(1001).label == "BoltPosition (HR1001)"
    assert holding(4).label == "LockRequestSource (HR4)"
    display_names = [p.label or p.name for p in PARAMS]
    assert len(display_names) == len(set(display_names))


def test_by_name():
    assert PARAMS.by_name["BoltPosition"].key == "input:2"
    assert PARAMS.by_name["LockStatus"].key == "holding:1000"
    assert PARAMS.by_name["SettingsProximityThresholdUnlock"].key == "holding:3004"
    assert PARAMS.by_name["SerialNumber"].key == "input:104"
    assert PARAMS.by_name["LockRequestSource"].key == "holding:1002"
    assert PARAMS.by_name["MotorState"].key == "input:3"


def test_signed_registers():
    signed = {p.key for p in PARAMS if p.signed}
    # 26.8: motor speeds 51/52 are negative moving in (the twin writes 0x10000 - speed), ErrVsum an integral part
    expected = {"input:11", "input:16", "input:51", "input:52", "input:53", "input:59"} | {
        f"holding:{a}" for a in (3003, 3004, 3006, 3007, 3008)}
    assert signed == expected
    assert PARAMS.get("input", 51).display(0x10000 - 120) == "-120 #/s"


@pytest.mark.parametrize(
    ("address", "value", "raw"),
    [(3004, -30, 65506), (3006, -60, 65476), (3007, 5, 5), (3008, -1, 0xFFFF), (3003, -1, 0xFFFF)],
)
def test_signed_encode_decode(address, value, raw):
    param = holding(address)
    assert param.validate(value) == raw
    assert param.decode(raw) == value
    assert param.encode(param.decode(raw)) == raw


def test_signed_inputs_decode():
    assert PARAMS.get(hd.INPUT, 11).enum_name(0xFFFF) == "Always right-hinged"
    assert PARAMS.get(hd.INPUT, 53).decode(0xFFFF) == -1
    assert PARAMS.get(hd.INPUT, 53).enum_name(0xFFFF) == "Inactive"


def test_defaults():
    expected = {
        4: 4, 1002: 4, 3000: 200, 3001: 4, 3002: 2, 3003: 0, 3004: 65506, 3005: 0,
        3006: 65476, 100: 19200, 101: 2, 102: 1, 103: 1, 2000: 0, 2001: 0, 2002: 0, 2003: 0,
    }
    for address, raw in expected.items():
        assert holding(address).default == raw, address
    assert holding(3004).decode(holding(3004).default) == -30
    assert holding(3006).decode(holding(3006).default) == -60


def test_defaults_are_valid_for_writable():
    for p in PARAMS:
        if p.writable and p.default is not None:
            assert p.validate(p.decode(p.default)) == p.default


def test_lock_status_fields():
    param = holding(1000)
    assert param.fields == hd.LOCK_STATUS_BITS
    values = param.field_values(0x0117)
    set_bits = {"LockRequest", "ProximityInPlace", "DoorInPosition", "LockRequest (bit 4)", "BoltLocked"}
    assert {name for name, v in values.items() if v} == set_bits
    assert set(values) == set_bits | {
        "ProximityOverrange", "ForceActive", "BoltUnlocked", "BoltMovingOut", "BoltMovingIn",
    }
    shifts = {f.name: f.shift for f in hd.LOCK_STATUS_BITS}
    assert shifts == {
        "LockRequest": 0, "ProximityInPlace": 1, "DoorInPosition": 2, "ProximityOverrange": 3,
        "LockRequest (bit 4)": 4, "ForceActive": 7, "BoltLocked": 8, "BoltUnlocked": 9,
        "BoltMovingOut": 10, "BoltMovingIn": 11,
    }
    assert all(f.width == 1 and f.description for f in hd.LOCK_STATUS_BITS)


def test_hall_and_clock_fields():
    assert holding(1006).field_values(0xA512) == {"H1": 0xA5, "H2": 0x12}
    clock = PARAMS.get(hd.INPUT, 15).field_values(0b10_0111)
    assert clock == {"HSI ready": 1, "HSE ready": 1, "PLL ready": 1, "HSE active": 0, "SysClkSource": 2}


def test_serial_number():
    param = PARAMS.get(hd.INPUT, 104)
    assert param.words == 2 and list(param.addresses) == [104, 105]
    raw = param.combine([0x000A, 0x1234])
    assert raw == 660020
    assert param.decode(raw) == 660020
    assert param.split(raw) == [0x000A, 0x1234]


def test_validate_rejections_and_names():
    with pytest.raises(ParamError):
        holding(3005).validate(3)
    with pytest.raises(ParamError):
        holding(1000).validate(0)
    with pytest.raises(ParamError):
        holding(0).validate(1)
    with pytest.raises(ParamError):
        holding(32770).validate(1)
    with pytest.raises(ParamError):
        holding(3001).validate(9)  # value 9 is "-" in section 3.2.4
    assert holding(1002).validate("IrsAlways") == 1
    assert holding(1002).validate("IrsAlways (door ignored)") == 0x81
    assert holding(1002).validate(0x87) == 0x87
    with pytest.raises(ParamError):
        holding(1002).validate(0x08)
    assert holding(3000).validate(65535) == 65535
    with pytest.raises(ParamError):
        holding(3000).validate(-1)


def test_lock_request_source_table():
    assert set(hd.LOCK_REQUEST_SOURCE) == set(range(0x00, 0x08)) | set(range(0x80, 0x88))
    assert hd.LOCK_REQUEST_SOURCE[0x04] == "IrsNotLine"
    assert hd.LOCK_REQUEST_SOURCE[0x07] == "IrsToggleOnLineNEdge"
    assert len(set(hd.LOCK_REQUEST_SOURCE.values())) == 16
    assert holding(4).enum == holding(1002).enum == hd.LOCK_REQUEST_SOURCE


def test_enums_attached():
    assert PARAMS.get(hd.INPUT, 8).enum is hd.DOOR_STATE
    assert PARAMS.get(hd.INPUT, 9).enum is hd.STATE_MACHINE_STATE
    assert set(hd.STATE_MACHINE_STATE) == set(range(13))
    assert PARAMS.get(hd.INPUT, 3).enum is hd.MOTOR_STATE_IR3
    assert PARAMS.get(hd.INPUT, 53).enum is hd.MOTOR_STATE_IR53
    assert PARAMS.get(hd.INPUT, 54).enum is hd.MOTOR_RESULT
    assert holding(3003).enum is hd.DIRECTION
    assert all(holding(a).enum is hd.OUTPUT_FUNCTION for a in (40, 41, 3001, 3002))
    assert set(hd.OUTPUT_FUNCTION) == set(range(9)) | {10}
    assert holding(101).enum is hd.PARITY
    assert holding(102).enum is hd.STOP_BITS
    assert holding(100).enum is None


def test_remove_magnet_confirmation():
    param = holding(3005)
    assert param.needs_confirmation(1)
    assert "security" in param.needs_confirmation(1).lower()
    assert param.needs_confirmation(0) == ""


@pytest.mark.parametrize(("space", "address", "unit"), [
    (hd.INPUT, 2, "Inc"), (hd.INPUT, 51, "#/s"), (hd.HOLDING, 13, "#/s²"), (hd.HOLDING, 17, "ADC#"),
    (hd.HOLDING, 31, "s"), (hd.HOLDING, 1007, "°C"), (hd.HOLDING, 1008, "mV"), (hd.HOLDING, 3000, "ms"),
])
def test_units(space, address, unit):
    assert PARAMS.get(space, address).unit == unit


def test_every_param_has_description():
    assert all(p.description.strip() for p in PARAMS)


def test_input_blocks():
    covered = {a for start, count in PARAMS.blocks(hd.INPUT) for a in range(start, start + count)}
    assert covered == set(range(0, 17)) | set(range(50, 64)) | set(range(100, 106))
