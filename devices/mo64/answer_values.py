"""The value types of the Bauer MO 64's answer telegrams (document 003, chapter 5.1; SPEC-NOTES "Bauer MO 64").

What each answer's payload holds (:data:`ANSWER_TYPES`, answer type -> value type of :mod:`devices.values`),
with the tables its fields are named from: the status bits, the gate states, the error memory's levels.
:mod:`devices.mo64.codec` decodes answers with them and names each as its own. Pure data.
"""

from __future__ import annotations

from enum import IntEnum

from devices import values as v
from devices.mo64.frames import CodecError

ERROR_MEMORY_LEVELS = 10  # chapter 5.1.23: "10 Ebenen (0...9)"

# -- value types of the answer telegrams -----------------------------------------------------------
DEVICE_CODES = {5: "MO 64-V4 (Stand 19.07.2011)"}  # chapter 5.1.5 (0x0001..0x0004 printed "xxx")
DEVICE_CODE = v.Enum(v.U16LE, DEVICE_CODES)  # Kennung_lo Kennung_hi
PROGRAM_VERSION = v.U16LE  # SPEC-NOTES: program version u16

STATUS_BIT_NAMES: tuple[tuple[str, ...], ...] = (  # chapter 5.1.7, bit names per SPEC-NOTES
    ("Funk", "BT", "BTA1", "BTA2", "BTA3", "BTZ1A", "BTZ1B", "BTZ2"),
    ("BTS", "Baum ab", "LS", "SLZ", "F_ereignis", "SERVICE", "mains monitoring"),
    ("adjusting loop A", "adjusting loop B", "adjusting loop C",
     "loop A occupied", "loop B occupied", "loop C occupied", "loop EXT"),
    tuple(f"multi relay {n}" for n in range(1, 9)),
    tuple(f"multi relay {n}" for n in range(9, 15)),
)
STATUS_GROUPS: dict[str, tuple[str, ...]] = {  # how the page groups the 40 bits (issue 13)
    "inputs": ("Funk", "BT", "BTA1", "BTA2", "BTA3", "BTZ1A", "BTZ1B", "BTZ2", "BTS", "SLZ"),
    "safety": ("LS", "Baum ab", "F_ereignis"),
    "loops": ("adjusting loop A", "adjusting loop B", "adjusting loop C",
              "loop A occupied", "loop B occupied", "loop C occupied", "loop EXT"),
    "multi relays": tuple(f"multi relay {n}" for n in range(1, 15)),
    "service": ("SERVICE", "mains monitoring"),
}
STATUS_BITS = v.Bits(v.Int(40), tuple(  # Status0 .. Status4, Status0 first (low byte first)
    v.BitField(name, 8 * byte + bit) for byte, names in enumerate(STATUS_BIT_NAMES) for bit, name in enumerate(names)
))
# SPEC-NOTES: some firmware sends more status bytes: decode the first five, keep the rest raw
BARRIER_STATUS = v.Struct("barrier_status", (("status", STATUS_BITS), ("more", v.Bytes(None))))
STATUS_MASK = v.Struct("status_mask", (("mask", STATUS_BITS), ("more", v.Bytes(None))))  # 5.1.8, Maske0..4

CHANGE_MONITORING = v.Bits(v.U16LE, tuple(v.BitField(name, bit) for bit, name in enumerate((
    "barrier status", "service counter", "maintenance counter", "gate state", "error memory",
    "vehicle counter", "barrier position", "motor status", "loop debug",
))))  # chapter 5.1.9, Flaggen_lo Flaggen_hi; bit names from SPEC-NOTES "Change monitoring"


class GateState(IntEnum):
    """Gate state, telegram 0x0C (chapter 5.1.12; numbers from SPEC-NOTES)."""

    OPENING = 0
    CLOSING = 1
    PREWARN_OPEN = 2
    PREWARN_CLOSE = 3
    OPEN = 4
    CLOSED = 5
    INTERMEDIATE = 6


GATE_STATE_NAMES = {
    0: "opening", 1: "closing", 2: "pre-warning before opening", 3: "pre-warning before closing",
    4: "open", 5: "closed", 6: "intermediate position",
}
GATE_STATE = v.Enum(v.U8, GATE_STATE_NAMES)
COUNTER = v.U32LE  # service / maintenance counter (SPEC-NOTES: u32)
TIME_10MS = v.U16LE  # t_offen_lo t_offen_hi, in multiples of 10 ms (chapter 5.1.13)
TIME_STEP_S = 0.01  # chapter 5.1.13: "in Vielfachen von 10ms"
TIME_MAX = 65500  # chapter 5.2.4.1: "Erlaubter Zahlenbereich: 0 bis 65500"
# chapter 5.1.16: A9..A1 take bits 17..0 (2 bits each), bit 31 = a radio code is stored
DEC_BT = v.Bits(v.U32LE, tuple(v.BitField(f"A{n}", 2 * (n - 1), 2) for n in range(1, 10))
                + (v.BitField("code stored", 31),))
INDUCTION_LOOPS = v.Array(v.U16LE, 3)  # chapter 5.1.18: one 16-bit mode register per loop A, B, C
# chapter 5.1.19, table 11: one 32-bit register per direction logic; only the fields numbered there
DIRECTION_LOGIC = v.Bits(v.U32LE, (
    v.BitField("input selection", 0, 3),
    v.BitField("presence right", 18, 2),
    v.BitField("reserve", 20, 12),
))
DIRECTION_LOGICS = v.Array(DIRECTION_LOGIC, 2)
SERIAL_NUMBER = v.U32LE  # snr_lo0 _lo1 _hi0 _hi1 (chapter 5.1.20)
MAC_ADDRESS = v.Bytes(6)  # chapter 5.1.21: six bytes, shown in the order received
OPERATING_HOURS = v.U32LE  # SPEC-NOTES: operating hours u32
ERROR_LEVEL = v.Struct("error_level", (("flags", v.U32LE), ("timestamp_h", v.U32LE)))  # chapter 5.1.23
ERROR_ENTRY = v.Struct("error_entry", (("index", v.U8), ("flags", v.U32LE), ("timestamp_h", v.U32LE)))
ERROR_MEMORY = v.Array(ERROR_LEVEL, ERROR_MEMORY_LEVELS)
# chapter 5.1.24, tables 13-16: four 16-bit words; only the 2-bit fields whose bits are printed
CONFIG_FIELDS: tuple[tuple[v.BitField, ...], ...] = (
    (v.BitField("RtApl blink in end position", 0, 2), v.BitField("RtApl blink at pre-warning open", 2, 2)),
    (v.BitField("GnApl blink at pre-warning open", 0, 2), v.BitField("GnApl blink at pre-warning close", 2, 2),
     v.BitField("GnApl blink while opening", 4, 2), v.BitField("GnApl blink while closing", 6, 2),
     v.BitField("GnApl blink at intermediate stop", 8, 2)),
    (v.BitField("warning light blink in end position open", 8, 2),),
    (),
)
CONFIG_FLAGS = v.Struct("config_flags", tuple(
    (f"konfig{i}", v.Bits(v.U16LE, fields)) for i, fields in enumerate(CONFIG_FIELDS)
))
MULTI_RELAYS = v.Array(v.U8, 6)  # chapter 5.1.25: multi1 .. multi6, one mode byte each
MULTI_MODE_NAMES = {0: "off", 1: "fault"}  # chapter 5.1.25: the summary names these modes by number only so far
MAINTENANCE_INTERVAL = v.U32LE  # ASSUMED width (see ASSUMPTIONS): like the maintenance counter
VEHICLE_COUNTER = v.I32LE  # chapter 5.2.5: signed 32 bit, RAM only, 0 after power-up
BARRIER_POSITION = v.I8  # chapter 5.1.29: percent, -1 while unknown
POSITION_UNKNOWN = -1
PASSWORD = v.U16LE  # chapter 5.1.30: passwort_lo passwort_hi
LOOP_ADJUST_COUNTERS = v.Array(v.U16LE, 3)  # chapter 5.1.31: schleife_a/b/c _lo _hi
RAW = v.Bytes(None)  # a layout the document does not name: kept raw

ANSWER_TYPES: dict[int, v.ValueType] = {
    0x05: DEVICE_CODE, 0x06: PROGRAM_VERSION, 0x07: BARRIER_STATUS, 0x08: STATUS_MASK,
    0x09: CHANGE_MONITORING, 0x0A: COUNTER, 0x0B: COUNTER, 0x0C: GATE_STATE,
    0x0D: TIME_10MS, 0x0E: TIME_10MS, 0x0F: TIME_10MS, 0x10: DEC_BT,
    0x11: RAW,  # counting function: layout not in the summary
    0x12: INDUCTION_LOOPS, 0x13: DIRECTION_LOGICS, 0x14: SERIAL_NUMBER, 0x15: MAC_ADDRESS,
    0x16: OPERATING_HOURS, 0x17: ERROR_ENTRY,  # or ERROR_MEMORY, by length (see decode_value)
    0x18: CONFIG_FLAGS, 0x19: MULTI_RELAYS, 0x1A: MAINTENANCE_INTERVAL,
    0x1B: RAW,  # loop periods: layout not in the summary
    0x1C: VEHICLE_COUNTER, 0x1D: BARRIER_POSITION, 0x1E: PASSWORD, 0x1F: LOOP_ADJUST_COUNTERS,
}


def answer_value_type(answer_type: int, payload_len: int | None = None) -> v.ValueType:
    """The value type of answer telegram ``answer_type`` (the error memory by its length)."""
    if answer_type == 0x17 and payload_len == ERROR_MEMORY.size:
        return ERROR_MEMORY
    try:
        return ANSWER_TYPES[answer_type]
    except KeyError:
        raise CodecError(f"telegram type 0x{answer_type:02X} is not an answer of chapter 5.1") from None


def format_mac(mac: bytes) -> str:
    return ":".join(f"{b:02X}" for b in mac)


def time_s(ticks: int) -> float:
    """A time register (10 ms units) in seconds."""
    return round(ticks * TIME_STEP_S, 2)
