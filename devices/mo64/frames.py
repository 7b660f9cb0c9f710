"""Bauer MO 64 LogiTed frames: the line, the CRC, the TCP and RS485 framing, the token telegram and
the splitter that cuts a byte stream into frames (document 003, chapters 2 and 3).

Frames::

    TCP    55 LE type payload... CSH CSL           LE counts type .. payload
    RS485  55 LE DA SA type payload... CSH CSL     ASSUMED (see Rs485Layout)

CSH CSL is the CRC-16/CCITT-FALSE (poly 0x1021, preset 0xFFFF, chapter 2.3) over SD, LE and
the data, high byte first. The telegrams inside a frame are :mod:`devices.mo64.codec`'s, which
names everything here as its own (the MO 64's codec is one module to its readers). Pure: no I/O.
"""

from __future__ import annotations

import binascii
from dataclasses import dataclass
from typing import Any

from devices import errors, framing

# -- line and connection (chapters 2.1, 3) ----------------------------------------------------------
SD = 0x55  # chapter 2.2: "Das Startbyte hat immer den Wert 0x55"
RS485_BAUDRATE = 38400  # chapter 2.1: 38,4 kBaud, 1 start bit, 8 data bits, 1 stop bit
TCP_PORT = 52719  # SPEC-NOTES "Bauer MO 64": the public client's port
TOKEN_PASS_LIMIT_S = 0.2  # chapter 2.6.1: "Der Token muss nach spätestens 200ms weitergegeben werden"
MAX_LE = 255  # chapter 2.1: 6 to 259 characters, i.e. LE at most 255 (one byte)
CRC_PRESET = 0xFFFF  # chapter 2.3: the CRC register is loaded with 0xFFFF


class CodecError(errors.CodecError):
    """A telegram that cannot be encoded or decoded."""


# -- the RS485 layout: an assumption beyond the document (see codec.ASSUMPTIONS) ----------------------------
@dataclass(frozen=True)
class Rs485Layout:
    """The RS485 address fields and token telegram, which the page summaries do not print.

    Every field is an assumption (SPEC-NOTES "Bauer MO 64", "Still unknown").
    """

    master_address: int = 0x00  # SPEC-NOTES: "the master at 0x00" (chapter 2.6 example: "Master 0x00")
    # SPEC-NOTES: DA SA follow LE and LE counts DA to the end of the payload (see encode_frame)
    # chapter 2.1 "6 bis 259 Zeichen": the shortest telegram, SD LE DA SA CSH CSL, is taken as the token
    token_le: int = 2


RS485_LAYOUT = Rs485Layout()


# -- CRC (chapter 2.3) ------------------------------------------------------------------------------
def crc16(data: bytes | bytearray) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (x^16 + x^12 + x^5 + 1, preset 0xFFFF, chapter 2.3)."""
    return binascii.crc_hqx(bytes(data), CRC_PRESET)


CHECKSUM = framing.Checksum(crc16, "big")  # CSH before CSL (chapter 2.1)
_seal = CHECKSUM.seal


# -- framing ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Framing:
    """How a transport wraps the telegram: ``addressed`` adds DA SA (RS485)."""

    name: str
    addressed: bool

    @property
    def min_le(self) -> int:
        """Smallest LE the framing allows (TCP: the type byte; RS485: the token's DA SA)."""
        return RS485_LAYOUT.token_le if self.addressed else 1


TCP = Framing("tcp", False)
RS485 = Framing("rs485", True)
TOKEN = -1  # Frame.type of a token telegram (it has no type byte)


@dataclass(frozen=True)
class Frame:
    """One telegram off the wire: ``type`` and ``payload``; ``da``/``sa`` only on RS485.

    ``type`` is :data:`TOKEN` for a token telegram. ``raw`` holds the bytes as received.
    """

    type: int
    payload: bytes = b""
    da: int | None = None
    sa: int | None = None
    raw: bytes = b""

    @property
    def is_token(self) -> bool:
        return self.type == TOKEN


def _address(value: int, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFF:
        raise CodecError(f"{what} {value!r} is not a bus address 0 .. 255")
    return value


def encode_frame(telegram: bytes, framing: Framing = TCP, *, da: int | None = None,
                 sa: int | None = None) -> bytes:
    """Wrap ``telegram`` (type + payload) in SD, LE and the checksum.

    :param framing: :data:`TCP` or :data:`RS485` (then ``da`` is required; ``sa`` defaults to
        the assumed master address)
    :raises CodecError: empty telegram, too long, or bad addresses
    """
    telegram = bytes(telegram)
    if not telegram:
        raise CodecError("a telegram needs at least its type byte")
    if framing.addressed:
        if da is None:
            raise CodecError("an RS485 telegram needs a destination address")
        sa = RS485_LAYOUT.master_address if sa is None else sa
        telegram = bytes((_address(da, "DA"), _address(sa, "SA"))) + telegram
    if len(telegram) > MAX_LE:
        raise CodecError(f"{len(telegram)} bytes exceed LE {MAX_LE}")
    return _seal(bytes((SD, len(telegram))) + telegram)


def encode_token(da: int, sa: int | None = None) -> bytes:
    """The RS485 token telegram passing the token to master ``da`` (ASSUMED layout, see above)."""
    sa = RS485_LAYOUT.master_address if sa is None else sa
    return _seal(bytes((SD, RS485_LAYOUT.token_le, _address(da, "DA"), _address(sa, "SA"))))


def decode_frame(raw: bytes, framing: Framing = TCP) -> Frame:
    """One complete frame, checked (SD, LE, CRC).

    :raises FrameError: the named error of the splitter
    """
    raw = bytes(raw)
    if len(raw) < 2 or raw[0] != SD:
        raise GarbageError(raw)
    le = raw[1]
    if le < framing.min_le:
        raise FrameLengthError(f"LE {le} is below {framing.min_le} ({framing.name})", raw)
    if len(raw) < le + 4:
        raise TruncatedFrameError(raw)
    if len(raw) > le + 4:
        raise FrameLengthError(f"{len(raw)} bytes for LE {le} (expected {le + 4})", raw)
    if not CHECKSUM.matches(raw):
        raise ChecksumError(raw)
    data = raw[2:-2]
    if not framing.addressed:
        return Frame(data[0], data[1:], raw=raw)
    if le == RS485_LAYOUT.token_le:
        return Frame(TOKEN, b"", da=data[0], sa=data[1], raw=raw)
    return Frame(data[2], data[3:], da=data[0], sa=data[1], raw=raw)


# -- named stream errors (devices/framing.py) ------------------------------------------------------
# Bad wire data: ``raw`` holds the bytes concerned; the splitter returns these as values. GarbageError:
# bytes that start no telegram (no SD), skipped; ChecksumError: CSH CSL do not match; FrameLengthError:
# an LE impossible for the framing; TruncatedFrameError: cut off before its end (silent or closed).
FrameError, GarbageError, ChecksumError, FrameLengthError, TruncatedFrameError = framing.error_tree(
    CodecError, __name__, CHECKSUM)


class FrameSplitter(framing.Splitter):
    """Cuts a byte stream (TCP or RS485) into :class:`Frame` values and :class:`FrameError` values.

    ``feed(data)`` returns them in stream order; nothing is raised. A frame cut short stays
    pending until more bytes come or :meth:`expire` is called (the stream went silent or closed).
    A checksum failure or an impossible LE resynchronises on the next SD that starts a valid
    frame, so a stray 0x55 does not swallow the telegram after it.

    :param framing: :data:`TCP` or :data:`RS485`
    """

    garbage_error = GarbageError
    truncated_error = TruncatedFrameError

    def __init__(self, framing: Framing = TCP):
        super().__init__()
        self.framing = framing

    def _starts_telegram(self, raw: bytes) -> bool:
        return raw[0] == SD

    def _length_at(self, i: int) -> int | None:
        """Frame length starting at ``i``: None if more bytes are needed, 0 if impossible."""
        buf = self._buf
        if i + 1 >= len(buf):
            return None
        le = buf[i + 1]
        return le + 4 if le >= self.framing.min_le else 0

    def _valid_at(self, i: int) -> bool:
        """A complete frame with a good CRC starts at ``i``."""
        n = self._length_at(i)
        return bool(n) and i + n <= len(self._buf) and CHECKSUM.matches(self._buf[i:i + n])

    def _next_valid(self, start: int, stop: int) -> int | None:
        for j in range(start, min(stop, len(self._buf))):
            if self._buf[j] == SD and self._valid_at(j):
                return j
        return None

    def _next(self) -> tuple[Any, int]:
        buf = self._buf
        if buf[0] != SD:
            end = buf.find(bytes((SD,)))
            return self._garbage(len(buf) if end < 0 else end)
        n = self._length_at(0)
        if n is None:
            return None, 0
        if n == 0:
            return FrameLengthError(f"LE {buf[1]} is below {self.framing.min_le} ({self.framing.name})",
                                    bytes(buf[:2])), 2  # an LE below the minimum is never SD
        if len(buf) < n:
            later = self._next_valid(1, len(buf))  # a stray SD announcing a long frame
            return (None, 0) if later is None else self._garbage(later)
        try:
            return decode_frame(bytes(buf[:n]), self.framing), n
        except ChecksumError as exc:
            later = self._next_valid(1, n)
            return (exc, n) if later is None else self._garbage(later)
