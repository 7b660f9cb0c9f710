"""Thomson Electrak HD with SY2 CAN option: control, status and service telegrams.

Pure: no I/O. All telegrams use standard 11-bit IDs at 500 kbit/s by default
(document "Das Netzwerk im Überblick"). Multi-byte values are little-endian.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

from devices import errors
from devices.message import Message, N_, joined

CONTROL_ID = 0x06  # sent by the master every 100 ms
STATUS_ID = 0x07  # sent by every actuator every 100 ms
SERVICE_REQUEST_ID = 0x0A
SERVICE_RESPONSE_ID = 0x0B
INTERNAL_IDS = range(0x600, 0x700)  # actuator-to-actuator traffic, to be ignored
CONTROL_PERIOD_S = 0.1
STATUS_PERIOD_S = 0.1
DEFAULT_TIMEOUT_MS = 250  # message-timeout flag after 250 ms without a control telegram
DEFAULT_BITRATE = 500_000
# "CAN-Steuerung": another master (a PLC, or an actuator whose control line is active, "Das Netzwerk
# im Überblick") repeats 0x06 every 100 ms; three periods without one mean there is none.
LISTEN_S = 0.3
# "Bewegungs-Flags" bit 2: Saturated must not stay set when driven over CAN; "stays" = 10 status periods.
SATURATED_WARN_S = 1.0
# "Fehler-Flags" bits 2 and 3: a motion already running goes on for 10 s after a voltage or temperature fault.
ENV_FAULT_RUN_ON_S = 10.0


class CodecError(errors.CodecError):
    """A telegram that cannot be encoded or decoded."""


def _u16(value: float, scale: float, name: str) -> int:
    raw = round(value / scale)
    if not 0 <= raw <= 0xFFFF:
        raise CodecError(f"{name} {value} does not fit the telegram (0 .. {0xFFFF * scale:g})")
    return raw


# -- control 0x06 ---------------------------------------------------------------------------

ENABLE = 0x01
OVERRIDE = 0x02


@dataclass(frozen=True)
class ControlFrame:
    """Control telegram: target position (0.1 mm), current limit (0.1 A, 0 = calibrated), speed (0.1 mm/s)."""

    position_mm: float
    current_a: float
    speed_mm_s: float
    enable: bool = False
    override: bool = False

    def encode(self) -> bytes:
        bits = (ENABLE if self.enable else 0) | (OVERRIDE if self.override else 0)
        return (
            _u16(self.position_mm, 0.1, "position").to_bytes(2, "little")
            + _u16(self.current_a, 0.1, "current limit").to_bytes(2, "little")
            + _u16(self.speed_mm_s, 0.1, "speed").to_bytes(2, "little")
            + bytes([0, bits])
        )

    @classmethod
    def decode(cls, data: bytes) -> ControlFrame:
        if len(data) != 8:
            raise CodecError(f"control telegram needs 8 bytes, got {len(data)}")
        pos, cur, spd = (int.from_bytes(data[i:i + 2], "little") for i in (0, 2, 4))
        return cls(round(pos * 0.1, 1), round(cur * 0.1, 1), round(spd * 0.1, 1), bool(data[7] & ENABLE), bool(data[7] & OVERRIDE))


# -- status 0x07 -----------------------------------------------------------------------------

MOTION_FLAGS = {
    0: ("Extending", "moving out"),
    1: ("Retracting", "moving in"),
    2: ("Saturated", "moving at the highest speed the supply voltage and load allow; when driven over CAN make sure "
        "this does not stay set on any actuator, or the network cannot keep synchronised"),
    3: ("Waiting", "standing still, waiting for the other actuators to catch up"),
}

# bit -> (name, explanation, what clears it)
ERROR_FLAGS = {
    0: ("Parameter", "a value of the control telegram is outside the range allowed for the model; no motion while set",
        "send values within the model's ranges"),
    1: ("Current overload", "the last motion exceeded the calibrated current limit or the limit in the control telegram "
        "(longer than 40 ms, not during start-up); no motion while set",
        "move in the opposite direction, or drop the enable bit"),
    2: ("Voltage", "the supply voltage is outside the operating range; a running motion goes on for 10 s, no new motion",
        "bring the supply voltage of every actuator back into range"),
    3: ("Temperature", "the temperature is outside the operating range; a running motion goes on for 10 s, no new motion",
        "let the actuators return to the operating temperature"),
    4: ("Backdrive", "the rod moved without a command (high static load or strong vibration)",
        "check the load. Assumption (the document does not say how it clears): with the next commanded motion"),
    5: ("Message timeout", "no control telegram within the timeout (250 ms by default); no actuator moves while set",
        "send control telegrams every 100 ms"),
    6: ("Severe fault", "no motion detected while driving the motor, or the position changed in the wrong direction; "
        "no motion while set", "move in the opposite direction, or drop the enable bit"),
    7: ("Too few devices", "an actuator found fewer networked devices than expected; no motion while set",
        "reconnect the missing actuator, or set the override/reset bit (or line) to reset the expected count"),
}


@dataclass(frozen=True)
class StatusFrame:
    """Status telegram of one actuator (which one cannot be told: SPEC-NOTES)."""

    position_mm: float
    current_a: float
    speed_mm_s: float
    motion: int
    errors: int

    def encode(self) -> bytes:
        return (
            _u16(self.position_mm, 0.1, "position").to_bytes(2, "little")
            + _u16(self.current_a, 0.1, "current").to_bytes(2, "little")
            + _u16(self.speed_mm_s, 0.1, "speed").to_bytes(2, "little")
            + bytes([self.motion & 0xFF, self.errors & 0xFF])
        )

    @classmethod
    def decode(cls, data: bytes) -> StatusFrame:
        if len(data) != 8:
            raise CodecError(f"status telegram needs 8 bytes, got {len(data)}")
        pos, cur, spd = (int.from_bytes(data[i:i + 2], "little") for i in (0, 2, 4))
        return cls(round(pos * 0.1, 1), round(cur * 0.1, 1), round(spd * 0.1, 1), data[6], data[7])

    @property
    def motion_names(self) -> list[str]:
        return [name for bit, (name, _) in MOTION_FLAGS.items() if self.motion >> bit & 1]

    @property
    def error_names(self) -> list[str]:
        return [name for bit, (name, _, _) in ERROR_FLAGS.items() if self.errors >> bit & 1]


# -- service 0x0A / 0x0B -----------------------------------------------------------------------


class ServiceType(IntEnum):
    READ_REQUEST = 0x00
    WRITE_REQUEST = 0x01
    READ_RESPONSE = 0x10
    WRITE_CONFIRMATION = 0x11
    ERROR_RESPONSE = 0x13


SERVICE_ERRORS = {
    0xFF01: "OBJECT_NOT_FOUND/INCORRECT_PASSWORD",
    0xFF02: "WRONG_SIZE",
    0xFF04: "INCORRECT_PERMISSION",
    0xFF08: "WRONG_ID",
}
ERROR_NOT_FOUND, ERROR_WRONG_SIZE, ERROR_PERMISSION, ERROR_WRONG_ID = 0xFF01, 0xFF02, 0xFF04, 0xFF08

PASSWORD_SPECIFIER = 0xFF
SAVE_SPECIFIER = 0xF0


@dataclass(frozen=True)
class ServiceMessage:
    """``[type, specifier, length, 0, payload uint32 LE]`` (document "Service-Telegramm")."""

    type: int
    specifier: int
    length: int
    payload: int = 0

    def encode(self) -> bytes:
        if not 0 <= self.payload <= 0xFFFFFFFF:
            raise CodecError(f"payload {self.payload} does not fit 4 bytes")
        return bytes([self.type, self.specifier, self.length, 0]) + self.payload.to_bytes(4, "little")

    @classmethod
    def decode(cls, data: bytes) -> ServiceMessage:
        if len(data) != 8:
            raise CodecError(f"service telegram needs 8 bytes, got {len(data)}")
        return cls(data[0], data[1], data[2], int.from_bytes(data[4:8], "little"))

    @property
    def error_code(self) -> int | None:
        return self.payload & 0xFFFF if self.type == ServiceType.ERROR_RESPONSE else None

    @property
    def error_name(self) -> str:
        code = self.error_code
        return "" if code is None else SERVICE_ERRORS.get(code, f"unknown error 0x{code:04X}")

    @property
    def value(self) -> int:
        """The payload cut to the parameter's length."""
        return self.payload & ((1 << (8 * min(max(self.length, 1), 4))) - 1)


def read_request(specifier: int, length: int) -> ServiceMessage:
    return ServiceMessage(ServiceType.READ_REQUEST, specifier, length, 0)


def write_request(specifier: int, length: int, value: int) -> ServiceMessage:
    if not 0 <= value < 1 << (8 * length):
        raise CodecError(f"value {value} does not fit {length} byte(s)")
    return ServiceMessage(ServiceType.WRITE_REQUEST, specifier, length, value)


def password_request(password: int) -> ServiceMessage:
    return write_request(PASSWORD_SPECIFIER, 4, password)


# "Parameter speichern": the table gives length 4, the example "02 F0 01 ..." length 1 (and type
# 0x02, none defined: SPEC-NOTES sends 0x01). Send the table's form; on WRONG_SIZE retry once with
# the example's, and report which one the network accepted.
SAVE_LENGTHS = (4, 1)
SAVE_FORMS = {4: "4-byte form (parameter table)", 1: "1-byte form (document example)"}


def save_request(length: int = SAVE_LENGTHS[0]) -> ServiceMessage:
    """Save all changed parameters ("any value" written to 0xF0)."""
    return ServiceMessage(ServiceType.WRITE_REQUEST, SAVE_SPECIFIER, length, 0)


ANSWER_TYPE = {ServiceType.READ_REQUEST: ServiceType.READ_RESPONSE, ServiceType.WRITE_REQUEST: ServiceType.WRITE_CONFIRMATION}


def belongs_to(request: ServiceMessage, answer: ServiceMessage) -> bool:
    """Is ``answer`` an actuator's answer to ``request``? An error answer is taken whatever its
    specifier: the document does not say that it repeats the request's."""
    return answer.type == ServiceType.ERROR_RESPONSE or (answer.specifier == request.specifier and answer.type == ANSWER_TYPE.get(request.type))


def describe_answer(answer: ServiceMessage) -> Message:
    """One actuator's answer to a service telegram in words, a Message its reader words."""
    if answer.type == ServiceType.ERROR_RESPONSE:
        return Message(N_("error {name}"), name=answer.error_name)
    if answer.type == ServiceType.WRITE_CONFIRMATION:
        return Message(N_("confirmed"))
    if answer.type == ServiceType.READ_RESPONSE:
        return Message(N_("value {value}"), value=answer.value)
    return Message(N_("type 0x{type:02X}"), type=answer.type)


def numbered(n: int, text: object) -> Message:
    """The ``n``-th answer of a service exchange (``answer 2: confirmed``)."""
    return Message(N_("answer {n}: {text}"), n=n, text=text)


def answer_problems(request: ServiceMessage, answers: list[ServiceMessage], expected: int) -> list[Message]:
    """What is wrong with the answers of a network of ``expected`` actuators, in words (Messages); empty when
    every actuator answered as asked and (reads) every one reports the same value.

    Every networked device answers a service request ("Gerätekonfiguration"), and the answers
    cannot be told apart: they are numbered in the order they came.
    """
    problems = []
    wanted = ANSWER_TYPE.get(request.type)
    for n, answer in enumerate(answers, 1):
        if answer.type != wanted:
            problems.append(numbered(n, describe_answer(answer)))
    if len(answers) < expected:
        problems.append(Message(N_("{missing} of {expected} actuators did not answer"),
                                missing=expected - len(answers), expected=expected))
    elif len(answers) > expected:
        problems.append(Message(N_("{n} answers, but {expected} actuators are configured"), n=len(answers),
                                expected=expected))
    values = [a.value for a in answers if a.type == ServiceType.READ_RESPONSE]
    if len(set(values)) > 1:
        problems.append(Message(N_("the actuators disagree: {answers}"),
                                answers=joined([numbered(n, v) for n, v in enumerate(values, 1)])))
    return problems


# -- model ranges (document "Strombegrenzung", "Sollgeschwindigkeit") -------------------------

CURRENT_LIMIT_A = {"MD12": 25.0, "HD24": 12.5, "HD48": 6.5}
SPEED_RANGE_MM_S = {
    "B017": (11.0, 58.0),
    "B026": (6.0, 32.0),
    "B045": (4.0, 19.0),
    "B068": (3.0, 14.0),
    "B100": (2.0, 9.0),
    "B160": (1.0, 5.0),
}
BITRATES = {0: 1_000_000, 2: 500_000, 3: 250_000, 4: 125_000}  # "Wert / Baudrate" table; 1 is not defined


def bitrate_code(bitrate: int) -> int:
    """The bit-rate parameter's value for a bus bit rate in bit/s."""
    for code, rate in BITRATES.items():
        if rate == bitrate:
            return code
    raise CodecError(f"{bitrate} bit/s is not one of the actuators' bit rates ({', '.join(f'{r:,}' for r in BITRATES.values())})")


@dataclass(frozen=True)
class Actuator:
    model: str
    gearing: str
    stroke_mm: float


@dataclass(frozen=True)
class Limits:
    """What every actuator of a network accepts (the strictest of each)."""

    stroke_mm: float
    current_a: float
    speed_min: float
    speed_max: float

    @classmethod
    def of(cls, actuators: list[Actuator]) -> Limits:
        if not actuators:
            raise CodecError("a network needs at least one actuator")
        lows, highs = zip(*(SPEED_RANGE_MM_S[a.gearing] for a in actuators))
        if max(lows) > min(highs):  # one control telegram, one speed for all (section "Control-Telegramm")
            windows = ", ".join(f"{g} {SPEED_RANGE_MM_S[g][0]:g}-{SPEED_RANGE_MM_S[g][1]:g} mm/s"
                                for g in dict.fromkeys(a.gearing for a in actuators))
            raise CodecError(f"the gearings of this network share no speed ({windows}): one control telegram "
                             "drives them all at one speed")
        return cls(min(a.stroke_mm for a in actuators), min(CURRENT_LIMIT_A[a.model] for a in actuators), max(lows), min(highs))

    @classmethod
    def of_one(cls, actuator: Actuator) -> Limits:
        """The ranges of one model, gearing and stroke (each device checks its own: "Parameterfehler")."""
        return cls.of([actuator])

    def check(self, position_mm: float, current_a: float, speed_mm_s: float) -> list[str]:
        """Problems with a control telegram's values, in words; empty when it is fine."""
        problems = []
        if not 0 <= position_mm <= self.stroke_mm:
            problems.append(f"target position {position_mm:g} mm is outside 0 .. {self.stroke_mm:g} mm (stroke)")
        if not 0 <= current_a <= self.current_a:
            problems.append(f"current limit {current_a:g} A is outside 0 .. {self.current_a:g} A (0 = calibrated limit)")
        if not self.speed_min <= speed_mm_s <= self.speed_max:
            problems.append(f"speed {speed_mm_s:g} mm/s is outside {self.speed_min:g} .. {self.speed_max:g} mm/s for the gearing")
        return problems


# the bus monitor's words (Messages: the page words them as the Electrak page does, Freigabe, Übersteuerung)
_ENABLE, _OVERRIDE, _NO_ENABLE = Message(N_("enable")), Message(N_("override")), Message(N_("no enable"))
_IDLE = Message(N_("idle"))
_INTERNAL = Message(N_("Electrak internal (actuator to actuator)"))


def describe_frame(arbitration_id: int, is_extended: bool, data: bytes, known_ids: set) -> str | None:
    """Bus monitor text for Electrak telegrams (on a bus where an Electrak network listens for 0x07)."""
    if is_extended or (False, STATUS_ID) not in known_ids:
        return None
    try:
        if arbitration_id == CONTROL_ID:
            c = ControlFrame.decode(data)
            bits = [word for word, on in ((_ENABLE, c.enable), (_OVERRIDE, c.override)) if on]
            return Message(N_("Electrak control: target {position:.1f} mm, limit {current:.1f} A, speed {speed:.1f} mm/s, "
                              "{bits}"), position=float(c.position_mm), current=float(c.current_a),
                           speed=float(c.speed_mm_s), bits=joined(bits) if bits else _NO_ENABLE)
        if arbitration_id == STATUS_ID:
            s = StatusFrame.decode(data)
            names = s.motion_names + s.error_names  # the flags by the names the Electrak page gives them
            return Message(N_("Electrak status: {position:.1f} mm, {current:.1f} A, {speed:.1f} mm/s, {flags}"),
                           position=float(s.position_mm), current=float(s.current_a), speed=float(s.speed_mm_s),
                           flags=joined([Message(n) for n in names]) if names else _IDLE)
        if arbitration_id in (SERVICE_REQUEST_ID, SERVICE_RESPONSE_ID):
            m = ServiceMessage.decode(data)
            kind = ServiceType(m.type).name if m.type in set(ServiceType) else f"type 0x{m.type:02X}"
            fields = {"kind": kind, "specifier": m.specifier, "length": m.length}
            if m.error_code is not None:
                return Message("Electrak service {kind} 0x{specifier:02X} len {length} {error}", error=m.error_name, **fields)
            if m.specifier == PASSWORD_SPECIFIER:  # a key, not a value: named, never decoded into words
                return Message(N_("Electrak service {kind} 0x{specifier:02X} len {length} (password: not shown)"), **fields)
            return Message(N_("Electrak service {kind} 0x{specifier:02X} len {length} value {value}"), value=m.value, **fields)
        if arbitration_id in INTERNAL_IDS:
            return _INTERNAL
    except CodecError as exc:
        return Message(N_("Electrak, malformed: {error}"), error=str(exc))
    return None


def discovered(arbitration_id: int, is_extended: bool, data: bytes) -> dict | None:
    return None  # an Electrak network is described in the plant file, not adopted
