"""Reading a recorded file back into frame rows: its format from its content, progress, and the
line or byte offset where a bad file stops."""

from __future__ import annotations

import asyncio
import contextlib
import io
import logging
import math
import re
import struct
import threading
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import can
from can.io.blf import BLFParseError

from app.can_bus import FrameRecord
from app.i18n import N_
from app.message import Message, message_of
from app.recording.base import MAX_FILE_FRAMES, PROGRESS_FRAMES, READERS, READ_SUFFIXES, SNIFF_BYTES, RecordingError

logger = logging.getLogger("app.recording")  # one logger for the recordings, as before the split

# what python-can's readers raise on a file they cannot read (can/io/*.py): their BLFParseError; ValueError
# (UnicodeDecodeError among them) for a bad line; struct.error, IndexError or KeyError for a cut or odd record;
# zlib's error for broken compressed BLF data; NotImplementedError for a TRC version they do not know; OSError
MALFORMED: tuple[type[Exception], ...] = (BLFParseError, ValueError, LookupError, struct.error, zlib.error,
                                          NotImplementedError, OSError)


# -- reading a recorded file ------------------------------------------------------------------------


@dataclass
class LoadedLog:
    """Frames of a recorded file (at most ``MAX_FILE_FRAMES``)."""

    name: str
    frames: list[FrameRecord] = field(default_factory=list)
    truncated: bool = False
    format: str = ""  # the format it was read as (from its content): ".log", ".trc", ...

    def page(self, number: int, size: int = 200) -> list[FrameRecord]:
        """Frames of page ``number`` (0-based) of ``size`` frames, in file order."""
        return self.frames[number * size:(number + 1) * size] if number >= 0 and size > 0 else []

    def pages(self, size: int = 200) -> int:
        return -(-len(self.frames) // size) if size > 0 else 0

    @property
    def duration(self) -> float:
        return self.frames[-1].time - self.frames[0].time if len(self.frames) > 1 else 0.0

    @property
    def error_frames(self) -> int:
        return sum(1 for f in self.frames if f.is_error_frame)


_CANDUMP_LINE = re.compile(r"^\(\d+(\.\d+)?\)\s+\S+\s+[0-9A-Fa-f]{1,8}#")


def detect_format(head: bytes) -> str | None:
    """The recording format of a file from its first bytes (``.blf``, ``.trc``, ``.asc``, ``.csv``,
    ``.log``), or None when the content does not tell."""
    if head.startswith(b"LOGG"):  # BLF file signature
        return ".blf"
    text = head.decode("utf-8", errors="replace").lstrip("\ufeff")
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    if not lines:
        return None
    first = lines[0]
    if first.startswith(";"):  # PEAK trace files start with ;$FILEVERSION or a ;### comment block
        return ".trc"
    if first.lower().startswith("timestamp,arbitration_id"):
        return ".csv"
    if _CANDUMP_LINE.match(first):
        return ".log"
    lower = [line.lower() for line in lines[:8]]
    if any(line.startswith(("date ", "base hex", "base dec", "begin triggerblock")) for line in lower):
        return ".asc"
    return None


class _Wrapped:
    """What both counting files say of the file they wrap: readable, its name, closed with it."""

    _file: io.IOBase

    def readable(self) -> bool:
        return True

    @property
    def name(self) -> str:
        return self._file.name

    def close(self) -> None:
        self._file.close()
        super().close()  # the io base class's close, after the wrapper's own


class _CountingText(_Wrapped, io.TextIOBase):
    """A text file handed to a python-can reader, counting the lines and characters it took."""

    def __init__(self, file: io.TextIOBase):
        self._file = file
        self.line = 0
        self.chars = 0

    def __iter__(self):
        return self

    def __next__(self) -> str:
        line = next(self._file)
        self.line += 1
        self.chars += len(line)
        return line

    def readline(self, size: int = -1) -> str:
        line = self._file.readline(size)
        if line:
            self.line += 1
            self.chars += len(line)
        return line

    def read(self, size: int | None = -1) -> str:
        text = self._file.read(size)
        self.chars += len(text)
        self.line += text.count("\n")
        return text

    def where(self) -> Message:
        return Message(N_("line {n}"), n=self.line)

    @property
    def done(self) -> int:
        return self.chars


class _CountingBinary(_Wrapped, io.RawIOBase):
    """A binary file handed to python-can's BLF reader, counting the bytes it took."""

    def __init__(self, file: io.BufferedIOBase):
        self._file = file
        self.offset = 0

    def read(self, size: int = -1) -> bytes:
        data = self._file.read(size)
        self.offset += len(data)
        return data

    def seek(self, offset: int, whence: int = 0) -> int:
        self.offset = self._file.seek(offset, whence)
        return self.offset

    def tell(self) -> int:
        return self.offset

    def where(self) -> Message:
        return Message(N_("byte offset {n}"), n=self.offset)

    @property
    def done(self) -> int:
        return self.offset


Progress = Callable[[int, float], None]  # (frames read so far, fraction of the file read 0..1)


def _record_of(msg: can.Message) -> FrameRecord:
    """A frame of a file, checked: a time that is a number, an ID that fits its width, at most 64 data bytes.

    :raises ValueError: naming what is wrong (the reader adds where)
    """
    if not math.isfinite(float(msg.timestamp)):
        raise ValueError(Message(N_("time stamp {stamp!r} is not a number"), stamp=msg.timestamp))
    limit = 0x1FFFFFFF if msg.is_extended_id else 0x7FF
    if not 0 <= int(msg.arbitration_id) <= limit:
        raise ValueError(Message(N_("CAN ID 0x{id:X} does not fit {bits} bits"), id=int(msg.arbitration_id),
                                 bits=29 if msg.is_extended_id else 11))
    if len(msg.data) > 64:
        raise ValueError(Message(N_("{n} data bytes (a CAN FD frame holds at most 64)"), n=len(msg.data)))
    return FrameRecord(
        float(msg.timestamp), int(msg.arbitration_id), bool(msg.is_extended_id), int(msg.dlc),
        bytes(msg.data), "rx" if msg.is_rx else "tx", bool(msg.is_error_frame), bool(msg.is_remote_frame),
    )


def cannot_open(name: str, exc: OSError) -> Message:
    """Why the file ``name`` cannot be opened: the system's words for it (as it says them)."""
    return Message(N_("{name}: cannot open: {error}"), name=name, error=exc.strerror or str(exc))


def file_format(path: str | Path, name: str | None = None) -> str:
    """The format to read ``path`` as: from its content, else from its suffix.

    :raises RecordingError: neither tells, or the file cannot be opened
    """
    path = Path(path)
    name = name or path.name
    try:
        with path.open("rb") as file:
            head = file.read(SNIFF_BYTES)
    except OSError as exc:
        raise RecordingError(cannot_open(name, exc)) from None
    found = detect_format(head)
    if found is not None:
        return found
    suffix = path.suffix.lower()
    if suffix in READERS:
        return suffix
    raise RecordingError(Message(N_("{name}: unsupported file type {suffix} and the content is not a recording python-can "
                                    "reads; readable are {readable}"), name=name, suffix=suffix or Message(N_("(none)")),
                                 readable=", ".join(READ_SUFFIXES)))


def iter_log(
    path: str | Path, name: str | None = None, chunk_frames: int = PROGRESS_FRAMES, progress: Progress | None = None,
    cancel: threading.Event | None = None,
) -> Iterator[list[FrameRecord]]:
    """The frames of a recorded file in chunks of at most ``chunk_frames`` (blocking: run it off the loop).

    The format comes from the content (:func:`file_format`). ``progress(frames, fraction)`` is
    called after every chunk, in the reading thread; ``cancel`` set ends the reading early.

    :raises RecordingError: unknown format, or a malformed file, naming the line (text formats) or the
        byte offset (BLF) where reading stopped and why
    """
    path = Path(path)
    name = name or path.name
    fmt = file_format(path, name)
    try:
        total = max(1, path.stat().st_size)
        raw = path.open("rb") if fmt == ".blf" else path.open("r", encoding="utf-8", newline=None)
    except OSError as exc:
        raise RecordingError(cannot_open(name, exc)) from None
    counted: _CountingText | _CountingBinary = _CountingBinary(raw) if fmt == ".blf" else _CountingText(raw)
    frames = 0
    try:
        try:
            reader = READERS[fmt](counted)
        except MALFORMED as exc:
            raise RecordingError(Message(N_("{name}: cannot open as {format} file ({where}): {error}"), name=name, format=fmt,
                                         where=counted.where(), error=message_of(exc))) from None
        chunk: list[FrameRecord] = []
        try:
            for msg in reader:
                chunk.append(_record_of(msg))
                if len(chunk) >= chunk_frames:
                    frames += len(chunk)
                    if progress is not None:
                        progress(frames, min(1.0, counted.done / total))
                    yield chunk
                    chunk = []
                    if cancel is not None and cancel.is_set():
                        return
        except RecordingError:
            raise
        except MALFORMED as exc:  # a malformed line or object: say where it stopped and why
            raise RecordingError(Message(
                N_("{name}: not a valid {format} file at {where} (after {n} frames): {error}"), name=name, format=fmt,
                where=counted.where(), n=frames + len(chunk), error=message_of(exc))) from None
        if chunk:
            frames += len(chunk)
            yield chunk
        if progress is not None:
            progress(frames, 1.0)
    finally:
        try:
            counted.close()
        except OSError as exc:  # closing a broken file may fail too
            logger.debug("closing %s failed: %s", name, exc)


def read_log(
    path: str | Path, name: str | None = None, limit: int = MAX_FILE_FRAMES, progress: Progress | None = None,
    cancel: threading.Event | None = None,
) -> LoadedLog:
    """Read a recorded ``.log``/``.asc``/``.blf``/``.csv``/``.trc`` file (the format from its content).

    Blocking: run it in a thread (``run.io_bound``, or :func:`load_log` from the loop).

    :param progress: ``progress(frames, fraction)`` every :data:`PROGRESS_FRAMES` frames (reading thread)
    :param cancel: set to stop early (the frames read so far are returned, ``truncated``)
    :raises RecordingError: unsupported or malformed file, saying where and why; or no frames in it
    """
    path = Path(path)
    name = name or path.name
    loaded = LoadedLog(name)
    fmt = file_format(path, name)
    loaded.format = fmt
    with contextlib.closing(iter_log(path, name, PROGRESS_FRAMES, progress, cancel)) as chunks:
        for chunk in chunks:
            room = limit - len(loaded.frames)
            if len(chunk) > room:  # (a chunk after the limit was reached has room 0)
                loaded.frames.extend(chunk[:room])
                loaded.truncated = True
                break
            loaded.frames.extend(chunk)
        else:
            loaded.truncated = cancel is not None and cancel.is_set()
    if not loaded.frames:
        raise RecordingError(Message(N_("{name}: no CAN frames found in this {format} file"), name=name, format=fmt))
    return loaded


async def load_log(
    path: str | Path, name: str | None = None, limit: int = MAX_FILE_FRAMES,
    progress: Progress | None = None, cancel: threading.Event | None = None,
) -> LoadedLog:
    """:func:`read_log` in a thread; ``progress(frames, fraction)`` is called on the event loop.

    For the monitor: show the fraction while a large file loads, then page through
    :meth:`LoadedLog.page`. Set ``cancel`` (e.g. when the page closes) to stop reading.
    """
    loop = asyncio.get_running_loop()

    def report(frames: int, fraction: float) -> None:
        if progress is not None:
            loop.call_soon_threadsafe(progress, frames, fraction)

    return await asyncio.to_thread(read_log, path, name, limit, report if progress else None, cancel)
