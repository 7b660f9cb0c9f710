"""Bauer MO 64 motor control, LogiTed bus: telegrams, answer decoders, settings.

Pure: no I/O. Document 003 ("Motorsteuerung MO 64, Protokollbeschreibung", page summaries
only), chapters 2 to 5; what a public client adds and what is still unknown follow
SPEC-NOTES.md ("Bauer MO 64"), each decision cited once where taken.

The frames around the telegrams (TCP and RS485, CRC, token, splitter) are in :mod:`devices.mo64.frames`,
the value types of the answers in :mod:`devices.mo64.answer_values`; both are named here too, so that
a reader of the MO 64's codec imports this one module. Every value inside a telegram is little-endian
(the document names the fields ``_lo`` before ``_hi``).

The same type byte means different telegrams in each direction (0x01 is ack from the MO 64
and an operating command to it), so a frame is decoded by direction: :func:`decode_answer`
(what the MO 64 sends, chapter 5.1) and :func:`decode_request` (what it receives, 5.2).

Public API:

* requests: :func:`encode_query` (refuses the indexes the document forbids),
  :func:`encode_command` (:class:`Command`, :class:`Function`), :func:`encode_short_command`,
  :func:`encode_setting` with the directory :data:`SETTINGS` (:class:`Setting`);
* answers: :func:`decode_answer` -> :class:`Answer` with a typed ``value``;
  a twin's side: :func:`encode_answer`, :func:`decode_request` -> :class:`Request`;
* frames (from :mod:`devices.mo64.frames`): :func:`encode_frame` / :func:`decode_frame` for :data:`TCP`
  and :data:`RS485` framing, the token telegram (:func:`encode_token`), and :class:`FrameSplitter`, which
  cuts a byte stream into :class:`Frame` values and named :class:`FrameError` values;
* :data:`ASSUMPTIONS`: every reading beyond the document, as sentences for the page.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

from devices import values as v
from devices.message import N_, Message, joined
from devices.mo64.answer_values import (  # noqa: F401 - the answers' value types, named here too
    ANSWER_TYPES, BARRIER_POSITION, BARRIER_STATUS, CHANGE_MONITORING, CONFIG_FIELDS, CONFIG_FLAGS, COUNTER,
    DEC_BT, DEVICE_CODE, DEVICE_CODES, DIRECTION_LOGIC, DIRECTION_LOGICS, ERROR_ENTRY, ERROR_LEVEL, ERROR_MEMORY,
    GATE_STATE, GATE_STATE_NAMES, GateState, INDUCTION_LOOPS, LOOP_ADJUST_COUNTERS, MAC_ADDRESS,
    MAINTENANCE_INTERVAL, MULTI_MODE_NAMES, MULTI_RELAYS, OPERATING_HOURS, PASSWORD, POSITION_UNKNOWN,
    PROGRAM_VERSION, RAW, SERIAL_NUMBER, STATUS_BITS, STATUS_BIT_NAMES, STATUS_GROUPS, STATUS_MASK, TIME_10MS,
    TIME_MAX, TIME_STEP_S, VEHICLE_COUNTER, answer_value_type, format_mac, time_s, ERROR_MEMORY_LEVELS,
)
from devices.mo64.frames import (  # noqa: F401 - the frame layer, named here too (app/logited.py and the twins read it from here)
    CHECKSUM, CRC_PRESET, MAX_LE, RS485, RS485_BAUDRATE, RS485_LAYOUT, SD, TCP, TCP_PORT, TOKEN, TOKEN_PASS_LIMIT_S,
    ChecksumError, CodecError, Frame, FrameError, FrameLengthError, FrameSplitter, Framing, GarbageError, Rs485Layout,
    TruncatedFrameError, crc16, decode_frame, encode_frame, encode_token,
)

# -- assumptions beyond the document: all in this one block (and RS485_LAYOUT, devices/mo64/frames.py) ---
# SPEC-NOTES "Still unknown": the short commands' codes (0x03); one command byte assumed.
SHORT_COMMAND_BYTES = 1
# SPEC-NOTES "Still unknown": how a level of the error memory is chosen; an index byte after the
# query index is assumed (the answer 0x17 starts with "index", chapter 5.1.23).
ERROR_MEMORY_QUERY_HAS_LEVEL = True
# SPEC-NOTES "Still unknown": the layouts of settings 0x05-0x08 beyond those the document names;
# each assumed selector is marked in SETTINGS with its reason.

# the two readings above, in the words the page shows (each tested as shown there, not as a fact)
ASSUMED_SHORT_COMMAND = ("Short commands (0x03) are sent as one command byte; the manual's summary names their effects "
                         "(e.g. clearing a loop-adjust counter) but not their codes.")
ASSUMED_ERROR_MEMORY_LEVEL = ("The error memory level is chosen by an index byte after the query index; each answer "
                              "carries index, error flags and time stamp.")

ASSUMPTIONS: tuple[str, ...] = (
    "RS485 telegrams are assumed to be 55 LE DA SA type data CSH CSL, with LE counting DA to the "
    "end of the data and this tool's master address 0x00 by default (the manual's summary does not "
    "print the address fields).",
    "The RS485 token telegram is assumed to be the shortest telegram of the manual (6 characters): "
    "55 02 DA SA CSH CSL, sent by the master that holds the token to the next master DA.",
    "TCP port 52719, the frame 55 LE type data CSH CSL and the reply types ack 0x01, nak 0x02, "
    "busy 0x03, syn 0x04 come from a public client, not from the manual.",
    ASSUMED_SHORT_COMMAND,
    ASSUMED_ERROR_MEMORY_LEVEL,
    "Queries: the manual prints 02 Auswahl index (page 33), the public client sends 02 Auswahl; the "
    "manual's form is tried first and the unit's answer decides (shown as the query form).",
    "Status bits: positions as the public client has them; the manual lists Multi3-6 before the loop "
    "adjustment bits and the MO 64 has six multi relays, so relays 7-14 are not shown.",
    "Setting selectors 0x04 0x01 (pre-warning before opening) and 0x04 0x02 (pre-warning before "
    "closing) follow the order of the answer telegrams 0x0D-0x0F; the manual's summary names only "
    "0x04 0x00 (open time) and 0x04 0x04 (change monitoring).",
    "The vehicle counter (0x05 0x00) and the maintenance interval (0x05 0x01, u32) selectors are "
    "assumed; the manual's summary names the 32-bit vehicle counter setting but not its selector.",
    "The layouts of the counting function (0x11), loop periods (0x1B) and the fields of induction "
    "loops, direction logics, configuration flags and multi relays that the summary does not number "
    "are shown as raw values.",
)


# -- telegram types (chapter 5, SPEC-NOTES "Replies") ----------------------------------------------
class Reply(IntEnum):
    """The MO 64's short replies (chapter 5.1.1-5.1.4; type numbers from SPEC-NOTES)."""

    ACK = 0x01
    NAK = 0x02
    BUSY = 0x03  # the motor runs: a setting is refused (chapter 5.2.4)
    SYN = 0x04  # a setting is being written to the EEPROM; ack follows


REPLY_TYPES = frozenset(int(r) for r in Reply)


class RequestType(IntEnum):
    """What the MO 64 receives (chapter 5.2)."""

    COMMAND = 0x01  # 5.2.1 Bedientelegramme
    QUERY = 0x02  # 5.2.2 Abfragetelegramme
    SHORT_COMMAND = 0x03  # 5.2.3 Kurze Befehlstelegramme
    SETTING_16 = 0x04  # 5.2.4
    SETTING_32 = 0x05  # 5.2.5
    SETTING_40 = 0x06  # 5.2.6
    SETTING_48 = 0x07  # 5.2.7
    SETTING_64 = 0x08  # 5.2.8


SETTING_VALUE_BYTES = {0x04: 2, 0x05: 4, 0x06: 5, 0x07: 6, 0x08: 8}  # chapter 5.2.4-5.2.8

# answer telegram type -> name (chapter 5.1.5-5.1.31; a query index n is answered by type n + 5)
TELEGRAMS: dict[int, str] = {
    0x05: N_("device"), 0x06: N_("program version"), 0x07: N_("barrier status"), 0x08: N_("status mask"),
    0x09: N_("change monitoring"), 0x0A: N_("service counter"), 0x0B: N_("maintenance counter"),
    0x0C: N_("gate state"), 0x0D: N_("open time"), 0x0E: N_("pre-warning before opening"),
    0x0F: N_("pre-warning before closing"), 0x10: N_("dec_bt"), 0x11: N_("counting function"),
    0x12: N_("induction loops"), 0x13: N_("direction logics"), 0x14: N_("serial number"), 0x15: N_("MAC address"),
    0x16: N_("operating hours"), 0x17: N_("error memory"), 0x18: N_("configuration flags"), 0x19: N_("multi relays"),
    0x1A: N_("maintenance interval"), 0x1B: N_("loop periods"), 0x1C: N_("vehicle counter"),
    0x1D: N_("barrier position"), 0x1E: N_("password"), 0x1F: N_("loop-adjust counters"),
}
QUERY_ANSWER_OFFSET = 5  # SPEC-NOTES "Replies": query index n is answered by telegram type n + 5
QUERY_INDEXES = range(0x00, 0x1B)  # chapter 5.2.2, table 21: 0x00 .. 0x1A
FORBIDDEN_QUERIES = frozenset(range(0x1B, 0x1F))  # table 21: 0x1B-0x1E "Nicht verwenden!"
# Chapter 5.1.23: the error flags are a 32-bit register; at every change of the flags they are stored together with
# the operating hours counter's value of that moment, the current value in level 0: level 0 is the newest, 9 the
# oldest, and each level's time stamp is the operating hours at which the flags took that value. The summary does
# not name the 32 flags: a set flag is named by its bit number (bit 0 = least significant of fehlerflaggen_lo0).
ERROR_MEMORY_MEANING = ("Each level is one change of the 32 error flags with the operating hours at that change "
                        "(chapter 5.1.23): level 0 the newest, level 9 the oldest. The document summary does not "
                        "name the flags: a set flag is shown by its bit number.")
NO_ERROR = N_("no error")


def error_flag_bits(flags: int) -> list[int]:
    """The numbers (0..31) of the error flags set in a stored value (chapter 5.1.23)."""
    return [n for n in range(32) if int(flags) >> n & 1]


def error_flags_text(flags: int, older: int | None = None) -> str:
    """A level of the error memory in words: which flags are set, and what changed against the older level
    (``older``, the level below it in time; None for the oldest or when it is not known).

    ``"no error"``, ``"no error (flags 3 cleared)"``, ``"error flags 3, 7 set (7 new)"``.
    """
    flags = int(flags)
    now = error_flag_bits(flags)
    before = set(error_flag_bits(older)) if older is not None else None

    def numbers(bits: list[int]) -> str:
        return ", ".join(map(str, bits))

    changes = []
    if before is not None:
        new = [n for n in now if n not in before]
        gone = sorted(before - set(now))
        if new and before:
            changes.append(Message(N_("{list} new"), list=numbers(new)))
        if gone:
            cleared = N_("{list} cleared") if now else N_("flags {list} cleared") if len(gone) > 1 else N_("flag {list} cleared")
            changes.append(Message(cleared, list=numbers(gone)))
    text = Message(NO_ERROR) if not now else Message(N_("error flags {list} set") if len(now) > 1 else
                                                     N_("error flag {list} set"), list=numbers(now))
    return Message("{text} ({changes})", text=text, changes=joined(changes, "; ")) if changes else text


EMPTY_LEVEL = N_("empty: no change stored")  # flags 0 at 0 operating hours: a level no change has reached yet


def error_level_meaning(flags: int, timestamp_h: int, older: int | None = None) -> str:
    """One level in words (:func:`error_flags_text`), or :data:`EMPTY_LEVEL` for a level never written."""
    return Message(EMPTY_LEVEL) if int(flags) == 0 and int(timestamp_h) == 0 else error_flags_text(flags, older)


def error_level_text(level: int) -> str:
    """Level 0 is the newest change, 9 the oldest (chapter 5.1.23)."""
    return f"{level} (newest)" if level == 0 else f"{level} (oldest)" if level == ERROR_MEMORY_LEVELS - 1 else str(level)


def query_index(answer_type: int) -> int:
    """The query index whose answer is telegram ``answer_type``."""
    index = answer_type - QUERY_ANSWER_OFFSET
    if index not in QUERY_INDEXES:
        raise CodecError(f"no query is answered by telegram 0x{answer_type:02X}")
    return index


# query indexes by name, for the adapter
Q_DEVICE, Q_PROGRAM_VERSION, Q_BARRIER_STATUS, Q_STATUS_MASK, Q_CHANGE_MONITORING = 0x00, 0x01, 0x02, 0x03, 0x04
Q_SERVICE_COUNTER, Q_MAINTENANCE_COUNTER, Q_GATE_STATE = 0x05, 0x06, 0x07
Q_T_OPEN, Q_T_PREWARN_OPEN, Q_T_PREWARN_CLOSE, Q_DEC_BT, Q_COUNTING = 0x08, 0x09, 0x0A, 0x0B, 0x0C
Q_INDUCTION_LOOPS, Q_DIRECTION_LOGICS, Q_SERIAL_NUMBER, Q_MAC, Q_OPERATING_HOURS = 0x0D, 0x0E, 0x0F, 0x10, 0x11
Q_ERROR_MEMORY, Q_CONFIG_FLAGS, Q_MULTI_RELAYS, Q_MAINTENANCE_INTERVAL = 0x12, 0x13, 0x14, 0x15
Q_LOOP_PERIODS, Q_VEHICLE_COUNTER, Q_BARRIER_POSITION, Q_PASSWORD, Q_LOOP_ADJUST = 0x16, 0x17, 0x18, 0x19, 0x1A


class Command(IntEnum):
    """Operating command (chapter 5.2.1; numbers from SPEC-NOTES "Operating commands")."""

    REVERSE = 0x00
    OPEN = 0x01  # BT
    CLOSE = 0x02  # BZ


class Function(IntEnum):
    """How an operating command acts (chapter 5.2.1, table 19: all other functions are invalid)."""

    PULSE = 0x00
    ACTIVATE = 0x01  # level on: stays until deactivated
    DEACTIVATE = 0x02  # level off


QUERY_FORMS = ("document", "short")  # SPEC-NOTES "Query form": the document's 02 Auswahl index, else 02 Auswahl


def encode_query(index: int, level: int | None = None, form: str = "short") -> bytes:
    """A query telegram (type + payload), framed by :func:`encode_frame`.

    :param index: 0x00 .. 0x1A (table 21)
    :param level: error memory level 0..9, only for :data:`Q_ERROR_MEMORY` (ASSUMED byte)
    :param form: "short" ``02 Auswahl`` (the public client's golden vectors) or "document"
        ``02 Auswahl index`` (page 33), whose index byte is the level for the error memory, else 0
    :raises CodecError: a forbidden ("Nicht verwenden!") or invalid index
    """
    if form not in QUERY_FORMS:
        raise CodecError(f"query form {form!r} is not one of {', '.join(QUERY_FORMS)}")
    if form == "document" and level is None and index != Q_ERROR_MEMORY:
        return encode_query(index, None, "short") + b"\x00"
    if isinstance(index, bool) or not isinstance(index, int):
        raise CodecError(f"query index {index!r} is not a number")
    if index in FORBIDDEN_QUERIES:
        raise CodecError(f"query index 0x{index:02X} is marked 'Nicht verwenden!' (table 21): never sent")
    if index not in QUERY_INDEXES:
        raise CodecError(f"query index 0x{index:02X} is not in table 21 (0x00 .. 0x1A)")
    if level is None:
        return bytes((RequestType.QUERY, index))
    if index != Q_ERROR_MEMORY or not ERROR_MEMORY_QUERY_HAS_LEVEL:
        raise CodecError("only the error memory query takes a level")
    if isinstance(level, bool) or not isinstance(level, int) or not 0 <= level < ERROR_MEMORY_LEVELS:
        raise CodecError(f"error memory level {level!r} is not 0 .. {ERROR_MEMORY_LEVELS - 1}")
    return bytes((RequestType.QUERY, index, level))


def encode_command(command: Command | int, function: Function | int = Function.PULSE) -> bytes:
    """An operating telegram ``01 command function`` (chapter 5.2.1).

    :raises CodecError: an unknown command or function (the MO 64 would answer nak)
    """
    try:
        command, function = Command(command), Function(function)
    except ValueError as exc:
        raise CodecError(f"invalid operating command: {exc}") from None
    return bytes((RequestType.COMMAND, command, function))


def encode_short_command(code: int) -> bytes:
    """A short command ``03 code`` (chapter 5.2.3; one code byte ASSUMED, codes not named)."""
    if isinstance(code, bool) or not isinstance(code, int) or not 0 <= code <= 0xFF:
        raise CodecError(f"short command {code!r} is not one byte")
    return bytes((RequestType.SHORT_COMMAND, code))


# -- answers (MO 64 -> master) ---------------------------------------------------------------------
@dataclass(frozen=True)
class Answer:
    """A decoded telegram from the MO 64.

    :param type: the telegram type; ``reply`` is set for 0x01-0x04
    :param value: the typed value (None for replies and for undecodable data)
    :param error: why ``value`` could not be decoded (the raw payload is still there)
    """

    type: int
    payload: bytes
    reply: Reply | None = None
    value: Any = None
    error: str | None = None
    frame: Frame | None = None

    @property
    def name(self) -> str:
        if self.reply is not None:
            return self.reply.name.lower()
        return TELEGRAMS.get(self.type, f"unknown telegram 0x{self.type:02X}")

    @property
    def query(self) -> int | None:
        """The query index this telegram answers (None for replies and unknown types)."""
        index = self.type - QUERY_ANSWER_OFFSET
        return index if index in QUERY_INDEXES else None


def decode_value(answer_type: int, payload: bytes) -> Any:
    """Decode the payload of answer telegram 0x05..0x1F.

    :raises devices.values.DecodeError: short or excess data
    :raises CodecError: not an answer type
    """
    return answer_value_type(answer_type, len(payload)).decode(payload)


def decode_answer(frame: Frame | bytes, framing: Framing = TCP) -> Answer:
    """A telegram the MO 64 sent (chapter 5.1). Undecodable data is kept raw with ``error`` set.

    :param frame: a :class:`Frame`, or the raw bytes of one
    :raises FrameError: raw bytes that are no valid frame
    """
    if not isinstance(frame, Frame):
        frame = decode_frame(frame, framing)
    if frame.is_token:
        raise CodecError("a token telegram is no answer")
    if frame.type in REPLY_TYPES:
        reply = Reply(frame.type)
        error = f"unexpected data after {reply.name.lower()}" if frame.payload else None
        return Answer(frame.type, frame.payload, reply=reply, error=error, frame=frame)
    if frame.type not in ANSWER_TYPES:
        return Answer(frame.type, frame.payload, error=f"unknown telegram type 0x{frame.type:02X}", frame=frame)
    try:
        value = decode_value(frame.type, frame.payload)
    except v.ValueCodecError as exc:
        return Answer(frame.type, frame.payload, error=str(exc), frame=frame)
    return Answer(frame.type, frame.payload, value=value, frame=frame)


def encode_answer(answer_type: int, value: Any = None) -> bytes:
    """A twin's telegram (type + payload): a reply (``value`` None) or answer 0x05..0x1F."""
    if answer_type in REPLY_TYPES:
        if value not in (None, b""):
            raise CodecError("a reply carries no data")
        return bytes((answer_type,))
    if isinstance(value, (bytes, bytearray)) and ANSWER_TYPES.get(answer_type) is RAW:
        return bytes((answer_type,)) + bytes(value)
    vtype = ERROR_MEMORY if answer_type == 0x17 and isinstance(value, (list, tuple)) else answer_value_type(answer_type)
    try:
        return bytes((answer_type,)) + vtype.encode(value)
    except v.EncodeError as exc:
        raise CodecError(f"{TELEGRAMS[answer_type]}: {exc}") from None


# -- settings (chapter 5.2.4-5.2.8) ----------------------------------------------------------------
@dataclass(frozen=True)
class Setting:
    """One setting telegram of the directory.

    :param telegram: setting type 0x04..0x08 (the value width)
    :param selector: the "Auswahl" byte
    :param vtype: the value's type on the wire
    :param unit: unit of the raw value ("10 ms" for times)
    :param query: the query index that reads it back
    :param backup: backed up and restored (False: RAM only)
    :param eeprom: a write wears the EEPROM (chapter 4: "Schreibzugriff auf das EEPROM")
    :param limits: allowed raw range for integers (None: the type's own)
    :param assumed: why the selector or layout is an assumption; None if the document names it
    """

    key: str
    name: str
    telegram: int
    selector: int
    vtype: v.ValueType
    query: int
    unit: str = ""
    backup: bool = True
    eeprom: bool = True
    limits: tuple[int, int] | None = None
    assumed: str | None = None
    doc: str = ""

    def check(self, value: Any) -> bytes:
        """The value bytes, range-checked.

        :raises CodecError: out of range or not of the type
        """
        if self.limits is not None:
            low, high = self.limits
            if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
                raise CodecError(f"{self.name}: {value!r} is outside {low} .. {high} {self.unit}".rstrip())
        try:
            data = self.vtype.encode(value)
        except v.EncodeError as exc:
            raise CodecError(f"{self.name}: {exc}") from None
        if len(data) != SETTING_VALUE_BYTES[self.telegram]:
            raise CodecError(f"{self.name}: {len(data)} bytes, setting 0x{self.telegram:02X} takes "
                             f"{SETTING_VALUE_BYTES[self.telegram]}")
        return data


_MASK_40 = v.Bits(v.Int(40), STATUS_BITS.fields)  # setting 0x06 0x00 takes exactly Maske0..Maske4

SETTINGS: dict[str, Setting] = {s.key: s for s in (
    Setting("t_open", N_("open time"), 0x04, 0x00, TIME_10MS, Q_T_OPEN, "10 ms", limits=(0, TIME_MAX),
            doc="0 switches automatic closing off (chapter 5.2.4.1)"),
    Setting("t_prewarn_open", N_("pre-warning before opening"), 0x04, 0x01, TIME_10MS, Q_T_PREWARN_OPEN, "10 ms",
            limits=(0, TIME_MAX), assumed=Message(N_("selector 0x01 follows the order of answers 0x0D-0x0F"))),
    Setting("t_prewarn_close", N_("pre-warning before closing"), 0x04, 0x02, TIME_10MS, Q_T_PREWARN_CLOSE, "10 ms",
            limits=(0, TIME_MAX), assumed=Message(N_("selector 0x02 follows the order of answers 0x0D-0x0F"))),
    Setting("change_monitoring", N_("change monitoring"), 0x04, 0x04, CHANGE_MONITORING, Q_CHANGE_MONITORING,
            doc="unsolicited telegrams over TCP (chapter 5.2.4.5)"),
    Setting("vehicle_counter", N_("vehicle counter"), 0x05, 0x00, VEHICLE_COUNTER, Q_VEHICLE_COUNTER,
            backup=False, eeprom=False, assumed=Message(N_("selector 0x00 not in the summary (chapter 5.2.5)")),
            doc="RAM only, 0 after power-up; answered ack (chapter 5.2.5)"),
    Setting("maintenance_interval", N_("maintenance interval"), 0x05, 0x01, MAINTENANCE_INTERVAL,
            Q_MAINTENANCE_INTERVAL, assumed=Message(N_("selector 0x01 and u32 width not in the summary"))),
    Setting("status_mask", N_("status mask"), 0x06, 0x00, _MASK_40, Q_STATUS_MASK,
            doc="status bits watched for change (chapter 5.2.6.1)"),
    Setting("multi_relays", N_("multi-relay modes"), 0x07, 0x00, MULTI_RELAYS, Q_MULTI_RELAYS,
            doc="multi1 .. multi6 (chapter 5.2.7.1)"),
    Setting("config_flags", N_("configuration flags"), 0x08, 0x00, CONFIG_FLAGS, Q_CONFIG_FLAGS,
            doc="konfig0 .. konfig3 (chapter 5.2.8.1)"),
)}


def setting_by_selector(telegram: int, selector: int) -> Setting | None:
    return next((s for s in SETTINGS.values() if s.telegram == telegram and s.selector == selector), None)


def encode_setting(key: str, value: Any) -> bytes:
    """A setting telegram ``type selector value...`` (chapter 5.2.4-5.2.8), range-checked.

    :param key: a key of :data:`SETTINGS`
    :raises CodecError: unknown setting or value out of range
    """
    try:
        setting = SETTINGS[key]
    except KeyError:
        raise CodecError(f"no setting {key!r}") from None
    return bytes((setting.telegram, setting.selector)) + setting.check(value)


def _type_limits(vtype: v.ValueType) -> tuple[int, int]:
    return vtype.base.limits if isinstance(vtype, v.Bits) else vtype.limits


def setting_fields(key: str) -> tuple[tuple[str, int, int], ...]:
    """The whole numbers a setting is entered and invoked as, ``(name, low, high)``: one ``value``, or one
    per member named as the document names them (multi1 .. multi6, 5.2.7.1; konfig0 .. konfig3, 5.2.8.1)."""
    setting = SETTINGS[key]
    vtype = setting.vtype
    if isinstance(vtype, v.Struct):
        return tuple((name, *_type_limits(t)) for name, t in vtype.members)
    if isinstance(vtype, v.Array):
        return tuple((f"multi{n}", *_type_limits(vtype.item)) for n in range(1, vtype.count + 1))
    return (("value", *(setting.limits or _type_limits(vtype))),)


def setting_from_fields(key: str, numbers: Iterable[int]) -> Any:
    """The value :func:`encode_setting` takes, from the numbers of :func:`setting_fields` (in order)."""
    numbers = list(numbers)
    vtype = SETTINGS[key].vtype
    if isinstance(vtype, v.Struct):
        return dict(zip((name for name, _ in vtype.members), numbers))
    if isinstance(vtype, v.Array):
        return numbers
    return numbers[0]


def setting_to_fields(key: str, value: Any) -> dict[str, int]:
    """The numbers of :func:`setting_fields` for ``value`` (the inverse of :func:`setting_from_fields`)."""
    names = [name for name, _, _ in setting_fields(key)]
    if isinstance(value, Mapping):
        return {name: int(value[name]) for name in names}
    if isinstance(value, (list, tuple)):
        return dict(zip(names, (int(x) for x in value)))
    return {names[0]: int(value)}


def setting_value(key: str, answer: Answer) -> Any:
    """The value of setting ``key`` from its read-back answer (for a restore's comparison)."""
    setting = SETTINGS[key]
    if answer.query != setting.query:
        raise CodecError(f"{answer.name} is not the read-back of {setting.name}")
    if answer.error is not None:
        raise CodecError(f"{setting.name}: {answer.error}")
    return setting.vtype.decode(setting.vtype.encode(_strip_extra(answer.value)))


def _strip_extra(value: Any) -> Any:
    if isinstance(value, Mapping) and set(value) == {"mask", "more"}:
        return value["mask"]
    return value


# -- requests (master -> MO 64), for the twin ------------------------------------------------------
@dataclass(frozen=True)
class Request:
    """A decoded telegram to the MO 64 (chapter 5.2).

    :param kind: the :class:`RequestType`
    :param query: the query index (queries); ``level`` the ASSUMED error memory level
    :param command, function: operating commands
    :param setting: the :class:`Setting` (None for a selector the directory does not know)
    :param value: the decoded setting value
    """

    kind: RequestType
    payload: bytes
    query: int | None = None
    level: int | None = None
    command: Command | None = None
    function: Function | None = None
    code: int | None = None
    selector: int | None = None
    setting: Setting | None = None
    value: Any = None
    frame: Frame | None = None


class InvalidRequest(CodecError):
    """A request the MO 64 answers with nak (unknown type, forbidden index, bad length)."""

    def __init__(self, message: str, frame: Frame | None = None):
        self.frame = frame
        super().__init__(message)


def decode_request(frame: Frame | bytes, framing: Framing = TCP) -> Request:
    """A telegram to the MO 64 (chapter 5.2).

    :raises InvalidRequest: what the MO 64 answers with nak
    :raises FrameError: raw bytes that are no valid frame
    """
    if not isinstance(frame, Frame):
        frame = decode_frame(frame, framing)
    if frame.is_token:
        raise InvalidRequest("a token telegram is no request (the MO 64 ignores it)", frame)
    try:
        kind = RequestType(frame.type)
    except ValueError:
        raise InvalidRequest(f"unknown telegram type 0x{frame.type:02X}", frame) from None
    p = frame.payload
    if kind is RequestType.QUERY:
        if len(p) not in (1, 2):  # 02 Auswahl (short form) or 02 Auswahl index (the document's, p. 33)
            raise InvalidRequest(f"query with {len(p)} data bytes", frame)
        if p[0] in FORBIDDEN_QUERIES or p[0] not in QUERY_INDEXES:
            raise InvalidRequest(f"query index 0x{p[0]:02X} is invalid (table 21)", frame)
        level = p[1] if len(p) == 2 else None
        if level is not None and p[0] == Q_ERROR_MEMORY and level >= ERROR_MEMORY_LEVELS:
            raise InvalidRequest(f"error memory level {level} is not 0 .. 9", frame)
        return Request(kind, p, query=p[0], level=level, frame=frame)
    if kind is RequestType.COMMAND:
        if len(p) != 2:
            raise InvalidRequest(f"operating command with {len(p)} data bytes", frame)
        try:
            return Request(kind, p, command=Command(p[0]), function=Function(p[1]), frame=frame)
        except ValueError:
            raise InvalidRequest(f"invalid command {p[0]:02X} / function {p[1]:02X} (table 19)", frame) from None
    if kind is RequestType.SHORT_COMMAND:
        if len(p) != SHORT_COMMAND_BYTES:
            raise InvalidRequest(f"short command with {len(p)} data bytes", frame)
        return Request(kind, p, code=p[0], frame=frame)
    if len(p) != 1 + SETTING_VALUE_BYTES[kind]:
        raise InvalidRequest(f"setting 0x{kind:02X} with {len(p)} data bytes "
                             f"(takes 1 + {SETTING_VALUE_BYTES[kind]})", frame)
    setting = setting_by_selector(kind, p[0])
    if setting is None:
        return Request(kind, p, selector=p[0], value=p[1:], frame=frame)
    value = setting.vtype.decode(p[1:])
    if setting.limits is not None and not setting.limits[0] <= value <= setting.limits[1]:
        raise InvalidRequest(f"{setting.name} {value} is outside {setting.limits[0]} .. {setting.limits[1]}", frame)
    return Request(kind, p, selector=p[0], setting=setting, value=value, frame=frame)


def describe(frame: Frame, to_device: bool) -> str:
    """One line for the bus monitor: what the frame is, decoded as far as possible."""
    where = f"{frame.sa:02X}->{frame.da:02X} " if frame.da is not None else ""

    def placed(text: str) -> str:  # a Message (the page words it) after the addresses
        return Message("{where}{text}", where=where, text=text) if where else text

    if frame.is_token:
        return placed(Message(N_("token")))
    try:
        if to_device:
            r = decode_request(frame)
            if r.kind is RequestType.QUERY:
                return placed(Message(N_("query 0x{query:02X} ({telegram})"), query=r.query,
                                      telegram=Message(TELEGRAMS[r.query + QUERY_ANSWER_OFFSET])))
            if r.kind is RequestType.COMMAND:
                template = _FUNCTION_WORDS.get(r.function)
                command = r.command.name.lower()
                if template is None or command not in _COMMAND_WORDS:
                    return f"{where}{command} {r.function.name.lower()}"
                return placed(Message(template, command=Message(_COMMAND_WORDS[command])))
            if r.kind is RequestType.SHORT_COMMAND:
                return placed(Message(N_("short command 0x{code:02X}"), code=r.code))
            name = r.setting.name if r.setting else Message(N_("setting 0x{kind:02X}/0x{selector:02X}"), kind=r.kind,
                                                            selector=r.selector)
            return placed(Message(N_("set {name} = {value}"), name=name, value=repr(r.value)))
        a = decode_answer(frame)
    except CodecError as exc:
        return f"{where}{exc}"
    if a.error:
        return placed(Message("{name}: {error} ({raw})", name=Message(a.name), error=a.error, raw=a.payload.hex(" ")))
    if a.reply is not None:
        return placed(Message(a.name))
    return placed(Message("{name} = {value}", name=Message(a.name), value=_short(a.value)))


# an operating command in the words devices/mo64/control.py gives it ("open pulse")
_COMMAND_WORDS = {"open": N_("open"), "close": N_("close"), "reverse": N_("reverse")}
_FUNCTION_WORDS = {Function.PULSE: N_("{command} pulse"), Function.ACTIVATE: N_("{command} activate"),
                   Function.DEACTIVATE: N_("{command} deactivate")}


def _short(value: Any) -> str:
    """A decoded value in few words for the monitor: the bits that are set, not all 40 of them."""
    if isinstance(value, v.FlagsValue):
        return ", ".join(value.active) or "none set"
    if isinstance(value, v.EnumValue):
        return f"{value.name or 'undefined'} ({int(value)})"
    if isinstance(value, dict):
        parts = [f"{k}: {_short(x)}" for k, x in value.items() if not (isinstance(x, bytes | bytearray) and not x)]
        return "; ".join(parts) if len(parts) > 1 else (parts[0].split(": ", 1)[1] if parts else "")
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_short(x) for x in value) + "]"
    if isinstance(value, bytes | bytearray):
        return value.hex(" ")
    return repr(value)


__all__ = [name for name in dir() if not name.startswith("_") and name not in {
    "annotations", "Iterable", "Mapping", "dataclass", "IntEnum", "Any", "v"}]
