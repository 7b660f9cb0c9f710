"""Recording a CAN bus into a file (python-can writers fed by the bus), the recordings folder and
uploaded recordings."""

from __future__ import annotations

import asyncio
import itertools
import logging
import os
import queue
import re
import threading
import time
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

import can
from can.io.canutils import CanutilsLogWriter
from can.util import channel2int

from app.can_bus import CanBusState
from app.i18n import N_
from app.message import Message
from app.recording.base import DIR_ENV, READ_SUFFIXES, WRITERS, RecordingError

logger = logging.getLogger("app.recording")  # one logger for the recordings, as before the split


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
        raise RecordingError(Message(N_("{name!r} is not a file name for a recording (e.g. trace.log)"), name=(name or "")[:60]))
    return base[-120:]


_UPLOAD_SERIAL = itertools.count(1)


async def store_upload(upload: Any, directory: str | Path | None = None) -> Path:
    """An uploaded recording (NiceGUI's ``FileUpload``) saved into the one uploads folder of the
    recordings folder, streamed (never read whole into memory), under a safe unique name; only the
    newest :data:`UPLOADS_KEPT` uploads are kept, so no folder or file is left behind per upload.

    :raises RecordingError: the file name is unusable, or the file cannot be written
    """
    name = upload_name(upload.name)
    folder = recordings_dir(directory) / UPLOADS_SUBDIR
    path = folder / f"{time.strftime('%Y%m%d-%H%M%S')}-{os.getpid()}-{next(_UPLOAD_SERIAL):06d}-{name}"
    try:
        await asyncio.to_thread(folder.mkdir, parents=True, exist_ok=True)
        await upload.save(path)
    except OSError as exc:
        await asyncio.to_thread(path.unlink, missing_ok=True)
        raise RecordingError(Message(N_("{name}: cannot store the upload: {error}"), name=name,
                                     error=exc.strerror or str(exc))) from None
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
            raise RecordingError(Message("{name}: {error}", name=self.path.name, error=self.error))
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
            except (OSError, ValueError) as exc:  # disk full, file gone or closed: the recording ends and says why
                self.error = str(exc) or exc.__class__.__name__
                self.stopped = self.stopped or time.time()
                continue
            self.frames += 1
        try:
            self.writer.stop()
        except (OSError, ValueError) as exc:  # a failing close must not hide that the recording ended
            self.error = self.error or Message(N_("closing {name} failed: {error}"), name=self.path.name, error=str(exc))

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
        raise RecordingError(Message(N_("cannot record to {suffix!r}: choose one of {formats}"), suffix=suffix,
                                     formats=", ".join(WRITERS)))
    if active_recording(state) is not None:
        raise RecordingError(Message(N_("{bus} is being recorded already ({file})"), bus=state.name,
                                     file=state.recorder.path.name))
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
        raise RecordingError(Message(N_("cannot create a recording in {folder}: {error}"), folder=folder,
                                     error=exc.strerror or str(exc))) from None
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
        except (can.CanError, OSError, ValueError) as exc:  # not ours; it is detached either way
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
        raise RecordingError(Message(N_("no recording named {name!r} in {folder}"), name=name, folder=folder))
    return path
