"""Files a user names (backups, parameter sets, projects, password files): read only when they are
regular files, and only up to a size, before a byte is read.

``/dev/zero`` would be read until the memory runs out and a FIFO would block for ever; a directory
is no file. :func:`read_regular` refuses each with a message that says what the path is and what to
give instead, as an :class:`OSError` (callers already report those with the path).
"""

from __future__ import annotations

import errno
import os
import stat
import tempfile
from pathlib import Path

from app import host
from devices.errors import CommissionError

MAX_DOCUMENT_BYTES = 32 * 1024 * 1024  # a backup or parameter file; the largest real ones are a few hundred KiB
MAX_SECRET_BYTES = 64 * 1024  # a password file


class FileRefused(CommissionError, OSError):
    """A named file that is not read: not a regular file, or too large. ``str()`` is the whole message."""

    def __init__(self, path: str | Path, message: str):
        super().__init__(errno.EINVAL, message)
        self.path, self.message = str(path), message
        self.strerror = message

    def __str__(self) -> str:
        return self.message


def kind_of(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def read_regular(path: str | Path, limit: int = MAX_DOCUMENT_BYTES, what: str = "file") -> bytes:
    """The bytes of ``path`` if it is a regular file (a link to one is followed) of at most ``limit``
    bytes; else :class:`FileRefused` (or the :class:`OSError` of a missing or unreadable file).

    Opened without blocking (a FIFO with no writer does not hang the open) and checked on the open
    descriptor, so the file checked is the file read."""
    path = Path(path)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | getattr(os, "O_CLOEXEC", 0))
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise FileRefused(path, f"{path}: {kind_of(info.st_mode)}, not a regular file: give the {what} itself")
        if info.st_size > limit:
            raise FileRefused(path, f"{path}: {info.st_size} bytes, more than a {what} can be ({limit} bytes at most)")
        chunks, size = [], 0
        while True:
            chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
            if size > limit:  # it grew while being read
                raise FileRefused(path, f"{path}: more than a {what} can be ({limit} bytes at most)")
        return b"".join(chunks)
    finally:
        os.close(fd)


def read_regular_text(path: str | Path, limit: int = MAX_DOCUMENT_BYTES, what: str = "file") -> str:
    """:func:`read_regular` as UTF-8 text (a :class:`UnicodeDecodeError` is a :class:`ValueError`)."""
    return read_regular(path, limit, what).decode("utf-8")


def writable_target(path: str | Path) -> Path:
    """The file a save of ``path`` writes: the end of its symlinks (the link itself stays). A target that
    is not a regular file, or is read-only, is refused with the reason (:class:`FileRefused`)."""
    target = Path(os.path.realpath(path))
    try:
        info = os.stat(target)
    except FileNotFoundError:
        return target
    if not stat.S_ISREG(info.st_mode):
        raise FileRefused(path, f"{path}: {kind_of(info.st_mode)}, not a regular file: nothing written")
    if not info.st_mode & stat.S_IWUSR or not os.access(target, os.W_OK):
        shown = f"{path} (a link to {target})" if target != Path(path).absolute() else str(path)
        raise FileRefused(path, f"{shown} is read-only (mode {stat.S_IMODE(info.st_mode):04o}): nothing written; "
                                f"make it writable (chmod u+w) to save here")
    return target


def replace_atomic(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` as a whole or not at all: a temporary file in the target's folder,
    flushed to disk, given the target's mode, then renamed over it. A symlink is followed (the link
    stays a link), a read-only file is refused (:func:`writable_target`). Returns the file written."""
    target = writable_target(path)
    try:
        mode = stat.S_IMODE(os.stat(target).st_mode)
    except FileNotFoundError:
        mode = None
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
            handle.flush()
            if mode is not None:
                host.copy_mode(handle.fileno(), mode)  # Windows before Python 3.13: no fchmod (app/host.py)
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    try:  # the rename itself on disk
        folder = os.open(target.parent, os.O_RDONLY)
        try:
            os.fsync(folder)
        finally:
            os.close(folder)
    except OSError:
        pass
    return target
