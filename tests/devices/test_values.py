"""Typed value model (devices/values.py): byte tables of (value, bytes) pairs.

Each row asserts decode(bytes) == value, encode(value) == bytes and
encode(decode(bytes)) == bytes, like cantools' database tests. The SCU data
directory (document 002, section 4.3 and 7) and the MO 64 telegram fields
(SPEC-NOTES "Bauer MO 64") are described here as data to show the model carries them.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import pickle

import pytest

from devices import values as v
from devices.hdlock import params as hd
from devices.params import Param


def h(text: str) -> bytes:
    return bytes.fromhex(text)


def assert_row(vtype: v.ValueType, value, data: bytes):
    decoded = vtype.decode(data)
    assert decoded == value, (vtype.name, data.hex(" "))
    assert vtype.encode(value) == data, (vtype.name, value)
    assert vtype.encode(decoded) == data
    assert vtype.size in (None, len(data))


# -- integers: every width, signedness and byte order -------------------------------------------
INT_ROWS = [
    (v.U8, 0, "00"), (v.U8, 0x7F, "7F"), (v.U8, 0xFF, "FF"),
    (v.I8, 0, "00"), (v.I8, 127, "7F"), (v.I8, -1, "FF"), (v.I8, -128, "80"),
    (v.U16LE, 0x1234, "34 12"), (v.U16BE, 0x1234, "12 34"), (v.U16LE, 0xFFFF, "FF FF"),
    (v.I16LE, -60, "C4 FF"), (v.I16BE, -60, "FF C4"), (v.I16LE, -32768, "00 80"), (v.I16BE, 32767, "7F FF"),
    (v.U32LE, 0x12345678, "78 56 34 12"), (v.U32BE, 0x12345678, "12 34 56 78"),
    (v.U32LE, 0xFFFFFFFF, "FF FF FF FF"), (v.U32BE, 660020, "00 0A 12 34"),
    (v.I32LE, -1, "FF FF FF FF"), (v.I32BE, -2, "FF FF FF FE"),
    (v.I32LE, -(2**31), "00 00 00 80"), (v.I32BE, 2**31 - 1, "7F FF FF FF"),
    (v.U64LE, 0x0102030405060708, "08 07 06 05 04 03 02 01"),
    (v.U64BE, 0x0102030405060708, "01 02 03 04 05 06 07 08"),
    (v.U64LE, 2**64 - 1, "FF FF FF FF FF FF FF FF"),
    (v.I64LE, -(2**63), "00 00 00 00 00 00 00 80"), (v.I64BE, -3, "FF FF FF FF FF FF FF FD"),
    (v.I64BE, 2**63 - 1, "7F FF FF FF FF FF FF FF"),
    # 24/40/48-bit values (MO 64 settings carry 16/32/40/48/64-bit values)
    (v.Int(24, False, v.LITTLE), 0x123456, "56 34 12"), (v.Int(24, True, v.BIG), -2, "FF FF FE"),
    (v.Int(40, False, v.LITTLE), 0x0102030405, "05 04 03 02 01"),
    (v.Int(48, True, v.BIG), -(2**47), "80 00 00 00 00 00"),
]


@pytest.mark.parametrize("vtype,value,data", INT_ROWS, ids=[f"{r[0].name}={r[1]}" for r in INT_ROWS])
def test_integer_byte_table(vtype, value, data):
    assert_row(vtype, value, h(data))


@pytest.mark.parametrize("vtype", [r[0] for r in INT_ROWS[::3]] + [v.U8, v.I8, v.I64BE])
def test_integer_range_is_checked_on_encode(vtype):
    low, high = vtype.limits
    assert vtype.encode(low) and vtype.encode(high)
    for bad in (low - 1, high + 1):
        with pytest.raises(v.EncodeError, match="outside"):
            vtype.encode(bad)
    for bad in (1.5, "7", None, b"\x01"):
        with pytest.raises(v.EncodeError):
            vtype.encode(bad)
    assert vtype.encode(3.0) == vtype.encode(3)  # a whole float is a whole number


def test_scalar_names_describe_types_as_data():
    for vtype, _, _ in INT_ROWS:
        assert v.scalar(vtype.name) == vtype
    assert v.scalar("i32le") == v.I32LE and v.scalar("u8") == v.U8 and v.scalar("F32BE") == v.F32BE
    for bad in ("u12le", "q16le", "u16", "f16le", ""):
        with pytest.raises(ValueError):
            v.scalar(bad)


# -- floats --------------------------------------------------------------------------------------
FLOAT_ROWS = [
    (v.F32LE, 1.0, "00 00 80 3F"), (v.F32BE, 1.0, "3F 80 00 00"),
    (v.F32LE, -2.5, "00 00 20 C0"), (v.F32BE, 0.15625, "3E 20 00 00"),
    (v.F32LE, 0.0, "00 00 00 00"), (v.F32BE, -0.0, "80 00 00 00"),
    (v.F32LE, 3.4028234663852886e38, "FF FF 7F 7F"), (v.F32BE, math.inf, "7F 80 00 00"),
    (v.Float(64, v.BIG), 1.0, "3F F0 00 00 00 00 00 00"), (v.Float(64, v.LITTLE), -2.0, "00 00 00 00 00 00 00 C0"),
]


@pytest.mark.parametrize("vtype,value,data", FLOAT_ROWS, ids=[f"{r[0].name}={r[1]}" for r in FLOAT_ROWS])
def test_float_byte_table(vtype, value, data):
    assert_row(vtype, value, h(data))
    assert math.copysign(1, vtype.decode(h(data))) == math.copysign(1, value)


def test_float_encode_errors():
    with pytest.raises(v.EncodeError, match="outside"):
        v.F32LE.encode(1e39)
    for bad in ("1.0", None, True):
        with pytest.raises(v.EncodeError):
            v.F32LE.encode(bad)
    assert math.isnan(v.F32LE.decode(v.F32LE.encode(math.nan)))


# -- strings and byte arrays -----------------------------------------------------------------------
STRING_ROWS = [
    (v.String(8), "V2B0", b"V2B0\0\0\0\0"),
    (v.String(4), "ABCD", b"ABCD"),  # full, no pad byte left
    (v.String(4), "", b"\0\0\0\0"),
    (v.String(6, pad=b" "), "SCU", b"SCU   "),
    (v.String(5, encoding="latin-1"), "Tür", b"T\xfcr\0\0"),
    (v.String(8, encoding="utf-8"), "Tür", b"T\xc3\xbcr\0\0\0\0"),
]


@pytest.mark.parametrize("vtype,value,data", STRING_ROWS, ids=[r[1] or "empty" for r in STRING_ROWS])
def test_string_byte_table(vtype, value, data):
    assert_row(vtype, value, data)


def test_string_errors():
    with pytest.raises(v.EncodeError, match="do not fit"):
        v.String(4).encode("ABCDE")
    with pytest.raises(v.EncodeError, match="ascii"):
        v.String(8).encode("Tür")
    with pytest.raises(v.EncodeError, match="pad byte"):
        v.String(8).encode("AB\0")  # would read back as "AB"
    with pytest.raises(v.EncodeError):
        v.String(8).encode(12)
    with pytest.raises(v.DecodeError, match="0xFC"):
        v.String(4).decode(b"T\xfcr\0")
    with pytest.raises(v.TruncatedError):
        v.String(31).decode(b"V2B0")


def test_byte_arrays():
    assert_row(v.Bytes(3), b"\x01\x02\xff", h("01 02 FF"))
    assert_row(v.Bytes(0), b"", b"")
    assert_row(v.Bytes(None), b"\x00\x01", h("00 01"))  # the rest of the data, any length
    assert v.Bytes(None).decode(b"") == b""
    with pytest.raises(v.EncodeError, match="3 needed"):
        v.Bytes(3).encode(b"\x01\x02")
    with pytest.raises(v.EncodeError):
        v.Bytes(2).encode("ab")
    with pytest.raises(v.TruncatedError):
        v.Bytes(3).decode(b"\x01")


def test_arrays():
    cyclic = v.Array(v.U16LE, 12)  # SCU CyclicObj 3001: UINT16[12], -1 = no transfer (section 4.3)
    unused = [0xFFFF] * 12
    assert_row(cyclic, tuple(unused), b"\xff" * 24)
    chosen = (0x3011, 0x3021) + (0xFFFF,) * 4 + (0x0011, 0x0171) + (0xFFFF,) * 4
    data = h("11 30 21 30") + b"\xff" * 8 + h("11 00 71 01") + b"\xff" * 8
    assert_row(cyclic, chosen, data)
    assert cyclic.size == 24
    with pytest.raises(v.EncodeError, match="11 items given, 12 needed"):
        cyclic.encode([0] * 11)
    with pytest.raises(v.EncodeError, match=r"^\[2\]: 70000 is outside"):
        cyclic.encode([0, 0, 70000] + [0] * 9)
    with pytest.raises(v.EncodeError):
        cyclic.encode(b"\x00" * 24)
    with pytest.raises(v.TruncatedError):
        cyclic.decode(b"\xff" * 23)


# -- enums and bit fields ------------------------------------------------------------------------
GATE_STATE = v.Enum(v.U8, {  # MO 64 gate state, telegram 0x0C (SPEC-NOTES "Bauer MO 64")
    0: "opening", 1: "closing", 2: "pre-warning before opening", 3: "pre-warning before closing",
    4: "open", 5: "closed", 6: "intermediate position",
})


def test_enum():
    assert_row(GATE_STATE, 5, h("05"))
    assert GATE_STATE.decode(h("04")).name == "open"
    assert GATE_STATE.encode("Closed") == h("05")
    undefined = GATE_STATE.decode(h("09"))  # kept so it can be shown, not a decode error
    assert undefined == 9 and undefined.name is None
    with pytest.raises(v.EncodeError, match="not one of"):
        GATE_STATE.encode(9)
    with pytest.raises(v.EncodeError, match="not one of"):
        GATE_STATE.encode("ajar")
    signed = v.Enum(v.I16BE, hd.DIRECTION)  # HD-Lock input 11: -1/0/1
    assert signed.decode(h("FF FF")) == -1 and signed.decode(h("FF FF")).name == hd.DIRECTION[-1]
    assert signed.encode(-1) == h("FF FF")


SCU_ACTUATOR_STATUS_1 = v.Bits(v.U8, (  # data IDs 0171..0176 (section 4.3)
    v.BitField("present", 0), v.BitField("limit_in_out", 1), v.BitField("switch_1", 2),
    v.BitField("switch_2", 3), v.BitField("motion", 4), v.BitField("in_position", 5),
    v.BitField("out_position", 6), v.BitField("stroke_recorded", 7),
))


def test_bit_fields():
    status = SCU_ACTUATOR_STATUS_1.decode(h("11"))  # RG 71 01 answer: bit 4 = motion active (section 5)
    assert status == 0x11 and status["motion"] is True and status.active == ["present", "motion"]
    assert_row(SCU_ACTUATOR_STATUS_1, 0x11, h("11"))
    assert SCU_ACTUATOR_STATUS_1.encode({"present": True, "motion": 1}) == h("11")
    clock = v.Bits(v.U16BE, (v.BitField("ready", 0), v.BitField("source", 4, 2, {0: "HSI", 1: "HSE", 2: "PLL"})))
    word = clock.decode(h("00 21"))
    assert word["source"] == 2 and word["source"].name == "PLL" and word["ready"] is True
    assert clock.encode({"ready": True, "source": "PLL"}) == h("00 21")
    assert_row(clock, 0x8021, h("80 21"))  # bits no field names survive the round trip
    with pytest.raises(v.EncodeError, match="does not fit in 2 bit"):
        clock.encode({"source": 4})
    with pytest.raises(v.EncodeError, match="no bit field"):
        clock.encode({"sauce": 1})
    with pytest.raises(v.EncodeError, match="source"):
        clock.encode({"source": "XTAL"})
    with pytest.raises(ValueError, match="overlaps"):
        v.Bits(v.U8, (v.BitField("a", 0, 2), v.BitField("b", 1)))
    with pytest.raises(ValueError, match="does not fit"):
        v.Bits(v.U8, (v.BitField("a", 7, 2),))
    with pytest.raises(ValueError, match="unsigned"):
        v.Bits(v.I8, (v.BitField("a", 0),))


def test_scaled():
    current = v.Scaled(v.U16LE, 0.1, "A")  # SCU 00A1 Strom: fixed point 0.1 A (section 4.3)
    assert_row(current, 12.5, h("7D 00"))
    assert_row(v.Scaled(v.I16BE, 0.1, "°C"), -3.2, h("FF E0"))
    with pytest.raises(v.EncodeError, match=r"outside 0 .. 6553.5 A"):
        current.encode(6553.6)
    with pytest.raises(v.EncodeError):
        current.encode("1")


# -- errors: short and excess data --------------------------------------------------------------
def test_short_and_excess_data_are_named_errors():
    with pytest.raises(v.TruncatedError) as exc:
        v.U32LE.decode(h("01 02 03"))
    assert exc.value.needed == 4 and exc.value.got == 3 and isinstance(exc.value, v.DecodeError)
    with pytest.raises(v.ExcessDataError) as exc:
        v.U16LE.decode(h("01 02 03"))
    assert exc.value.size == 2 and exc.value.got == 3
    assert v.U16LE.decode(h("01 02 03"), allow_excess=True) == 0x0201
    assert v.U8.decode_from(h("AA BB CC"), 1) == (0xBB, 2)
    assert issubclass(v.DecodeError, ValueError) and issubclass(v.EncodeError, ValueError)


# -- SCU data directory as data (document 002, sections 4.3, 5, 7) ----------------------------------
def _actuator_positions() -> v.Struct:
    """ACTUATOR_POSITIONSstruct (section 7): 4 users x 6 INT32, then the two virtual limits."""
    names = ["Position_Memory_1", "Position_Memory_2", "Position_Memory_3", "Position_Memory_4",
             "Position_Intermediate_In", "Position_Intermediate_Out"]
    members = [(f"{n}[USER_{u}]", v.I32LE) for u in range(1, 5) for n in names]
    members += [("Position_Virtual_Limit_In", v.I32LE), ("Position_Virtual_Limit_Out", v.I32LE)]
    return v.Struct("ACTUATOR_POSITIONS", tuple(members))


# data ID -> (name, type); multi-byte values little-endian (section 3 "Intel Little Endian")
SCU_DATA = {
    0x0001: ("Firmware info", v.String(31)),
    0x0011: ("Actual_Position Actuator 1", v.I32LE),
    0x0010: ("Actual_Position Actuators 1..6", v.Array(v.I32LE, 6)),
    0x0031: ("Actual_State_Analogue_Input_1", v.Scaled(v.U16LE, 0.01, "V")),
    0x00A1: ("Strom A1", v.Scaled(v.U16LE, 0.1, "A")),
    0x00D1: ("Error_Code 1", v.U32LE),
    0x0164: ("Battery voltage", v.Scaled(v.U16LE, 0.1, "V")),
    0x0171: ("Actuator Status 1 A1", SCU_ACTUATOR_STATUS_1),
    0x1011: ("Conversion factor A1", v.F32LE),
    0x2001: ("UserPositionData A1", _actuator_positions()),
    0x3001: ("CyclicObj 1", v.Array(v.U16LE, 12)),
    0x3011: ("Remote Speed F1", v.U16LE),
    0x3021: ("Remote Position A1", v.I32LE),
}


def test_scu_data_directory_sizes_match_the_document_examples():
    # RG 11 00 answers ctp 04 00 + 4 data bytes; RG 71 01 answers ctp 01 00 + Status (section 5)
    assert SCU_DATA[0x0011][1].size == 4 and SCU_DATA[0x0171][1].size == 1
    assert SCU_DATA[0x0001][1].size == 31  # "Size = 31 B"
    assert SCU_DATA[0x0010][1].size == 24  # group index 0010: all six positions
    assert SCU_DATA[0x2001][1].size == 26 * 4
    assert SCU_DATA[0x3001][1].size == 24


def test_scu_example_telegram_fields():
    # RT 04 00 11 30 01 00: ctp 4 = data ID 3011 + UINT16 remote speed 1 (section 5)
    payload = h("11 30 01 00")
    assert v.U16LE.decode(payload[:2]) == 0x3011
    assert SCU_DATA[0x3011][1].decode(payload[2:]) == 1
    assert SCU_DATA[0x3011][1].encode(1) == payload[2:]
    # an actual position answer (RG 11 00 -> ctp 04 00, 1.Byte..4.Byte)
    assert_row(SCU_DATA[0x0011][1], -1000, h("18 FC FF FF"))
    assert_row(SCU_DATA[0x0010][1], (1, -1, 0, 0, 256, 2**31 - 1),
               h("01000000 FFFFFFFF 00000000 00000000 00010000 FFFFFF7F"))
    assert_row(SCU_DATA[0x0001][1], "SCU V2B3", b"SCU V2B3" + b"\0" * 23)
    assert_row(SCU_DATA[0x0164][1], 24.0, h("F0 00"))
    assert_row(SCU_DATA[0x1011][1], 0.5, h("00 00 00 3F"))


def test_scu_struct_round_trip():
    positions = _actuator_positions()
    value = {name: i * 1000 - 5000 for i, (name, _) in enumerate(positions.members)}
    data = b"".join(v.I32LE.encode(x) for x in value.values())
    assert_row(positions, value, data)
    assert positions.offsets["Position_Memory_1[USER_2]"] == 24
    assert positions.offsets["Position_Virtual_Limit_Out"] == 100
    missing = dict(value)
    del missing["Position_Virtual_Limit_In"]
    with pytest.raises(v.EncodeError, match="missing"):
        positions.encode(missing)
    with pytest.raises(v.EncodeError, match=r"^Position_Memory_3\[USER_1\]: "):
        positions.encode({**value, "Position_Memory_3[USER_1]": 2**31})
    with pytest.raises(v.TruncatedError):
        positions.decode(data[:-1])


# -- MO 64 telegram fields as data (SPEC-NOTES "Bauer MO 64") ------------------------------------------
ERROR_LEVEL = v.Struct("error_level", (("flags", v.U32LE), ("timestamp_h", v.U32LE)))
ERROR_MEMORY = v.Array(ERROR_LEVEL, 10)  # telegram 0x17: 10 levels of (flags u32, time stamp u32)

_STATUS_BITS = (
    ["Funk", "BT", "BTA1", "BTA2", "BTA3", "BTZ1A", "BTZ1B", "BTZ2"],
    ["BTS", "Baum ab", "LS", "SLZ", "F_ereignis", "SERVICE", "mains monitoring"],
    ["adjusting loop A", "adjusting loop B", "adjusting loop C",
     "loop A occupied", "loop B occupied", "loop C occupied", "loop EXT"],
    [f"multi relay {n}" for n in range(1, 9)],
    [f"multi relay {n}" for n in range(9, 15)],
)
BARRIER_STATUS = v.Struct("barrier_status", (  # telegram 0x07: 40 bits, Status0..Status4
    ("status", v.Bits(v.Int(40, False, v.LITTLE), tuple(
        v.BitField(name, 8 * byte + bit) for byte, names in enumerate(_STATUS_BITS) for bit, name in enumerate(names)
    ))),
    ("more", v.Bytes(None)),  # some firmware sends more status bytes: kept raw
))


def test_mo64_error_memory():
    assert ERROR_MEMORY.size == 80
    levels = tuple({"flags": 1 << i, "timestamp_h": 1000 * i} for i in range(10))
    data = b"".join((1 << i).to_bytes(4, "little") + (1000 * i).to_bytes(4, "little") for i in range(10))
    assert_row(ERROR_MEMORY, levels, data)
    assert data[8:16] == h("02 00 00 00 E8 03 00 00")  # fehlerflaggen_lo0 ..., zeitstempel_lo0 ...
    with pytest.raises(v.TruncatedError):
        ERROR_MEMORY.decode(data[:-1])
    with pytest.raises(v.ExcessDataError):
        ERROR_MEMORY.decode(data + b"\0")
    broken = list(levels)
    broken[3] = {"flags": 0, "timestamp_h": -1}
    with pytest.raises(v.EncodeError, match=r"^\[3\]\.timestamp_h: -1 is outside"):
        ERROR_MEMORY.encode(broken)


def test_mo64_barrier_status_bit_fields():
    data = h("02 02 08 81 20")  # BT, Baum ab, loop A occupied, relays 1 and 8, relay 14
    status = BARRIER_STATUS.decode(data)
    assert status["status"].active == ["BT", "Baum ab", "loop A occupied", "multi relay 1", "multi relay 8",
                                       "multi relay 14"]
    assert status["more"] == b""
    assert BARRIER_STATUS.encode(status) == data
    longer = BARRIER_STATUS.decode(data + h("AA BB"))
    assert longer["status"] == status["status"] and longer["more"] == h("AA BB")
    assert BARRIER_STATUS.encode(longer) == data + h("AA BB")
    assert BARRIER_STATUS.encode({"status": {"BT": 1, "multi relay 14": True}, "more": b""}) == h("02 00 00 00 20")
    with pytest.raises(v.TruncatedError):
        BARRIER_STATUS.decode(data[:4])


def test_mo64_scalar_fields():
    assert_row(v.I8, -1, h("FF"))  # barrier position, -1 while unknown
    assert_row(v.I32LE, -5, h("FB FF FF FF"))  # vehicle counter
    assert_row(v.Scaled(v.U16LE, 0.01, "s"), 12.5, h("E2 04"))  # t_open in 10 ms, t_offen_lo t_offen_hi
    assert_row(v.Array(v.U16LE, 3), (1, 2, 0xFFFF), h("01 00 02 00 FF FF"))  # loop-adjust counters


# -- a Modbus register is one case of the model ---------------------------------------------------------
def _samples(param: Param) -> list[int]:
    top = (1 << param.bits) - 1
    return sorted({0, 1, 0x7F, 0x80, 0x7FFF, 0x8000, 0xFFC4 & top, 0x0117, top, top >> 1, (top >> 1) + 1})


@pytest.mark.parametrize("param", list(hd.PARAMS), ids=lambda p: p.key)
def test_param_value_type_decodes_what_param_decodes(param):
    vtype = param.value_type
    assert vtype.size == 2 * param.words
    for raw in _samples(param):
        data = v.words_to_bytes(param.split(raw))
        decoded = vtype.decode(data)
        assert decoded == param.decode(raw)
        if isinstance(vtype, v.Enum) and decoded.name is None:
            assert param.enum_name(raw) is None
            with pytest.raises(v.EncodeError, match="not one of"):  # only named values are written
                vtype.encode(decoded)
            continue
        if param.enum is not None:
            assert decoded.name == param.enum_name(raw)
        assert vtype.encode(decoded) == data
        if param.fields:
            assert dict(decoded.fields) == {k: bool(x) if f.width == 1 else x for (k, x), f in
                                                       zip(param.field_values(raw).items(), param.fields)}


def test_hdlock_registers_as_typed_values():
    serial = hd.PARAMS.get(hd.INPUT, 104).value_type
    assert serial == v.U32BE  # input 104 = high word, 105 = low word (SPEC-NOTES)
    assert serial.decode(v.words_to_bytes([0x000A, 0x1234])) == 660020
    threshold = hd.PARAMS.by_name["SettingsProximityThresholdLock"].value_type
    assert threshold == v.I16BE and threshold.decode(h("FF C4")) == -60 and threshold.encode(-60) == h("FF C4")
    status = hd.PARAMS.by_name["LockStatus"].value_type.decode(h("01 17"))  # 0x0117 (section 4.3)
    assert status.active == ["LockRequest", "ProximityInPlace", "DoorInPosition", "LockRequest (bit 4)", "BoltLocked"]
    direction = hd.PARAMS.get(hd.INPUT, 11).value_type.decode(h("FF FF"))
    assert direction == -1 and direction.name == hd.DIRECTION[-1]
    assert v.bytes_to_words(h("00 0A 12 34")) == [0x000A, 0x1234]
    with pytest.raises(v.DecodeError):
        v.bytes_to_words(h("00 0A 12"))


def test_value_type_is_no_field_of_param():
    # additive only: equality, hashing, backups and constructors of Param are unchanged
    assert "value_type" not in {f.name for f in dataclasses.fields(Param)}
    p = Param("X", "holding", 1, scale=0.5, unit="V")
    assert p.value_type == v.Scaled(v.U16BE, 0.5, "V") and p.value_type.decode(h("00 03")) == p.decode(3)


def test_decoded_values_copy_pickle_and_serialise_as_numbers():
    status = BARRIER_STATUS.decode(h("02 02 08 81 20 AA"))
    state = GATE_STATE.decode(h("05"))
    for clone in (copy.deepcopy((status, state)), pickle.loads(pickle.dumps((status, state)))):
        assert clone == (status, state)
        assert clone[0]["status"].active == status["status"].active and clone[1].name == "closed"
    assert json.loads(json.dumps({"gate": state, "status": status["status"]})) == {
        "gate": 5, "status": int(status["status"])}
