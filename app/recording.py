"""CAN bus recordings and the pure helpers of the bus monitor.

A recording is a python-can writer (candump ``.log``, Vector ``.asc``, ``.blf``,
``.csv``, PEAK ``.trc``) attached to :attr:`app.can_bus.CanBusState.recorder`; the bus feeds it every
frame it records (received and sent). Starting and stopping happen in the event loop,
the same thread that feeds the writer, so no frame reaches a closed file. Recorded files
are read back with python-can's readers into :class:`~app.can_bus.FrameRecord` rows; the
format is taken from the file's content (:func:`detect_format`), the suffix only when the
content does not tell, and a file that cannot be read names the line (text formats) or
byte offset (BLF) where reading stopped. Recordings live in the data folder, beside the
backups and the audit log (:func:`recordings_dir`).

Decoding and filtering are plain functions of ``(arbitration_id, is_extended, data)``
that ask the device codecs (``describe_frame``) and the device adapters
(``owns_frame``), which also name the device that sent or answered a frame. Modbus
transactions are decoded through the parameter model of the device at their unit
(:class:`TransactionDecoder`). No UI here.
"""

from __future__ import annotations

import asyncio
import contextlib
import importlib
import io
import itertools
import logging
import math
import os
import queue
import re
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from types import ModuleType
from typing import Any

import can
from can.io.asc import ASCReader, ASCWriter
from can.io.blf import BLFReader, BLFWriter
from can.io.canutils import CanutilsLogReader, CanutilsLogWriter
from can.io.csv import CSVReader, CSVWriter
from can.io.trc import TRCReader, TRCWriter
from can.util import channel2int

from app.can_bus import CanBusState, FrameRecord
from devices.adapter import FrameDescriber, FrameOwner
from devices.params import ParamMap
from devices.registry import DEVICE_TYPES

# suffix -> (writer class, what the engineer sees in the format select)
WRITERS: dict[str, tuple[type[can.io.generic.MessageWriter], str]] = {
    ".log": (CanutilsLogWriter, "candump .log"),
    ".asc": (ASCWriter, "Vector .asc"),
    ".blf": (BLFWriter, "Vector .blf"),
    ".csv": (CSVWriter, "python-can .csv"),
    ".trc": (TRCWriter, "PEAK .trc"),
}
READERS: dict[str, type[can.io.generic.MessageReader]] = {
    ".log": CanutilsLogReader, ".asc": ASCReader, ".blf": BLFReader, ".csv": CSVReader, ".trc": TRCReader,
}
READ_SUFFIXES = tuple(READERS)  # what python-can reads without extras
SNIFF_BYTES = 4096  # the head of a file looked at to tell its format
PROGRESS_FRAMES = 5_000  # frames between two progress reports while reading a file
MAX_FILE_FRAMES = 200_000  # frames kept of an opened file (memory bound)
MAX_CACHE = 20_000  # decoded texts kept per decoder
DIR_ENV = "COMMISSION_RECORDINGS_DIR"
UNKNOWN = "unknown"

logger = logging.getLogger(__name__)

Key = tuple[bool, int]


class RecordingError(Exception):
    """A recording that cannot be started, or a file that cannot be read; the message says why."""


# -- recording the bus ----------------------------------------------------------------------------


RECORDINGS_SUBDIR = "recordings"


def recordings_dir(directory: str | Path | None = None) -> Path:
    """Where recordings go: ``directory``, else ``$COMMISSION_RECORDINGS_DIR``, else the folder
    ``recordings`` in the data folder of the running plant (beside ``backups`` and the audit log),
    else in the user's data folder; never the current working directory."""
    if directory is not None:
        return Path(directory)
    if os.environ.get(DIR_ENV):
        return Path(os.environ[DIR_ENV])
    from app import runtime  # noqa: PLC0415 - the running plant's data folder; runtime imports much of app/
    from app.users import default_data_dir  # noqa: PLC0415

    try:
        base = runtime.current().data_dir
    except RuntimeError:  # no plant is running (a command-line tool)
        base = default_data_dir()
    return Path(base) / RECORDINGS_SUBDIR


UPLOADS_SUBDIR = "uploads"  # uploaded recordings, inside the recordings folder
UPLOADS_KEPT = 3  # the newest uploaded recordings kept; older ones are deleted when another arrives


def upload_name(name: str | None) -> str:
    """A browser's file name made safe to create: its last path component, at most 120 characters.

    :raises RecordingError: nothing usable is left (``..``, ``.``, a hidden or empty name)
    """
    base = re.split(r"[\\/]", name or "")[-1].strip().replace("\0", "")
    if base in ("", ".", "..") or base.startswith("."):
        raise RecordingError(f"{(name or '')[:60]!r} is not a file name for a recording (e.g. trace.log)")
    return base[-120:]


_UPLOAD_SERIAL = itertools.count(1)


async def store_upload(upload: Any, directory: str | Path | None = None) -> Path:
    """An uploaded recording (NiceGUI's ``FileUpload``) saved into the one uploads folder of the
    recordings folder, streamed (never read whole into memory), under a safe unique name; only the
    newest :data:`UPLOADS_KEPT` uploads are kept, so no folder or file is left behind per upload.

    :raises RecordingError: the file name is unusable, or the file cannot be written
    """
    name = upload_name(getattr(upload, "name", ""))
    folder = recordings_dir(directory) / UPLOADS_SUBDIR
    path = folder / f"{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}-{next(_UPLOAD_SERIAL):06d}-{name}"
    try:
        await asyncio.to_thread(folder.mkdir, parents=True, exist_ok=True)
        await upload.save(path)
    except OSError as exc:
        await asyncio.to_thread(path.unlink, missing_ok=True)
        raise RecordingError(f"{name}: cannot store the upload: {exc.strerror or exc}") from None
    await asyncio.to_thread(_prune_uploads, folder, keep=path)
    return path


def _prune_uploads(folder: Path, keep: Path) -> None:
    files = sorted((p for p in folder.iterdir() if p.is_file()), key=lambda p: (p.stat().st_mtime_ns, p.name), reverse=True)
    for old in [p for p in files if p != keep][UPLOADS_KEPT - 1:]:
        try:
            old.unlink()
        except OSError as exc:
            logger.warning("cannot remove the old upload %s: %s", old, exc)


RECORD_QUEUE = 200_000  # frames waiting for the disk (about 20 s of a full 1 Mbit/s bus)


class Recording(can.Listener):
    """A python-can writer fed through a queue and written by a thread of its own.

    Set as ``CanBusState.recorder``; :class:`app.can_bus.CanBus` calls
    :meth:`on_message_received` for every frame in the event loop, which only queues the
    frame: a slow or full disk never holds up the loop (and with it every keep-alive).
    Frames that do not fit the queue are counted in ``dropped``.
    """

    def __init__(self, bus: str, path: Path, writer: can.io.generic.MessageWriter):
        self.bus = bus
        self.path = path
        self.suffix = path.suffix
        self.writer = writer
        self.started = time.time()
        self.stopped: float | None = None
        self.frames = 0
        self.dropped = 0
        self.error = ""
        self._channel_ok: dict[Any, bool] = {}  # msg.channel -> the writer can take it as it is
        self._queue: queue.Queue = queue.Queue(maxsize=RECORD_QUEUE)
        self._thread = threading.Thread(target=self._write_loop, name=f"recording {bus}", daemon=True)
        self._thread.start()

    def _usable_channel(self, channel: Any) -> bool:
        """Whether the writer can store ``channel``; others are replaced by the writer's default.

        candump lines are split on white space, so a channel name with blanks breaks them;
        ASC/BLF take the number at the end of a channel name ("can1", "PCAN_USBBUS1"), and a
        long number there (a virtual channel "test-20240101") does not fit their channel field.
        """
        ok = self._channel_ok.get(channel)
        if ok is None:
            if channel is None:
                ok = True
            elif self.suffix == ".log":
                ok = isinstance(channel, int) or (isinstance(channel, str) and bool(channel) and not any(c.isspace() for c in channel))
            elif self.suffix == ".trc":
                # one bus per file, all on bus 1: TRCWriter numbers a channel it can read from 1 up ("demo-can1"
                # became bus 2) and a frame without one (what this tool sent) goes to bus 1
                ok = False
            elif self.suffix in (".asc", ".blf"):
                number = channel2int(channel)
                ok = number is None or 0 <= number < 255
            else:
                ok = True
            if len(self._channel_ok) < 64:
                self._channel_ok[channel] = ok
        return ok

    def on_message_received(self, msg: can.Message) -> None:
        """Queue one frame (event loop; O(1), never blocks); raises once the file has failed."""
        if self.error:
            raise RecordingError(f"{self.path.name}: {self.error}")
        if self.stopped is not None:
            return
        try:
            self._queue.put_nowait(msg)
        except queue.Full:
            self.dropped += 1

    def _write_loop(self) -> None:
        while True:
            msg = self._queue.get()
            if msg is None:
                break
            if self.error:
                continue  # the file failed: drain the queue, write nothing more
            if not self._usable_channel(msg.channel):
                msg = can.Message(
                    timestamp=msg.timestamp, arbitration_id=msg.arbitration_id, is_extended_id=msg.is_extended_id,
                    is_remote_frame=msg.is_remote_frame, is_error_frame=msg.is_error_frame, dlc=msg.dlc,
                    data=msg.data, is_rx=msg.is_rx, channel=None, check=False,
                )
            try:
                self.writer.on_message_received(msg)
            except Exception as exc:  # noqa: BLE001 - disk full, file gone: the recording ends and says why
                self.error = str(exc) or exc.__class__.__name__
                self.stopped = self.stopped or time.time()
                continue
            self.frames += 1
        try:
            self.writer.stop()
        except Exception as exc:  # noqa: BLE001 - a failing close must not hide that the recording ended
            self.error = self.error or f"closing {self.path.name} failed: {exc}"

    @property
    def active(self) -> bool:
        return self.stopped is None

    @property
    def elapsed(self) -> float:
        return (self.stopped or time.time()) - self.started

    @property
    def size(self) -> int:
        try:
            return self.path.stat().st_size
        except OSError:
            return 0

    def close(self, timeout: float = 30.0) -> None:
        """Write what is queued, flush and close the file (idempotent; waits for the writer
        thread, so call it through a thread from the event loop)."""
        if self.stopped is None:
            self.stopped = time.time()
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join(timeout)

    def stop(self) -> None:  # can.Listener API
        self.close()


def _safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._") or "bus"


def _writer_channel(options: dict[str, Any] | None) -> str:
    channel = str((options or {}).get("channel", "can0"))
    return channel if channel and not any(c.isspace() for c in channel) else "can0"


def active_recording(state: CanBusState) -> Recording | None:
    recorder = state.recorder
    return recorder if isinstance(recorder, Recording) and recorder.active else None


def start_recording(
    state: CanBusState,
    suffix: str,
    directory: str | Path | None = None,
    bus_options: dict[str, Any] | None = None,
) -> Recording:
    """Open a new file ``<bus>-<date>-<time>.<suffix>`` and attach it to the bus.

    Creates a file: from the event loop, call it through a thread.

    :param suffix: ``.log``, ``.asc``, ``.blf``, ``.csv`` or ``.trc``
    :param directory: the folder; default :func:`recordings_dir` (the data folder's ``recordings``)
    :param bus_options: the bus's plant options; its channel names frames without one in ``.log``
    :raises RecordingError: unknown format, a recording already running, or the file cannot be created
    """
    suffix = suffix if suffix.startswith(".") else f".{suffix}"
    suffix = suffix.lower()
    if suffix not in WRITERS:
        raise RecordingError(f"cannot record to {suffix!r}: choose one of {', '.join(WRITERS)}")
    if active_recording(state) is not None:
        raise RecordingError(f"{state.name} is being recorded already ({state.recorder.path.name})")
    folder = recordings_dir(directory)
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{_safe_name(state.name)}-{stamp}{suffix}"
        n = 1
        while path.exists():
            n += 1
            path = folder / f"{_safe_name(state.name)}-{stamp}-{n}{suffix}"
        writer_class = WRITERS[suffix][0]
        if writer_class is CanutilsLogWriter:
            writer = writer_class(path, channel=_writer_channel(bus_options))
        else:
            writer = writer_class(path)
    except OSError as exc:
        raise RecordingError(f"cannot create a recording in {folder}: {exc.strerror or exc}") from None
    recording = Recording(state.name, path, writer)
    state.recorder = recording
    return recording


def stop_recording(state: CanBusState) -> Recording | None:
    """Detach the recording from the bus, then flush and close its file; None if none ran.

    Waits until the file is complete: from the event loop, call it through a thread.
    """
    recorder = state.recorder
    state.recorder = None
    if isinstance(recorder, Recording):
        recorder.close()
        return recorder
    if recorder is not None:  # some other python-can listener: stop it all the same
        try:
            recorder.stop()
        except Exception as exc:  # noqa: BLE001 - not ours; it is detached either way
            logger.debug("%s: stopping recorder %r failed: %s", state.name, recorder, exc)
    return None


@dataclass(frozen=True)
class RecordingFile:
    name: str
    path: Path
    size: int
    mtime: float


def list_recordings(directory: str | Path | None = None) -> list[RecordingFile]:
    """Files of a readable format in the recordings folder, newest first."""
    folder = recordings_dir(directory)
    found = []
    try:
        entries = list(folder.iterdir())
    except OSError:
        return []
    for path in entries:
        if path.suffix.lower() not in READ_SUFFIXES or not path.is_file():
            continue
        try:
            st = path.stat()
        except OSError:
            continue
        found.append(RecordingFile(path.name, path, st.st_size, st.st_mtime))
    return sorted(found, key=lambda f: (f.mtime, f.name), reverse=True)


def recording_path(name: str, directory: str | Path | None = None) -> Path:
    """The file ``name`` in the recordings folder (no path tricks)."""
    folder = recordings_dir(directory).resolve()
    path = (folder / name).resolve()
    if path.parent != folder or not path.is_file():
        raise RecordingError(f"no recording named {name!r} in {folder}")
    return path


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


class _CountingText(io.TextIOBase):
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

    def readable(self) -> bool:
        return True

    @property
    def name(self) -> str:
        return getattr(self._file, "name", "")

    def close(self) -> None:
        self._file.close()
        super().close()

    def where(self) -> str:
        return f"line {self.line}"

    @property
    def done(self) -> int:
        return self.chars


class _CountingBinary(io.RawIOBase):
    """A binary file handed to python-can's BLF reader, counting the bytes it took."""

    def __init__(self, file: io.BufferedIOBase):
        self._file = file
        self.offset = 0

    def read(self, size: int = -1) -> bytes:
        data = self._file.read(size)
        self.offset += len(data)
        return data

    def readable(self) -> bool:
        return True

    def seek(self, offset: int, whence: int = 0) -> int:
        self.offset = self._file.seek(offset, whence)
        return self.offset

    def tell(self) -> int:
        return self.offset

    @property
    def name(self) -> str:
        return getattr(self._file, "name", "")

    def close(self) -> None:
        self._file.close()
        super().close()

    def where(self) -> str:
        return f"byte offset {self.offset}"

    @property
    def done(self) -> int:
        return self.offset


Progress = Callable[[int, float], None]  # (frames read so far, fraction of the file read 0..1)


def _record_of(msg: can.Message) -> FrameRecord:
    """A frame of a file, checked: a time that is a number, an ID that fits its width, at most 64 data bytes.

    :raises ValueError: naming what is wrong (the reader adds where)
    """
    if not math.isfinite(float(msg.timestamp)):
        raise ValueError(f"time stamp {msg.timestamp!r} is not a number")
    limit = 0x1FFFFFFF if msg.is_extended_id else 0x7FF
    if not 0 <= int(msg.arbitration_id) <= limit:
        raise ValueError(f"CAN ID 0x{int(msg.arbitration_id):X} does not fit {'29' if msg.is_extended_id else '11'} bits")
    if len(msg.data) > 64:
        raise ValueError(f"{len(msg.data)} data bytes (a CAN FD frame holds at most 64)")
    return FrameRecord(
        float(msg.timestamp), int(msg.arbitration_id), bool(msg.is_extended_id), int(msg.dlc),
        bytes(msg.data), "rx" if msg.is_rx else "tx", bool(msg.is_error_frame), bool(msg.is_remote_frame),
    )


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
        raise RecordingError(f"{name}: cannot open: {exc.strerror or exc}") from None
    found = detect_format(head)
    if found is not None:
        return found
    suffix = path.suffix.lower()
    if suffix in READERS:
        return suffix
    raise RecordingError(f"{name}: unsupported file type {suffix or '(none)'} and the content is not a recording "
                         f"python-can reads; readable are {', '.join(READ_SUFFIXES)}")


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
        raise RecordingError(f"{name}: cannot open: {exc.strerror or exc}") from None
    counted: _CountingText | _CountingBinary = _CountingBinary(raw) if fmt == ".blf" else _CountingText(raw)
    frames = 0
    try:
        try:
            reader = READERS[fmt](counted)
        except Exception as exc:  # noqa: BLE001 - ValueError, BLFParseError, UnicodeDecodeError ... from the readers
            raise RecordingError(f"{name}: cannot open as {fmt} file ({counted.where()}): {exc}") from None
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
        except Exception as exc:  # noqa: BLE001 - a malformed line/object: say where it stopped and why
            raise RecordingError(
                f"{name}: not a valid {fmt} file at {counted.where()} (after {frames + len(chunk)} frames): "
                f"{exc or exc.__class__.__name__}") from None
        if chunk:
            frames += len(chunk)
            yield chunk
        if progress is not None:
            progress(frames, 1.0)
    finally:
        try:
            counted.close()
        except Exception as exc:  # noqa: BLE001 - closing a broken file may fail too
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
        raise RecordingError(f"{name}: no CAN frames found in this {fmt} file")
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


# -- decoding -------------------------------------------------------------------------------------------


def can_codecs(prefer: Iterable[str] = ()) -> list[ModuleType]:
    """The codec modules of every device type that speaks CAN, those named in ``prefer`` first.

    Device types reuse small standard IDs (an Electrak's service response 0x0B is an
    HD-Lock's device ID 11), so the types present on a bus are asked before the others.
    """
    prefer = set(prefer)
    types = [dt for dt in DEVICE_TYPES.values() if dt.can_codec and "can" in dt.bus_types]
    types.sort(key=lambda dt: dt.name not in prefer)  # stable: registry order otherwise
    return [importlib.import_module(dt.can_codec) for dt in types]


class AdapterDescriber:
    """A device adapter whose frame IDs follow from its configuration (e.g. an M3IO's SW1),
    asked like a codec module."""

    def __init__(self, adapter: Any):
        self.adapter = adapter

    def __eq__(self, other: object) -> bool:
        return isinstance(other, AdapterDescriber) and other.adapter is self.adapter

    def __hash__(self) -> int:
        return id(self.adapter)

    def describe_frame(self, arbitration_id: int, is_extended: bool, data: bytes, known_ids: set[Key]) -> str | None:
        return self.adapter.describe_frame(arbitration_id, is_extended, data)


def describers(worker: Any, bus: str, types_on_bus: Iterable[str]) -> list[Any]:
    """What decodes frames on a bus: adapters that know their own IDs, then the device codecs."""
    adapters = [
        AdapterDescriber(worker.adapters[d.name])
        for d in worker.plant.devices_on(bus)
        if isinstance(worker.adapters.get(d.name), FrameDescriber)
    ]
    return adapters + can_codecs(types_on_bus)


def describe(arbitration_id: int, is_extended: bool, data: bytes, known_ids: set[Key], codecs: Iterable[ModuleType] | None = None) -> str:
    """The first device codec's meaning of a frame, else ``"unknown"``."""
    for codec in can_codecs() if codecs is None else codecs:
        try:
            text = codec.describe_frame(arbitration_id, is_extended, data, known_ids)
        except Exception as exc:  # noqa: BLE001 - a codec bug must not take the monitor down
            return f"decode failed: {exc}"
        if text is not None:
            return text
    return UNKNOWN


class FrameDecoder:
    """:func:`describe` with the codecs resolved once and a bounded cache of texts; with
    ``owners`` (:func:`device_owners`) it also names the device of a frame (:meth:`device`)."""

    def __init__(self, known_ids: set[Key] | None = None, codecs: Iterable[ModuleType] | None = None,
                 owners: Iterable[tuple[str, Owner]] = ()):
        self.known_ids: set[Key] = set(known_ids or ())
        self.codecs = list(can_codecs() if codecs is None else codecs)
        self.owners: list[tuple[str, Owner]] = list(owners)
        self._cache: dict[tuple[bool, int, bytes], str] = {}
        self._devices: dict[tuple[bool, int, bytes], str] = {}

    def set_owners(self, owners: Iterable[tuple[str, Owner]]) -> None:
        owners = list(owners)
        if [name for name, _ in owners] != [name for name, _ in self.owners]:
            self._devices.clear()
        self.owners = owners

    def device(self, arbitration_id: int, is_extended: bool, data: bytes) -> str:
        """The plant name(s) of the device(s) a frame comes from or is addressed to, else ``""``."""
        key = (is_extended, arbitration_id, data)
        name = self._devices.get(key)
        if name is None:
            if len(self._devices) >= MAX_CACHE:
                self._devices.clear()
            name = self._devices[key] = device_of(self.owners, arbitration_id, is_extended, data)
        return name

    def record_device(self, rec: FrameRecord) -> str:
        if rec.is_error_frame:
            return ""
        return self.device(rec.arbitration_id, rec.is_extended_id, b"" if rec.is_remote_frame else rec.data)

    def set_codecs(self, codecs: Iterable[ModuleType]) -> None:
        codecs = list(codecs)
        if codecs != self.codecs:
            self.codecs = codecs
            self._cache.clear()

    def set_known_ids(self, known_ids: set[Key]) -> None:
        if known_ids != self.known_ids:
            self.known_ids = set(known_ids)
            self._cache.clear()
            self._devices.clear()  # a device ID changed (Set Device Address) or a device was adopted

    def __call__(self, arbitration_id: int, is_extended: bool, data: bytes) -> str:
        key = (is_extended, arbitration_id, data)
        text = self._cache.get(key)
        if text is None:
            if len(self._cache) >= MAX_CACHE:
                self._cache.clear()
            text = self._cache[key] = describe(arbitration_id, is_extended, data, self.known_ids, self.codecs)
        return text

    def record(self, rec: FrameRecord) -> str:
        if rec.is_error_frame:
            return "error frame"
        if rec.is_remote_frame:
            meaning = self(rec.arbitration_id, rec.is_extended_id, b"")
            return "remote request" + ("" if meaning == UNKNOWN else f" ({meaning})")
        return self(rec.arbitration_id, rec.is_extended_id, rec.data)


def ids_of_devices(frames: Iterable[FrameRecord], codecs: Iterable[ModuleType] | None = None) -> set[Key]:
    """IDs in a recorded file that some codec recognises as a device (its ``discovered`` hook)."""
    codecs = list(can_codecs() if codecs is None else codecs)
    hooks = [c.discovered for c in codecs if callable(getattr(c, "discovered", None))]
    found: set[Key] = set()
    for rec in frames:
        key = (rec.is_extended_id, rec.arbitration_id)
        if key in found or rec.is_error_frame or rec.is_remote_frame:
            continue
        for hook in hooks:
            try:
                if hook(rec.arbitration_id, rec.is_extended_id, rec.data):
                    found.add(key)
                    break
            except Exception:  # noqa: BLE001, S112 - a frame a hook cannot parse is simply not a device
                continue
    return found


# -- filters and formatting ---------------------------------------------------------------------------


def parse_id(text: str | None) -> int | None:
    """A CAN ID typed as hex (``704``, ``0x704``, ``A1284``); None for empty.

    :raises ValueError: not a hex number or above 0x1FFFFFFF
    """
    text = (text or "").strip().replace("_", "")
    if not text:
        return None
    value = int(text, 16)
    if not 0 <= value <= 0x1FFFFFFF:
        raise ValueError(f"{text} is not a CAN ID (0..1FFFFFFF)")
    return value


Owner = Callable[[int, bool, bytes], bool]


def owner_of(adapter: Any) -> Owner:
    """``adapter.owns_frame``, or a filter that matches nothing for adapters without it."""
    if not isinstance(adapter, FrameOwner):
        return lambda _id, _ext, _data: False
    owns = adapter.owns_frame

    def safe(arbitration_id: int, is_extended: bool, data: bytes) -> bool:
        try:
            return bool(owns(arbitration_id, is_extended, data))
        except Exception:  # noqa: BLE001 - a frame the adapter cannot parse is not its frame
            return False

    return safe


MAX_DEVICE_NAMES = 3  # a broadcast request names at most this many devices, then counts the rest


def device_owners(worker: Any, bus: str) -> list[tuple[str, Owner]]:
    """``(plant name, owner)`` for every device on a CAN bus.

    The owner is the adapter's ``owns_frame`` (frames it sends and requests addressed to it),
    else the CAN IDs its device type declares for it (``DeviceType.can_id_uses``).
    """
    owners: list[tuple[str, Owner]] = []
    for dev in worker.plant.devices_on(bus):
        adapter = worker.adapters.get(dev.name)
        if isinstance(adapter, FrameOwner):
            owners.append((dev.name, owner_of(adapter)))
            continue
        device_type = DEVICE_TYPES.get(dev.type)
        uses = device_type.can_id_uses(dev.options, "can") if device_type is not None else ()
        if uses:
            owners.append((dev.name, lambda can_id, ext, _data, uses=uses: any(u.covers(ext, can_id) for u in uses)))
    return owners


def device_of(owners: Iterable[tuple[str, Owner]], arbitration_id: int, is_extended: bool, data: bytes) -> str:
    """The names of the devices that own a frame (one, or several for a broadcast), else ``""``."""
    names = [name for name, owns in owners if owns(arbitration_id, is_extended, data)]
    if len(names) > MAX_DEVICE_NAMES:
        return ", ".join(names[:MAX_DEVICE_NAMES]) + f" +{len(names) - MAX_DEVICE_NAMES}"
    return ", ".join(names)


# -- Modbus transactions ------------------------------------------------------------------------------

MAX_DECODED_REGISTERS = 16  # registers named in one transaction's text; the rest are counted


def describe_registers(params: ParamMap, space: str, address: int, values: Iterable[int]) -> str:
    """Registers from ``address`` on as ``Name = value`` through the parameter model (signed, scaled,
    enum and bit names, unit); a value of several words is joined; unlisted registers by number."""
    values = [int(v) & 0xFFFF for v in values]
    parts: list[str] = []
    i = 0
    while i < len(values) and len(parts) < MAX_DECODED_REGISTERS:
        addr = address + i
        param = params.get(space, addr)
        if param is not None and param.words > 1 and i + param.words <= len(values):
            raw = param.combine(values[i:i + param.words])
            parts.append(f"{param.label or param.name} = {param.display(raw)}")
            i += param.words
            continue
        if param is not None and param.words == 1:
            parts.append(f"{param.label or param.name} = {param.display(values[i])}")
        elif param is not None:
            parts.append(f"{param.label or param.name} (first word) = {values[i]}")
        else:
            whole = next((p for p in params.space(space) if addr in p.addresses), None)
            parts.append(f"{whole.label or whole.name} (word {addr - whole.address + 1} of {whole.words}) = {values[i]}"
                         if whole is not None else f"{space} {addr} = {values[i]}")
        i += 1
    if i < len(values):
        parts.append(f"... {len(values) - i} more")
    return "; ".join(parts)


class TransactionDecoder:
    """Names the device at a Modbus unit and decodes a transaction through its parameter model.

    The unit of a device is its adapter's current ``address`` (it follows a Set Modbus Address),
    else its type's ``bus_identity``. A unit no configured device has (a line scan) is decoded with
    the parameter model of the line's device type when the line carries one type only.
    """

    def __init__(self, worker: Any, bus: str):
        self.worker = worker
        self.bus = bus
        self.units: dict[int, tuple[str, ParamMap | None]] = {}
        self.line_params: ParamMap | None = None
        self._cache: dict[tuple, str] = {}
        self.refresh()

    def refresh(self) -> None:
        """Read the units again (an address may have changed)."""
        bus_config = self.worker.plant.buses.get(self.bus)
        bus_type = bus_config.type if bus_config is not None else "modbus-rtu"
        units: dict[int, tuple[str, ParamMap | None]] = {}
        types: set[str] = set()
        for dev in self.worker.plant.devices_on(self.bus):
            device_type = DEVICE_TYPES.get(dev.type)
            types.add(dev.type)
            unit = getattr(self.worker.adapters.get(dev.name), "address", None)
            if not isinstance(unit, int) and device_type is not None:
                unit = device_type.bus_identity(dev.options, bus_type)
            if isinstance(unit, int):
                units[unit] = (dev.name, device_type.params if device_type is not None else None)
        line_params = DEVICE_TYPES[next(iter(types))].params if len(types) == 1 and next(iter(types)) in DEVICE_TYPES else None
        self.modbus = bus_type == "modbus-rtu"
        names = [dev.name for dev in self.worker.plant.devices_on(self.bus)]
        self.only = names[0] if len(names) == 1 and not self.modbus else ""  # a point-to-point line or a TCP link
        if units != self.units or line_params is not self.line_params:
            self.units, self.line_params = units, line_params
            self._cache.clear()

    def device(self, unit: int) -> str:
        """``door-1 (unit 1)``; ``broadcast (unit 0)``; ``unit 7`` for an address no device has.

        Other lines name their device by its bus address (``barrier-out-1 (address 16)``), or name
        the one device of a point-to-point line or TCP link.
        """
        if self.only:
            return self.only
        if not self.modbus:
            return f"{self.units[unit][0]} (address {unit})" if unit in self.units else (f"address {unit}" if unit else "")
        if unit in self.units:
            return f"{self.units[unit][0]} (unit {unit})"
        if unit in (0, 255):  # Modbus broadcast 0; 255 broadcast of the HD-Lock's Set Modbus Address (section 4.3)
            return f"broadcast (unit {unit})"
        return f"unit {unit}"

    def decoded(self, t: Any) -> str:
        """The transaction's registers by name and value, else the line's own text."""
        if getattr(t, "error", "") or not getattr(t, "space", "") or getattr(t, "address", None) is None or not t.values:
            return t.decoded
        params = self.units[t.unit][1] if t.unit in self.units else self.line_params
        if params is None:
            return t.decoded
        write = "write" in t.request.split()
        key = (t.unit, t.space, t.address, t.values, write)
        text = self._cache.get(key)
        if text is None:
            if len(self._cache) >= MAX_CACHE:
                self._cache.clear()
            try:
                body = describe_registers(params, t.space, t.address, t.values)
            except Exception as exc:  # noqa: BLE001 - a model bug must not take the monitor down
                body = f"decode failed: {exc}"
            text = self._cache[key] = ("wrote " if write else "") + body
        return text


@dataclass
class FrameFilter:
    """ID range (inclusive, either end open) and/or a device's frames, or only error frames."""

    id_min: int | None = None
    id_max: int | None = None
    owner: Owner | None = None
    errors_only: bool = False

    @property
    def active(self) -> bool:
        return self.id_min is not None or self.id_max is not None or self.owner is not None or self.errors_only

    def matches(self, arbitration_id: int, is_extended: bool, data: bytes, is_error_frame: bool = False) -> bool:
        if self.errors_only and not is_error_frame:
            return False
        if self.id_min is not None and arbitration_id < self.id_min:
            return False
        if self.id_max is not None and arbitration_id > self.id_max:
            return False
        return self.owner is None or (not is_error_frame and self.owner(arbitration_id, is_extended, data))

    def matches_record(self, rec: FrameRecord) -> bool:
        return self.matches(rec.arbitration_id, rec.is_extended_id, rec.data, rec.is_error_frame)


def newest(frames: Iterable[FrameRecord], flt: FrameFilter, limit: int) -> list[FrameRecord]:
    """The newest ``limit`` frames that match, newest first (frames in arrival order).

    Walks from the end, so the cost is bounded by the buffer, not by the traffic.
    """
    result: list[FrameRecord] = []
    source: Iterator[FrameRecord] = reversed(frames) if hasattr(frames, "__reversed__") else reversed(list(frames))
    if not flt.active:
        for rec in source:
            result.append(rec)
            if len(result) >= limit:
                break
        return result
    for rec in source:
        if flt.matches_record(rec):
            result.append(rec)
            if len(result) >= limit:
                break
    return result


def format_id(arbitration_id: int, is_extended: bool) -> str:
    """``0x704`` (standard) or ``0x000A1284 (ext)``."""
    return f"0x{arbitration_id:08X} (ext)" if is_extended else f"0x{arbitration_id:03X}"


def format_data(data: bytes) -> str:
    return data.hex(" ").upper()


def format_time(t: float, relative_to: float | None = None) -> str:
    """Clock time with milliseconds, or seconds since ``relative_to``."""
    if relative_to is not None:
        return f"{t - relative_to:.3f}"
    try:
        return datetime.fromtimestamp(t).strftime("%H:%M:%S.%f")[:-3]
    except (OverflowError, OSError, ValueError):
        return f"{t:.3f}"


def changed_bytes(data: bytes, changed: int) -> list[tuple[str, bool]]:
    """Each byte as hex with whether it changed since the previous frame of its ID."""
    return [(f"{b:02X}", bool(changed >> i & 1)) for i, b in enumerate(data)]
