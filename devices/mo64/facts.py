"""What the MO 64 adapter publishes beside the telegrams' points, and the words its values are shown in.

The names of the live points and facts (what the page, the API and MQTT read), their records, the errors
the adapter raises, and the conversions of a decoded answer into the backup file's form and into words.
Pure: no I/O (devices/mo64/adapter.py publishes, pages/mo64.py reads).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from devices import errors
from devices import values as v
from devices.live import session_tag
from devices.mo64 import codec
from devices.mo64 import params as model

BUSY_TEXT = "the motor runs, try again when it stands"
NAMES = {  # answer type -> live point name
    0x05: "Device code", 0x06: "Program version", 0x07: "Barrier status", 0x08: "Status mask",
    0x09: "Change monitoring", 0x0A: "Service counter", 0x0B: "Maintenance counter", 0x0C: "Gate state",
    0x0D: "Open time", 0x0E: "Pre-warning before opening", 0x0F: "Pre-warning before closing",
    0x10: "Radio code (dec_bt)", 0x11: "Counting function", 0x12: "Induction-loop modes",
    0x13: "Direction logics", 0x14: "Serial number", 0x15: "MAC address", 0x16: "Operating hours",
    0x18: "Configuration flags", 0x19: "Multi-relay modes", 0x1A: "Maintenance interval",
    0x1B: "Loop periods", 0x1C: "Vehicle counter", 0x1D: "Position", 0x1E: "Password",
}


# -- the facts the adapter publishes beside the telegrams' points (what the page, the API and MQTT read) ------
P_LINE = "Line"  # LineFacts: transport, RS485 bus address and master
P_CONNECTION = "Connection"  # connected, not connected, released, reconnecting
P_POLLING = "Polling"
P_QUERY_FORM = "Query form"  # "document" or "short" once the unit answered one (text in words)
P_LATE = "Late answers"
P_UNEXPECTED = "Unexpected telegrams"
P_UNAVAILABLE = "Not available"  # the queries this unit refused (point names)
P_LEVELS_UNAVAILABLE = "Error memory levels not available"
P_LAST_REPLY = "Last reply"
P_ERROR_LEVELS = "Error memory levels"  # ErrorMemoryLevel records, level 0 the newest
P_MONITORING = "Change monitoring state"  # on / off / unknown, from the change monitoring read
P_LEVELS = "Levels set by this tool"  # HeldLevel records
P_EEPROM = "EEPROM writes"  # EepromWrites record
P_VERIFIED = "Verified selectors"  # assumed selectors an engineer confirmed for this unit
# kept empty: a confirmation that the area is clear belongs to the one motion it was given for (issue 42 item 6),
# so no session is ever shown as having confirmed (a page that read it skipped the question for later motions)
P_CONFIRMED = "Motion confirmed"
POLLING_SLOWER = "gate state and position slower (changes are reported); status every cycle"
QUERY_FORM_WORDS = {None: "not known yet", "document": "02 Auswahl index (the document's, page 33)",
                    "short": "02 Auswahl (the document's form refused)"}


@dataclass(frozen=True, slots=True)
class ErrorMemoryLevel:
    """One level of the error memory (chapter 5.1.23): error flags and the operating hours they were set at."""

    level: int
    flags: int
    timestamp_h: int


@dataclass(frozen=True, slots=True)
class HeldLevel:
    """A level this tool activated and the barrier keeps until it is deactivated; ``dead_man``: released when
    the session that set it goes away (close and reverse, :data:`HELD_LEVELS`)."""

    command: str
    dead_man: bool


@dataclass(frozen=True, slots=True)
class LineFacts:
    """How the tool reaches the barrier: ``logited-tcp`` or ``logited-rs485`` with bus address and master."""

    transport: str
    rs485: bool
    address: int | None
    master: int


@dataclass(frozen=True, slots=True)
class EepromWrites:
    """Setting writes that reached the EEPROM (chapter 4: each wears it), in all and per session tag."""

    total: int
    sessions: tuple[tuple[str, int], ...] = ()

    def of(self, session: str) -> int:
        """The writes of ``session`` (a page's own id; matched by its tag)."""
        return dict(self.sessions).get(session_tag(session), 0)


class CommandError(errors.CommandError):
    """A command or write that did not take effect; the message says why."""


class NeedsConfirmation(CommandError):
    """A motion needs its own confirmation that the area is clear (every one, every time)."""


def to_json(value: Any) -> Any:
    """A decoded setting value in the backup file's form (numbers and lists of numbers)."""
    if isinstance(value, Mapping):
        if set(value) == {"mask", "more"}:
            return to_json(value["mask"])
        return [to_json(x) for x in value.values()]
    if isinstance(value, (list, tuple)):
        return [to_json(x) for x in value]
    if isinstance(value, (bytes, bytearray)):
        return bytes(value).hex(" ")
    if isinstance(value, bool) or value is None:
        return value
    if isinstance(value, int):
        return int(value)
    return value


def from_json(setting: codec.Setting, raw: Any) -> Any:
    """The file's form of a setting back to what :func:`codec.encode_setting` takes."""
    if isinstance(setting.vtype, v.Struct):
        names = [name for name, _ in setting.vtype.members]
        if not isinstance(raw, list) or len(raw) != len(names):
            raise CommandError(f"{setting.name}: {raw!r} is not a list of {len(names)} numbers")
        return dict(zip(names, raw))
    if isinstance(setting.vtype, v.Array):
        return list(raw) if isinstance(raw, list) else raw
    return raw


def value_text(answer_type: int, value: Any) -> str:
    """A decoded answer in words for tables."""
    if answer_type in (0x0D, 0x0E, 0x0F):
        return f"{codec.time_s(int(value)):g} s ({int(value)} x 10 ms)"
    if answer_type == 0x15:
        return codec.format_mac(value)
    if answer_type == 0x10:  # chapter 5.1.16: bit 31 says whether a radio code is stored, A9..A1 in bits 17..0
        fields = value.fields
        if not fields.get("code stored"):
            return f"0x{int(value):08X}: no radio code stored"
        return f"0x{int(value):08X}: radio code stored; switches " + " ".join(
            f"A{n}={int(fields[f'A{n}'])}" for n in range(1, 10))
    if answer_type == 0x05:
        return f"{int(value)}" + (f" ({value.name})" if isinstance(value, v.EnumValue) and value.name else "")
    if answer_type == 0x1D:
        return "unknown" if int(value) == codec.POSITION_UNKNOWN else f"{int(value)} %"
    if answer_type == 0x19:
        return ", ".join(f"multi{n}: {codec.MULTI_MODE_NAMES.get(m, f'mode {m}')}" for n, m in enumerate(value, 1))
    if answer_type == 0x12:
        return ", ".join(f"loop {c}: 0x{int(m):04X}" for c, m in zip("ABC", value))
    if answer_type == 0x13:
        return "; ".join(f"logic {n}: 0x{int(x):08X} " + ", ".join(f"{k} {f}" for k, f in x.fields.items())
                         for n, x in enumerate(value, 1))
    if answer_type == 0x18:  # the words, and the safety flags by the parameter model's names (devices/mo64/params.py)
        number = model.value_int(0x18, value)
        return (", ".join(f"{k} 0x{int(x):04X}" for k, x in value.items()) + " ("
                + ", ".join(f"{p.name}: {p.display(model.extract(p, number))}" for p in model.SAFETY) + ")")
    if answer_type in (0x07, 0x08):
        bits = value["status"] if "status" in value else value["mask"]
        on = bits.active
        return f"0x{int(bits):010X}: " + (", ".join(on) if on else "none") + (
            f" (+ raw {value['more'].hex(' ')})" if value.get("more") else "")
    if answer_type == 0x09:
        on = value.active
        return f"0x{int(value):04X}: " + (", ".join(on) if on else "off")
    if isinstance(value, (bytes, bytearray)):
        return f"raw {bytes(value).hex(' ')}" if value else "raw (empty)"
    return str(to_json(value))
