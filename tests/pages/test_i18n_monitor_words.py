"""The bus monitors' meanings in the page's language (docs/i18n.md): what the codecs and the line decoders say of a
CAN frame or a line's telegram is a Message (devices/message.py), English as before (recordings and tests compare
it), worded by the monitor with ``said`` in the words of each device page.

The German of the templates added with this test comes into the catalogs with their next update; until then a
test here words them through a small table of that German on top of the German catalog (``with_german``), and
checks what the catalog already has (the SCU's Flanken, its group names, the MO 64's Abfrage and Torzustand)
straight from it."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from app import i18n
from app.line_base import Transaction
from app.message import said
from app.recording.decode import FrameDecoder
from devices.electrak import codec as electrak
from devices.hdlock import codec as hdlock
from devices.m3io import codec as m3io
from devices.message import Message, Word
from devices.mo64 import codec as mo64
from devices.mo64 import linewords as mo64_words
from devices.scu import codec as scu
from devices.scu import linewords as scu_words

pytestmark = pytest.mark.timeout(60)

# a few of the new templates in German (their catalog entries come with the next catalog update)
GERMAN = {
    "Input register {address} {value} (0x{raw:04X})": "Input-Register {address} {value} (0x{raw:04X})",
    "Holding register {address} {value} (0x{raw:04X})": "Holding-Register {address} {value} (0x{raw:04X})",
    "{address} {name} count {count}": "{address} {name} Anzahl {count}",
    "lock {id}": "Schloss {id}",
    "no input": "kein Eingang",
    "load, fuse {fuse}, triac {triac}": "Last, Si {fuse}, Triac {triac}",
    "{temp} out of range ({value:.1f} °C)": "{temp} Messbereichsüberschreitung ({value:.1f} °C)",
    "not conducting": "leitet nicht",
    "RC keep-alive": "RC Keep-alive",
    "Error memory level {level}: {flags} at {hours} h": "Fehlerspeicher Ebene {level}: {flags} bei {hours} h",
    "error flags {list} set": "Fehler: Flaggen {list} gesetzt",
    "Electrak status: {position:.1f} mm, {current:.1f} A, {speed:.1f} mm/s, {flags}":
        "Electrak-Status: {position:.1f} mm, {current:.1f} A, {speed:.1f} mm/s, {flags}",
    "idle": "Stillstand",
}


class with_german:
    """The German catalog with :data:`GERMAN` on top: a language that words a :class:`Message`."""

    def __init__(self):
        self.lang = i18n.get("de")

    def gettext(self, message: str) -> str:
        return GERMAN.get(message) or self.lang.gettext(message)

    def value(self, value, context=None):
        return self.lang.value(value, context)


def templates(text) -> set[str]:
    """Every template of a Message and of the Messages in its fields."""
    found = set()
    if isinstance(text, Message):
        found.add(text.template)
        for field in text.fields.values():
            found |= templates(field)
    return found


def line(request: bytes, answer: bytes, what: str = "x") -> Transaction:
    return Transaction(0.0, 0, what, request.hex(" ").upper(), answer.hex(" ").upper(), "", 1.0, "")


def hd(can_id: int, data: bytes) -> str:
    return hdlock.describe_frame(can_id, False, data, {(False, 0x11)})


# -- HD-Lock (CAN) ----------------------------------------------------------------------------------------------


def test_hdlock_frames_are_english_as_before_and_german_on_a_german_page():
    de = with_german()
    answer = hd(0x11, bytes([0, 1, 6, 0, 0xBE, 0x00]))
    assert answer == "HD-Lock Input register 6 ValueHallSensor2 = 190 (0x00BE)"
    assert isinstance(answer, Message) and said(answer, None) == answer
    assert said(answer, de) == "HD-Lock Input-Register 6 ValueHallSensor2 = 190 (0x00BE)"
    setting = hd(0x11, bytes([1, 1, 0xBE, 0x0B, 0xC4, 0xFF]))
    assert setting == "HD-Lock Holding register 3006 SettingsProximityThresholdLock = -60 Inc (0xFFC4)"
    assert said(setting, de) == "HD-Lock Holding-Register 3006 SettingsProximityThresholdLock = -60 Inc (0xFFC4)"
    read = hd(0x703, hdlock.encode_read(hdlock.DeviceId.make(0x11), "holding", 3006, 2).data)
    assert read == "HD-Lock Read Holding-Register -> lock 17 (std 0x11): 3006 SettingsProximityThresholdLock count 2"
    assert said(read, de) == "HD-Lock Read Holding-Register -> Schloss 17 (std 0x11): 3006 SettingsProximityThresholdLock Anzahl 2"


def test_hdlock_status_names_its_source_as_the_catalog_has_it():
    status = hd(0x11, bytes([0, 0, 0x03, 0x01, 0x05, 0x00, 0xC4, 0x01]))
    assert status == ("HD-Lock Status 0x0103 [LockRequest, ProximityInPlace, BoltLocked] motorPos 5 proximity 7 "
                      "source 4 IrsNotLine")
    source = status.fields["text"].fields["source"]
    assert isinstance(source, Word) and source.context == "LockRequestSource"  # worded as the HD-Lock page words it


# -- CAN-M3IO ----------------------------------------------------------------------------------------------------


def test_m3io_frames_in_the_words_of_its_page():
    de = with_german()
    ids = m3io.derive_ids(0)
    dig_in = m3io.describe_frame_for(ids, m3io.Variant.HM, ids.dig_in, bytes([0xC0]))
    assert dig_in == "M3IO DigIn: no input" and said(dig_in, de) == "M3IO DigIn: kein Eingang"
    text = m3io.describe_temp(m3io.Variant.HM, 1, m3io.TempWord(215))
    assert said(text, None) == text and text.startswith("TEMP1 21.5 °C · SSR1 ")
    assert said(text, de).startswith("TEMP1 21,5 °C · SSR1 ")  # the decimal comma
    assert said(m3io.describe_temp(m3io.Variant.HM, 1, m3io.TempWord(0x0FFF)), de).startswith("TEMP1 ")


# -- SCU (RS232) -------------------------------------------------------------------------------------------------


def test_scu_line_in_the_words_of_the_scu_page_counts_are_flanken():
    de = i18n.get("de")
    decoder = scu_words.ScuLineDecoder([], {})
    read = decoder.text(line(scu.encode_rg(0x0011), scu.encode_answer(scu.RG, scu.ACK, (1200).to_bytes(4, "little", signed=True))))
    assert read.decoded == "Actual_Position Actuator 1 = 1200 counts"  # as before
    assert said(read.decoded, de) == "Actual_Position Actuator 1 = 1200 Flanken"  # the catalog's unit, as the page
    end = decoder.text(line(scu.encode_ra(), scu.encode_answer(scu.RA)))
    assert (end.request, said(end.request, de)) == ("RA end remote mode", "RA Remote-Betrieb beenden")
    keep = decoder.text(line(scu.KEEP_ALIVE, scu.encode_answer(scu.RC, scu.ACK, b"")))
    assert keep.request == "RC keep-alive" and said(keep.request, with_german()) == "RC Keep-alive"


# -- MO 64 (LogiTed) ---------------------------------------------------------------------------------------------


def test_logited_line_in_the_words_of_the_mo64_page():
    de = i18n.get("de")
    decoder = mo64_words.LogitedLineDecoder([SimpleNamespace(name="gate", options={"address": 0x10})], False, {})
    frame = mo64.encode_frame
    gate = decoder.text(line(frame(mo64.encode_query(7)), frame(mo64.encode_answer(0x0C, 5))))
    assert (gate.request, gate.decoded) == ("query gate state", "Gate state = closed")
    assert said(gate.request, de) == "Abfrage Torzustand"
    assert said(gate.decoded, de).startswith("Torzustand = ")
    pulse = decoder.text(line(frame(mo64.encode_command(mo64.Command.OPEN)), frame(mo64.encode_answer(mo64.Reply.ACK))))
    assert pulse.request == "open pulse" and said(pulse.request, de) == "öffnen Impuls"


def test_mo64_error_memory_level():
    de = with_german()
    answer = mo64_words.answer_words(SimpleNamespace(reply=None, error="", type=0x17, name="error memory",
                                                     value={"index": 0, "flags": 0, "timestamp_h": 0}))
    assert answer == "Error memory level 0: no error at 0 h"
    assert said(answer, de) == "Fehlerspeicher Ebene 0: kein Fehler bei 0 h"
    flags = mo64.error_flags_text(0x88, older=0x08)
    assert flags == "error flags 3, 7 set (7 new)"  # as before (the MO 64 page's test too)
    assert said(flags, de) == "Fehler: Flaggen 3, 7 gesetzt (7 neu)"


# -- Electrak HD (CAN) -------------------------------------------------------------------------------------------


def test_electrak_status_with_the_decimal_comma():
    de = with_german()
    data = (123).to_bytes(2, "little") + (15).to_bytes(2, "little") + (0).to_bytes(2, "little") + bytes([0, 0])
    text = electrak.describe_frame(electrak.STATUS_ID, False, data, {(False, electrak.STATUS_ID)})
    assert text == "Electrak status: 12.3 mm, 1.5 A, 0.0 mm/s, idle"
    assert said(text, de) == "Electrak-Status: 12,3 mm, 1,5 A, 0,0 mm/s, Stillstand"


# -- what every family says is a Message whose templates the catalog takes ---------------------------------------


def test_decoded_meanings_are_messages_kept_by_the_decoders_cache():
    decoder = FrameDecoder({(False, 0x11)}, [hdlock])
    first = decoder(0x11, False, bytes([0, 1, 6, 0, 0xBE, 0x00]))
    assert isinstance(first, Message) and decoder(0x11, False, bytes([0, 1, 6, 0, 0xBE, 0x00])) is first
    assert hash(first) == hash(str(first)) and {first: 1}[str(first)] == 1
    for text in (first, electrak.describe_frame(electrak.CONTROL_ID, False, bytes(8), {(False, electrak.STATUS_ID)}),
                 m3io.describe_frame_for(m3io.derive_ids(0), m3io.Variant.HM, m3io.derive_ids(0).dig_out, b"\x00")):
        assert isinstance(text, Message) and said(text, None) == text
        assert templates(text) & MARKED, text  # a marked template, worded by the catalog


MARKED = set(GERMAN) | {"all off", "no enable",
                        "Electrak control: target {position:.1f} mm, limit {current:.1f} A, speed {speed:.1f} mm/s, {bits}"}


def test_an_scu_struct_read_is_named_by_its_fields_not_refused_as_undecodable():
    """RG of UserPositionData (0x2001..0x2006, a struct of table 6) answers a block keyed by the struct's field names,
    not by data IDs; the monitor said "cannot decode: Unknown format code 'X' for object of type 'str'" for it."""
    positions = b"".join(n.to_bytes(4, "little", signed=True) for n in range(100, 2700, 100))  # 26 INT32 fields
    read = scu_words.ScuLineDecoder([], {}).text(line(scu.encode_rg(0x2001), scu.encode_answer(scu.RG, scu.ACK, positions)))
    assert read.request == "RG 0x2001 UserPositionData A1"
    assert read.decoded.startswith("UserPositionData A1: Position_Memory_1[USER_1] 100, Position_Memory_2[USER_1] 200, ")
    assert "decod" not in said(read.decoded, i18n.get("de"))
