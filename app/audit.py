"""Audit log: every write, command and restore, in an SQLite database that survives restarts."""

from __future__ import annotations

import logging
import re
import sqlite3
import time
from dataclasses import dataclass
from pathlib import Path

from app import i18n
from app.i18n import N_
from app.owner_db import OwnerDatabase

SCHEMA = """
CREATE TABLE IF NOT EXISTS audit (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    time REAL NOT NULL,
    user TEXT NOT NULL,
    role TEXT NOT NULL,
    device TEXT NOT NULL,
    action TEXT NOT NULL,
    parameter TEXT NOT NULL DEFAULT '',
    old TEXT NOT NULL DEFAULT '',
    new TEXT NOT NULL DEFAULT '',
    result TEXT NOT NULL
);
CREATE INDEX IF NOT EXISTS audit_time ON audit (time);
CREATE INDEX IF NOT EXISTS audit_device ON audit (device);
"""
log = logging.getLogger(__name__)
BUSY_TIMEOUT_MS = 2000  # a locked database is waited for this long (in the audit thread), then the write is refused

WRITE_ERRORS = (OSError, sqlite3.Error)  # what a row that cannot be written (or read) raises: file, lock, disk
COLUMNS = ("id", "time", "user", "role", "device", "action", "parameter", "old", "new", "result")


@dataclass(frozen=True)
class AuditEntry:
    id: int
    time: float
    user: str
    role: str
    device: str
    action: str
    parameter: str
    old: str
    new: str
    result: str


class AuditLog(OwnerDatabase):
    """A small, thread-safe SQLite store; each record is committed at once.

    The ``a...`` methods run in one thread of their own, in order, so a locked or slow
    database never blocks the event loop that carries the keep-alives. ``healthy`` and
    ``problem`` say whether the last write went through (shown in the header).
    """

    def __init__(self, path: str | Path):
        super().__init__(path, "audit")
        self.problem = ""
        try:
            self._open()
        except (OSError, sqlite3.Error) as exc:
            self.problem = f"cannot open {self.path}: {exc}"
            log.error("audit log: %s: every write will be refused until it can be written", self.problem)

    def _open(self) -> None:
        db = self._connect(BUSY_TIMEOUT_MS / 1000)
        db.executescript(SCHEMA)
        self._protected(db)

    @property
    def healthy(self) -> bool:
        return not self.problem

    def _execute(self, sql: str, args: tuple | list = ()) -> sqlite3.Cursor:
        with self._lock:
            if self._db is None:
                self._open()
            try:
                cursor = self._db.execute(sql, args)
            except sqlite3.Error as exc:
                self.problem = f"{self.path}: {exc}"
                raise
            if sql.startswith(("INSERT", "UPDATE")):
                self.problem = ""
            return cursor

    def check_writable(self) -> str:
        """"" when a row can be written now, else why not (a write is tried and rolled back)."""
        try:
            with self._lock:
                if self._db is None:
                    self._open()
                self._db.execute("BEGIN IMMEDIATE")
                self._db.execute("ROLLBACK")
            self.problem = ""
        except (OSError, sqlite3.Error) as exc:
            self.problem = f"{self.path}: {exc}"
        return self.problem

    def record(
        self, *, user: str, role: str, device: str, action: str, result: str,
        parameter: str = "", old: object = "", new: object = "", when: float | None = None,
    ) -> int:
        cursor = self._execute(
            "INSERT INTO audit (time, user, role, device, action, parameter, old, new, result) VALUES (?,?,?,?,?,?,?,?,?)",
            (when or time.time(), user, role, device, action, parameter, _text(old), _text(new), result),
        )
        return int(cursor.lastrowid)

    def finish(self, row: int, result: str) -> None:
        self._execute("UPDATE audit SET result = ? WHERE id = ?", (result, row))

    async def arecord(self, **kwargs) -> int:
        """:meth:`record` off the event loop; raises when the row cannot be written."""
        return await self.run(self.record, **kwargs)

    async def afinish(self, row: int, result: str) -> None:
        """Put the outcome into a row written before the action; a failure here is logged and shown."""
        try:
            await self.run(self.finish, row, result)
        except WRITE_ERRORS as exc:  # the action has happened; say that its outcome is not in the log
            log.error("audit log: the outcome %r of row %s could not be written: %s", result, row, exc)

    async def aquery(self, **kwargs) -> list["AuditEntry"]:
        return await self.run(self.query, **kwargs)

    async def adevices(self) -> list[str]:
        return await self.run(self.devices)

    def query(
        self, *, device: str = "", user: str = "", text: str = "", since: float | None = None,
        until: float | None = None, result: str = "", limit: int = 1000,
    ) -> list[AuditEntry]:
        where, args = [], []
        for column, value in (("device", device), ("user", user)):
            if value:
                where.append(f"{column} = ?")
                args.append(value)
        if result:
            where.append("result LIKE ?")
            args.append(f"{result}%")
        if text:
            # old and new too: a Save-Settings row names the changes it made permanent in its new value
            where.append("(action LIKE ? OR parameter LIKE ? OR old LIKE ? OR new LIKE ? OR result LIKE ?)")
            args += [f"%{text}%"] * 5
        if since is not None:
            where.append("time >= ?")
            args.append(since)
        if until is not None:
            where.append("time <= ?")
            args.append(until)
        sql = f"SELECT {', '.join(COLUMNS)} FROM audit"
        if where:
            sql += " WHERE " + " AND ".join(where)
        sql += " ORDER BY time DESC, id DESC LIMIT ?"
        args.append(limit)
        rows = self._execute(sql, args).fetchall()
        return [AuditEntry(*row) for row in rows]

    def devices(self) -> list[str]:
        return [r[0] for r in self._execute("SELECT DISTINCT device FROM audit ORDER BY device")]


FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")  # what a spreadsheet reads as the start of a formula
PLAIN_NUMBER = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?")


def csv_cell(text: str) -> str:
    """A cell a spreadsheet shows as text, never runs: one starting like a formula (a typed user
    name "=HYPERLINK(...)") gets a leading apostrophe; a plain number ("-30") stays as it is."""
    if text.startswith(FORMULA_STARTS) and not PLAIN_NUMBER.fullmatch(text):
        return "'" + text
    return text


CSV_HEAD = (N_("time"), N_("user"), N_("role"), N_("device"), N_("action"), N_("parameter"), N_("old"), N_("new"), N_("result"))


def to_csv(entries: list[AuditEntry], lang: i18n.Lang | None = None) -> str:
    """The rows as a CSV file: headings in ``lang`` (English when None) and its spreadsheets' separator; the
    rows' texts as they were written (records), each made plain text."""
    from app.csvfile import csv_text

    return csv_text(CSV_HEAD, ([time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(e.time)),
                                *(csv_cell(str(v)) for v in (e.user, e.role, e.device, e.action, e.parameter, e.old, e.new,
                                                              e.result))] for e in entries), lang)


def _text(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bytes):
        return value.hex(" ")
    return str(value)


class LogBudget(logging.Filter):
    """A bound on the log lines that others (network clients, brokers) can make the program write:
    at most ``lines`` per ``window_s``; the rest are counted, and the next line let through says
    how many were left out. A ``logging.Filter``, so it can sit on a library's loggers too."""

    def __init__(self, lines: int = 20, window_s: float = 60.0, clock=time.monotonic):
        super().__init__()
        self.lines, self.window_s, self.clock = lines, window_s, clock
        self._start, self._used, self.left_out, self._pending = -window_s, 0, 0, 0

    def take(self) -> int | None:
        """None: write no line (it is counted); else write one, after the returned number left out."""
        now = self.clock()
        if now - self._start >= self.window_s:
            self._start, self._used = now, 0
        if self._used >= self.lines:
            self.left_out += 1
            self._pending += 1
            return None
        self._used += 1
        skipped, self._pending = self._pending, 0
        return skipped

    def filter(self, record: logging.LogRecord) -> bool:
        skipped = self.take()
        if skipped is None:
            return False
        if skipped:
            record.msg = f"{record.msg} [{skipped} similar lines left out before this one]"
        return True
