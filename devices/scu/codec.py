"""Ewellix (Schaeffler) SCU control unit, RS232 interface: telegrams of the remote session.

Pure: no I/O. Document 002 ("Schnittstelle RS232, Steuereinheit SCU"), sections 3 to 7;
decisions on its ambiguities follow SPEC-NOTES.md ("Ewellix SCU"), each cited once where taken.

Frame (section 3, "Telegrammstruktur")::

    request  <X><Y><P1..Pn><C1><C2>
    answer   <X><Y><ACK>[<ctp lo><ctp hi><data ...>]<C1><C2>

X, Y are the ASCII command letters, parameters are little-endian, and C1 C2 the
CRC-16/XMODEM (poly 0x1021, init 0) of X..Pn, low byte first.

Public API, in the order a session uses it:

* requests: :func:`encode_ro`, :func:`encode_rc` (:data:`KEEP_ALIVE`), :func:`encode_rg`,
  :func:`encode_rt`, :func:`encode_re`, :func:`encode_rs`, :func:`encode_ra`;
* answers: :func:`decode_answer` -> :class:`Answer` (``raise_for_status`` raises
  :class:`CommandRefused` naming CSE/PDE/PCE/ICE/PE with meaning and remedy);
* a serial byte stream: :class:`FrameSplitter` (answers, or requests for a twin) yields frames
  and named :class:`FrameError` values (garbage, bad CRC, implausible length, truncated);
* a twin's side: :func:`decode_request` -> :class:`Request` with typed fields,
  :func:`encode_answer`;
* directories: :class:`Function`, :class:`Motion`, :class:`Ramp`, :data:`FUNCTIONS`,
  :class:`SafetyId` (:data:`SAFETY_MODES`), :data:`ERROR_BITS` with :func:`error_bits`.
"""

from __future__ import annotations

import binascii
from dataclasses import dataclass, field
from enum import IntEnum

from devices import errors, framing
from devices.message import Message, N_
from devices.scu.errorcodes import (  # noqa: F401 - the error code bits (table 10) are part of the codec's names
    CLEARED_BY_NEXT_MOVE, ERROR_BITS, NO_ERROR, REMOTE_TIMEOUT_MASK, ErrorBit, error_bits, error_hex, error_text,
    unknown_error_bits)

# -- line (section 3, "Physikalische Ebene" / "Netzwerkebene") ---------------------------------------
DEFAULT_BAUDRATE = 38400
BAUDRATES = (9600, 19200, 38400)  # custom units only for 9600/19200
BYTE_BITS = 10  # 1 start, 8 data, 1 stop, no parity
MAX_ANSWER_DELAY_S = 2.0  # "max. Anfrageverzögerung: 2000 ms"
MAX_INTER_BYTE_S = 1.0  # "max. Verzögerung zwischen einzelnen Telegrammbytes: 1000 ms"
WATCHDOG_S = 0.5  # section 4.1: remote commands at least every 500 ms, else remote mode ends
KEEP_ALIVE_PERIOD_S = 0.2  # SPEC-NOTES "Remote session": RC every 200 ms, well inside the 500 ms watchdog

# -- commands (section 4.1, table 3) -----------------------------------------------------------------
RO, RA, RC, RG, RT, RE, RS = b"RO", b"RA", b"RC", b"RG", b"RT", b"RE", b"RS"
COMMANDS: dict[bytes, str] = {
    RO: "Remote mode open",
    RA: "Remote mode abort",
    RC: "Remote cyclic",
    RG: "Remote data get",
    RT: "Remote data transfer",
    RE: "Remote execute function",  # table 3 prints "WK": a print error for RE (SPEC-NOTES)
    RS: "Remote stop function",  # table 3 prints "SG": a print error for RS (SPEC-NOTES)
}
REMOTE_ONLY = frozenset({RG, RT, RC, RE, RS})  # section 4.1: only while remote mode is open
UNUSED = 0xFF  # section 4.4: unused parameters are -1, one byte 0xFF (SPEC-NOTES)
NO_CYCLIC_OBJECT = 0xFF  # table 3, RC: P3 = -1 transfers no data
CYCLIC_OBJECT_IDS = (0x3001, 0x3002, 0x3003, 0x3004, 0x3005)  # RC index 0..4 (table 3, table 7)
REMOTE_DATA_IDS = range(0x3000, 0x4000)  # table 3, RT: "Nur data_Ids 3xxx sind erlaubt"
# Longest ctp the codec believes: the largest directory block (0x2000, 6 x 104 B) plus room. It also
# tells a bare ACK from an ACK with ctp: the CRC of "RC"/"RG" + ACK read as a ctp is above it (see
# FrameSplitter).
MAX_CTP = 1024

ACK = 0x06


class CodecError(errors.CodecError):
    """A telegram that cannot be encoded or decoded."""


# -- CRC (section 3 "Transportebene", section 6) ----------------------------------------------------
def crc16(data: bytes | bytearray) -> int:
    """CRC-16/XMODEM (CCITT poly 0x1021, start value 0) of ``data`` (section 6)."""
    return binascii.crc_hqx(bytes(data), 0)


CHECKSUM = framing.Checksum(crc16, "little")  # C1 = low byte first (section 3, table 3)
_seal = CHECKSUM.seal


def _check_crc(frame: bytes) -> bool:
    return len(frame) >= 4 and CHECKSUM.matches(frame)


def _byte(value: int, what: str) -> int:
    """One parameter byte; -1 is the document's 'unused' (0xFF)."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise CodecError(f"{what} must be a whole number, not {value!r}")
    if value == -1:
        return UNUSED
    if not 0 <= value <= 0xFF:
        raise CodecError(f"{what} {value} does not fit one byte (0 .. 255, or -1 for unused)")
    return value


def _u16(value: int, what: str) -> bytes:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFFFF:
        raise CodecError(f"{what} {value!r} is not 0 .. 0xFFFF")
    return value.to_bytes(2, "little")


# -- directories: functions, motions, Safety_ID (sections 4.1, 4.4) -------------------------------------
class Function(IntEnum):
    """fnc_ID of the function directory (section 4.4, table 8)."""

    F1 = 0
    F2 = 1
    F3 = 2
    F4 = 3
    F5 = 4
    F6 = 5
    F7 = 6
    F8 = 7
    F9 = 8
    F10 = 9
    BUZZER = 10
    BINARY_OUTPUT_1 = 16
    BINARY_OUTPUT_2 = 17
    EMERGENCY_STOP = 19
    LED_1 = 20
    LED_2 = 21  # table 8 says "Operating unit LED1" twice: fnc_ID 21 is LED2 (SPEC-NOTES)


MOTION_FUNCTIONS = tuple(Function(n) for n in range(10))


@dataclass(frozen=True)
class FunctionInfo:
    label: str
    description: str
    motion: bool
    since_firmware: str = ""


FUNCTIONS: dict[Function, FunctionInfo] = {
    **{f: FunctionInfo(f"F{f + 1}", Message(N_("Motion function F{n} (actuators and behaviour per the unit's configuration)"),
                                            n=f + 1), True) for f in MOTION_FUNCTIONS},
    Function.BUZZER: FunctionInfo("F11", Message(N_("Buzzer")), False, "V2B1"),
    Function.BINARY_OUTPUT_1: FunctionInfo("F17", Message(N_("Binary output 1")), False, "V2B1"),
    Function.BINARY_OUTPUT_2: FunctionInfo("F18", Message(N_("Binary output 2")), False, "V2B1"),
    Function.EMERGENCY_STOP: FunctionInfo("F20", Message(N_("Emergency stop")), False, "V2B1"),
    Function.LED_1: FunctionInfo("F21", Message(N_("Operating unit LED1")), False, "V2B1"),
    Function.LED_2: FunctionInfo("F22", Message(N_("Operating unit LED2")), False, "V2B1"),
}


class Motion(IntEnum):
    """para_ID[0] of RE for F1..F10: motion_direction (section 4.4, table 9)."""

    NONE = 0  # undefined direction (no motion)
    IN = 1
    OUT = 2
    MEM1 = 3
    MEM2 = 4
    MEM3 = 5
    MEM4 = 6
    INTERMEDIATE_IN = 7
    INTERMEDIATE_OUT = 8
    REMOTE_POSITION = 9


MOTION_LABELS: dict[Motion, str] = {
    Motion.NONE: "undefined direction (no motion)",
    Motion.IN: "Move to position In",
    Motion.OUT: "Move to position Out",
    Motion.MEM1: "Move to position Mem1",
    Motion.MEM2: "Move to position Mem2",
    Motion.MEM3: "Move to position Mem3",
    Motion.MEM4: "Move to position Mem4",
    Motion.INTERMEDIATE_IN: "Move to position Intermediate In",
    Motion.INTERMEDIATE_OUT: "Move to position Intermediate Out",
    Motion.REMOTE_POSITION: "Move to remote position (data IDs 0x3021..0x3026)",
}


class Ramp(IntEnum):
    """para_ID[1] of RE for F1..F10: motion_stop (section 4.4, table 9); -1 leaves it to the configuration."""

    FAST = 0  # start/stop ramp not applied
    SOFT = 1  # start/stop ramp applied
    DEFAULT = UNUSED  # section 5 example RE 00 09 FF: "ohne Start/Stop" sends -1


class SafetyId(IntEnum):
    """Safety_ID of RO (section 4.1, table 3)."""

    NO_START_AFTER_TIMEOUT = 0
    STOP_ALL = 1
    STOP_REMOTE = 2


DEFAULT_SAFETY_ID = SafetyId.STOP_ALL  # SPEC-NOTES / issue: the plant file's default is 1

SAFETY_MODES: dict[SafetyId, str] = {
    SafetyId.NO_START_AFTER_TIMEOUT: (
        "On a communication timeout (0.5 s) every motion is stopped and none is started; after the "
        "timeout only RC, RA and RO are available."),
    SafetyId.STOP_ALL: "On a communication timeout (0.5 s) every motion is stopped.",
    SafetyId.STOP_REMOTE: (
        "On a communication timeout (0.5 s) only the remote motion is stopped (firmware V2B3 and later)."),
}


# -- answer status codes (section 4.2, table 4.4) ------------------------------------------------------
class Status(IntEnum):
    ACK = 0x06
    CSE = 0x80
    PDE = 0x81
    PCE = 0x82
    ICE = 0x83
    PE = 0x84


@dataclass(frozen=True)
class StatusInfo:
    name: str
    title: str
    meaning: str
    remedy: str


STATUS_INFO: dict[int, StatusInfo] = {
    Status.ACK: StatusInfo("ACK", "Command acknowledged", Message(N_("the request was accepted")), ""),
    Status.CSE: StatusInfo(
        "CSE", "Checksum error", Message(N_("the unit received the telegram with a wrong checksum")),
        Message(N_("resend; if it repeats, check the cable, its screen and earthing, and the baud rate"))),
    Status.PDE: StatusInfo(
        "PDE", "Parameter data error", Message(N_("a data byte of the telegram is not valid (unknown data ID or function, "
        "a value out of range, a write to a data ID outside 0x3xxx)")),
        Message(N_("check the data ID, function or value against the data and function directories"))),
    Status.PCE: StatusInfo(
        "PCE", "Parameter count error", Message(N_("the number of data bytes does not match (ctp, or the size of the data ID)")),
        Message(N_("send exactly the bytes the data ID or cyclic object defines, with a matching ctp"))),
    Status.ICE: StatusInfo(
        "ICE", "Invalid command error", Message(N_("the unit does not know the command code")),
        Message(N_("check the command letters; the unit's firmware may be older than the function needs (V2B1)"))),
    Status.PE: StatusInfo(
        "PE", "Permission error", Message(N_("the command is not possible in the unit's current mode or state "
        "(remote mode not open, or dropped after a 500 ms gap without RC)")),
        Message(N_("open remote mode with RO and keep it with RC at least every 500 ms, then repeat the command"))),
}


class CommandRefused(CodecError):
    """The unit answered with an error code instead of ACK; ``info`` names it."""

    def __init__(self, command: bytes, code: int):
        self.command = command
        self.code = code
        self.info = STATUS_INFO.get(code) or StatusInfo(
            f"0x{code:02X}", "Unknown status", Message(N_("an undocumented answer code")),
            Message(N_("note the code and the command and ask the vendor")))
        info, sent = self.info, command.decode("ascii", "replace")
        super().__init__(Message("{command}: {name} ({title}): {meaning}; {remedy}", command=sent, name=info.name, title=info.title,
                                 meaning=info.meaning, remedy=info.remedy) if info.remedy else
                         Message("{command}: {name} ({title}): {meaning}", command=sent, name=info.name, title=info.title,
                                 meaning=info.meaning))


# -- requests ----------------------------------------------------------------------------------------
def encode_frame(command: bytes, params: bytes = b"") -> bytes:
    """``<X><Y><P1..Pn><C1><C2>`` for any command.

    :param command: two ASCII letters, one of :data:`COMMANDS`
    :param params: the parameter bytes P1..Pn
    """
    if command not in COMMANDS:
        raise CodecError(f"unknown command {command!r}")
    return _seal(bytes(command) + bytes(params))


def encode_ro(safety_id: int = DEFAULT_SAFETY_ID) -> bytes:
    """RO: open remote mode (section 4.1).

    Table 3 lists a para_ID[0] after the Safety_ID; the section 5 example sends the Safety_ID alone
    ("RO 00"), which is what this sends (one decision, here).

    :param safety_id: 0, 1 or 2 (:class:`SafetyId`)
    """
    if safety_id not in tuple(SafetyId):
        raise CodecError(f"Safety_ID {safety_id!r} is not one of 0, 1, 2")
    return encode_frame(RO, bytes([int(safety_id)]))


def encode_ra() -> bytes:
    """RA: end remote mode, the unit returns to normal mode without a reset (section 4.1)."""
    return encode_frame(RA)


def encode_rc(index: int = -1, write_data: bytes = b"") -> bytes:
    """RC: the remote watchdog, optionally with a cyclic object (table 3).

    ctp counts every byte after it: the index byte plus the write data (SPEC-NOTES).

    :param index: cyclic object 0..4 (data ID 0x3001..0x3005), or -1 for no data transfer
    :param write_data: the write data the cyclic object's definition asks for
    """
    idx = _byte(index, "cyclic object index")
    if idx != NO_CYCLIC_OBJECT and idx >= len(CYCLIC_OBJECT_IDS):
        raise CodecError(f"cyclic object index {index} is not 0 .. {len(CYCLIC_OBJECT_IDS) - 1} or -1")
    if idx == NO_CYCLIC_OBJECT and write_data:
        raise CodecError("RC without a cyclic object (-1) carries no write data")
    return encode_frame(RC, _u16(1 + len(write_data), "ctp") + bytes([idx]) + bytes(write_data))


KEEP_ALIVE = encode_rc(-1)  # RC 01 00 FF (section 5, table 12)


def encode_rg(data_id: int) -> bytes:
    """RG: read a data ID or a group ID of the data directory (section 4.3).

    :param data_id: 0x0000 .. 0xFFFF, sent little-endian
    """
    return encode_frame(RG, _u16(data_id, "data ID"))


def encode_rt(data_id: int, data: bytes) -> bytes:
    """RT: write remote data (only data IDs 0x3xxx, table 3); ctp = 2 ID bytes + the data.

    :param data_id: 0x3000 .. 0x3FFF
    :param data: the value's bytes (see :mod:`devices.scu.params` for each ID's type)
    """
    if data_id not in REMOTE_DATA_IDS:
        raise CodecError(f"data ID 0x{data_id:04X} cannot be written: RT takes only remote data 0x3xxx (table 3)")
    return encode_frame(RT, _u16(2 + len(data), "ctp") + _u16(data_id, "data ID") + bytes(data))


def encode_re(function: int, para0: int = -1, para1: int = -1) -> bytes:
    """RE: execute a function (table 3, section 4.4). Every RE must be followed by its RS (section 4.6).

    :param function: fnc_ID (:class:`Function`)
    :param para0: for F1..F10 the motion (:class:`Motion`); -1 for the other functions
    :param para1: for F1..F10 the ramp (:class:`Ramp`, -1 = configuration); -1 for the other functions
    """
    fn = _function(function)
    p0, p1 = _byte(para0, "para_ID[0]"), _byte(para1, "para_ID[1]")
    if fn in MOTION_FUNCTIONS:
        if p0 not in tuple(Motion):
            raise CodecError(f"motion {para0!r} is not one of 0 .. 9 (table 9)")
        if p1 not in tuple(Ramp):
            raise CodecError(f"ramp {para1!r} is not 0 (fast), 1 (soft) or -1 (table 9)")
    elif (p0, p1) != (UNUSED, UNUSED):
        raise CodecError(f"{FUNCTIONS[fn].description} takes no parameters (table 8: -1, -1)")
    return encode_frame(RE, bytes([fn, p0, p1]))


def encode_rs(function: int, para0: int = -1, para1: int | None = None) -> bytes:
    """RS: stop a function (table 3, "SG"); fnc_ID and para_ID[0], -1 by default (table 9 lists
    parameters for RE only).

    Table 3's row gives P1 and P2, its text "P2, P3 sind zusätzliche Funktionsparameter": a unit that
    reads the text answers PCE to the two-byte form, and gets the three-byte form (``para1`` -1) from
    the adapter after that (SPEC-NOTES).

    :param function: fnc_ID (:class:`Function`)
    :param para1: None for the two-byte form; -1 for the three-byte form
    """
    params = bytes([_function(function), _byte(para0, "para_ID[0]")])
    if para1 is not None:
        params += bytes([_byte(para1, "para_ID[1]")])
    return encode_frame(RS, params)


def _function(function: int) -> Function:
    try:
        return Function(function)
    except ValueError:
        raise CodecError(f"fnc_ID {function!r} is not in the function directory (table 8)") from None


# -- answers -----------------------------------------------------------------------------------------
# Answers that carry ctp after ACK (table 3: RG and RC return data; "P2 bis Pn ist nur in der Antwort
# enthalten, wenn P1 = ACK"). Error answers and the ACK of RO/RA/RT/RE/RS are X Y code C1 C2.
ANSWERS_WITH_DATA = frozenset({RG, RC})


@dataclass(frozen=True)
class Answer:
    """A decoded answer. ``data`` is empty for error answers and for commands without data."""

    command: bytes
    status: int
    data: bytes = b""
    has_ctp: bool = False
    raw: bytes = b""

    @property
    def ok(self) -> bool:
        return self.status == ACK

    @property
    def status_info(self) -> StatusInfo | None:
        return STATUS_INFO.get(self.status)

    @property
    def status_name(self) -> str:
        info = self.status_info
        return info.name if info else f"0x{self.status:02X}"

    def raise_for_status(self) -> Answer:
        """Return self if ACK, else raise :class:`CommandRefused`."""
        if not self.ok:
            raise CommandRefused(self.command, self.status)
        return self


def encode_answer(command: bytes, status: int = ACK, data: bytes | None = None) -> bytes:
    """An answer as the unit sends it (for the twin and tests).

    :param data: read data for RG/RC (ctp = its length; ``b""`` gives ctp 0); None: no ctp
    """
    if command not in COMMANDS:
        raise CodecError(f"unknown command {command!r}")
    body = bytes(command) + bytes([status])
    if data is not None:
        if status != ACK:
            raise CodecError("error answers carry no data (table 3)")
        body += _u16(len(data), "ctp") + bytes(data)
    return _seal(body)


def _telegram(frame: bytes, shortest: int, what: str) -> bytes:
    """``frame`` as bytes once its length, C1 C2 and command letters are plausible (section 3).

    :raises FrameLengthError: shorter than ``shortest``
    :raises ChecksumError: C1 C2 do not match
    :raises GarbageError: not a command of table 3
    """
    frame = bytes(frame)
    if len(frame) < shortest:
        raise FrameLengthError(f"{what} has at least {shortest} bytes, got {len(frame)}", frame)
    if not _check_crc(frame):
        raise ChecksumError(frame)
    if frame[:2] not in COMMANDS:
        raise GarbageError(frame)
    return frame


def decode_answer(frame: bytes, expected: bytes | None = None) -> Answer:
    """Decode one complete answer frame.

    :param expected: the command that was sent; a different echo raises :class:`UnexpectedAnswer`
    :raises ChecksumError: C1 C2 do not match
    :raises FrameLengthError: ctp and the frame length disagree, or the frame is too short
    """
    frame = _telegram(frame, 5, "an answer")
    command, status = frame[:2], frame[2]
    if expected is not None and command != expected:
        raise UnexpectedAnswer(expected, command, frame)
    if len(frame) == 5:
        return Answer(command, status, b"", False, frame)
    if status != ACK or command not in ANSWERS_WITH_DATA:
        raise FrameLengthError(f"{command.decode()} answer {status:#04x} carries no data, got {len(frame)} bytes",
                               frame)
    ctp = int.from_bytes(frame[3:5], "little")
    if len(frame) != 7 + ctp:
        raise FrameLengthError(f"ctp {ctp} but {len(frame) - 7} data bytes", frame)
    return Answer(command, status, frame[5:-2], True, frame)


# -- requests as the unit reads them (for the twin) ------------------------------------------------------
@dataclass(frozen=True)
class Request:
    """A decoded request; fields not used by ``command`` stay None / empty."""

    command: bytes
    params: bytes
    raw: bytes = b""
    safety_id: int | None = None
    index: int | None = None
    data_id: int | None = None
    data: bytes = b""
    function: int | None = None
    para: tuple[int, ...] = field(default_factory=tuple)


# Parameter bytes per request (table 3); RC and RT carry ctp. RO is read in both forms: the Safety_ID
# alone (section 5 example, what encode_ro sends) and with the para_ID[0] that table 3 lists.
_REQUEST_PARAMS = {RO: (1, 2), RA: (0,), RG: (2,), RE: (3,), RS: (2, 3)}


def decode_request(frame: bytes) -> Request:
    """Decode a request as the unit would (table 3).

    :raises ChecksumError: CSE
    :raises GarbageError: not a command the table knows (ICE)
    :raises ParameterCountError: PCE
    :raises ParameterDataError: PDE
    """
    frame = _telegram(frame, 4, "a request")
    command, p = frame[:2], frame[2:-2]
    if command in (RC, RT):
        if len(p) < 2 or int.from_bytes(p[:2], "little") != len(p) - 2:
            raise ParameterCountError(f"{command.decode()}: ctp does not match {len(p) - 2} following bytes", frame)
        body = p[2:]
        if command == RC:
            if not body:
                raise ParameterCountError("RC: the cyclic object index is missing", frame)
            idx = body[0]
            if idx != NO_CYCLIC_OBJECT and idx >= len(CYCLIC_OBJECT_IDS):
                raise ParameterDataError(f"RC: cyclic object index {idx} is not 0 .. 4 or -1", frame)
            return Request(command, p, frame, index=-1 if idx == NO_CYCLIC_OBJECT else idx, data=body[1:])
        if len(body) < 2:
            raise ParameterCountError("RT: the data ID is missing", frame)
        data_id = int.from_bytes(body[:2], "little")
        if data_id not in REMOTE_DATA_IDS:
            raise ParameterDataError(f"RT: data ID 0x{data_id:04X} is not remote data 0x3xxx", frame)
        return Request(command, p, frame, data_id=data_id, data=body[2:])
    if len(p) not in _REQUEST_PARAMS[command]:
        raise ParameterCountError(f"{command.decode()}: {len(p)} parameter bytes", frame)
    if command == RO:
        if p[0] not in tuple(SafetyId):
            raise ParameterDataError(f"RO: Safety_ID {p[0]} is not 0, 1 or 2", frame)
        return Request(command, p, frame, safety_id=p[0], para=tuple(p[1:]))
    if command == RG:
        return Request(command, p, frame, data_id=int.from_bytes(p, "little"))
    if command in (RE, RS):
        if p[0] not in tuple(Function):
            raise ParameterDataError(f"{command.decode()}: fnc_ID {p[0]} is not in the function directory", frame)
        if command == RE and p[0] in MOTION_FUNCTIONS and (p[1] not in tuple(Motion) or p[2] not in tuple(Ramp)):
            raise ParameterDataError(f"RE: motion {p[1]} / ramp {p[2]} not in table 9", frame)
        return Request(command, p, frame, function=p[0], para=tuple(p[1:]))
    return Request(command, p, frame)


# -- named stream errors (devices/framing.py) ---------------------------------------------------------
# Bad wire data: ``raw`` holds the bytes concerned; the splitter yields these as values. GarbageError: bytes
# that start no telegram (skipped); ChecksumError: C1 C2 do not match (count it and retry the request);
# FrameLengthError: ctp beyond MAX_CTP or not matching; TruncatedFrameError: the inter-byte limit of
# 1000 ms passed before the end (section 3).
FrameError, GarbageError, ChecksumError, FrameLengthError, TruncatedFrameError = framing.error_tree(
    CodecError, __name__, CHECKSUM)


class ParameterCountError(FrameError):
    """A request whose byte count is wrong (the unit answers PCE)."""

    status = Status.PCE


class ParameterDataError(FrameError):
    """A request whose data bytes are not valid (the unit answers PDE)."""

    status = Status.PDE


class UnexpectedAnswer(FrameError):
    """A valid answer to another command than the one sent."""

    def __init__(self, expected: bytes, got: bytes, raw: bytes):
        self.expected, self.got = expected, got
        super().__init__(f"answer to {got.decode('ascii', 'replace')} while waiting for {expected.decode()}", raw)


# -- streaming splitter ----------------------------------------------------------------------------------
ANSWERS = "answers"
REQUESTS = "requests"


class FrameSplitter(framing.Splitter):
    """Cuts a serial byte stream into telegrams (devices/framing.py).

    ``feed(data)`` returns, in stream order, :class:`Answer` (or :class:`Request` with
    ``direction=REQUESTS``) values and :class:`FrameError` values (never raised): garbage before a
    telegram, a bad CRC, an implausible ctp. A telegram cut short stays pending until more bytes
    come or :meth:`expire` is called (after :data:`MAX_INTER_BYTE_S` of silence).

    Lengths: an answer is ``X Y code C1 C2``, or for an ACK of RG/RC ``X Y 06 ctp(2) data(ctp) C1 C2``.
    A bare ACK of RG/RC is also accepted: its C1 C2 read as ctp exceed :data:`MAX_CTP`, so the two
    forms cannot be confused. A request's length follows from its command and, for RC/RT, its ctp.

    :param direction: :data:`ANSWERS` (the adapter's side) or :data:`REQUESTS` (the twin's side)
    """

    garbage_error = GarbageError
    truncated_error = TruncatedFrameError

    def __init__(self, direction: str = ANSWERS):
        if direction not in (ANSWERS, REQUESTS):
            raise ValueError(f"direction must be {ANSWERS!r} or {REQUESTS!r}")
        super().__init__()
        self.direction = direction

    def _starts_telegram(self, raw: bytes) -> bool:
        return raw[:2] in COMMANDS

    def _next(self):
        start = self._sync()
        if start:
            return self._garbage(start)
        if len(self._buf) < 2:
            return None, 0
        return self._one() or (None, 0)

    def _sync(self) -> int:
        """Offset of the first possible telegram start (known command, or a trailing 'R')."""
        buf = self._buf
        for i in range(len(buf)):
            if bytes(buf[i:i + 2]) in COMMANDS or (i == len(buf) - 1 and buf[i] == ord("R")):
                return i
        return len(buf)

    def _lengths(self) -> list[int] | None:
        """Candidate telegram lengths for the buffer head; None if more bytes are needed to tell."""
        buf, command = self._buf, bytes(self._buf[:2])
        if self.direction == ANSWERS:
            if len(buf) < 3:
                return None
            if buf[2] != ACK or command not in ANSWERS_WITH_DATA:
                return [5]
            if len(buf) < 5:
                return None
            ctp = int.from_bytes(buf[3:5], "little")
            if crc16(buf[:3]) == ctp:
                return [5]  # bare ACK: its CRC (> MAX_CTP for RC/RG) sits where ctp would be
            return [7 + ctp] if ctp <= MAX_CTP else []
        if command in (RC, RT):
            if len(buf) < 4:
                return None
            ctp = int.from_bytes(buf[2:4], "little")
            return [6 + ctp] if ctp <= MAX_CTP else []
        return [4 + n for n in _REQUEST_PARAMS[command]]

    def _one(self):
        lengths = self._lengths()
        if lengths is None:
            return None
        buf = bytes(self._buf)
        if not lengths:
            return FrameLengthError(f"implausible ctp in {buf[:5].hex(' ')}", buf[:1]), 1
        for n in lengths:
            if len(buf) < n:
                return None  # a longer form may still complete
            if _check_crc(buf[:n]):
                frame = buf[:n]
                try:
                    if self.direction == ANSWERS:
                        return decode_answer(frame), n
                    return decode_request(frame), n
                except FrameError as exc:  # e.g. a request the unit refuses with PCE/PDE: still one telegram
                    return exc, n
        return ChecksumError(buf[:lengths[0]]), lengths[0]


def wire_time_s(n_bytes: int, baudrate: int = DEFAULT_BAUDRATE) -> float:
    """Time ``n_bytes`` take on the line at 8N1 (10 bit times each)."""
    return n_bytes * BYTE_BITS / baudrate
