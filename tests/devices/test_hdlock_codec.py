"""HD-Lock codec: the document's examples as golden vectors."""

import pytest

from devices.hdlock import codec
from devices.hdlock.params import PARAMS

# section 4.3, LockStatus of both examples: bolt out, door closed, hall sensors not overdriven
STATUS_0117 = 0x0117


@pytest.mark.parametrize(
    ("mask", "expected", "result", "accepted"),
    [
        (0x010C, 0x0104, 0x0000, True),  # example 1: new address 8 taken
        (0x0100, 0x0000, 0x0100, False),  # example 2: new address 16 refused
    ],
)
def test_set_address_examples(mask, expected, result, accepted):
    assert codec.set_address_condition(mask, expected, STATUS_0117) == result
    assert codec.set_address_accepted(mask, expected, STATUS_0117) is accepted


def test_lock_status_example_0117():
    bits = codec.lock_status_bits(STATUS_0117)
    assert {name for name, on in bits.items() if on} == {
        "LockRequest", "ProximityInPlace", "DoorInPosition", "LockRequest (bit 4)", "BoltLocked",
    }
    assert PARAMS.by_name["LockStatus"].display(STATUS_0117) == (
        "LockRequest, ProximityInPlace, DoorInPosition, LockRequest (bit 4), BoltLocked"
    )


@pytest.mark.parametrize(("value", "raw"), [(-30, 65506), (-60, 65476), (-1, 0xFFFF), (0, 0), (32767, 0x7FFF), (-32768, 0x8000)])
def test_signed_round_trip(value, raw):
    assert codec.from_signed16(value) == raw
    assert codec.to_signed16(raw) == value


def test_signed_out_of_range():
    with pytest.raises(codec.CodecError):
        codec.from_signed16(40000)


def test_serial_number_example():
    assert codec.serial_number(0x000A, 0x1234) == 0x000A1234 == 660020
    serial = PARAMS.by_name["SerialNumber"]
    assert serial.decode(serial.combine([0x000A, 0x1234])) == 660020
    assert serial.split(660020) == [0x000A, 0x1234]


@pytest.mark.parametrize(
    ("name", "raw", "text"),
    [
        ("DoorState", 3, "Door closed"),
        ("StateMachineState", 4, "Locked"),
        ("MotorState", 1, "Extending"),
        ("MotorState (IR53)", 0xFFFF, "Inactive"),
        ("LockRequestSource", 0x81, "IrsAlways (door ignored)"),
        ("LockRequestSource", 0x04, "IrsNotLine"),
    ],
)
def test_enum_decoding(name, raw, text):
    assert PARAMS.by_name[name].enum_name(raw) == text


def test_enum_undefined_value_is_said():
    assert "undefined" in PARAMS.by_name["DoorState"].display(9)


def test_system_command_order_parameters_before_command():
    writes = codec.encode_system_command(codec.SystemCommand.SET_MODBUS_ADDRESS, 8, 0x010C, 0x0104).writes
    assert writes == ((2000, 8), (2001, 0x010C), (2002, 0x0104), (2003, 3))
    assert codec.encode_system_command(codec.SystemCommand.SAVE_SETTINGS).writes[-1] == (2003, 1)
    assert codec.encode_system_command(codec.SystemCommand.RESTORE_SETTINGS).writes[-1] == (2003, 2)


@pytest.mark.parametrize("address", [0, 255, 300])
def test_set_address_range(address):
    with pytest.raises(codec.CodecError):
        codec.encode_system_command(codec.SystemCommand.SET_MODBUS_ADDRESS, address, 0, 0)


# -- section 6.2: byte order on CAN (LSB first) -------------------------------------------------

BYTE_ORDER_TABLE = [  # section 6.2, "Beispiel": type, value, CAN data length, bytes 0..3
    ("uint8", 0x01, 1, "01"),
    ("uint16", 0x1234, 2, "34 12"),
    ("uint32", 0x12345678, 4, "78 56 34 12"),
]


@pytest.mark.parametrize(("kind", "value", "length", "data"), BYTE_ORDER_TABLE, ids=[row[0] for row in BYTE_ORDER_TABLE])
def test_byte_order_table(kind, value, length, data):
    wire = bytes.fromhex(data)
    assert codec.pack_le(value, length) == wire  # encode
    assert codec.unpack_le(wire) == value  # decode
    assert codec.pack_le(codec.unpack_le(wire), len(wire)) == wire  # round trip
    assert len(wire) == length


def test_byte_order_in_frames():
    """The frames themselves carry uint16/uint32 fields LSB first, as the table of section 6.2."""
    target = codec.DeviceId.make(0x345678)  # above 0x7FF: extended, flag 0x80000000 in byte 3
    frame = codec.encode_write(target, 0x1234, 0x5678)
    assert frame.data == bytes.fromhex("78 56 34 80") + bytes.fromhex("34 12") + bytes.fromhex("78 56")
    answer = codec.RegisterAnswer("holding", 0x1234, 0x5678)
    assert codec.encode_register_answer(answer) == bytes.fromhex("01 01 34 12 78 56")
    assert codec.decode_lock_frame(bytes.fromhex("01 01 34 12 78 56")) == answer


@pytest.mark.parametrize(("value", "length"), [(0x100, 1), (0x10000, 2), (-1, 2), (1 << 32, 4)])
def test_byte_order_out_of_range(value, length):
    with pytest.raises(codec.CodecError):
        codec.pack_le(value, length)


# -- section 4.3: broadcast address change ------------------------------------------------------


def test_broadcast_address_is_255():
    assert codec.MODBUS_BROADCAST_SET_ADDRESS == 255
    assert codec.MODBUS_BROADCAST == 0  # section 5.6: reads, answered by a single lock


def test_broadcast_takers_by_last_lock_status():
    """Which known locks would take the address, by the condition of section 4.3."""
    statuses = {"door-1": 0x0117, "door-2": 0x0202, "door-3": None}
    takers, unknown = codec.broadcast_takers(0x010C, 0x0104, statuses)  # example 1's masks
    assert takers == ["door-1"] and unknown == ["door-3"]
    takers, unknown = codec.broadcast_takers(0x0000, 0x0000, statuses)  # no condition: every lock
    assert takers == ["door-1", "door-2"] and unknown == ["door-3"]


def test_address_command_answer_not_expected():
    """Section 4.3 does not say the lock answers the write of 2003 at its old address."""
    assert codec.ADDRESS_COMMAND_ANSWERED is False
