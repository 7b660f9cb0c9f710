"""What the SCU adapter publishes and the pure helpers around it (document 002): the names of its live points
and facts, the records they carry (actuator scales, the line, the speed range, the function map, the last error
answer), how an answer is found in the byte stream and how a value is worded. No I/O: pages and the record read
these names and records; the adapter (devices/scu/adapter.py) writes them."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from devices import errors
from devices import values as v
from devices.live import Holder, Point  # noqa: F401 - Holder: the record of P_CONTROL
from devices.message import Message, N_, joined
from devices.scu import codec
from devices.scu import params as p

# -- the facts this adapter publishes besides the unit's data (DeviceState.fact): what the page, the API and
# MQTT read. Records (frozen dataclasses below) where a fact is more than a number or a word.
P_SESSION = "Session"  # closed, opening, open, lost, released; text with the reason
P_SESSION_REASON = "Session reason"  # why the session is as it is ("" when open as asked)
P_WATCH = "Watching"  # WATCH_RG, WATCH_SESSION or None (not known yet); text: what that means
P_CYCLIC = "Cyclic object"  # how live data comes: the cyclic object with every RC, or RG reads (and why)
P_REFUSAL = "Last error answer"  # Refusal: the last command the unit answered with an error code
P_RC_PERIOD = "RC period"  # mean time between acknowledged RCs [ms]
P_RC_GAP = "RC longest gap"  # longest time between two acknowledged RCs of the last 50 [ms]
P_CONTROL = "Control"  # Holder: who drives the unit (a browser session by its tag), None: nobody
P_CONTROLLED_BY = "Controlled by"  # the holder's user name (the tile's line)
P_RUNNING = "Running functions"  # fnc_IDs whose RE was sent and whose RS is not yet acknowledged
P_RS_PENDING = "RS pending"  # fnc_IDs whose RS was not acknowledged: held, sent again every poll
P_ESTOP = "Emergency stop"  # function 19 on
P_SINGLE_IDS = "Single-ID groups"  # group IDs this unit refused: read member by member
P_SKIPPED = "Skipped bytes"  # stray bytes before an answer's header (resynchronisation)
P_RESYNCS = "Resynchronisations"  # times the line's input was flushed after a shifted answer
P_CRC_RETRIES = "CRC retries"  # answers with a bad CRC, sent again
P_SAFETY_ID = "Safety_ID"  # what the unit does on a communication timeout (RO parameter)
P_ACTUATORS = "Actuators"  # configured actuators
P_SCALES = "Actuator scales"  # tuple of ActuatorScale: counts -> mm and the end positions per actuator
P_LINE = "Line"  # SerialLine: port and baud rate
P_SPEED = "Remote speed range"  # SpeedRange: the unit's speed select (table 7)
P_FUNCTIONS = "Function actuators"  # FunctionMap: which actuators F1..F10 drive (plant file, or assumed)
P_SERIAL = "Serial number"  # the plant file's serial (the RS232 interface has no data ID for it)
P_FIRMWARE = "Firmware info"  # 0x0001 (read with the service data and the backup)
P_CONFIGURATION = "Configuration info"  # 0x0002


class CommandError(errors.CommandError):
    """A command that did not take effect; the message says what to do."""


class ControlBusy(CommandError, errors.ControlBusy):
    """Another session holds control."""


@dataclass(frozen=True, slots=True)
class ActuatorScale:
    """Counts -> mm of one actuator: ``counts_per_mm``, or ``stroke_mm`` between the in/out end positions."""

    number: int
    counts_per_mm: float | None = None
    stroke_mm: float | None = None
    in_counts: int | None = None
    out_counts: int | None = None

    def with_ends(self, in_counts: int | None, out_counts: int | None) -> ActuatorScale:
        return ActuatorScale(self.number, self.counts_per_mm, self.stroke_mm,
                             self.in_counts if self.in_counts is not None else in_counts,
                             self.out_counts if self.out_counts is not None else out_counts)

    @property
    def has_mm(self) -> bool:
        if self.counts_per_mm:
            return True
        return bool(self.stroke_mm) and self.in_counts is not None and self.out_counts not in (None, self.in_counts)

    def mm(self, counts: int) -> float | None:
        if self.counts_per_mm:
            return round(counts / self.counts_per_mm, 2)
        if self.has_mm:
            return round((counts - self.in_counts) / (self.out_counts - self.in_counts) * self.stroke_mm, 2)
        return None

    def counts(self, mm: float) -> int:
        if self.counts_per_mm:
            return round(mm * self.counts_per_mm)
        if self.has_mm:
            return round(self.in_counts + mm / self.stroke_mm * (self.out_counts - self.in_counts))
        raise CommandError(f"actuator {self.number} has no conversion to mm: give counts_per_mm or stroke_mm in the plant file")


def actuator_scales(options: dict) -> list[ActuatorScale]:
    actuators = options.get("actuators", 1)
    if isinstance(actuators, int):
        return [ActuatorScale(n) for n in range(1, actuators + 1)]
    return [ActuatorScale(n, a.get("counts_per_mm"), a.get("stroke_mm"), a.get("in_counts"), a.get("out_counts"))
            for n, a in enumerate(actuators, 1)]


def chart_points(scales) -> tuple[str, ...]:
    """The position point of each actuator the history records (and the page charts): in mm where the actuator
    converts counts to mm, else in counts."""
    return tuple(f"A{s.number} position mm" if s.counts_per_mm or s.stroke_mm else f"A{s.number} position"
                 for s in scales)


def point_collector(points: dict[str, Point], now: float, every: float | None):
    """A ``DeviceState.publish`` that puts the point into ``points`` instead (published together afterwards)."""
    make = Point._make

    def publish(name: str, value: Any, unit: str = "", *, raw: Any = None, text: str | None = None,
                time: float | None = None, periodic: bool = True, every: float | None = every) -> None:
        points[name] = make((value, unit, now if time is None else time, raw, text, periodic, every))

    return publish


_STATUS_CODES = frozenset(int(x) for x in codec.Status)


def header_offset(buffer: bytes, expected: bytes | None = None) -> int | None:
    """Where the answer starts: the first ``X Y`` (the command sent, or any command) followed by a status code.
    Bytes before it are a stray byte or the tail of an earlier answer (resynchronisation, issue 32)."""
    for i in range(len(buffer) - 1):
        head = bytes(buffer[i:i + 2])
        if (head == expected if expected is not None else head in codec.COMMANDS) and (
                len(buffer) <= i + 2 or buffer[i + 2] in _STATUS_CODES):
            return i
    return None


def answer_length(buffer: bytes, expected: bytes | None = None) -> int | None:
    """The line's completion rule for an SCU answer (section 3, table 4): total length (with any bytes before
    the answer's header) once it can be told, else None (read more)."""
    start = header_offset(buffer, expected)
    if start is None:
        return None
    frame = bytes(buffer[start:])
    if len(frame) < 3:
        return None
    if frame[2] != codec.ACK or frame[:2] not in codec.ANSWERS_WITH_DATA:
        return start + 5
    if len(frame) < 5:
        return None
    ctp = int.from_bytes(frame[3:5], "little")
    if codec.crc16(frame[:3]) == ctp:
        return start + 5  # a bare ACK: its CRC sits where ctp would be (codec.FrameSplitter)
    return start + (7 + ctp if ctp <= codec.MAX_CTP else 5)


def describe_answer(raw: bytes) -> str:
    start = header_offset(raw) or 0
    try:
        a = codec.decode_answer(raw[start:])
    except codec.FrameError as exc:
        return str(exc)
    return f"{a.status_name}" + (f", {len(a.data)} data bytes" if a.has_ctp else "")


# the error counters of 0x0081.. (table 6: "Fehlerzähler: 2 B: Linearantriebfehler 1 B: Spitzenstrom erreicht 1 B:
# Kurzschluss-Detektionen"), named by their fields
ERROR_COUNTER_WORDS = {"actuator_errors": N_("actuator_errors {n}"), "peak_current": N_("peak_current {n}"),
                       "short_circuit": N_("short_circuit {n}")}


def value_text(data_id: int, value: Any) -> str:
    """A decoded value in words for tables and the data browser (a Message where it has words: the page words it)."""
    if isinstance(value, dict):
        return joined([Message("0x{id:04X}: {text}", id=k, text=value_text(k, x)) if isinstance(k, int)
                       else f"{k}: {x}" for k, x in value.items()], "; ")
    if isinstance(value, v.FlagsValue):
        on = [k for k, x in value.fields.items() if x is True or (not isinstance(x, bool) and x)]
        if data_id in p.DIRECTORY and p.DIRECTORY[data_id].vtype is p.ACTUATOR_ERRORS:
            return joined([Message(ERROR_COUNTER_WORDS[k], n=x) for k, x in value.fields.items()])
        if data_id in p.FLAG_WORDS:  # in the words the page uses (params.flags_text)
            return p.flags_text(data_id, int(value))
        return Message("0x{value:X}: {flags}", value=int(value), flags=", ".join(on) if on else Message(N_("none")))
    if isinstance(value, float):
        return f"{value:g}"
    return str(value)


@dataclass(frozen=True, slots=True)
class Refusal:
    """An error answer of the unit (section 4.2): to which command, its code and what to do."""

    command: str
    name: str
    title: str
    meaning: str
    remedy: str
    time: float


@dataclass(frozen=True, slots=True)
class SerialLine:
    """The RS232 line as configured (8N1; DTR and RTS on)."""

    port: str
    baudrate: int


@dataclass(frozen=True, slots=True)
class SpeedRange:
    """The remote speed the unit takes (table 7): relative 0 .. 100 %, or absolute 0 .. 1000 counts/s."""

    select: str
    high: int
    unit: str


@dataclass(frozen=True, slots=True)
class FunctionMap:
    """Which actuators each function F1..F10 (fnc_ID 0..9) drives; ``assumed``: SCP11, not from the plant file."""

    actuators: tuple[tuple[int, tuple[int, ...]], ...]
    assumed: bool

    def actuators_of(self, function: int) -> list[int]:
        return next((list(acts) for fn, acts in self.actuators if fn == int(function)), [])

    def text(self, function: int) -> str:
        acts = self.actuators_of(function)
        return (", ".join(f"A{a}" for a in acts) if acts else "no actuator") + (
            " (assumed: SCP11, section 5; set functions in the plant file)" if self.assumed else "")


def jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {(f"0x{k:04X}" if isinstance(k, int) else k): jsonable(x) for k, x in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(x) for x in value]
    if isinstance(value, bool) or value is None or isinstance(value, str):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return value
    return str(value)
