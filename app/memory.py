"""Giving freed heap memory back to the system.

Every table the program keeps is bounded, so once they are full the Python heap stays
the same size. The C allocator under it (glibc's malloc) does not give pages back on
its own when the freed blocks lie between blocks still in use: they stay in the
process as free space and the resident size creeps up over hours as it is fragmented.
``malloc_trim`` returns such free pages to the system (it advises the kernel page by
page, not only at the top of the heap), so the resident size follows what is in use.

It runs in a worker thread once a minute: it takes a few milliseconds and holds the
allocator's locks meanwhile, so it must not run on the event loop.
"""

from __future__ import annotations

import asyncio
import logging

from app import host

log = logging.getLogger(__name__)

TRIM_PERIOD_S = 60.0


def _load_trim():
    """glibc's ``malloc_trim``, or None on a C library without it (musl) and on Windows and macOS
    (:func:`app.host.heap_trimmer`)."""
    return host.heap_trimmer()


_malloc_trim = _load_trim()


def available() -> bool:
    return _malloc_trim is not None


def trim() -> bool:
    """Return free heap pages to the system; True if any were returned. Blocking: call it from a thread."""
    if _malloc_trim is None:
        return False
    return bool(_malloc_trim(0))


async def keep_trimmed(period_s: float = TRIM_PERIOD_S) -> None:
    """Trim once every ``period_s`` in a worker thread, for as long as the program runs."""
    if _malloc_trim is None:
        log.info("this C library has no malloc_trim: freed heap pages are left to it")
        return
    while True:
        await asyncio.sleep(period_s)
        await asyncio.to_thread(trim)
