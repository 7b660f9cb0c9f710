"""SCU data directory (document 002, section 4.3 tables 6 and 7, section 7): byte tables.

Each row asserts decode(bytes) == value, encode(value) == bytes and encode(decode(b)) == b.
"""

from __future__ import annotations

import math

import pytest

from devices import values as v
from devices.scu import codec as c
from devices.scu import params as p


def h(text: str) -> bytes:
    return bytes.fromhex(text)


def assert_row(data_id: int, value, data: bytes):
    decoded = p.decode_data(data_id, data)
    assert decoded == value, (hex(data_id), data.hex(" "))
    assert p.encode_data(data_id, value, remote_only=False) == data
    assert p.encode_data(data_id, decoded, remote_only=False) == data
    assert p.item(data_id).size == len(data)


# -- every data ID of the tables ----------------------------------------------------------------------
TABLE_6 = (
    [0x0001, 0x0002, 0x0020, 0x0040, 0x008F, 0x00BF, 0x00C0, 0x00C1, 0x0100, 0x0110, 0x0120, 0x0130, 0x0140,
     0x0150, 0x0162, 0x0164, 0x0165, 0x0166]
    + [g + n for g in (0x0010, 0x0060, 0x0070, 0x0080, 0x0090, 0x00A0, 0x00B0, 0x00E0, 0x00F0, 0x0170, 0x1010, 0x2000)
       for n in range(1, 7)]
    + [0x0031, 0x0032, 0x0033, 0x0034] + [0x00D1, 0x00D2, 0x00D3, 0x00D4, 0x00D5]
)
TABLE_7 = [0x3001, 0x3002, 0x3003, 0x3004, 0x3005] + list(range(0x3011, 0x301B)) + list(range(0x3021, 0x3027))


def test_every_data_id_of_the_tables_is_there():
    singles = {i for i, entry in p.DIRECTORY.items() if not entry.is_group}
    assert singles == set(TABLE_6) | set(TABLE_7)
    for data_id in TABLE_6 + TABLE_7:
        entry = p.item(data_id)
        assert entry.name and entry.type_name and entry.key == f"0x{data_id:04X}"
        assert entry.writable == (data_id >= 0x3000)  # section 4.3: only collection 3000 is written (RT)
    with pytest.raises(p.UnknownDataId, match="0x0017"):
        p.item(0x0017)


def test_names_types_and_units_follow_the_tables():
    assert p.item(0x0011).name == "Actual_Position Actuator 1" and p.item(0x0011).unit == "counts"
    assert p.item(0x0001).size == 31 and p.item(0x0002).size == 36  # "Size = 31 B", "Size = 36 B"
    assert p.item(0x00A3).name == "Strom A3" and p.item(0x00A3).unit == "A"
    assert p.item(0x0164).unit == "V" and p.item(0x0034).unit == "V"
    assert p.item(0x00C0).vtype == v.U8 and p.item(0x0040).vtype == v.U32LE
    assert p.item(0x1016).vtype == v.F32LE and p.item(0x2006).vtype is p.ACTUATOR_POSITIONS
    assert p.item(0x301A).name == "Remote Speed F10" and p.item(0x301A).function == 10
    assert p.item(0x3026).name == "Remote Position A6" and p.item(0x3026).actuator == 6
    assert p.item(0x00D1).name == "Error_Code 1 (last recent)" and p.item(0x00D5).name == "Error_Code 5 (History 4)"
    for entry in p.DIRECTORY.values():
        assert entry.comment or entry.data_id in (0x008F, 0x00C1), hex(entry.data_id)


def test_per_actuator_ids_are_group_plus_actuator():
    assert p.actuator_id(0x0010, 1) == 0x0011 and p.actuator_id(0x0170, 6) == 0x0176
    assert p.actuator_id(0x00A0, 3) == 0x00A3 and p.remote_position_id(1) == 0x3021
    assert p.speed_id(1) == 0x3011 and p.speed_id(10) == 0x301A
    for group in (0x0010, 0x0060, 0x0070, 0x0080, 0x0090, 0x00A0, 0x00B0, 0x00E0, 0x00F0, 0x0170, 0x1010, 0x2000,
                  0x3020):
        for n in range(1, 7):
            entry = p.item(p.actuator_id(group, n))
            assert entry.group == group and entry.actuator == n
    with pytest.raises(ValueError):
        p.actuator_id(0x0010, 7)
    with pytest.raises(ValueError):
        p.speed_id(11)
    with pytest.raises(p.UnknownDataId):
        p.actuator_id(0x0030, 1)  # analogue inputs are not per actuator


def test_group_0010_returns_all_six_positions():
    group = p.GROUPS[0x0010]
    assert group.members == tuple(range(0x0011, 0x0017)) and group.size == 24
    data = h("01000000 FFFFFFFF 00000000 18FCFFFF 00010000 FFFFFF7F")
    assert_row(0x0010, {0x11: 1, 0x12: -1, 0x13: 0, 0x14: -1000, 0x15: 256, 0x16: 2**31 - 1}, data)
    with pytest.raises(v.TruncatedError):
        p.decode_data(0x0010, data[:-4])  # a block of another length is a named error
    assert p.GROUPS[0x0080].members == (0x81, 0x82, 0x83, 0x84, 0x85, 0x86, 0x8F)
    assert p.GROUPS[0x2000].size == 6 * 104


# -- byte tables ------------------------------------------------------------------------------------------
ROWS = [
    # positions, INT32 counts (section 5: RG 11 00 answers ctp 04 00 + 4 bytes)
    (0x0011, 1000, "E8 03 00 00"), (0x0016, -1000, "18 FC FF FF"), (0x0013, -(2**31), "00 00 00 80"),
    # currents, fixed point 0.1 A
    (0x00A1, 12.5, "7D 00"), (0x00A6, 100.0, "E8 03"), (0x00B1, 0.1, "01 00"), (0x00BF, 35.2, "60 01"),
    # battery voltage 0.1 V, analogue inputs 0.01 V
    (0x0164, 24.0, "F0 00"), (0x0164, 40.0, "90 01"), (0x0031, 6.0, "58 02"), (0x0034, 2.47, "F7 00"),
    # counters and speeds
    (0x0061, 123456, "40 E2 01 00"), (0x0076, 0, "00 00 00 00"), (0x0091, 0xFFFFFFFF, "FF FF FF FF"),
    (0x00C0, 200, "C8"), (0x00C1, 3, "03 00 00 00"), (0x00F1, 100, "64 00"), (0x0165, 2, "02"), (0x0166, 4, "04"),
    # conversion factors FLOAT
    (0x1011, 0.5, "00 00 00 3F"), (0x1016, -2.5, "00 00 20 C0"), (0x1013, 12.5, "00 00 48 41"),
    # remote data
    (0x3011, 1, "01 00"), (0x301A, 100, "64 00"), (0x3021, 5000, "88 13 00 00"), (0x3026, -1, "FF FF FF FF"),
]


@pytest.mark.parametrize("data_id,value,data", ROWS, ids=[f"{r[0]:04X}={r[1]}" for r in ROWS])
def test_value_byte_table(data_id, value, data):
    assert_row(data_id, value, h(data))


def test_strings():
    firmware = b"SCU V2B3 CS 4A1F".ljust(31, b"\0")
    assert_row(0x0001, "SCU V2B3 CS 4A1F", firmware)
    config = b"SCP11 V1.4 CS \xe9".ljust(36, b"\0")  # any byte reads (latin-1)
    assert_row(0x0002, "SCP11 V1.4 CS é", config)
    with pytest.raises(v.TruncatedError):
        p.decode_data(0x0001, b"SCU")
    with pytest.raises(v.EncodeError):
        p.encode_data(0x0001, "x" * 32, remote_only=False)


def test_actuator_status_1_from_rg_71_01():
    status = p.decode_data(0x0171, h("11"))  # section 5: bit 4 set while the motion is active
    assert status["present"] and status["motion"] and status.active == ["present", "motion"]
    assert_row(0x0171, 0x11, h("11"))
    full = p.decode_data(0x0176, h("FF"))
    assert full.active == ["present", "limit_in_out", "switch_1", "switch_2", "motion", "in_position",
                           "out_position", "stroke_recorded"]
    assert p.encode_data(0x0171, {"present": True, "out_position": True}, remote_only=False) == h("41")


def test_actuator_status_2_and_unit_bits():
    assert p.decode_data(0x00E1, h("07")).active == ["initialised", "enable_in", "enable_out"]
    assert_row(0x00E2, 0x05, h("05"))
    mains = p.decode_data(0x0100, h("0A"))
    assert mains.active == ["battery", "charging"] and not mains["mains"]
    assert p.decode_data(0x0110, h("02")).active == ["output_2"]
    assert p.decode_data(0x0120, h("03")).active == ["led_1", "led_2"]
    assert p.decode_data(0x0130, h("81")).active == ["led_1", "led_8"]
    assert p.decode_data(0x0140, h("01"))["buzzer"] and not p.decode_data(0x0150, h("00"))["sensor_supply"]
    lock = p.decode_data(0x0162, h("01 02"))
    assert lock.active == ["F1_locked", "F10_locked"]
    assert_row(0x0162, 0x0201, h("01 02"))


def test_binary_inputs_logical_and_level_nibbles():
    inputs = p.decode_data(0x0020, h("A5"))  # logical 1 and 3, level 2 and 4
    assert inputs.active == ["input_1", "input_3", "input_2_level", "input_4_level"]
    assert_row(0x0020, 0xA5, h("A5"))
    assert p.encode_data(0x0020, {"input_4": 1, "input_4_level": 1}, remote_only=False) == h("88")


def test_error_code_bits_by_name():
    data = h("01 40 20 00")  # bit 1 (mask 1), bit 15 (1 << 14), bit 22 (1 << 21)
    code = p.decode_data(0x00D1, data)
    assert code == 0x00204001
    assert code.active == ["rom_crc", "actuator_1", "remote_timeout"]
    assert [b.key for b in c.error_bits(code)] == code.active
    assert_row(0x00D3, 0x00204001, data)
    assert p.decode_data(0x00D2, h("00 01 40 00")).active == []  # bits 9 and 23: unused, kept in the raw value
    assert_row(0x00D5, 0x00400100, h("00 01 40 00"))
    assert p.ERROR_CODE.field("remote_timeout").mask == c.REMOTE_TIMEOUT_MASK


def test_actuator_error_counter_in_three_parts():
    counter = p.decode_data(0x0081, h("34 12 05 02"))
    assert counter["actuator_errors"] == 0x1234 and counter["peak_current"] == 5 and counter["short_circuit"] == 2
    assert_row(0x0086, 0x02051234, h("34 12 05 02"))
    assert p.encode_data(0x0081, {"actuator_errors": 1, "peak_current": 0, "short_circuit": 255},
                         remote_only=False) == h("01 00 00 FF")


def test_actuator_positions_struct_of_section_7():
    names = [n for n, _ in p.ACTUATOR_POSITIONS.members]
    assert len(names) == 26 and p.ACTUATOR_POSITIONS.size == 104
    assert names[:6] == ["Position_Memory_1[USER_1]", "Position_Memory_2[USER_1]", "Position_Memory_3[USER_1]",
                         "Position_Memory_4[USER_1]", "Position_Intermediate_In[USER_1]",
                         "Position_Intermediate_Out[USER_1]"]
    assert names[-2:] == ["Position_Virtual_Limit_In", "Position_Virtual_Limit_Out"]
    assert p.ACTUATOR_POSITIONS.offsets["Position_Memory_1[USER_4]"] == 72
    value = {name: (i - 3) * 250 for i, name in enumerate(names)}
    data = b"".join(((i - 3) * 250).to_bytes(4, "little", signed=True) for i in range(26))
    assert data[:8] == h("12 FD FF FF 0C FE FF FF")  # -750, -500
    assert_row(0x2001, value, data)
    assert_row(0x2006, value, data)
    with pytest.raises(v.TruncatedError):
        p.decode_data(0x2001, data[:-1])


def test_nan_and_extremes_of_a_conversion_factor():
    assert math.isnan(p.decode_data(0x1011, h("00 00 C0 7F")))
    with pytest.raises(v.EncodeError):
        p.encode_data(0x1011, 1e39, remote_only=False)


# -- writing: RT data -----------------------------------------------------------------------------------
def test_rt_example_of_section_5():
    assert p.encode_data(0x3011, 1) == h("01 00")
    assert p.rt_frame(0x3011, 1) == h("52 54 04 00 11 30 01 00 B5 F2")
    assert c.decode_request(p.rt_frame(0x3021, -1000)).data == h("18 FC FF FF")


def test_only_remote_data_is_written():
    with pytest.raises(PermissionError, match="0x3xxx"):
        p.encode_data(0x0011, 1000)
    with pytest.raises(v.EncodeError, match="outside"):
        p.encode_data(0x3011, 70000)
    with pytest.raises(v.EncodeError):
        p.encode_data(0x3021, 2**31)
    with pytest.raises(v.EncodeError):
        p.encode_data(0x00A1, 6553.6, remote_only=False)


def test_rg_value_from_an_answer():
    answer = c.decode_answer(c.encode_answer(c.RG, data=h("E8 03 00 00")), expected=c.RG)
    assert p.rg_value(0x0011, answer) == 1000
    with pytest.raises(c.CommandRefused, match="PDE"):
        p.rg_value(0x0011, c.decode_answer(c.encode_answer(c.RG, c.Status.PDE)))


# -- cyclic objects (table 7) -------------------------------------------------------------------------------
def test_cyclic_definition_bytes():
    definition = p.CyclicDefinition(write_ids=(0x3011, 0x3021), read_ids=(0x0010, 0x0171, 0x0172))
    data = h("11 30 21 30") + b"\xff" * 8 + h("10 00 71 01 72 01") + b"\xff" * 6
    assert definition.encode() == data and p.CyclicDefinition.decode(data) == definition
    assert p.rt_frame(0x3001, list(p.CYCLIC_OBJECT.decode(data)))[:6] == b"RT" + h("1A 00 01 30")
    assert definition.write_size == 6 and definition.read_size == 26
    assert p.decode_data(0x3001, b"\xff" * 24) == (0xFFFF,) * 12  # default: -1, no transfer
    assert p.CyclicDefinition.decode(b"\xff" * 24) == p.CyclicDefinition()


def test_cyclic_write_and_read_data():
    definition = p.CyclicDefinition(write_ids=(0x3011, 0x3021), read_ids=(0x0011, 0x0171, 0x00A1))
    write = definition.encode_write([50, 1000])
    assert write == h("32 00 E8 03 00 00") and definition.encode_write({0x3021: 1000, 0x3011: 50}) == write
    frame = p.rc_frame(0, definition, [50, 1000])
    assert frame[:-2] == b"RC" + h("07 00 00 32 00 E8 03 00 00")
    assert definition.decode_write(c.decode_request(frame).data) == {0x3011: 50, 0x3021: 1000}
    read = h("E8 03 00 00 11 7D 00")
    values = definition.decode_read(read)
    assert values[0x0011] == 1000 and values[0x0171].active == ["present", "motion"] and values[0x00A1] == 12.5
    assert definition.encode_read(values) == read
    with pytest.raises(v.TruncatedError):
        definition.decode_read(read[:-1])
    with pytest.raises(v.ExcessDataError):
        definition.decode_read(read + b"\0")
    with pytest.raises(v.EncodeError):
        definition.encode_write([50])
    positions = p.CyclicDefinition(read_ids=(0x0010,))
    assert positions.decode_read(bytes(24)) == {0x0010: {i: 0 for i in range(0x11, 0x17)}}


def test_cyclic_definition_limits():
    with pytest.raises(ValueError, match="at most 6"):
        p.CyclicDefinition(read_ids=tuple(range(0x0011, 0x0017)) + (0x0171,))
    with pytest.raises(ValueError, match="cannot be written"):
        p.CyclicDefinition(write_ids=(0x0011,))
    with pytest.raises(p.UnknownDataId):
        p.CyclicDefinition(read_ids=(0x0017,))
