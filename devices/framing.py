"""What the byte-stream codecs share: the checksum at a telegram's end, the named errors of bad wire
data, and a splitter that cuts a stream into telegrams and resynchronises after garbage.

Pure: no I/O. The SCU (RS232, devices/scu/codec.py) and the MO 64 (LogiTed, devices/mo64/codec.py)
both end a telegram with a CRC-16 and both reach the tool as a byte stream in which a telegram may
be cut short, preceded by noise or damaged. Each keeps its own telegram rules (where one starts, how
long it is); what is left is here:

* :class:`Checksum`: a CRC-16 function and the byte order of its two bytes on the wire;
* the error tree :class:`FrameError` -> :class:`GarbageError`, :class:`ChecksumError`,
  :class:`FrameLengthError`, :class:`TruncatedFrameError`; :func:`error_tree` gives a family its
  own copy under its own ``CodecError``, so an adapter catches exactly its family's errors while
  code that handles any bad wire data catches these (or ``devices.errors.CodecError``);
* :class:`Splitter`: ``feed``/``expire``/``pending``/``reset`` and the frame and error counters;
  a family says only what the head of the buffer is (:meth:`Splitter._next`).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from devices import errors
from devices.message import Message, N_


@dataclass(frozen=True)
class Checksum:
    """A CRC-16 over the telegram, sent in its last two bytes."""

    crc16: Callable[[bytes], int]
    byteorder: str  # "little": low byte first (SCU C1 C2); "big": high byte first (MO 64 CSH CSL)

    def seal(self, body: bytes) -> bytes:
        """``body`` with its checksum appended."""
        return body + self.crc16(body).to_bytes(2, self.byteorder)

    def received(self, frame: bytes) -> int:
        """The checksum the last two bytes of ``frame`` carry."""
        return int.from_bytes(frame[-2:], self.byteorder)

    def matches(self, frame: bytes) -> bool:
        """The last two bytes of ``frame`` are the CRC of the bytes before them."""
        frame = bytes(frame)
        return len(frame) >= 2 and self.crc16(frame[:-2]) == self.received(frame)


# -- named stream errors -----------------------------------------------------------------------------
class FrameError(errors.CodecError):
    """Bad wire data; ``raw`` holds the bytes concerned. A splitter yields these as values, never raises them."""

    def __init__(self, message: str, raw: bytes = b""):
        self.raw = bytes(raw)
        super().__init__(message)


class GarbageError(FrameError):
    """Bytes that start no telegram; they were skipped."""

    def __init__(self, raw: bytes):
        super().__init__(f"{len(raw)} byte(s) that start no telegram: {bytes(raw).hex(' ')}", raw)


class ChecksumError(FrameError):
    """A telegram whose checksum bytes do not match its CRC (count it; a request may be repeated)."""

    checksum: Checksum  # the family's (see error_tree)

    def __init__(self, raw: bytes):
        raw = bytes(raw)
        self.expected = self.checksum.crc16(raw[:-2]) if len(raw) >= 2 else 0
        self.received = self.checksum.received(raw) if len(raw) >= 2 else 0
        super().__init__(Message(N_("CRC 0x{received:04X} received, 0x{expected:04X} computed: {raw}"), received=self.received,
                                 expected=self.expected, raw=raw.hex(" ")), raw)


class FrameLengthError(FrameError):
    """A telegram whose length is impossible (a length field out of range, or not matching the bytes)."""


class TruncatedFrameError(FrameError):
    """A telegram that stopped before its end (the stream went silent or closed)."""

    def __init__(self, raw: bytes):
        super().__init__(f"telegram incomplete after {len(raw)} byte(s): {bytes(raw).hex(' ')}", raw)


def error_tree(root: type[errors.CodecError], module: str, checksum: Checksum) -> tuple[type[FrameError], ...]:
    """The tree above for one device family: ``(FrameError, GarbageError, ChecksumError, FrameLengthError,
    TruncatedFrameError)``, each deriving from the shared class of its name and (through its
    ``FrameError``) from the family's ``root``.

    :param module: the family codec's ``__name__`` (the classes are that module's)
    :param checksum: the family's, for :class:`ChecksumError`
    """
    def make(shared: type[FrameError], parent: type, extra: dict[str, Any] | None = None) -> type[FrameError]:
        name = shared.__name__
        attrs = {"__module__": module, "__qualname__": name, "__doc__": shared.__doc__, **(extra or {})}
        return type(name, (shared, parent), attrs)

    frame = make(FrameError, root)
    return (frame, make(GarbageError, frame), make(ChecksumError, frame, {"checksum": checksum}),
            make(FrameLengthError, frame), make(TruncatedFrameError, frame))


# -- streaming splitter ------------------------------------------------------------------------------
class Splitter:
    """Cuts a byte stream into telegrams.

    ``feed(data)`` returns, in stream order, decoded telegrams and :class:`FrameError` values (never
    raised). A telegram cut short stays pending until more bytes come or :meth:`expire` is called
    (the stream went silent). A family's splitter sets :attr:`garbage_error` and
    :attr:`truncated_error` and implements :meth:`_next` and :meth:`_starts_telegram`.
    """

    garbage_error: type[FrameError] = GarbageError
    truncated_error: type[FrameError] = TruncatedFrameError

    def __init__(self) -> None:
        self._buf = bytearray()
        self.frames = 0
        self.errors = 0

    @property
    def pending(self) -> bytes:
        """Bytes received that do not yet form a telegram."""
        return bytes(self._buf)

    def reset(self) -> None:
        self._buf.clear()

    def expire(self) -> list[FrameError]:
        """Drop an incomplete telegram (the stream went silent); returns its error, or nothing if idle."""
        if not self._buf:
            return []
        raw = bytes(self._buf)
        self._buf.clear()
        self.errors += 1
        return [self.truncated_error(raw) if self._starts_telegram(raw) else self.garbage_error(raw)]

    def feed(self, data: bytes | bytearray | Iterable[int]) -> list:
        self._buf += bytes(data)
        out: list = []
        while self._buf:
            item, used = self._next()
            if item is None:
                break
            del self._buf[:used]
            if isinstance(item, FrameError):
                self.errors += 1
            else:
                self.frames += 1
            out.append(item)
        return out

    def _garbage(self, end: int) -> tuple[FrameError, int]:
        """The bytes before ``end`` as garbage: what :meth:`_next` returns to resynchronise there."""
        return self.garbage_error(bytes(self._buf[:end])), end

    def _next(self) -> tuple[Any, int]:
        """The item at the head of the (non-empty) buffer and how many bytes it takes; ``(None, 0)`` when
        more bytes are needed to tell."""
        raise NotImplementedError

    def _starts_telegram(self, raw: bytes) -> bool:
        """``raw`` (left over when the stream went silent) begins like a telegram of the family."""
        raise NotImplementedError
