"""The store of the commissioning record (app/record.py): one SQLite database beside the audit log.

The database is ``record.sqlite`` in the data folder, owner only. Rows are append-only (ARCHITECTURE
rule 11): triggers refuse every UPDATE, DELETE and REPLACE, so a signed record is never changed; a newer
row supersedes an older one. Each row carries the SHA-256 of the row before it and its own over every
field (app/verify.py), and the last row written is kept beside the database (``record.sqlite.head``): a
row changed, replaced or deleted from outside the program is named by ``commission verify`` and by every
report. The kinds of row (:data:`KINDS`) are described in app/record.py.
"""

from __future__ import annotations

import json
import logging
import os
import sqlite3
import time
from dataclasses import dataclass
from pathlib import Path

from app.i18n import N_
from app.message import Message
from app.owner_db import OwnerDatabase
from app.verify import GENESIS, Check, check_database, head_path, legacy_digest, read_head, read_rows, row_hash
from devices.errors import CommissionError

log = logging.getLogger(__name__)

KINDS = ("approved", "snapshot", "restore", "checkout", "signoff", "integrity")
PLANT = ""  # the device name of plant-wide rows (a plant sign-off)

SCHEMA = """
CREATE TABLE IF NOT EXISTS record (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    time REAL NOT NULL,
    plant TEXT NOT NULL,
    device TEXT NOT NULL,
    kind TEXT NOT NULL,
    user TEXT NOT NULL,
    role TEXT NOT NULL,
    title TEXT NOT NULL DEFAULT '',
    data TEXT NOT NULL,
    supersedes INTEGER,
    prev_hash TEXT,
    hash TEXT
);
CREATE INDEX IF NOT EXISTS record_device ON record (plant, device, kind);
"""
TRIGGER_SQL = {
    "record_no_update": """CREATE TRIGGER IF NOT EXISTS record_no_update BEFORE UPDATE ON record
BEGIN SELECT RAISE(ABORT, 'commissioning records are append-only: add a new row that supersedes this one'); END;""",
    "record_no_delete": """CREATE TRIGGER IF NOT EXISTS record_no_delete BEFORE DELETE ON record
BEGIN SELECT RAISE(ABORT, 'commissioning records are append-only: they are never deleted'); END;""",
    "record_no_replace": """CREATE TRIGGER IF NOT EXISTS record_no_replace BEFORE INSERT ON record
WHEN EXISTS (SELECT 1 FROM record WHERE id = NEW.id)
BEGIN SELECT RAISE(ABORT, 'commissioning records are append-only: a row is never replaced'); END;""",
}
COLUMNS = ("id", "time", "plant", "device", "kind", "user", "role", "title", "data", "supersedes", "prev_hash", "hash")


class RecordError(CommissionError):
    """A record that cannot be written or read; the message says which and why (a :class:`~app.message.Message`, or the
    database's path with SQLite's own words)."""


@dataclass(frozen=True)
class Entry:
    id: int
    time: float
    plant: str
    device: str
    kind: str
    user: str
    role: str
    title: str
    data: dict
    supersedes: int | None
    prev_hash: str | None = None
    hash: str | None = None

    def brief(self) -> dict:
        return {"id": self.id, "time": self.time, "device": self.device, "kind": self.kind, "user": self.user,
                "role": self.role, "title": self.title, "supersedes": self.supersedes}


class RecordStore(OwnerDatabase):
    """Append-only SQLite store, opened like the audit log (owner only, WAL); ``a...`` methods run
    in one thread of their own so the event loop never waits on the disk."""

    def __init__(self, path: str | Path):
        super().__init__(path, "record")
        self.altered: list[str] = []  # what was found changed from outside when the database was opened

    def _open(self) -> sqlite3.Connection:
        if self._db is None:
            db = self._connect(2.0)
            existed = db.execute("SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = 'record'").fetchone() is not None
            columns = {c[1] for c in db.execute("PRAGMA table_info(record)")}
            triggers = {r[0] for r in db.execute("SELECT name FROM sqlite_master WHERE type = 'trigger'")}
            db.executescript(SCHEMA)
            legacy = existed and "hash" not in columns  # a record of an older version: its rows have no chain yet
            if legacy:
                db.execute("ALTER TABLE record ADD COLUMN prev_hash TEXT")
                db.execute("ALTER TABLE record ADD COLUMN hash TEXT")
            removed = [] if legacy or not existed else [t for t in TRIGGER_SQL if t not in triggers]
            for sql in TRIGGER_SQL.values():
                db.execute(sql)
            self._protected(db)
            if legacy:
                rows = read_rows(db)
                if rows:
                    self._append(db, plant=PLANT, device=PLANT, kind="integrity", user="commission", role="",
                                 title=f"chain begins: {len(rows)} earlier rows kept by their digest",
                                 data={"legacy": {"rows": len(rows), "first": rows[0]["id"], "last": rows[-1]["id"],
                                                  "sha256": legacy_digest(rows)}}, supersedes=None, when=None)
            if removed:
                self.altered = [f"the record's protection {t} had been removed from outside the program (put back now)"
                                for t in removed]
                log.error("%s: %s", self.path, "; ".join(self.altered))
                self._append(db, plant=PLANT, device=PLANT, kind="integrity", user="commission", role="",
                             title="altered from outside: " + ", ".join(removed) + " removed",
                             data={"removed_triggers": removed, "found": time.time()}, supersedes=None, when=None)
        return self._db

    def _append(self, db: sqlite3.Connection, *, plant: str, device: str, kind: str, user: str, role: str, data: dict,
                title: str, supersedes: int | None, when: float | None) -> int:
        """Insert one row chained to the last one, in one write transaction (other processes wait)."""
        text = json.dumps(data, ensure_ascii=False, default=str)
        db.execute("BEGIN IMMEDIATE")
        try:
            last = db.execute("SELECT id, hash FROM record ORDER BY id DESC LIMIT 1").fetchone()
            seq = db.execute("SELECT seq FROM sqlite_sequence WHERE name = 'record'").fetchone()
            row = {"id": max(last[0] if last else 0, seq[0] if seq else 0) + 1, "time": when or time.time(), "plant": plant,
                   "device": device, "kind": kind, "user": user, "role": role, "title": title, "data": text,
                   "supersedes": supersedes, "prev_hash": (last[1] or GENESIS) if last else GENESIS}
            row["hash"] = row_hash(row)
            db.execute(f"INSERT INTO record ({', '.join(COLUMNS)}) VALUES ({', '.join('?' * len(COLUMNS))})",
                       tuple(row[c] for c in COLUMNS))
            db.execute("COMMIT")
        except BaseException:
            db.execute("ROLLBACK")
            raise
        self._write_head(row["id"], row["hash"])
        return row["id"]

    def _write_head(self, entry_id: int, digest: str) -> None:
        path = head_path(self.path)
        current = read_head(self.path)
        if current is not None and current.get("id", 0) > entry_id:
            return  # another process wrote a later row already
        tmp = path.with_name(f".{path.name}.{os.getpid()}.part")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w") as handle:
            handle.write(json.dumps({"id": entry_id, "hash": digest, "time": time.time()}))
        os.replace(tmp, path)

    def add(self, *, plant: str, device: str, kind: str, user: str, role: str, data: dict, title: str = "",
            supersedes: int | None = None, when: float | None = None) -> int:
        if kind not in KINDS:
            raise RecordError(Message(N_("unknown record kind {kind}"), kind=repr(kind)))
        with self._lock:
            try:
                return self._append(self._open(), plant=plant, device=device, kind=kind, user=user, role=role, data=data,
                                    title=title, supersedes=supersedes, when=when)
            except sqlite3.Error as exc:
                raise RecordError(f"{self.path}: {exc}") from None

    def verify(self) -> Check:
        """The chain, the sign-offs and the protection of this database (app/verify.py)."""
        with self._lock:
            self._open()
            return check_database(self.path)

    def chain_rows(self) -> list[dict]:
        """Every row as stored (``data`` as text), ordered by id: the chain an archive carries."""
        with self._lock:
            return read_rows(self._open())

    def _rows(self, sql: str, args: tuple = ()) -> list[Entry]:
        with self._lock:
            rows = self._open().execute(sql, args).fetchall()
        return [Entry(*row[:8], json.loads(row[8]), *row[9:]) for row in rows]

    def get(self, entry_id: int) -> Entry | None:
        rows = self._rows(f"SELECT {', '.join(COLUMNS)} FROM record WHERE id = ?", (entry_id,))
        return rows[0] if rows else None

    def list(self, plant: str, device: str | None = None, kinds: tuple[str, ...] = (), limit: int = 500) -> list[Entry]:
        """Newest first."""
        sql, args = f"SELECT {', '.join(COLUMNS)} FROM record WHERE plant = ?", [plant]
        if device is not None:
            sql += " AND device = ?"
            args.append(device)
        if kinds:
            sql += f" AND kind IN ({', '.join('?' * len(kinds))})"
            args += list(kinds)
        sql += " ORDER BY id DESC LIMIT ?"
        args.append(limit)
        return self._rows(sql, tuple(args))

    def latest(self, plant: str, device: str, kind: str) -> Entry | None:
        rows = self.list(plant, device, (kind,), limit=1)
        return rows[0] if rows else None

