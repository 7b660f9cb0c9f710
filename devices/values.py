"""Typed values on the wire: integers of any byte width, floats, fixed strings, byte
arrays, arrays, named structs, bit fields and enums, little- or big-endian.

Pure: no I/O. Every type answers three questions the same way::

    t.size                      # bytes on the wire (None: takes the rest of the data)
    t.decode(data)              # bytes -> value; DecodeError on short or excess data
    t.encode(value)             # value -> bytes; EncodeError when it does not fit

so a device document's data directory (SCU data IDs: INT32, UINT8, FLOAT, STRING,
structs), telegram fields (MO 64: u8 ... 64 bit, int8, little-endian) and Modbus
registers (16-bit big-endian words, high word first) are all described as data.
``encode(decode(b)) == b`` holds for every type (enums: for the values they name).

The types describe bytes only; where a device decides a byte order, a padding or a
scale, that decision is written where the type is used (the device's codec or params).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from devices import errors

LITTLE = "little"
BIG = "big"
_ORDERS = (LITTLE, BIG)


# -- errors ------------------------------------------------------------------------------
class ValueCodecError(errors.CodecError):
    """Base of the errors below; ``path`` names the struct member or array item."""

    def __init__(self, message: str, path: str = ""):
        self.message = message
        self.path = path
        super().__init__(f"{path}: {message}" if path else message)

    def within(self, name: str) -> ValueCodecError:
        """The same error, one level further in (``name`` of the enclosing member)."""
        path = f"{name}.{self.path}" if self.path and not self.path.startswith("[") else f"{name}{self.path}"
        clone = self.__class__.__new__(self.__class__)
        clone.__dict__.update(self.__dict__)
        ValueCodecError.__init__(clone, self.message, path)
        return clone


class DecodeError(ValueCodecError):
    """Bytes that are not a value of the type (malformed wire data)."""


class TruncatedError(DecodeError):
    """Fewer bytes than the type needs."""

    def __init__(self, needed: int, got: int, path: str = ""):
        self.needed = needed
        self.got = got
        super().__init__(f"needs {needed} byte(s), got {got}", path)


class ExcessDataError(DecodeError):
    """More bytes than the type takes (pass ``allow_excess=True`` to ignore them)."""

    def __init__(self, size: int, got: int, path: str = ""):
        self.size = size
        self.got = got
        super().__init__(f"takes {size} byte(s), got {got}", path)


class EncodeError(ValueCodecError):
    """A value that the type cannot carry (range, type, length, unknown name)."""


# -- decoded values that keep their meaning ------------------------------------------------
class EnumValue(int):
    """An integer that knows its name in the document (``name`` is None if undefined)."""

    name: str | None

    def __new__(cls, value: int, name: str | None):
        obj = super().__new__(cls, value)
        obj.name = name
        return obj

    def __getnewargs__(self):  # copy, deepcopy and pickle
        return int(self), self.name

    def __repr__(self) -> str:
        return f"{int(self)} ({self.name or 'undefined'})"


class FlagsValue(int):
    """The raw integer of a bit-field word, with its named fields."""

    fields: dict[str, Any]

    def __new__(cls, raw: int, fields: dict[str, Any]):
        obj = super().__new__(cls, raw)
        obj.fields = fields
        return obj

    def __getitem__(self, name: str):
        return self.fields[name]

    def __getnewargs__(self):  # copy, deepcopy and pickle
        return int(self), self.fields

    @property
    def active(self) -> list[str]:
        """Names of the 1-bit fields that are set."""
        return [name for name, value in self.fields.items() if value is True]

    def __repr__(self) -> str:
        return f"0x{int(self):X} {self.fields}"


# -- the types -------------------------------------------------------------------------------
class ValueType:
    """Base class: subclasses give ``size``, ``name``, ``decode_from`` and ``encode``."""

    size: int | None = None
    name: str = ""

    def decode(self, data: bytes | bytearray | memoryview, *, allow_excess: bool = False) -> Any:
        """Decode ``data`` completely.

        :param allow_excess: ignore bytes after the value instead of raising
        :raises TruncatedError: data shorter than the type
        :raises ExcessDataError: data longer than the type
        """
        data = bytes(data)
        value, end = self.decode_from(data, 0)
        if end != len(data) and not allow_excess:
            raise ExcessDataError(end, len(data))
        return value

    def decode_from(self, data: bytes, offset: int) -> tuple[Any, int]:
        """Decode one value at ``offset``; return it and the offset after it."""
        raise NotImplementedError

    def encode(self, value: Any) -> bytes:
        raise NotImplementedError

    def _take(self, data: bytes, offset: int, count: int) -> bytes:
        if len(data) - offset < count:
            raise TruncatedError(count, max(0, len(data) - offset))
        return data[offset:offset + count]

    def __repr__(self) -> str:
        return self.name


def _integral(value: Any, what: str) -> int:
    """An int from an int, bool or whole float; EncodeError otherwise."""
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float) and value.is_integer():
        return int(value)
    raise EncodeError(f"{value!r} is not a whole number ({what})")


@dataclass(frozen=True, repr=False)
class Int(ValueType):
    """Two's-complement or unsigned integer of 1..8 bytes."""

    bits: int
    signed: bool = False
    byteorder: str = LITTLE

    def __post_init__(self):
        if self.bits % 8 or not 8 <= self.bits <= 64:
            raise ValueError(f"integer width must be 8..64 bits in whole bytes, not {self.bits}")
        if self.byteorder not in _ORDERS:
            raise ValueError(f"byte order must be 'little' or 'big', not {self.byteorder!r}")

    @property
    def size(self) -> int:
        return self.bits // 8

    @property
    def name(self) -> str:
        order = "" if self.bits == 8 else ("le" if self.byteorder == LITTLE else "be")
        return f"{'i' if self.signed else 'u'}{self.bits}{order}"

    @property
    def limits(self) -> tuple[int, int]:
        if self.signed:
            return -(1 << (self.bits - 1)), (1 << (self.bits - 1)) - 1
        return 0, (1 << self.bits) - 1

    def decode_from(self, data: bytes, offset: int) -> tuple[int, int]:
        chunk = self._take(data, offset, self.size)
        return int.from_bytes(chunk, self.byteorder, signed=self.signed), offset + self.size

    def encode(self, value: Any) -> bytes:
        number = _integral(value, self.name)
        low, high = self.limits
        if not low <= number <= high:
            raise EncodeError(f"{number} is outside {low} .. {high} ({self.name})")
        return number.to_bytes(self.size, self.byteorder, signed=self.signed)


@dataclass(frozen=True, repr=False)
class Float(ValueType):
    """IEEE 754 binary32 (``bits=32``) or binary64."""

    bits: int = 32
    byteorder: str = LITTLE

    def __post_init__(self):
        if self.bits not in (32, 64):
            raise ValueError(f"float width must be 32 or 64 bits, not {self.bits}")
        if self.byteorder not in _ORDERS:
            raise ValueError(f"byte order must be 'little' or 'big', not {self.byteorder!r}")

    @property
    def _format(self) -> str:
        return ("<" if self.byteorder == LITTLE else ">") + ("f" if self.bits == 32 else "d")

    @property
    def size(self) -> int:
        return self.bits // 8

    @property
    def name(self) -> str:
        return f"f{self.bits}{'le' if self.byteorder == LITTLE else 'be'}"

    def decode_from(self, data: bytes, offset: int) -> tuple[float, int]:
        chunk = self._take(data, offset, self.size)
        return struct.unpack(self._format, chunk)[0], offset + self.size

    def encode(self, value: Any) -> bytes:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise EncodeError(f"{value!r} is not a number ({self.name})")
        try:
            packed = struct.pack(self._format, value)
        except OverflowError:
            raise EncodeError(f"{value!r} is outside the range of {self.name}") from None
        if math.isfinite(value) and math.isinf(struct.unpack(self._format, packed)[0]):
            raise EncodeError(f"{value!r} is outside the range of {self.name}")
        return packed


@dataclass(frozen=True, repr=False)
class String(ValueType):
    """Text in a fixed number of bytes, filled up with ``pad``.

    Decoding drops the trailing pad bytes; encoding refuses text that is too long,
    cannot be encoded, or ends in the pad character (it would not read back).
    """

    length: int
    encoding: str = "ascii"
    pad: bytes = b"\x00"

    def __post_init__(self):
        if len(self.pad) != 1:
            raise ValueError("pad must be one byte")
        if self.length < 0:
            raise ValueError("string length must not be negative")

    @property
    def size(self) -> int:
        return self.length

    @property
    def name(self) -> str:
        return f"str{self.length}"

    def decode_from(self, data: bytes, offset: int) -> tuple[str, int]:
        chunk = self._take(data, offset, self.length).rstrip(self.pad)
        try:
            return chunk.decode(self.encoding), offset + self.length
        except UnicodeDecodeError as exc:
            raise DecodeError(f"byte 0x{chunk[exc.start]:02X} at {exc.start} is not {self.encoding}") from None

    def encode(self, value: Any) -> bytes:
        if not isinstance(value, str):
            raise EncodeError(f"{value!r} is not text ({self.name})")
        try:
            raw = value.encode(self.encoding)
        except UnicodeEncodeError as exc:
            raise EncodeError(f"{value[exc.start]!r} cannot be written in {self.encoding}") from None
        if len(raw) > self.length:
            raise EncodeError(f"{len(raw)} bytes do not fit in {self.length} ({self.name})")
        if raw.endswith(self.pad):
            raise EncodeError(f"text must not end in the pad byte 0x{self.pad[0]:02X} ({self.name})")
        return raw.ljust(self.length, self.pad)


@dataclass(frozen=True, repr=False)
class Bytes(ValueType):
    """Raw bytes: exactly ``length`` of them, or with ``length=None`` the rest of the data."""

    length: int | None = None

    @property
    def size(self) -> int | None:
        return self.length

    @property
    def name(self) -> str:
        return "bytes" if self.length is None else f"bytes{self.length}"

    def decode_from(self, data: bytes, offset: int) -> tuple[bytes, int]:
        if self.length is None:
            return bytes(data[offset:]), len(data)
        return bytes(self._take(data, offset, self.length)), offset + self.length

    def encode(self, value: Any) -> bytes:
        if not isinstance(value, (bytes, bytearray, memoryview)):
            raise EncodeError(f"{value!r} is not bytes ({self.name})")
        value = bytes(value)
        if self.length is not None and len(value) != self.length:
            raise EncodeError(f"{len(value)} bytes given, {self.length} needed ({self.name})")
        return value


@dataclass(frozen=True, repr=False)
class Array(ValueType):
    """``count`` items of one fixed-size type, decoded to a tuple."""

    item: ValueType
    count: int

    def __post_init__(self):
        if self.item.size is None:
            raise ValueError("array items must have a fixed size")

    @property
    def size(self) -> int:
        return self.item.size * self.count

    @property
    def name(self) -> str:
        return f"{self.item.name}[{self.count}]"

    def decode_from(self, data: bytes, offset: int) -> tuple[tuple, int]:
        self._take(data, offset, self.size)  # the whole array must be there
        items = []
        for i in range(self.count):
            try:
                value, offset = self.item.decode_from(data, offset)
            except ValueCodecError as exc:
                raise exc.within(f"[{i}]") from None
            items.append(value)
        return tuple(items), offset

    def encode(self, value: Any) -> bytes:
        if isinstance(value, (str, bytes, bytearray, Mapping)) or not isinstance(value, Sequence):
            raise EncodeError(f"{type(value).__name__} is not a list of {self.count} ({self.name})")
        if len(value) != self.count:
            raise EncodeError(f"{len(value)} items given, {self.count} needed ({self.name})")
        out = bytearray()
        for i, item in enumerate(value):
            try:
                out += self.item.encode(item)
            except ValueCodecError as exc:
                raise exc.within(f"[{i}]") from None
        return bytes(out)


@dataclass(frozen=True, repr=False)
class Struct(ValueType):
    """Named members in order, decoded to a dict; only the last may take the rest."""

    struct_name: str
    members: tuple[tuple[str, ValueType], ...]

    def __post_init__(self):
        names = [name for name, _ in self.members]
        if len(set(names)) != len(names):
            raise ValueError(f"{self.struct_name}: duplicate member name")
        if any(t.size is None for _, t in self.members[:-1]):
            raise ValueError(f"{self.struct_name}: only the last member may have a variable size")

    @property
    def size(self) -> int | None:
        sizes = [t.size for _, t in self.members]
        return None if None in sizes else sum(sizes)

    @property
    def name(self) -> str:
        return self.struct_name

    @property
    def offsets(self) -> dict[str, int]:
        """Byte offset of each member."""
        result, at = {}, 0
        for name, t in self.members:
            result[name] = at
            at += t.size or 0
        return result

    def decode_from(self, data: bytes, offset: int) -> tuple[dict, int]:
        if self.size is not None:
            self._take(data, offset, self.size)  # the whole struct must be there
        result = {}
        for name, t in self.members:
            try:
                result[name], offset = t.decode_from(data, offset)
            except ValueCodecError as exc:
                raise exc.within(name) from None
        return result, offset

    def encode(self, value: Any) -> bytes:
        if not isinstance(value, Mapping):
            raise EncodeError(f"{type(value).__name__} is not a mapping of members ({self.name})")
        names = [name for name, _ in self.members]
        unknown = [k for k in value if k not in names]
        missing = [n for n in names if n not in value]
        if unknown or missing:
            raise EncodeError(f"members unknown {unknown}, missing {missing} ({self.name})")
        out = bytearray()
        for name, t in self.members:
            try:
                out += t.encode(value[name])
            except ValueCodecError as exc:
                raise exc.within(name) from None
        return bytes(out)


def _int_base(base: ValueType, what: str) -> Int:
    if not isinstance(base, Int):
        raise ValueError(f"{what} needs an integer type, not {base.name}")
    return base


@dataclass(frozen=True, repr=False)
class Enum(ValueType):
    """An integer whose values have names; decodes to :class:`EnumValue`.

    Decoding keeps a value the table does not name (``name`` None) so it can be shown;
    encoding accepts a named number or a name and refuses anything else.
    """

    base: Int
    names: Mapping[int, str]

    def __post_init__(self):
        _int_base(self.base, "an enum")

    @property
    def size(self) -> int:
        return self.base.size

    @property
    def name(self) -> str:
        return f"enum({self.base.name})"

    def decode_from(self, data: bytes, offset: int) -> tuple[EnumValue, int]:
        number, end = self.base.decode_from(data, offset)
        return EnumValue(number, self.names.get(number)), end

    def encode(self, value: Any) -> bytes:
        if isinstance(value, str):
            for number, text in self.names.items():
                if text.lower() == value.strip().lower():
                    return self.base.encode(number)
            raise EncodeError(f"{value!r} is not one of {sorted(self.names.values())} ({self.name})")
        number = _integral(value, self.name)
        if number not in self.names:
            allowed = ", ".join(f"{k} {v}" for k, v in self.names.items())
            raise EncodeError(f"{number} is not one of: {allowed}")
        return self.base.encode(number)


@dataclass(frozen=True)
class BitField:
    """``width`` bits from bit ``shift`` (bit 0 = least significant) of a word.

    A 1-bit field decodes to a bool; wider ones to an int, or an :class:`EnumValue`
    when ``names`` are given.
    """

    name: str
    shift: int
    width: int = 1
    names: Mapping[int, str] | None = None
    description: str = ""

    @property
    def mask(self) -> int:
        return ((1 << self.width) - 1) << self.shift

    def extract(self, raw: int):
        value = (raw >> self.shift) & ((1 << self.width) - 1)
        if self.names is not None:
            return EnumValue(value, self.names.get(value))
        return bool(value) if self.width == 1 else value


@dataclass(frozen=True, repr=False)
class Bits(ValueType):
    """An unsigned integer read as named bit fields; decodes to :class:`FlagsValue`.

    Bits no field names are kept in the raw value, so ``encode(decode(b)) == b``.
    Encoding takes the raw integer or a mapping of field values (unnamed bits 0).
    """

    base: Int
    fields: tuple[BitField, ...]

    def __post_init__(self):
        base = _int_base(self.base, "bit fields")
        if base.signed:
            raise ValueError("bit fields need an unsigned integer type")
        used, names = 0, set()
        for f in self.fields:
            if f.name in names:
                raise ValueError(f"duplicate bit field {f.name!r}")
            if f.shift < 0 or f.width < 1 or f.shift + f.width > base.bits:
                raise ValueError(f"bit field {f.name!r} does not fit in {base.bits} bits")
            if used & f.mask:
                raise ValueError(f"bit field {f.name!r} overlaps another")
            used |= f.mask
            names.add(f.name)

    @property
    def size(self) -> int:
        return self.base.size

    @property
    def name(self) -> str:
        return f"bits({self.base.name})"

    def field(self, name: str) -> BitField:
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(name)

    def decode_from(self, data: bytes, offset: int) -> tuple[FlagsValue, int]:
        raw, end = self.base.decode_from(data, offset)
        return FlagsValue(raw, {f.name: f.extract(raw) for f in self.fields}), end

    def encode(self, value: Any) -> bytes:
        if not isinstance(value, Mapping):
            return self.base.encode(value)
        raw = 0
        for key, item in value.items():
            try:
                f = self.field(key)
            except KeyError:
                raise EncodeError(f"no bit field {key!r} ({self.name})") from None
            if isinstance(item, str) and f.names is not None:
                number = next((k for k, v in f.names.items() if v.lower() == item.lower()), None)
                if number is None:
                    raise EncodeError(f"{item!r} is not one of {sorted(f.names.values())}", key)
            else:
                try:
                    number = _integral(item, f"{f.width}-bit field")
                except EncodeError as exc:
                    raise exc.within(key) from None
            if not 0 <= number < (1 << f.width):
                raise EncodeError(f"{number} does not fit in {f.width} bit(s)", key)
            raw |= number << f.shift
        return self.base.encode(raw)


@dataclass(frozen=True, repr=False)
class Scaled(ValueType):
    """An integer on the wire, ``raw * scale`` in engineering units (``unit``).

    Encoding rounds to the nearest step and range-checks the raw value.
    """

    base: Int
    scale: float
    unit: str = ""

    def __post_init__(self):
        _int_base(self.base, "a scaled value")
        if not self.scale:
            raise ValueError("scale must not be 0")

    @property
    def size(self) -> int:
        return self.base.size

    @property
    def name(self) -> str:
        return f"{self.base.name}*{self.scale:g}"

    def decode_from(self, data: bytes, offset: int) -> tuple[float, int]:
        raw, end = self.base.decode_from(data, offset)
        return round(raw * self.scale, 6), end

    def encode(self, value: Any) -> bytes:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise EncodeError(f"{value!r} is not a number ({self.name})")
        raw = round(value / self.scale)
        low, high = self.base.limits
        if not low <= raw <= high:
            raise EncodeError(
                f"{value} is outside {round(low * self.scale, 6):g} .. {round(high * self.scale, 6):g} {self.unit}".rstrip()
            )
        return self.base.encode(raw)


# -- names ------------------------------------------------------------------------------------
def scalar(spec: str) -> ValueType:
    """A scalar type from its short name: ``u8``, ``i8``, ``u16le``, ``i32be``, ``u40le``,
    ``f32le``, ``f64be`` ... (the ``name`` of :class:`Int` and :class:`Float`)."""
    text = spec.strip().lower()
    order = LITTLE
    if text.endswith(("le", "be")):
        order = LITTLE if text.endswith("le") else BIG
        text = text[:-2]
    kind, digits = text[:1], text[1:]
    if kind not in ("u", "i", "f") or not digits.isdigit():
        raise ValueError(f"unknown value type {spec!r}")
    bits = int(digits)
    if bits > 8 and not spec.strip().lower().endswith(("le", "be")):
        raise ValueError(f"{spec!r} needs a byte order suffix (le or be)")
    if kind == "f":
        return Float(bits, order)
    return Int(bits, kind == "i", order)


U8 = Int(8)
I8 = Int(8, True)
U16LE, U16BE = Int(16, False, LITTLE), Int(16, False, BIG)
I16LE, I16BE = Int(16, True, LITTLE), Int(16, True, BIG)
U32LE, U32BE = Int(32, False, LITTLE), Int(32, False, BIG)
I32LE, I32BE = Int(32, True, LITTLE), Int(32, True, BIG)
U64LE, U64BE = Int(64, False, LITTLE), Int(64, False, BIG)
I64LE, I64BE = Int(64, True, LITTLE), Int(64, True, BIG)
F32LE, F32BE = Float(32, LITTLE), Float(32, BIG)


def register_type(words: int = 1, signed: bool = False) -> Int:
    """A Modbus register value: ``words`` 16-bit words, high word first, each big-endian
    (Modbus application protocol 4.2), which is one big-endian integer."""
    return Int(16 * words, signed, BIG)


def words_to_bytes(words: Sequence[int]) -> bytes:
    """Register words as they travel in a Modbus PDU (big-endian, in address order)."""
    return b"".join((w & 0xFFFF).to_bytes(2, BIG) for w in words)


def bytes_to_words(data: bytes) -> list[int]:
    """The inverse of :func:`words_to_bytes`; DecodeError on an odd length."""
    if len(data) % 2:
        raise DecodeError(f"{len(data)} bytes are not whole 16-bit words")
    return [int.from_bytes(data[i:i + 2], BIG) for i in range(0, len(data), 2)]


__all__ = [
    "LITTLE", "BIG", "ValueCodecError", "DecodeError", "TruncatedError", "ExcessDataError",
    "EncodeError", "EnumValue", "FlagsValue", "ValueType", "Int", "Float", "String", "Bytes",
    "Array", "Struct", "Enum", "BitField", "Bits", "Scaled", "scalar", "register_type",
    "words_to_bytes", "bytes_to_words", "U8", "I8", "U16LE", "U16BE", "I16LE", "I16BE",
    "U32LE", "U32BE", "I32LE", "I32BE", "U64LE", "U64BE", "I64LE", "I64BE", "F32LE", "F32BE",
]
