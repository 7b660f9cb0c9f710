"""The generic parameter model every device's ``params.py`` is written in.

Pure: no I/O. A :class:`Param` describes one register (or a group of 16-bit
words forming one value) and knows how to decode, display, validate and encode
it. Register tables, input validation, the JSON API, backup and restore are all
driven by these objects, so a new device only has to describe its registers.

A write is checked here once: :meth:`Param.accept` turns an entry into the raw value to store and names the
confirmation it needs (an :class:`Accepted`), and that result is what the command gate's arguments carry and what
the send policy and the adapter take, so nothing on the way checks the entry again.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum

from devices import values
from devices.errors import DeviceError
from devices.message import Message, N_


class Access(str, Enum):
    """Access classes as printed in the device documents."""

    R = "R"  # read only (input registers, live values)
    RW = "RW"  # read / write by the commissioning engineer
    RO = "RO"  # read only (protected by the firmware)
    MFR = "MFR"  # manufacturer only: shown, never written


class ParamError(DeviceError, ValueError):
    """An entry that cannot be written to a parameter (range, type, access); its message is a
    :class:`~devices.message.Message`, worded in the reader's language where it is shown."""


def outside(name: str, value: float, low: float, high: float, unit: str = "") -> Message:
    """The refusal of a value out of range: ``"Timeout: 70000 is outside 0 .. 65535 ms"``."""
    if unit:
        return Message(N_("{name}: {value} is outside {low} .. {high} {unit}"), name=name, value=value, low=low,
                       high=high, unit=unit)
    return Message(N_("{name}: {value} is outside {low} .. {high}"), name=name, value=value, low=low, high=high)


def _worded(item) -> None:
    """A description marked ``N_("...")`` where it is declared becomes a :class:`Message`, so a page words it in its
    language (``said``); one without an entry in the catalogs reads as written."""
    if item.description and not isinstance(item.description, Message):
        object.__setattr__(item, "description", Message(item.description))


@dataclass(frozen=True)
class Field:
    """A named group of bits inside a register (a status bit is a 1-bit field)."""

    name: str
    shift: int
    width: int = 1
    description: str = ""

    def __post_init__(self) -> None:
        _worded(self)

    def extract(self, raw: int) -> int:
        return (raw >> self.shift) & ((1 << self.width) - 1)


@dataclass(frozen=True)
class Param:
    """One parameter of a device.

    :param space: register space, e.g. ``"input"`` or ``"holding"``
    :param address: first register address
    :param words: number of 16-bit words (2 = 32-bit value, high word first)
    :param signed: two's complement
    :param scale: decoded value = raw * scale
    :param enum: raw value -> name
    :param fields: named bit fields (status words, packed bytes)
    :param minimum: smallest decoded value accepted on write
    :param maximum: largest decoded value accepted on write
    :param confirm: text shown before writing the value(s) in ``confirm_values``
    :param never_write: the GUI never offers to write it, whatever its access class
    :param device_updates: the device changes the value itself (a measured maximum, a counter): a
        difference from the approved set is not drift
    """

    name: str
    space: str
    address: int
    access: Access = Access.R
    unit: str = ""
    description: str = ""
    words: int = 1
    signed: bool = False
    scale: float = 1
    enum: Mapping[int, str] | None = None
    fields: tuple[Field, ...] = ()
    minimum: float | None = None
    maximum: float | None = None
    default: int | None = None
    confirm: str = ""
    confirm_values: tuple[int, ...] = ()
    never_write: bool = False
    device_updates: bool = False
    label: str = ""  # display name where the document's name is not unique
    extra: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        _worded(self)

    # -- identity -------------------------------------------------------------------
    @property
    def key(self) -> str:
        """Unique key of the parameter within its device."""
        return f"{self.space}:{self.address}"

    @property
    def addresses(self) -> range:
        return range(self.address, self.address + self.words)

    @property
    def writable(self) -> bool:
        """True only for parameters a commissioning engineer may write."""
        return self.access is Access.RW and not self.never_write and self.words == 1

    @property
    def setting(self) -> bool:
        """Whether the value is a setting the engineer chooses, not one the device measures or counts itself
        (a measured maximum such as HD-Lock's MaximumTimeLock, "longest time measured so far"). Only settings are
        restored, applied in a batch, preselected when a device is replaced and compared as drift; a measured
        value stays writable one at a time where the device allows it (to reset it), never copied from a set."""
        return self.writable and not self.device_updates

    @property
    def bits(self) -> int:
        return 16 * self.words

    @property
    def value_type(self) -> values.ValueType:
        """This parameter as a typed value of :mod:`devices.values` (decodes the same numbers).

        The bytes are those of a Modbus register: ``words`` 16-bit words, high word first,
        each big-endian (see :func:`devices.values.words_to_bytes`). Bit fields give
        :class:`~devices.values.Bits`, an enum :class:`~devices.values.Enum`, a scale
        :class:`~devices.values.Scaled`.
        """
        if self.fields:
            bits = tuple(values.BitField(f.name, f.shift, f.width, description=f.description) for f in self.fields)
            return values.Bits(values.register_type(self.words, signed=False), bits)
        base = values.register_type(self.words, self.signed)
        if self.scale != 1:
            return values.Scaled(base, self.scale, self.unit)
        if self.enum is not None:
            return values.Enum(base, self.enum)
        return base

    # -- conversions -----------------------------------------------------------------
    def combine(self, words: list[int]) -> int:
        """Join register words (high word first) into one unsigned raw value."""
        raw = 0
        for word in words:
            raw = (raw << 16) | (word & 0xFFFF)
        return raw

    def split(self, raw: int) -> list[int]:
        return [(raw >> (16 * (self.words - 1 - i))) & 0xFFFF for i in range(self.words)]

    def decode(self, raw: int) -> int | float:
        """Raw unsigned register value -> engineering value (signed, scaled)."""
        value = raw
        if self.signed and raw & (1 << (self.bits - 1)):
            value = raw - (1 << self.bits)
        if self.scale != 1:
            return round(value * self.scale, 6)
        return value

    def encode(self, value: int | float) -> int:
        """Engineering value -> raw unsigned register value (two's complement)."""
        raw = round(value / self.scale) if self.scale != 1 else int(value)
        if raw < 0:
            raw += 1 << self.bits
        return raw & ((1 << self.bits) - 1)

    def enum_name(self, raw: int) -> str | None:
        if self.enum is None:
            return None
        value = self.decode(raw)
        return self.enum.get(int(value))

    def display(self, raw: int) -> str:
        """Human text of a raw value: enum name, signed value with unit, or bits."""
        value = self.decode(raw)
        if self.enum is not None:
            name = self.enum.get(int(value))
            return f"{name} ({value})" if name else f"{value} (undefined)"
        if self.fields:
            if all(f.width == 1 for f in self.fields):
                active = [f.name for f in self.fields if f.extract(raw)]
                return ", ".join(active) if active else "-"
            return ", ".join(f"{f.name}={f.extract(raw)}" for f in self.fields)
        return f"{value} {self.unit}".strip()

    def field_values(self, raw: int) -> dict[str, int]:
        return {f.name: f.extract(raw) for f in self.fields}

    def validate(self, value: int | float | str) -> int:
        """Check an entry for writing and return the raw register value.

        Accepts the decoded number, or an enum name. Raises :class:`ParamError`
        with a message that says what is allowed.
        """
        if not self.writable:
            raise ParamError(Message(N_("{name} is {access} and cannot be written"), name=self.name,
                                     access=self.access.value))
        if isinstance(value, str):
            text = value.strip()
            if self.enum is not None:
                for number, name in self.enum.items():
                    if name.lower() == text.lower():
                        value = number
                        break
            if isinstance(value, str):
                try:
                    value = float(text) if "." in text else int(text, 0)
                except ValueError:
                    raise ParamError(Message(N_("{name}: '{text}' is not a number"), name=self.name, text=text)) from None
        if isinstance(value, float) and self.scale == 1:
            if not value.is_integer():
                raise ParamError(Message(N_("{name}: {value} is not a whole number"), name=self.name, value=value))
            value = int(value)
        low, high = self.limits()
        if not low <= value <= high:
            raise ParamError(outside(self.name, value, low, high, self.unit))
        if self.enum is not None and int(value) not in self.enum:
            allowed = ", ".join(f"{k} {v}" for k, v in self.enum.items())
            raise ParamError(Message(N_("{name}: {value} is not one of: {allowed}"), name=self.name, value=value,
                                     allowed=allowed))
        return self.encode(value)

    def accept(self, value: int | float | str) -> Accepted:
        """The one check of an entry for writing: :meth:`validate` (type, access, range, value table) and the
        confirmation the value needs. :raises ParamError: it cannot be written"""
        raw = self.validate(value)
        return Accepted(self, raw, self.needs_confirmation(raw))

    def prepare_write(self, value: int | float | str, *, confirmed: bool = False) -> int:
        """:meth:`accept`, then refuse a value that needs a confirmation nobody gave; the raw value to write."""
        return self.accept(value).cleared(confirmed)

    def limits(self) -> tuple[float, float]:
        """Range accepted on write: the declared range, else the register's range."""
        if self.signed:
            low, high = -(1 << (self.bits - 1)), (1 << (self.bits - 1)) - 1
        else:
            low, high = 0, (1 << self.bits) - 1
        low, high = low * self.scale, high * self.scale
        if self.minimum is not None:
            low = self.minimum
        if self.maximum is not None:
            high = self.maximum
        return low, high

    def needs_confirmation(self, raw: int) -> str:
        """The warning to show before writing ``raw``, or ``""``."""
        if self.confirm and (not self.confirm_values or raw in self.confirm_values):
            return self.confirm
        return ""


@dataclass(frozen=True)
class Accepted:
    """An entry the parameter model accepted for writing (:meth:`Param.accept`).

    :param param: the parameter written
    :param raw: the raw value to store (what the device keeps)
    :param risk: the confirmation the value needs before it is sent ("" for none)
    """

    param: Param
    raw: int
    risk: str = ""

    @property
    def value(self) -> int | float:
        """The engineering value (signed, scaled)."""
        return self.param.decode(self.raw)

    @property
    def text(self) -> str:
        """The value as an engineer reads it (:meth:`Param.display`)."""
        return self.param.display(self.raw)

    def cleared(self, confirmed: bool) -> int:
        """The raw value to send. :raises ParamError: it needs a confirmation and ``confirmed`` is False"""
        if self.risk and not confirmed:
            raise ParamError(Message(N_("needs confirmation: {risk}"), risk=self.risk))
        return self.raw


class ParamMap:
    """The parameter map of one device type, indexed by key and by name."""

    def __init__(self, params: list[Param]):
        self.params = list(params)
        self.by_key = {p.key: p for p in self.params}
        self.by_name: dict[str, Param] = {}
        for p in self.params:
            self.by_name.setdefault(p.label or p.name, p)
        if len(self.by_key) != len(self.params):
            raise ValueError("duplicate parameter address")

    def __iter__(self):
        return iter(self.params)

    def space(self, space: str) -> list[Param]:
        return [p for p in self.params if p.space == space]

    def get(self, space: str, address: int) -> Param | None:
        return self.by_key.get(f"{space}:{address}")

    def blocks(self, space: str, max_count: int = 64) -> list[tuple[int, int]]:
        """Contiguous (start, count) read blocks that cover every register of a space."""
        addresses = sorted({a for p in self.space(space) for a in p.addresses})
        blocks: list[tuple[int, int]] = []
        for a in addresses:
            if blocks and blocks[-1][0] + blocks[-1][1] == a and blocks[-1][1] < max_count:
                blocks[-1] = (blocks[-1][0], blocks[-1][1] + 1)
            else:
                blocks.append((a, 1))
        return blocks


def backup_entry(param: Param, raw: int) -> dict:
    """One parameter as a backup file lists it."""
    return {
        "key": param.key,
        "name": param.label or param.name,
        "space": param.space,
        "address": param.address,
        "raw": raw,
        "value": param.decode(raw),
        "text": param.display(raw),
        "unit": param.unit,
        "writable": param.writable,
        "setting": param.setting,
    }
