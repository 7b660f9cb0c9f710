"""Audit log: every write, command and restore, in an SQLite database that survives restarts."""

from __future__ import annotations

import csv
import io
import sqlite3
import threading
import time
from dataclasses import dataclass
from pathlib import Path

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


class AuditLog:
    """A small, thread-safe SQLite store; each record is committed at once."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        self._db = sqlite3.connect(str(self.path), check_same_thread=False, isolation_level=None)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.executescript(SCHEMA)

    def record(
        self, *, user: str, role: str, device: str, action: str, result: str,
        parameter: str = "", old: object = "", new: object = "", when: float | None = None,
    ) -> int:
        with self._lock:
            cursor = self._db.execute(
                "INSERT INTO audit (time, user, role, device, action, parameter, old, new, result) VALUES (?,?,?,?,?,?,?,?,?)",
                (when or time.time(), user, role, device, action, parameter, _text(old), _text(new), result),
            )
            return int(cursor.lastrowid)

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
            where.append("(action LIKE ? OR parameter LIKE ? OR result LIKE ?)")
            args += [f"%{text}%"] * 3
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
        with self._lock:
            rows = self._db.execute(sql, args).fetchall()
        return [AuditEntry(*row) for row in rows]

    def devices(self) -> list[str]:
        with self._lock:
            return [r[0] for r in self._db.execute("SELECT DISTINCT device FROM audit ORDER BY device")]

    def close(self) -> None:
        with self._lock:
            self._db.close()


def to_csv(entries: list[AuditEntry]) -> str:
    out = io.StringIO()
    writer = csv.writer(out)
    writer.writerow(["time", "user", "role", "device", "action", "parameter", "old", "new", "result"])
    for e in entries:
        writer.writerow([
            time.strftime("%Y-%m-%d %H:%M:%S", time.localtime(e.time)), e.user, e.role, e.device, e.action,
            e.parameter, e.old, e.new, e.result,
        ])
    return out.getvalue()


def _text(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bytes):
        return value.hex(" ")
    return str(value)
