"""An SQLite file of the program's own that only its owner may read (the audit log, the commissioning record).

Both are opened the same way, owner only and in WAL mode, and both keep their writes and reads off the event
loop: every ``run`` goes to one thread of the database's own, in order, so a locked or slow disk never delays
the loop that carries the keep-alives. What a database holds and how it checks it stays with its module.
"""

from __future__ import annotations

import asyncio
import os
import sqlite3
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from app import host


class OwnerDatabase:
    """The file at ``path``, its lock, its own thread (named ``thread``) and, once opened, its connection."""

    def __init__(self, path: str | Path, thread: str):
        self.path = Path(path)
        self._lock = threading.Lock()
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix=thread)
        self._db: sqlite3.Connection | None = None

    def _connect(self, busy_timeout_s: float) -> sqlite3.Connection:
        """Create the file owner only (with its folder), connect in autocommit and WAL mode; a write that finds the
        database locked waits ``busy_timeout_s``. The caller creates its tables, then calls :meth:`_protected`."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        os.close(os.open(self.path, os.O_RDWR | os.O_CREAT, 0o600))
        host.protect_file(self.path)  # who did, approved and signed what is nobody else's business
        db = sqlite3.connect(str(self.path), check_same_thread=False, isolation_level=None, timeout=busy_timeout_s)
        db.execute(f"PRAGMA busy_timeout = {int(busy_timeout_s * 1000)}")
        db.execute("PRAGMA journal_mode=WAL")
        return db

    def _protected(self, db: sqlite3.Connection) -> sqlite3.Connection:
        """``db`` kept as this database's connection, its WAL side files owner only too."""
        host.protect_database_sidecars(self.path)
        self._db = db
        return db

    async def run(self, fn, *args, **kwargs):
        """``fn(*args, **kwargs)`` in the database's own thread, after what was handed to it before."""
        return await asyncio.get_running_loop().run_in_executor(self._executor, lambda: fn(*args, **kwargs))

    def close(self) -> None:
        with self._lock:
            if self._db is not None:
                self._db.close()
                self._db = None
        self._executor.shutdown(wait=False)
