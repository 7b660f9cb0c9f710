"""Bauer MO 64 LogiTed codec: golden vectors of SPEC-NOTES "Bauer MO 64", byte tables of every
named field (little-endian), refused queries, settings, and the frame splitter on TCP and RS485."""

from __future__ import annotations

import binascii
import random

import pytest

from devices import values as v
from devices.mo64 import codec as c


def h(text: str) -> bytes:
    return bytes.fromhex(text)


# -- golden vectors (SPEC-NOTES "Bauer MO 64", TCP frame) ------------------------------------------
GOLDEN = [
    ("query device", c.encode_query(0x00), h("55 02 02 00 45 BC")),
    ("query barrier status", c.encode_query(0x02), h("55 02 02 02 65 FE")),
    ("query gate state", c.encode_query(0x07), h("55 02 02 07 35 5B")),
    ("open pulse", c.encode_command(c.Command.OPEN, c.Function.PULSE), h("55 03 01 01 00 B8 B4")),
    ("close pulse", c.encode_command(c.Command.CLOSE, c.Function.PULSE), h("55 03 01 02 00 ED E7")),
]


@pytest.mark.parametrize("name,telegram,wire", GOLDEN, ids=[g[0] for g in GOLDEN])
def test_golden_vectors(name, telegram, wire):
    assert c.encode_frame(telegram) == wire
    frame = c.decode_frame(wire)
    assert bytes((frame.type,)) + frame.payload == telegram and frame.raw == wire
    assert c.encode_frame(bytes((frame.type,)) + frame.payload) == wire  # round trip
    request = c.decode_request(wire)
    if name.startswith("query"):
        assert request.kind is c.RequestType.QUERY and request.query == telegram[1]
    else:
        assert request.command == telegram[1] and request.function is c.Function.PULSE


@pytest.mark.parametrize("wire", [g[2] for g in GOLDEN])
def test_crc_is_crc_hqx_preset_ffff_high_byte_first(wire):
    crc = binascii.crc_hqx(wire[:-2], 0xFFFF)
    assert c.crc16(wire[:-2]) == crc
    assert wire[-2:] == bytes((crc >> 8, crc & 0xFF))  # CSH then CSL


def test_crc_check_value():
    assert c.crc16(b"123456789") == 0x29B1  # CRC-16/CCITT-FALSE check value


def test_split_golden_vectors_in_one_stream():
    stream = b"".join(g[2] for g in GOLDEN)
    frames = c.FrameSplitter().feed(stream)
    assert [f.raw for f in frames] == [g[2] for g in GOLDEN]


# -- queries ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("index", [0x1B, 0x1C, 0x1D, 0x1E])
def test_forbidden_query_indexes_are_never_encoded(index):
    with pytest.raises(c.CodecError, match="Nicht verwenden"):
        c.encode_query(index)
    with pytest.raises(c.InvalidRequest):  # a twin answers them with nak
        c.decode_request(c.encode_frame(bytes((0x02, index))))


@pytest.mark.parametrize("index", [0x1F, 0x20, 0xFF, -1, True, "2"])
def test_invalid_query_indexes_are_refused(index):
    with pytest.raises(c.CodecError):
        c.encode_query(index)


def test_every_valid_query_is_answered_by_index_plus_5():
    for index in range(0x1B):
        assert c.encode_query(index) == bytes((0x02, index))
        assert c.query_index(index + 5) == index
        assert index + 5 in c.TELEGRAMS and index + 5 in c.ANSWER_TYPES
    assert set(c.TELEGRAMS) == set(range(0x05, 0x20))


@pytest.mark.parametrize("level", range(10))
def test_error_memory_query_in_the_documents_form(level):
    # page 33 prints the query as "0x02 Auswahl index"; tele_fehlerspeicher is telegram 0x17 (5.1.23), the answer
    # to query index 0x17 - 5 like every answer (SPEC-NOTES "Replies"); "10 Ebenen (0...9)" (5.1.23)
    wire = c.encode_frame(c.encode_query(0x17 - 5, level=level, form="document"))
    assert wire[2:-2] == bytes((0x02, 0x17 - 5, level))  # type, Auswahl, index
    assert len(wire) == 7 and int.from_bytes(wire[-2:], "big") == binascii.crc_hqx(wire[:-2], 0xFFFF)  # 2.1, 2.3
    # 5.1.23: the answer carries "index fehlerflaggen_lo0 _lo1 _hi0 _hi1 zeitstempel_lo0 _lo1 _hi0 _hi1"
    answer = c.decode_answer(c.encode_frame(bytes((0x17, level)) + h("04 03 02 01 E8 03 00 00")))
    assert answer.value == {"index": level, "flags": 0x01020304, "timestamp_h": 1000}


def test_error_memory_levels_beyond_the_document_are_not_asked():
    for bad in (10, -1):  # "10 Ebenen (0...9)" (5.1.23)
        with pytest.raises(c.CodecError):
            c.encode_query(c.Q_ERROR_MEMORY, level=bad, form="document")
    with pytest.raises(c.CodecError):  # a level only where the document's answer has an index
        c.encode_query(c.Q_GATE_STATE, level=0)
    # that the index byte chooses the level is the reading the page lists among its assumptions
    assert c.ASSUMED_ERROR_MEMORY_LEVEL in c.ASSUMPTIONS


# -- operating commands ----------------------------------------------------------------------------
COMMANDS = [
    (c.Command.OPEN, c.Function.PULSE, h("01 01 00")),
    (c.Command.CLOSE, c.Function.PULSE, h("01 02 00")),
    (c.Command.REVERSE, c.Function.PULSE, h("01 00 00")),
    (c.Command.OPEN, c.Function.ACTIVATE, h("01 01 01")),
    (c.Command.OPEN, c.Function.DEACTIVATE, h("01 01 02")),
    (c.Command.CLOSE, c.Function.ACTIVATE, h("01 02 01")),
]


@pytest.mark.parametrize("command,function,telegram", COMMANDS)
def test_operating_commands(command, function, telegram):
    assert c.encode_command(command, function) == telegram
    request = c.decode_request(c.encode_frame(telegram))
    assert (request.command, request.function) == (command, function)


@pytest.mark.parametrize("command,function", [(3, 0), (1, 3), (0xFF, 0)])
def test_invalid_operating_commands(command, function):
    with pytest.raises(c.CodecError):
        c.encode_command(command, function)
    with pytest.raises(c.InvalidRequest):
        c.decode_request(c.encode_frame(bytes((0x01, command, function))))


def test_short_command_what_the_document_fixes():
    # 5.2.3 "Kurze Befehlstelegramme 0x03": the type byte; 2.1: 6 to 259 characters; 2.3: CRC preset 0xFFFF, CSH CSL
    wire = c.encode_frame(c.encode_short_command(0x05))
    assert wire[0] == 0x55 and wire[2] == 0x03 and 6 <= len(wire) <= 259 and wire[1] == len(wire) - 4
    assert int.from_bytes(wire[-2:], "big") == binascii.crc_hqx(wire[:-2], 0xFFFF)
    # the number of code bytes and the codes are not in the summary: one sentence of the assumptions the page shows
    assert c.ASSUMED_SHORT_COMMAND in c.ASSUMPTIONS


# -- replies ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("reply", list(c.Reply))
def test_replies(reply):
    wire = c.encode_frame(c.encode_answer(reply))
    assert wire[:3] == bytes((0x55, 0x01, reply))
    answer = c.decode_answer(wire)
    assert answer.reply is reply and answer.value is None and answer.error is None
    assert answer.name == reply.name.lower()


def test_same_type_byte_means_different_things_per_direction():
    wire = c.encode_frame(h("02 07"))
    assert c.decode_request(wire).query == 7
    assert c.decode_answer(c.encode_frame(h("02"))).reply is c.Reply.NAK


# -- answer telegrams: byte tables (type, payload, value), little-endian ----------------------------
ANSWERS = [
    (0x05, h("05 00"), 5),  # device code, Kennung_lo Kennung_hi
    (0x06, h("34 12"), 0x1234),  # program version u16
    (0x0A, h("78 56 34 12"), 0x12345678),  # service counter u32
    (0x0B, h("01 00 01 00"), 65537),  # maintenance counter u32
    (0x0C, h("04"), 4),  # gate state open
    (0x0D, h("E8 03"), 1000),  # t_offen = 10.00 s
    (0x0E, h("2C 01"), 300),  # pre-warning before opening = 3 s
    (0x0F, h("DC FF"), 65500),  # pre-warning before closing, the maximum
    (0x14, h("15 CD 5B 07"), 123456789),  # serial number snr_lo0 _lo1 _hi0 _hi1
    (0x15, h("00 1A 2B 3C 4D 5E"), h("00 1A 2B 3C 4D 5E")),  # MAC address
    (0x16, h("10 27 00 00"), 10000),  # operating hours u32
    (0x19, h("00 01 02 03 04 05"), (0, 1, 2, 3, 4, 5)),  # multi relays
    (0x1A, h("A0 86 01 00"), 100000),  # maintenance interval (u32 assumed)
    (0x1C, h("FB FF FF FF"), -5),  # vehicle counter i32
    (0x1C, h("00 00 00 80"), -2**31),
    (0x1C, h("FF FF FF 7F"), 2**31 - 1),
    (0x1D, h("FF"), -1),  # barrier position unknown
    (0x1D, h("64"), 100),
    (0x1D, h("32"), 50),
    (0x1E, h("D2 04"), 1234),  # password u16
    (0x1F, h("01 00 02 01 FF FF"), (1, 0x0102, 0xFFFF)),  # loop-adjust counters A, B, C
    (0x12, h("01 00 00 80 03 00"), (1, 0x8000, 3)),  # induction loop mode registers
    (0x11, h("AA BB"), h("AA BB")),  # counting function: raw
    (0x1B, h("01 02 03 04 05 06"), h("01 02 03 04 05 06")),  # loop periods: raw
]


@pytest.mark.parametrize("answer_type,payload,value", ANSWERS,
                         ids=[f"{t:02X}-{p.hex()}" for t, p, _ in ANSWERS])
def test_answer_byte_table(answer_type, payload, value):
    wire = c.encode_frame(bytes((answer_type,)) + payload)
    answer = c.decode_answer(wire)
    assert answer.error is None, answer.error
    assert answer.value == value
    assert answer.query == answer_type - 5
    assert c.encode_answer(answer_type, answer.value) == bytes((answer_type,)) + payload  # round trip
    assert c.encode_frame(c.encode_answer(answer_type, value)) == wire


def test_named_values():
    assert c.decode_value(0x05, h("05 00")).name == "MO 64-V4 (Stand 19.07.2011)"
    assert c.decode_value(0x05, h("01 00")).name is None  # printed "xxx": kept, unnamed
    for number, name in c.GATE_STATE_NAMES.items():
        state = c.decode_value(0x0C, bytes((number,)))
        assert state.name == name and state == c.GateState(number)
    assert c.decode_value(0x0C, h("07")).name is None
    assert c.time_s(c.decode_value(0x0D, h("E8 03"))) == 10.0
    assert c.format_mac(c.decode_value(0x15, h("00 1A 2B 3C 4D 5E"))) == "00:1A:2B:3C:4D:5E"


def test_gate_state_names_cover_the_enum():
    assert [c.GATE_STATE_NAMES[s] for s in c.GateState] == [
        "opening", "closing", "pre-warning before opening", "pre-warning before closing",
        "open", "closed", "intermediate position"]


def test_barrier_status_40_bits_by_name():
    payload = h("02 06 08 81 20")  # BT; Baum ab, LS; loop A occupied; relays 1, 8; relay 14
    status = c.decode_value(0x07, payload)
    assert status["status"].active == ["BT", "Baum ab", "LS", "loop A occupied", "multi relay 1",
                                       "multi relay 8", "multi relay 14"]
    assert status["more"] == b""
    assert c.encode_answer(0x07, status) == b"\x07" + payload
    longer = c.decode_value(0x07, payload + h("AA BB"))  # more status bytes: kept raw
    assert longer["status"] == status["status"] and longer["more"] == h("AA BB")
    assert c.encode_answer(0x07, longer) == b"\x07" + payload + h("AA BB")
    names = [f.name for f in c.STATUS_BITS.fields]
    assert len(names) == 36 and len(set(names)) == 36  # 8 + 7 + 7 + 8 + 6 named of 40
    assert sorted(n for group in c.STATUS_GROUPS.values() for n in group) == sorted(names)
    single = {0: "Funk", 8: "BTS", 9: "Baum ab", 10: "LS", 12: "F_ereignis", 13: "SERVICE", 16: "adjusting loop A",
              19: "loop A occupied", 22: "loop EXT", 24: "multi relay 1", 32: "multi relay 9", 37: "multi relay 14"}
    for bit, name in single.items():
        assert c.decode_value(0x07, (1 << bit).to_bytes(5, "little"))["status"].active == [name]
    answer = c.decode_answer(c.encode_frame(b"\x07" + payload[:4]))  # too short: kept raw with error
    assert answer.value is None and "needs" in answer.error and answer.payload == payload[:4]


def test_status_mask_and_change_monitoring():
    mask = c.decode_value(0x08, h("00 04 38 00 00"))
    assert mask["mask"].active == ["LS", "loop A occupied", "loop B occupied", "loop C occupied"]
    flags = c.decode_value(0x09, h("49 01"))  # bits 0, 3, 6, 8 (Flaggen_lo Flaggen_hi)
    assert flags.active == ["barrier status", "gate state", "barrier position", "loop debug"]
    assert c.CHANGE_MONITORING.encode({"barrier status": 1, "loop debug": 1}) == h("01 01")


def test_error_memory_entries():
    entry = c.decode_value(0x17, h("03 04 03 02 01 E8 03 00 00"))  # index, fehlerflaggen_lo0 .., zeitstempel_lo0 ..
    assert entry == {"index": 3, "flags": 0x01020304, "timestamp_h": 1000}
    assert c.encode_answer(0x17, entry) == h("17 03 04 03 02 01 E8 03 00 00")
    levels = tuple({"flags": 1 << i, "timestamp_h": 1000 * i} for i in range(10))
    data = b"".join((1 << i).to_bytes(4, "little") + (1000 * i).to_bytes(4, "little") for i in range(10))
    assert c.decode_value(0x17, data) == levels  # all ten levels in one telegram
    assert c.encode_answer(0x17, levels) == b"\x17" + data
    assert data[8:16] == h("02 00 00 00 E8 03 00 00")
    assert c.decode_answer(c.encode_frame(b"\x17" + data[:7])).error


def test_dec_bt_direction_logics_config_flags():
    dec = c.decode_value(0x10, h("06 00 00 80"))  # A1 = 2, A2 = 1, a code is stored
    assert dec["A1"] == 2 and dec["A2"] == 1 and dec["A9"] == 0 and dec["code stored"] is True
    logics = c.decode_value(0x13, h("05 00 0C 00 00 00 00 00"))
    assert logics[0]["input selection"] == 5 and logics[0]["presence right"] == 3
    assert logics[1] == 0
    assert c.encode_answer(0x13, logics) == h("13 05 00 0C 00 00 00 00 00")
    flags = c.decode_value(0x18, h("06 00 00 02 00 01 FF FF"))
    assert flags["konfig0"]["RtApl blink in end position"] == 2
    assert flags["konfig0"]["RtApl blink at pre-warning open"] == 1
    assert flags["konfig1"]["GnApl blink at intermediate stop"] == 2
    assert flags["konfig2"]["warning light blink in end position open"] == 1
    assert flags["konfig3"] == 0xFFFF  # no numbered fields: raw word
    assert c.encode_answer(0x18, flags) == h("18 06 00 00 02 00 01 FF FF")


def test_unknown_answer_kept_raw():
    answer = c.decode_answer(c.encode_frame(h("42 01 02")))
    assert answer.value is None and answer.payload == h("01 02") and "unknown" in answer.error
    assert c.describe(c.decode_frame(c.encode_frame(h("42 01 02"))), to_device=False).startswith("unknown")


def test_describe_for_the_monitor():
    assert c.describe(c.decode_frame(h("55 02 02 07 35 5B")), to_device=True) == "query 0x07 (gate state)"
    assert c.describe(c.decode_frame(h("55 03 01 01 00 B8 B4")), to_device=True) == "open pulse"
    assert "gate state" in c.describe(c.decode_frame(c.encode_frame(h("0C 05"))), to_device=False)


# -- settings --------------------------------------------------------------------------------------
SETTING_ROWS = [
    ("t_open", 1000, h("04 00 E8 03")),
    ("t_open", 0, h("04 00 00 00")),  # 0: automatic closing off
    ("t_open", 65500, h("04 00 DC FF")),
    ("t_prewarn_open", 300, h("04 01 2C 01")),
    ("t_prewarn_close", 200, h("04 02 C8 00")),
    ("change_monitoring", 0x01FF, h("04 04 FF 01")),
    ("vehicle_counter", -5, h("05 00 FB FF FF FF")),
    ("maintenance_interval", 100000, h("05 01 A0 86 01 00")),
    ("status_mask", 0x2081060402, h("06 00 02 04 06 81 20")),
    ("multi_relays", (1, 2, 3, 4, 5, 6), h("07 00 01 02 03 04 05 06")),
    ("config_flags", {"konfig0": 6, "konfig1": 0x200, "konfig2": 0x100, "konfig3": 0xFFFF},
     h("08 00 06 00 00 02 00 01 FF FF")),
]


@pytest.mark.parametrize("key,value,telegram", SETTING_ROWS, ids=[f"{r[0]}={r[1]}" for r in SETTING_ROWS])
def test_setting_encoding(key, value, telegram):
    assert c.encode_setting(key, value) == telegram
    request = c.decode_request(c.encode_frame(telegram))
    assert request.setting is c.SETTINGS[key] and request.value == value
    setting = c.SETTINGS[key]
    assert len(telegram) == 2 + c.SETTING_VALUE_BYTES[setting.telegram]
    # read back: the answer to the setting's query decodes to the same value
    answer = c.decode_answer(c.encode_frame(bytes((setting.query + 5,)) + telegram[2:]))
    assert c.setting_value(key, answer) == value


@pytest.mark.parametrize("key,value", [
    ("t_open", 65501), ("t_open", -1), ("t_prewarn_open", 70000), ("t_open", 1.5), ("t_open", True),
    ("vehicle_counter", 2**31), ("change_monitoring", 0x10000), ("status_mask", 1 << 40),
    ("multi_relays", (1, 2, 3)), ("multi_relays", (256, 0, 0, 0, 0, 0)), ("maintenance_interval", -1),
    ("config_flags", {"konfig0": 0}), ("no such setting", 0),
])
def test_setting_range_checks(key, value):
    with pytest.raises(c.CodecError):
        c.encode_setting(key, value)


def test_setting_directory():
    for s in c.SETTINGS.values():
        assert 0x04 <= s.telegram <= 0x08 and s.query in c.QUERY_INDEXES
    vehicle = c.SETTINGS["vehicle_counter"]
    assert not vehicle.backup and not vehicle.eeprom  # RAM only, not restored
    assert all(s.backup and s.eeprom for k, s in c.SETTINGS.items() if k != "vehicle_counter")
    assumed = {k for k, s in c.SETTINGS.items() if s.assumed}
    assert assumed == {"t_prewarn_open", "t_prewarn_close", "vehicle_counter", "maintenance_interval"}
    assert len(c.ASSUMPTIONS) >= 5 and all(isinstance(a, str) and a for a in c.ASSUMPTIONS)


def test_setting_request_out_of_range_is_nak():
    with pytest.raises(c.InvalidRequest):
        c.decode_request(c.encode_frame(h("04 00 DD FF")))  # 65501 > 65500
    with pytest.raises(c.InvalidRequest):
        c.decode_request(c.encode_frame(h("04 00 01")))  # short
    unknown = c.decode_request(c.encode_frame(h("04 09 01 00")))  # selector not in the directory: raw
    assert unknown.setting is None and unknown.value == h("01 00")


# -- RS485 framing (ASSUMED layout) -----------------------------------------------------------------
def test_rs485_frame_layout():
    wire = c.encode_frame(c.encode_query(0x07), c.RS485, da=0x10)
    assert wire[:6] == h("55 04 10 00 02 07")  # SD LE DA SA type index
    assert int.from_bytes(wire[-2:], "big") == binascii.crc_hqx(wire[:-2], 0xFFFF)
    frame = c.decode_frame(wire, c.RS485)
    assert (frame.da, frame.sa, frame.type, frame.payload) == (0x10, 0x00, 0x02, h("07"))
    answer = c.decode_answer(c.encode_frame(h("0C 05"), c.RS485, da=0x00, sa=0x10), c.RS485)
    assert answer.value.name == "closed" and answer.frame.sa == 0x10
    with pytest.raises(c.CodecError):
        c.encode_frame(h("02 00"), c.RS485)  # no DA
    with pytest.raises(c.CodecError):
        c.encode_frame(h("02 00"), c.RS485, da=256)


def test_rs485_token_telegram():
    token = c.encode_token(0x01, sa=0x00)
    assert len(token) == 6 and token[:4] == h("55 02 01 00")  # the shortest telegram: 6 characters
    frame = c.decode_frame(token, c.RS485)
    assert frame.is_token and (frame.da, frame.sa) == (0x01, 0x00)
    with pytest.raises(c.InvalidRequest):
        c.decode_request(frame)


def test_length_limits():
    assert len(c.encode_frame(bytes(255))) == 259  # chapter 2.1: at most 259 characters
    with pytest.raises(c.CodecError):
        c.encode_frame(bytes(256))
    with pytest.raises(c.CodecError):
        c.encode_frame(bytes(254), c.RS485, da=1)
    with pytest.raises(c.CodecError):
        c.encode_frame(b"")


# -- the splitter ----------------------------------------------------------------------------------
def _tcp_stream():
    frames = [g[2] for g in GOLDEN] + [c.encode_frame(c.encode_answer(0x0C, 4)),
                                       c.encode_frame(c.encode_answer(c.Reply.ACK)),
                                       c.encode_frame(b"\x17" + bytes(80))]
    return frames


def _rs485_stream():
    return [c.encode_frame(c.encode_query(0x02), c.RS485, da=0x10),
            c.encode_token(0x01),
            c.encode_frame(h("07 02 06 08 81 20"), c.RS485, da=0x00, sa=0x10),
            c.encode_token(0x00, sa=0x01),
            c.encode_frame(c.encode_command(1), c.RS485, da=0x11, sa=0x01)]


@pytest.mark.parametrize("framing,frames", [(c.TCP, _tcp_stream()), (c.RS485, _rs485_stream())],
                         ids=["tcp", "rs485"])
def test_splitter_split_and_merged(framing, frames):
    stream = b"".join(frames)
    whole = c.FrameSplitter(framing).feed(stream)
    assert [f.raw for f in whole] == frames
    splitter = c.FrameSplitter(framing)  # byte by byte
    got = [item for byte in stream for item in splitter.feed(bytes((byte,)))]
    assert [f.raw for f in got] == frames and splitter.pending == b"" and splitter.errors == 0
    rng = random.Random(13)  # random chunks
    splitter, got, at = c.FrameSplitter(framing), [], 0
    while at < len(stream):
        n = rng.randint(1, 9)
        got += splitter.feed(stream[at:at + n])
        at += n
    assert [f.raw for f in got] == frames and splitter.frames == len(frames)


@pytest.mark.parametrize("framing,frames", [(c.TCP, _tcp_stream()), (c.RS485, _rs485_stream())],
                         ids=["tcp", "rs485"])
def test_splitter_garbled(framing, frames):
    bad_crc = bytearray(frames[0])
    bad_crc[-1] ^= 0xFF
    stream = b"\x00\xAA" + frames[1] + bytes(bad_crc) + b"\x55" + frames[2] + frames[3]
    splitter = c.FrameSplitter(framing)
    items = splitter.feed(stream)
    kinds = [type(i).__name__ for i in items]
    assert kinds == ["GarbageError", "Frame", "ChecksumError", "GarbageError", "Frame", "Frame"]
    assert items[0].raw == b"\x00\xAA" and items[2].raw == bytes(bad_crc) and items[3].raw == b"\x55"
    assert [items[1].raw, items[4].raw, items[5].raw] == [frames[1], frames[2], frames[3]]
    assert splitter.errors == 3 and splitter.frames == 3


def test_splitter_impossible_length_and_cut_off():
    splitter = c.FrameSplitter(c.TCP)
    items = splitter.feed(h("55 00") + GOLDEN[0][2])  # LE 0: no type byte
    assert isinstance(items[0], c.FrameLengthError) and items[1].raw == GOLDEN[0][2]
    rs = c.FrameSplitter(c.RS485)
    items = rs.feed(h("55 01 10") + c.encode_token(2))  # LE 1: below DA SA
    assert isinstance(items[0], c.FrameLengthError)
    assert isinstance(items[-1], c.Frame) and items[-1].is_token
    cut = GOLDEN[3][2][:4]
    assert splitter.feed(cut) == [] and splitter.pending == cut
    expired = splitter.expire()
    assert len(expired) == 1 and isinstance(expired[0], c.TruncatedFrameError) and expired[0].raw == cut
    assert splitter.expire() == []


def test_splitter_stray_sd_does_not_swallow_the_next_frame():
    splitter = c.FrameSplitter(c.TCP)
    items = splitter.feed(b"\x55" + GOLDEN[2][2])  # 0x55 read as SD announces LE 0x55
    assert [type(i).__name__ for i in items] == ["GarbageError", "Frame"]
    assert items[1].raw == GOLDEN[2][2]


def test_decode_frame_errors():
    wire = GOLDEN[0][2]
    with pytest.raises(c.GarbageError):
        c.decode_frame(b"\x00" + wire[1:])
    with pytest.raises(c.TruncatedFrameError):
        c.decode_frame(wire[:-1])
    with pytest.raises(c.FrameLengthError):
        c.decode_frame(wire + b"\x00")
    with pytest.raises(c.ChecksumError) as err:
        c.decode_frame(wire[:-1] + b"\x00")
    assert err.value.expected == 0x45BC and err.value.received == 0x4500


def test_codec_is_pure():
    import ast
    import inspect
    tree = ast.parse(inspect.getsource(c))
    imported = {n.names[0].name.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.Import)}
    imported |= {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    assert imported <= {"__future__", "binascii", "collections", "dataclasses", "enum", "typing", "devices"}
    assert v.Int(40).size == 5
