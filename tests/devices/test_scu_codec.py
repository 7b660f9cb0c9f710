"""SCU codec (document 002, sections 3 to 6): golden vectors, answers, error codes, the stream splitter.

Every example telegram of section 5 is a row: encode, decode and round trip. The checksums
are checked against the document's own CRC table and algorithm (section 6), not only
against binascii.crc_hqx.
"""

from __future__ import annotations

import binascii

import pytest

from devices.scu import codec as c


def h(text: str) -> bytes:
    return bytes.fromhex(text)


# -- section 6: the document's CRC table, as printed -----------------------------------------------------
DOC_CRC_TABLE = [
    0x0000, 0x1021, 0x2042, 0x3063, 0x4084, 0x50A5, 0x60C6, 0x70E7,
    0x8108, 0x9129, 0xA14A, 0xB16B, 0xC18C, 0xD1AD, 0xE1CE, 0xF1EF,
    0x1231, 0x0210, 0x3273, 0x2252, 0x52B5, 0x4294, 0x72F7, 0x62D6,
    0x9339, 0x8318, 0xB37B, 0xA35A, 0xD3BD, 0xC39C, 0xF3FF, 0xE3DE,
    0x2462, 0x3443, 0x0420, 0x1401, 0x64E6, 0x74C7, 0x44A4, 0x5485,
    0xA56A, 0xB54B, 0x8528, 0x9509, 0xE5EE, 0xF5CF, 0xC5AC, 0xD58D,
    0x3653, 0x2672, 0x1611, 0x0630, 0x76D7, 0x66F6, 0x5695, 0x46B4,
    0xB75B, 0xA77A, 0x9719, 0x8738, 0xF7DF, 0xE7FE, 0xD79D, 0xC7BC,
    0x48C4, 0x58E5, 0x6886, 0x78A7, 0x0840, 0x1861, 0x2802, 0x3823,
    0xC9CC, 0xD9ED, 0xE98E, 0xF9AF, 0x8948, 0x9969, 0xA90A, 0xB92B,
    0x5AF5, 0x4AD4, 0x7AB7, 0x6A96, 0x1A71, 0x0A50, 0x3A33, 0x2A12,
    0xDBFD, 0xCBDC, 0xFBBF, 0xEB9E, 0x9B79, 0x8B58, 0xBB3B, 0xAB1A,
    0x6CA6, 0x7C87, 0x4CE4, 0x5CC5, 0x2C22, 0x3C03, 0x0C60, 0x1C41,
    0xEDAE, 0xFD8F, 0xCDEC, 0xDDCD, 0xAD2A, 0xBD0B, 0xED68, 0xD49,
    0x7E97, 0x6EB6, 0x5ED5, 0x4EF4, 0x3E13, 0x2E32, 0x1E51, 0x0E70,
    0xFF9F, 0xEFBE, 0xDFDD, 0xCFFC, 0xBF1B, 0xAF3A, 0x9F59, 0x8F78,
    0x9188, 0x81A9, 0xB1CA, 0xA1EB, 0xD10C, 0xC12D, 0xF14E, 0xE16F,
    0x1080, 0x00A1, 0x30C2, 0x20E3, 0x5004, 0x4025, 0x7046, 0x6067,
    0x83B9, 0x9398, 0xA3FB, 0xB3DA, 0xC33D, 0xD31C, 0xE37F, 0xF35E,
    0x02B1, 0x1290, 0x22F3, 0x32D2, 0x4235, 0x5214, 0x6277, 0x7256,
    0xB5EA, 0xA5CB, 0x95A8, 0x8589, 0xF56E, 0xE54F, 0xD52C, 0xC50D,
    0x34E2, 0x24C3, 0x14A0, 0x0481, 0x7466, 0x6447, 0x5424, 0x4405,
    0xA7DB, 0xB7FA, 0x8799, 0x97B8, 0xE75F, 0xF77E, 0xC71D, 0xD73C,
    0x26D3, 0x36F2, 0x0691, 0x16B0, 0x6657, 0x7676, 0x4615, 0x5634,
    0xD94C, 0xC96D, 0xF90E, 0xE92F, 0x99C8, 0x89E9, 0xB98A, 0xA9AB,
    0x5844, 0x4865, 0x7806, 0x6827, 0x18C0, 0x08E1, 0x3882, 0x28A3,
    0xCB7D, 0xDB5C, 0xEB3F, 0xFB1E, 0x8BF9, 0x9BD8, 0xABBB, 0xBB9A,
    0x4A75, 0x5A54, 0x6A37, 0x7A16, 0x0AF1, 0x1AD0, 0x2AB3, 0x3A92,
    0xFD2E, 0xED0F, 0xDD6C, 0xCD4D, 0xBDAA, 0xAD8B, 0x9DE8, 0x8DC9,
    0x7C26, 0x6C07, 0x5C64, 0x4C45, 0x3CA2, 0x2C83, 0x1CE0, 0x0CC1,
    0xEF1F, 0xFF3E, 0xCF5D, 0xDF7C, 0xAF9B, 0xBFBA, 0x8FD9, 0x9FF8,
    0x6E17, 0x7E36, 0x4E55, 0x5E74, 0x2E93, 0x3EB2, 0x0ED1, 0x1EF0,
]
# Two entries of the printed table are print errors: 0xED68 stands for 0x8D68 and 0xD49 for 0x9D49.
DOC_TABLE_PRINT_ERRORS = {110: (0xED68, 0x8D68), 111: (0x0D49, 0x9D49)}


def _doc_table() -> list[int]:
    table = list(DOC_CRC_TABLE)
    for index, (printed, correct) in DOC_TABLE_PRINT_ERRORS.items():
        assert table[index] == printed
        table[index] = correct
    return table


def doc_checksum(data: bytes) -> int:
    """CalculateChecksum of section 6, code example 6, line by line."""
    table, crc = _doc_table(), 0
    for byte in data:
        crc = (table[((crc >> 8) ^ byte) & 0xFF] ^ (crc << 8)) & 0xFFFF
    return crc


def test_crc_table_of_section_6_is_crc_hqx():
    assert len(DOC_CRC_TABLE) == 256
    for index, printed in enumerate(DOC_CRC_TABLE):
        expected = binascii.crc_hqx(bytes([index]), 0)
        if index in DOC_TABLE_PRINT_ERRORS:
            assert printed != expected and DOC_TABLE_PRINT_ERRORS[index][1] == expected
        else:
            assert printed == expected, f"entry {index}"


def test_document_checksum_algorithm_equals_crc16():
    samples = [b"", b"RA", b"123456789", bytes(range(256)), b"RG\x06\x04\x00\xff\xff\xff\x7f"]
    for data in samples:
        assert doc_checksum(data) == c.crc16(data) == binascii.crc_hqx(data, 0)
    assert c.crc16(b"123456789") == 0x31C3  # CRC-16/XMODEM check value


# -- section 5: the examples, with their checksums -------------------------------------------------------
GOLDEN_REQUESTS = [  # (what, encoder result, wire bytes with C1 C2)
    ("RO 00", lambda: c.encode_ro(0), "52 4F 00 5C 2D"),
    ("RC 01 00 FF", lambda: c.encode_rc(-1), "52 43 01 00 FF 31 8D"),
    ("RT 04 00 11 30 01 00", lambda: c.encode_rt(0x3011, h("01 00")), "52 54 04 00 11 30 01 00 B5 F2"),
    ("RE 00 09 FF", lambda: c.encode_re(c.Function.F1, c.Motion.REMOTE_POSITION, -1), "52 45 00 09 FF 00 27"),
    ("RG 71 01", lambda: c.encode_rg(0x0171), "52 47 71 01 27 2B"),
    ("RG 11 00", lambda: c.encode_rg(0x0011), "52 47 11 00 2C 30"),
    ("RA", lambda: c.encode_ra(), "52 41 38 30"),
]


@pytest.mark.parametrize("what,encode,wire", GOLDEN_REQUESTS, ids=[r[0] for r in GOLDEN_REQUESTS])
def test_section_5_examples(what, encode, wire):
    frame = h(wire)
    assert encode() == frame
    body = bytes(what.split()[0], "ascii") + h(" ".join(what.split()[1:]))
    assert frame[:-2] == body
    assert frame[-2:] == doc_checksum(body).to_bytes(2, "little")  # C1 low byte first
    # section 6, code example 7: the receiver appends C2 then C1 and expects a checksum of 0
    assert doc_checksum(body + frame[-1:] + frame[-2:-1]) == 0
    request = c.decode_request(frame)
    assert request.command == body[:2] and request.params == body[2:] and request.raw == frame
    assert c.encode_frame(request.command, request.params) == frame  # round trip


def test_section_5_examples_decode_to_their_meaning():
    assert c.decode_request(h("52 4F 00 5C 2D")).safety_id == c.SafetyId.NO_START_AFTER_TIMEOUT
    keep_alive = c.decode_request(c.KEEP_ALIVE)
    assert keep_alive.index == -1 and keep_alive.data == b"" and c.KEEP_ALIVE == h("52 43 01 00 FF 31 8D")
    rt = c.decode_request(h("52 54 04 00 11 30 01 00 B5 F2"))
    assert rt.data_id == 0x3011 and rt.data == h("01 00")
    re = c.decode_request(h("52 45 00 09 FF 00 27"))
    assert re.function == c.Function.F1 and re.para == (c.Motion.REMOTE_POSITION, c.UNUSED)
    assert c.decode_request(h("52 47 71 01 27 2B")).data_id == 0x0171
    assert c.decode_request(h("52 47 11 00 2C 30")).data_id == 0x0011


# -- answers (section 3 table 4, section 5 answer columns) ----------------------------------------------------
ANSWERS = [  # (command, status, data or None, wire)
    (c.RO, c.ACK, None, "52 4F 06 9A 4D"),
    (c.RC, c.ACK, b"", "52 43 06 00 00 51 16"),  # keep-alive: ctp 0
    (c.RT, c.ACK, None, "52 54 06 13 92"),
    (c.RE, c.ACK, None, "52 45 06 51 A2"),
    (c.RG, c.ACK, h("11"), "52 47 06 01 00 11 D1 9F"),  # RG 71 01: ctp 01 00, Status (bit 4 motion)
    (c.RG, c.ACK, h("E8 03 00 00"), None),  # RG 11 00: ctp 04 00, 4 bytes of position
    (c.RA, c.ACK, None, "52 41 06 95 6E"),
    (c.RS, c.ACK, None, None),
]


ANSWER_IDS = [f"{r[0].decode()}{'' if r[2] is None else len(r[2])}" for r in ANSWERS]


@pytest.mark.parametrize("command,status,data,wire", ANSWERS, ids=ANSWER_IDS)
def test_answer_layouts(command, status, data, wire):
    frame = c.encode_answer(command, status, data)
    if wire:
        assert frame == h(wire)
    assert frame[:3] == command + bytes([status])
    assert frame[-2:] == doc_checksum(frame[:-2]).to_bytes(2, "little")
    if data is not None:
        assert frame[3:5] == len(data).to_bytes(2, "little") and frame[5:-2] == data
    answer = c.decode_answer(frame, expected=command)
    assert answer.ok and answer.command == command and answer.data == (data or b"")
    assert answer.has_ctp == (data is not None) and answer.raw == frame
    assert c.encode_answer(answer.command, answer.status, answer.data if answer.has_ctp else None) == frame


def test_rg_position_answer_layout():
    frame = c.encode_answer(c.RG, c.ACK, h("E8 03 00 00"))
    assert frame[:7] == h("52 47 06 04 00 E8 03")
    assert len(frame) == 2 + 1 + 2 + 4 + 2


ERRORS = [
    (0x80, "CSE", "Checksum error"), (0x81, "PDE", "Parameter data error"), (0x82, "PCE", "Parameter count error"),
    (0x83, "ICE", "Invalid command error"), (0x84, "PE", "Permission error"),
]


@pytest.mark.parametrize("code,name,title", ERRORS, ids=[e[1] for e in ERRORS])
def test_error_answers_by_name(code, name, title):
    frame = c.encode_answer(c.RG, code)
    assert len(frame) == 5  # no ctp after an error code (table 3: "nur, wenn P1 = ACK")
    answer = c.decode_answer(frame, expected=c.RG)
    assert not answer.ok and answer.status_name == name and answer.status_info.title == title
    assert c.Status[name] == code
    with pytest.raises(c.CommandRefused) as exc:
        answer.raise_for_status()
    assert exc.value.code == code and exc.value.info.name == name
    assert name in str(exc.value) and exc.value.info.meaning in str(exc.value)
    assert exc.value.info.remedy  # every error says what to do
    with pytest.raises(c.CodecError, match="no data"):
        c.encode_answer(c.RG, code, b"\x00")


def test_permission_error_says_to_open_remote_mode():
    with pytest.raises(c.CommandRefused, match="RO") as exc:
        c.decode_answer(c.encode_answer(c.RE, c.Status.PE)).raise_for_status()
    assert "500 ms" in exc.value.info.remedy
    unknown = c.decode_answer(c.encode_answer(c.RG, 0x85))
    assert unknown.status_name == "0x85"
    with pytest.raises(c.CommandRefused, match="0x85"):
        unknown.raise_for_status()


def test_answer_decode_errors_are_named():
    good = c.encode_answer(c.RG, c.ACK, h("E8 03 00 00"))
    bad = good[:-1] + bytes([good[-1] ^ 1])
    with pytest.raises(c.ChecksumError) as exc:
        c.decode_answer(bad)
    assert exc.value.received != exc.value.expected and exc.value.raw == bad
    with pytest.raises(c.UnexpectedAnswer):
        c.decode_answer(good, expected=c.RC)
    with pytest.raises(c.FrameLengthError):
        c.decode_answer(good[:3])
    longer = c._seal(good[:3] + h("05 00") + good[5:-2])  # ctp 5, four data bytes
    with pytest.raises(c.FrameLengthError, match="ctp 5"):
        c.decode_answer(longer)
    with pytest.raises(c.FrameLengthError):
        c.decode_answer(c._seal(b"RE\x06\x00\x00"))  # RE carries no data
    with pytest.raises(c.GarbageError):
        c.decode_answer(c._seal(b"XY\x06"))
    assert issubclass(c.FrameError, c.CodecError) and issubclass(c.CodecError, ValueError)


# -- request encoders: what the unit would refuse is refused before sending --------------------------------------------
def test_request_encoders_refuse_what_the_document_forbids():
    with pytest.raises(c.CodecError, match="0x3xxx"):
        c.encode_rt(0x0011, h("00 00 00 00"))  # RT writes remote data only (table 3)
    with pytest.raises(c.CodecError, match="Safety_ID"):
        c.encode_ro(3)
    with pytest.raises(c.CodecError, match="cyclic object index"):
        c.encode_rc(5)
    with pytest.raises(c.CodecError, match="no write data"):
        c.encode_rc(-1, b"\x00")
    with pytest.raises(c.CodecError, match="motion"):
        c.encode_re(c.Function.F1, 10)
    with pytest.raises(c.CodecError, match="ramp"):
        c.encode_re(c.Function.F1, c.Motion.IN, 2)
    with pytest.raises(c.CodecError, match="no parameters"):
        c.encode_re(c.Function.BUZZER, 1)
    with pytest.raises(c.CodecError, match="function directory"):
        c.encode_rs(11)
    with pytest.raises(c.CodecError, match="data ID"):
        c.encode_rg(0x10000)
    with pytest.raises(c.CodecError):
        c.encode_frame(b"WK")  # the table's print error is not a command


def test_rc_with_a_cyclic_object_counts_index_and_write_data():
    frame = c.encode_rc(0, h("64 00 E8 03 00 00"))
    assert frame[:-2] == b"RC" + h("07 00 00 64 00 E8 03 00 00")
    request = c.decode_request(frame)
    assert request.index == 0 and request.data == h("64 00 E8 03 00 00")
    assert c.CYCLIC_OBJECT_IDS[request.index] == 0x3001


@pytest.mark.parametrize("function", list(c.Function))
def test_re_and_rs_for_every_function(function):
    if function in c.MOTION_FUNCTIONS:
        frame = c.encode_re(function, c.Motion.MEM2, c.Ramp.SOFT)
        assert frame[2:5] == bytes([function, 4, 1])
    else:
        frame = c.encode_re(function)
        assert frame[2:5] == bytes([function, 0xFF, 0xFF])  # table 8: para_ID -1, -1
    assert c.decode_request(frame).function == function
    stop = c.encode_rs(function)
    assert stop[:-2] == b"RS" + bytes([function, 0xFF])
    assert c.decode_request(stop).function == function


def test_decode_request_names_what_the_unit_answers():
    with pytest.raises(c.ChecksumError):
        c.decode_request(h("52 4F 00 5C 2E"))
    with pytest.raises(c.ParameterCountError) as exc:
        c.decode_request(c._seal(b"RT" + h("05 00 11 30 01 00")))  # ctp 5, 4 bytes follow
    assert exc.value.status == c.Status.PCE
    with pytest.raises(c.ParameterCountError):
        c.decode_request(c._seal(b"RG" + h("11 00 00")))
    with pytest.raises(c.ParameterDataError) as exc:
        c.decode_request(c._seal(b"RT" + h("06 00 11 00 00 00 00 00")))  # RT to 0x0011
    assert exc.value.status == c.Status.PDE
    with pytest.raises(c.ParameterDataError):
        c.decode_request(c._seal(b"RE" + h("0B FF FF")))  # fnc_ID 11 is not in table 8
    with pytest.raises(c.ParameterDataError):
        c.decode_request(c._seal(b"RE" + h("00 0A FF")))  # motion 10 is not in table 9
    with pytest.raises(c.ParameterDataError):
        c.decode_request(c._seal(b"RC" + h("01 00 05")))
    assert c.decode_request(c._seal(b"RO" + h("01 FF"))).safety_id == 1  # table 3 form with para_ID[0]


# -- the streaming splitter -----------------------------------------------------------------------------
def _stream():
    return [
        c.encode_answer(c.RO),
        c.encode_answer(c.RC, data=b""),
        c.encode_answer(c.RG, data=h("11")),
        c.encode_answer(c.RG, data=h("E8 03 00 00")),
        c.encode_answer(c.RE, c.Status.PE),
        c.encode_answer(c.RC, data=bytes(range(40))),
    ]


def test_splitter_on_merged_frames():
    frames = _stream()
    splitter = c.FrameSplitter()
    out = splitter.feed(b"".join(frames))
    assert [a.raw for a in out] == frames and splitter.pending == b""
    assert splitter.frames == len(frames) and splitter.errors == 0
    assert out[4].status_name == "PE" and out[5].data == bytes(range(40))


def test_splitter_on_frames_split_byte_by_byte():
    frames = _stream()
    splitter, out = c.FrameSplitter(), []
    for byte in b"".join(frames):
        out += splitter.feed(bytes([byte]))
    assert [a.raw for a in out] == frames


def test_splitter_reports_garbage_and_bad_crc_and_goes_on():
    frames = _stream()
    bad = bytearray(frames[3])
    bad[6] ^= 0x40  # a data bit flipped on the line
    data = h("00 FF 13") + frames[0] + b"R" + bytes(bad) + frames[2] + h("AA") + frames[4]
    splitter = c.FrameSplitter()
    out = splitter.feed(data)
    kinds = [type(x).__name__ for x in out]
    assert kinds == ["GarbageError", "Answer", "GarbageError", "ChecksumError", "Answer", "GarbageError", "Answer"]
    assert out[0].raw == h("00 FF 13") and out[2].raw == b"R" and out[5].raw == h("AA")
    assert out[3].raw == bytes(bad)
    assert out[4].raw == frames[2] and out[6].raw == frames[4]
    assert splitter.errors == 4 and splitter.frames == 3


def test_splitter_waits_for_the_rest_and_expires_a_cut_telegram():
    frame = c.encode_answer(c.RG, data=h("E8 03 00 00"))
    splitter = c.FrameSplitter()
    assert splitter.feed(frame[:6]) == [] and splitter.pending == frame[:6]
    (error,) = splitter.expire()
    assert isinstance(error, c.TruncatedFrameError) and error.raw == frame[:6]
    assert splitter.pending == b"" and splitter.expire() == []
    assert splitter.feed(frame) == [c.decode_answer(frame)]


def test_splitter_takes_a_bare_ack_of_rc_and_rg():
    bare_rc, bare_rg = c._seal(b"RC\x06"), c._seal(b"RG\x06")
    # read as ctp, their checksums exceed MAX_CTP: the two forms cannot be confused
    assert int.from_bytes(bare_rc[3:5], "little") > c.MAX_CTP and int.from_bytes(bare_rg[3:5], "little") > c.MAX_CTP
    out = c.FrameSplitter().feed(bare_rc + bare_rg)
    assert [(a.command, a.ok, a.has_ctp) for a in out] == [(c.RC, True, False), (c.RG, True, False)]


def test_splitter_rejects_an_implausible_ctp():
    data = b"RG\x06" + (c.MAX_CTP + 1).to_bytes(2, "little") + c.encode_answer(c.RO)
    out = c.FrameSplitter().feed(data)
    assert isinstance(out[0], c.FrameLengthError)
    assert out[-1] == c.decode_answer(c.encode_answer(c.RO))


def test_splitter_for_requests_serves_a_twin():
    rt_to_position = c._seal(b"RT" + h("06 00 11 00 00 00 00 00"))
    requests = [c.encode_ro(1), c.KEEP_ALIVE, c.encode_rt(0x3021, h("E8 03 00 00")), c.encode_re(0, 9, 1),
                c.encode_rs(0), c.encode_rg(0x0010), rt_to_position, c.encode_ra()]
    splitter, out = c.FrameSplitter(c.REQUESTS), []
    for i in range(0, len(b"".join(requests)), 3):
        out += splitter.feed(b"".join(requests)[i:i + 3])
    assert [getattr(x, "command", None) for x in out] == [c.RO, c.RC, c.RT, c.RE, c.RS, c.RG, None, c.RA]
    assert isinstance(out[6], c.ParameterDataError) and out[6].status == c.Status.PDE  # one telegram, answered PDE
    assert out[2].data_id == 0x3021 and out[3].para == (9, 1) and out[5].data_id == 0x0010
    bad = bytearray(c.encode_rg(0x0011))
    bad[3] ^= 1
    (error,) = c.FrameSplitter(c.REQUESTS).feed(bytes(bad))
    assert isinstance(error, c.ChecksumError)  # the unit answers CSE
    with pytest.raises(ValueError):
        c.FrameSplitter("both")


# -- directories (sections 4.1, 4.4, 4.5) ----------------------------------------------------------------
def test_function_directory():
    assert [int(f) for f in c.MOTION_FUNCTIONS] == list(range(10))
    assert (c.Function.BUZZER, c.Function.BINARY_OUTPUT_1, c.Function.BINARY_OUTPUT_2) == (10, 16, 17)
    assert (c.Function.EMERGENCY_STOP, c.Function.LED_1, c.Function.LED_2) == (19, 20, 21)
    assert c.FUNCTIONS[c.Function.F1].label == "F1" and c.FUNCTIONS[c.Function.F10].label == "F10"
    assert c.FUNCTIONS[c.Function.EMERGENCY_STOP].label == "F20"
    assert c.FUNCTIONS[c.Function.LED_2].description == "Operating unit LED2"
    assert all(c.FUNCTIONS[f].motion == (f in c.MOTION_FUNCTIONS) for f in c.Function)


def test_motion_table_and_ramps():
    assert [m.name for m in c.Motion] == ["NONE", "IN", "OUT", "MEM1", "MEM2", "MEM3", "MEM4", "INTERMEDIATE_IN",
                                          "INTERMEDIATE_OUT", "REMOTE_POSITION"]
    assert [int(m) for m in c.Motion] == list(range(10)) and set(c.MOTION_LABELS) == set(c.Motion)
    assert (c.Ramp.FAST, c.Ramp.SOFT, c.Ramp.DEFAULT) == (0, 1, 0xFF)


def test_safety_id_modes():
    assert [int(s) for s in c.SafetyId] == [0, 1, 2] and c.DEFAULT_SAFETY_ID == 1
    assert "none is started" in c.SAFETY_MODES[c.SafetyId.NO_START_AFTER_TIMEOUT]
    assert "only the remote motion" in c.SAFETY_MODES[c.SafetyId.STOP_REMOTE]
    assert c.encode_ro()[:-2] == b"RO\x01"


def test_error_code_bits_are_numbered_from_one():
    assert c.ERROR_BITS[1].mask == 0x00000001 and c.ERROR_BITS[32].mask == 0x80000000
    assert c.REMOTE_TIMEOUT_MASK == 1 << 21 and c.ERROR_BITS[22].behaviour == "depends on the Safety_ID (RO)"
    assert set(c.ERROR_BITS) == set(range(1, 33)) - {9, 23}
    assert [c.ERROR_BITS[n].key for n in range(15, 21)] == [f"actuator_{n}" for n in range(1, 7)]
    for bit in c.ERROR_BITS.values():
        assert bit.cause and bit.behaviour
    assert c.ERROR_BITS[8].condition == "tested at the start of a motion"
    code = (1 << 21) | (1 << 14) | (1 << 8) | 1
    assert [b.key for b in c.error_bits(code)] == ["rom_crc", "actuator_1", "remote_timeout"]
    assert c.unknown_error_bits(code) == [9]
    assert c.error_bits(0) == [] and len(c.error_bits(0xFFFFFFFF)) == 30


def test_wire_time_at_38400_8n1():
    assert c.wire_time_s(len(c.KEEP_ALIVE)) == pytest.approx(7 * 10 / 38400)
    assert c.DEFAULT_BAUDRATE == 38400 and c.BAUDRATES == (9600, 19200, 38400)
    assert c.KEEP_ALIVE_PERIOD_S < c.WATCHDOG_S == 0.5
