"""The commissioning record: approved sets, snapshots, checkouts with evidence, sign-offs.

Everything lives in one SQLite database beside the audit log (``record.sqlite`` in the data
folder, owner only). Rows are append-only (ARCHITECTURE rule 11): triggers refuse every UPDATE,
DELETE and REPLACE, so a signed record is never changed; a newer row supersedes an older one.
Each row carries the SHA-256 of the row before it and its own over every field (app/verify.py), and
the last row written is kept beside the database (``record.sqlite.head``): a row changed, replaced
or deleted from outside the program is named by ``commission verify`` and by every report.

- **approved set** (kind ``approved``): the parameters an engineer approves for a device, from a
  backup file or from the device as it is at sign-off;
- **snapshot** (kind ``snapshot``): every parameter read fresh from the device; one is taken by
  itself after every Save-Settings and every restore (the end of a write session), and on demand;
- **checkout** (kind ``checkout``): the result of a declared checkout (``devices/<type>/checkout.py``)
  with each step's measured values, limits, the answers a person gave and the bus traffic;
- **sign-off** (kind ``signoff``): the account that signed, name, role, time, comment and the frozen
  report content;
- **integrity** (kind ``integrity``): what the program found changed from outside (a removed
  protection trigger) or the digest of rows kept before the chain began.

Drift: each device's parameters are compared with its approved set whenever its live values
change (at most once a second); a device that differs carries ``DeviceState.drift``, which the
overview, the plant view, ``/api/devices`` and MQTT show.
"""

from __future__ import annotations

import asyncio
import importlib
import json
import logging
import os
import sqlite3
import threading
import time
import uuid
from collections.abc import Awaitable, Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from app import host
from app.verify import GENESIS, Check, check_database, content_sha256, head_path, legacy_digest, read_head, read_rows, row_hash
from devices.commands import READ_PARAMETERS

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
DRIFT_POINT = "Changed since approved"


class RecordError(Exception):
    """A record that cannot be written or read; the message says which and why."""


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


class RecordStore:
    """Append-only SQLite store, opened like the audit log (owner only, WAL); ``a...`` methods run
    in one thread of their own so the event loop never waits on the disk."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._lock = threading.Lock()
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="record")
        self._db: sqlite3.Connection | None = None
        self.altered: list[str] = []  # what was found changed from outside when the database was opened

    def _open(self) -> sqlite3.Connection:
        if self._db is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            os.close(os.open(self.path, os.O_RDWR | os.O_CREAT, 0o600))
            host.protect_file(self.path)  # who approved and signed what is nobody else's business either
            db = sqlite3.connect(str(self.path), check_same_thread=False, isolation_level=None, timeout=2.0)
            db.execute("PRAGMA journal_mode=WAL")
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
            for suffix in ("-wal", "-shm"):
                side = self.path.with_name(self.path.name + suffix)
                if side.exists():
                    host.protect_file(side)
            self._db = db
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
            raise RecordError(f"unknown record kind {kind!r}")
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

    async def run(self, fn, *args, **kwargs):
        return await asyncio.get_running_loop().run_in_executor(self._executor, lambda: fn(*args, **kwargs))

    def close(self) -> None:
        with self._lock:
            if self._db is not None:
                self._db.close()
                self._db = None
        self._executor.shutdown(wait=False)


# -- parameter sets, diffs and drift -----------------------------------------------------------
def param_set(entries: list[dict]) -> dict[str, dict]:
    """A backup's parameter list as ``{key: {name, raw, text, unit, writable}}``."""
    return {e["key"]: {"name": e.get("name", e["key"]), "raw": e.get("raw"), "text": str(e.get("text") or e.get("value")),
                       "unit": e.get("unit", ""), "writable": bool(e.get("writable"))} for e in entries}


def diff_sets(old: dict[str, dict], new: dict[str, dict]) -> list[dict]:
    """Rows of every parameter that differs (or exists in only one set), in the order of ``new``."""
    rows = []
    for key in [*new, *(k for k in old if k not in new)]:
        a, b = old.get(key), new.get(key)
        if a is not None and b is not None and a.get("raw") == b.get("raw"):
            continue
        ref = b or a
        rows.append({"key": key, "name": ref["name"], "old": None if a is None else a["text"],
                     "new": None if b is None else b["text"]})
    return rows


LIVE_VALUE = "live value"  # a read-only value (state, measurement, counter) that differs: not a setting, never "changed"


def compare_with_approved(current: dict[str, dict], approved: dict[str, dict] | None) -> list[dict]:
    """Every current parameter against the approved set: ``equal``, ``changed`` or ``not approved``;
    a differing value the device changes itself is ``updated by the device``, and a differing read-only
    value (the bolt's position, a state, a timer: read with the set, but no setting) a ``live value``,
    as drift leaves both out."""
    rows = []
    for key, now in current.items():
        ref = None if approved is None else approved.get(key)
        if ref is None:
            verdict = "not approved"
        elif _same(ref.get("raw"), now.get("raw")):
            verdict = "equal"
        elif now.get("device_updates"):
            verdict = "updated by the device"
        elif not (now.get("writable") if "writable" in now else ref.get("writable")):
            verdict = LIVE_VALUE
        else:
            verdict = "changed"
        rows.append({"key": key, "name": now["name"], "value": now["text"], "unit": now.get("unit", ""),
                     "approved": None if ref is None else ref["text"], "verdict": verdict, "writable": now.get("writable")})
    return rows


def live_set(state, approved: dict[str, dict]) -> dict[str, dict]:
    """The values of the approved keys as the live store holds them now (the last full read):
    register parameters through the parameter model, other entries by their name's live point."""
    current: dict[str, dict] = {}
    params = state.params
    for key, ref in approved.items():
        param = params.by_key.get(key) if params is not None else None
        if param is not None:
            raw = state.raw(param)
            if raw is not None:
                current[key] = {"name": ref["name"], "raw": raw, "text": param.display(raw), "unit": param.unit}
        else:
            point = state.points.get(ref["name"])
            if point is not None and point.value is not None:
                current[key] = {"name": ref["name"], "raw": point.value, "text": str(point.text or point.value), "unit": point.unit}
    return current


def live_params(state) -> dict[str, dict]:
    """Every register parameter the live store holds now (the device's last poll, as its page shows
    it), in the form of :func:`param_set`; empty for a device without a parameter model or before
    its first read."""
    params = getattr(state, "params", None)
    current: dict[str, dict] = {}
    for param in params if params is not None else ():
        raw = state.raw(param)
        if raw is not None:
            current[param.key] = {"name": param.label or param.name, "raw": raw, "text": param.display(raw), "unit": param.unit,
                                  "writable": bool(param.writable)}
    return current


def device_updated(state, key: str) -> bool:
    """The parameter model marks ``key`` as changed by the device itself (``Param.device_updates``:
    a measured maximum, a counter): never drift."""
    params = getattr(state, "params", None)
    param = params.by_key.get(key) if params is not None else None
    return param is not None and param.writable and not param.setting


def drift_of(state, approved: dict[str, dict], snapshot: dict[str, dict] | None = None) -> list[dict]:
    """The writable approved parameters whose value now differs (live store first, else the last
    snapshot); parameters the device changes itself are left out."""
    current = dict(snapshot or {})
    current.update(live_set(state, approved))
    rows = []
    for key, ref in approved.items():
        now = current.get(key)
        if not ref.get("writable") or now is None or _same(now.get("raw"), ref.get("raw")) or device_updated(state, key):
            continue
        rows.append({"key": key, "name": ref["name"], "approved": ref["text"], "now": now["text"]})
    return rows


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, int | float) and isinstance(b, int | float):
        return a == b
    return str(a) == str(b)


# -- evidence: the bus traffic of a checkout step ------------------------------------------------
class TrafficTap:
    """Collects what the bus monitor buffers of one bus hold from the moment it starts: CAN frames
    (``CanBusState.frames``) or serial, Modbus and LogiTed transactions (``BusState.transactions``).
    Swept every 0.2 s while a step runs, so a busy bus cannot push frames out of the ring first."""

    def __init__(self, bus_state):
        self.bus_state = bus_state
        self.is_can = hasattr(bus_state, "frames")
        self.items: list = []
        self.since = time.time()
        self._last = self.since - 1e-6

    def sweep(self) -> None:
        buffer = self.bus_state.frames if self.is_can else self.bus_state.transactions
        new = []
        for item in reversed(buffer):
            if item.time <= self._last:
                break
            new.append(item)
        if new:
            new.reverse()
            self._last = new[-1].time
            self.items.extend(new)

    def take(self) -> dict:
        self.sweep()
        items, self.items = self.items, []
        if self.is_can:
            rows = [{"t": f.time, "id": f.arbitration_id, "ext": f.is_extended_id, "dir": f.direction,
                     "data": f.data.hex(), "err": f.is_error_frame} for f in items]
            return {"kind": "can", "frames": rows}
        rows = [{"t": t.time, "request": t.request, "tx": t.request_hex, "rx": t.response_hex, "decoded": t.decoded,
                 "error": t.error} for t in items]
        return {"kind": "serial", "transactions": rows}


# -- checkouts ---------------------------------------------------------------------------------
class Aborted(Exception):
    """The engineer aborted the checkout (or the page that ran it went away)."""


class StepFailed(Exception):
    """A step's check failed; the message is the reason the report shows."""


class NotAvailable(Exception):
    """A step this device (or its adapter) cannot do; the message says why. It does not fail the
    checkout: the report lists the step as "not available" with the reason."""


NOT_AVAILABLE = "not available"
NOT_FAILING = ("passed", NOT_AVAILABLE, "skipped")  # step results that let a checkout pass


class Skipped(NotAvailable):
    """A step the person running the checkout chose to leave out (e.g. no test input wired); the
    message says who and why."""

    status = "skipped"


@dataclass
class StepResult:
    name: str
    limits: str = ""
    status: str = "pending"  # pending, running, passed, failed, aborted, error, skipped, not available
    reason: str = ""
    values: list[dict] = field(default_factory=list)
    answers: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    started: float | None = None
    ended: float | None = None
    evidence: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {"name": self.name, "limits": self.limits, "status": self.status, "reason": self.reason, "values": self.values,
                "answers": self.answers, "notes": self.notes, "started": self.started, "ended": self.ended,
                "evidence": self.evidence}


AskFn = Callable[[str], Awaitable[bool]]


def checkout_module(device_type: str):
    """``devices/<type>/checkout.py``, or None when the type declares no checkout."""
    try:
        return importlib.import_module(f"devices.{device_type}.checkout")
    except ModuleNotFoundError:
        return None


class CheckoutContext:
    """What a declared checkout step may do: every command through the worker's gate (the one
    place that sends), waits on conditions, measurements against limits, questions to a person."""

    WAIT_STEP_S = 0.05

    def __init__(self, run: "CheckoutRun"):
        self._run = run
        runtime = run.runtime
        self.device = run.device
        self.state = runtime.store.devices[run.device]
        self.config = runtime.plant.devices[run.device]
        self.options = dict(self.config.options)
        self.session = run.session
        self.user = run.user
        self.settings = run.settings
        self.adapter = runtime.worker.adapters[run.device]  # to ask what it offers; commands go through invoke()

    @property
    def step(self) -> StepResult:
        return self._run.current

    def check_abort(self) -> None:
        if self._run.abort_event.is_set():
            raise Aborted(self._run.abort_reason or "aborted")

    async def invoke(self, name: str, args: dict | None = None) -> Any:
        """Run the device type's declared command ``name`` through the worker's gate, for the run's
        session. A command that names a risk is run confirmed only when the person running the checkout
        answered that risk's question yes in this run (asked here if not yet; the answer is recorded)."""
        from app.gate import NeedsConfirmation

        self.check_abort()
        worker = self._run.runtime.worker
        confirmed = False
        while True:
            try:
                return await worker.invoke(self.device, name, args, user=self.user, role=self._run.role,
                                           session=self.session, confirmed=confirmed)
            except NeedsConfirmation as exc:
                if confirmed:
                    raise
                if exc.question not in self._run.confirmed:
                    await self.ask(exc.question)
                else:
                    self.note(f"{name}: {exc.question!r} answered yes earlier in this run")
                confirmed = True

    async def wait(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """True once ``predicate()`` holds, False after ``timeout_s``; an abort ends the wait at once."""
        loop = asyncio.get_running_loop()
        end = loop.time() + timeout_s
        while True:
            self.check_abort()
            try:
                if predicate():
                    return True
            except (KeyError, TypeError, ValueError):
                pass
            if loop.time() >= end:
                return False
            self._run.tap_sweep()
            await asyncio.sleep(self.WAIT_STEP_S)

    def entry(self, name: str) -> dict | None:
        return self.state.entry(name)

    def value(self, name: str) -> Any:
        e = self.state.entry(name)
        return None if e is None else e.get("value")

    def field(self, name: str, field_name: str) -> int | None:
        e = self.state.entry(name)
        return None if e is None or not e.get("fields") else e["fields"].get(field_name)

    def measure(self, name: str, value: Any, unit: str = "", *, low: float | None = None, high: float | None = None,
                expect: Any = None, fail: bool = True) -> bool:
        """Record a measured value against its limit; a value outside it fails the step (``fail``)."""
        ok = True
        limit = ""
        if value is None:
            ok, limit = False, "a value"
        if expect is not None:
            limit = f"= {expect}"
            ok = ok and value == expect
        if low is not None:
            limit = f">= {low:g}" if high is None else f"{low:g} .. {high:g}"
            ok = ok and value is not None and value >= low
        if high is not None:
            limit = limit or f"<= {high:g}"
            ok = ok and value is not None and value <= high
        self.step.values.append({"name": name, "value": value, "unit": unit, "limit": f"{limit} {unit}".strip() if limit else "",
                                 "ok": ok})
        if not ok and fail:
            shown = "no value" if value is None else f"{value} {unit}".strip()
            raise StepFailed(f"{name}: {shown}, expected {limit} {unit}".strip())
        return ok

    def note(self, text: str) -> None:
        self.step.notes.append(text)

    def fail(self, reason: str) -> None:
        raise StepFailed(reason)

    def not_available(self, reason: str) -> None:
        """End the step as "not available" (it does not fail the checkout) with ``reason``."""
        raise NotAvailable(reason)

    def skip(self, reason: str) -> None:
        """End the step as "skipped" by the person running it (it does not fail the checkout)."""
        raise Skipped(reason)

    async def ask(self, question: str) -> bool:
        """Ask the person running the checkout; the answer and who gave it are recorded. "No" fails the step."""
        self.check_abort()
        answer = await self._run.ask(question)
        self.step.answers.append({"question": question, "answer": "yes" if answer else "no", "by": self.user,
                                  "role": self._run.role, "time": time.time()})
        if not answer:
            raise StepFailed(f"{question} - answered no by {self.user}")
        self._run.confirmed.add(question)
        return True

    async def choose(self, question: str, no_means: str) -> bool:
        """Ask a question whose "no" is an answer, not a failure (e.g. "is a test input wired to E1?");
        the answer and who gave it are recorded; ``no_means`` says in the step's notes what "no" did."""
        self.check_abort()
        answer = await self._run.ask(question)
        self.step.answers.append({"question": question, "answer": "yes" if answer else "no", "by": self.user,
                                  "role": self._run.role, "time": time.time()})
        if not answer:
            self.note(f"answered no by {self.user}: {no_means}")
        return bool(answer)


class CheckoutRun:
    """One run of a device's declared checkout: progress, a visible abort, evidence per step.

    :param session: the browser session the run belongs to: outputs it switches on are under
        that session's dead-man rule. Without one (CLI, tests) the run confirms it is alive itself.
    """

    def __init__(self, runtime, device: str, *, user: str, role: str, ask: AskFn | None = None, session: str = "",
                 settings: dict | None = None):
        state = runtime.store.devices[device]
        module = checkout_module(state.type)
        if module is None:
            raise RecordError(f"{device}: the {state.type} type declares no checkout")
        self.runtime, self.device, self.user, self.role = runtime, device, user, role
        self.module = module
        self.settings = {**getattr(module, "SETTINGS", {}), **(settings or {})}
        self.steps_decl = module.steps(runtime.plant.devices[device].options, self.settings)
        self.results = [StepResult(s["name"], s.get("limits", "")) for s in self.steps_decl]
        self.current: StepResult = self.results[0] if self.results else StepResult("-")
        self.session = session or f"checkout-{uuid.uuid4().hex[:8]}"
        self._own_session = not session
        self._ask = ask
        self.abort_event = asyncio.Event()
        self.abort_reason = ""
        self.status = "ready"
        self.started: float | None = None
        self.ended: float | None = None
        self.listeners: list[Callable[[], None]] = []
        self._tap = TrafficTap(runtime.store.buses[state.bus])
        self.record_id: int | None = None
        self.confirmed: set[str] = set()  # questions answered yes in this run (a declared risk is asked once)
        self.drift_before: set[str] = set()  # keys drifting before the run (set by RecordService.new_run)

    @property
    def progress(self) -> float:
        done = sum(r.status not in ("pending", "running") for r in self.results)
        return done / max(1, len(self.results))

    def abort(self, reason: str = "aborted by the engineer") -> None:
        self.abort_reason = reason
        self.abort_event.set()

    def tap_sweep(self) -> None:
        self._tap.sweep()

    def _changed(self) -> None:
        for fn in list(self.listeners):
            try:
                fn()
            except Exception:  # noqa: BLE001 - a page that went away
                log.debug("checkout listener failed", exc_info=True)

    async def ask(self, question: str) -> bool:
        if self._ask is None:
            raise StepFailed(f"{question} - nobody to ask (run it from the device's record page)")
        return await self._ask(question)

    async def _beat(self) -> None:
        while True:
            self.runtime.worker.heartbeat(self.session)
            await asyncio.sleep(0.1)

    async def run(self) -> dict:
        """Run every step in order; the first failure ends the run (later steps are skipped), the
        cleanup always runs. Returns the result as stored (its ``record_id`` set)."""
        if self.role != "engineer":
            raise PermissionError(f"{self.user} has the {self.role or 'no'} role and may not run checkouts")
        ctx = CheckoutContext(self)
        beat = asyncio.create_task(self._beat()) if self._own_session else None
        self.status, self.started = "running", time.time()
        self._changed()
        try:
            for decl, result in zip(self.steps_decl, self.results):
                self.current = result
                result.status, result.started = "running", time.time()
                self._tap.take()  # the evidence of each step starts with it
                self._changed()
                try:
                    ctx.check_abort()
                    await decl["run"](ctx)
                    result.status = "passed"
                except StepFailed as exc:
                    result.status, result.reason = "failed", str(exc)
                except NotAvailable as exc:
                    result.status, result.reason = getattr(exc, "status", NOT_AVAILABLE), str(exc)
                except Aborted as exc:
                    result.status, result.reason = "aborted", str(exc)
                except Exception as exc:  # noqa: BLE001 - a refused or failed command is the step's reason
                    result.status, result.reason = "failed", f"{type(exc).__name__}: {exc}" if not str(exc) else str(exc)
                result.ended = time.time()
                result.evidence = self._tap.take()
                self._changed()
                if result.status not in NOT_FAILING:
                    break
            for result in self.results:
                if result.status == "pending":
                    result.status, result.reason = "skipped", "not run: an earlier step did not pass"
        finally:
            cleanup = getattr(self.module, "cleanup", None)
            if cleanup is not None:
                ctx.step.notes.append("cleanup ran")
                self.abort_event.clear()  # the cleanup stops and restores: it must run after an abort too
                try:
                    await cleanup(ctx, self.settings)
                except Exception as exc:  # noqa: BLE001 - said in the result
                    ctx.step.notes.append(f"cleanup failed: {exc}")
            if beat is not None:
                beat.cancel()
        self.ended = time.time()
        if any(r.status == "aborted" for r in self.results):
            self.status = "aborted"
        elif all(r.status in NOT_FAILING for r in self.results):
            self.status = "passed"
        else:
            self.status = "failed"
        data = self.as_dict()
        service = getattr(self.runtime, "record", None)
        if service is not None:
            service.check_drift(self.device)  # what the checkout changed and restored is no longer held back
            self.record_id = await service.add(self.device, "checkout", user=self.user, role=self.role, data=data,
                                               title=f"{self.module.TITLE}: {self.status}")
            data["record_id"] = self.record_id
        self._changed()
        return data

    def as_dict(self) -> dict:
        failed = next((r for r in self.results if r.status in ("failed", "aborted")), None)
        return {"device": self.device, "title": self.module.TITLE, "status": self.status, "reason": failed.reason if failed else "",
                "user": self.user, "role": self.role, "started": self.started, "ended": self.ended,
                "duration_s": None if self.started is None or self.ended is None else round(self.ended - self.started, 2),
                "settings": self.settings, "steps": [r.as_dict() for r in self.results]}


# -- the service the runtime holds -------------------------------------------------------------
AUTO_SNAPSHOT_ACTIONS = ("Save-Settings", "restore: save step", "restore")  # the end of a write session
AUDIT_FOLLOW_S = 1.0


class RecordService:
    """The commissioning record of one running plant (``runtime.record``)."""

    def __init__(self, runtime):
        self.runtime = runtime
        self.plant = runtime.plant.name
        self.store = RecordStore(Path(runtime.data_dir) / "record.sqlite")
        self.approved: dict[str, dict[str, dict]] = {}  # device -> approved parameter set
        self.snapshots: dict[str, dict[str, dict]] = {}  # device -> its last snapshot's set
        self.runs: dict[str, CheckoutRun] = {}  # device -> the checkout running or last run in this process
        self._watches = []
        self._task: asyncio.Task | None = None
        self._audit_seen = 0.0
        self.problem = ""

    # -- storage -----------------------------------------------------------------------------
    async def add(self, device: str, kind: str, *, user: str, role: str, data: dict, title: str = "",
                  supersedes: int | None = None) -> int:
        if role != "engineer":
            raise PermissionError(f"{user} has the {role or 'no'} role and may not add to the commissioning record")
        try:
            return await self.store.run(self.store.add, plant=self.plant, device=device, kind=kind, user=user, role=role,
                                        data=data, title=title, supersedes=supersedes)
        except RecordError as exc:
            self.problem = str(exc)
            raise

    async def timeline(self, device: str | None = None, kinds: tuple[str, ...] = ()) -> list[Entry]:
        return await self.store.run(self.store.list, self.plant, device, kinds)

    async def get(self, entry_id: int) -> Entry | None:
        return await self.store.run(self.store.get, entry_id)

    async def start(self) -> None:
        for name in self.runtime.store.devices:
            latest = await self.store.run(self.store.latest, self.plant, name, "approved")
            if latest is not None:
                self.approved[name] = latest.data["parameters"]
            snap = await self.store.run(self.store.latest, self.plant, name, "snapshot")
            if snap is not None:
                self.snapshots[name] = snap.data["parameters"]
            self._watches.append(self.runtime.store.watch(name, lambda n=name: self.check_drift(n), slow=True))
            self.check_drift(name)
        self._audit_seen = time.time()
        self._task = asyncio.create_task(self._follow_audit(), name="record: auto snapshots")

    async def stop(self) -> None:
        for w in self._watches:
            w.cancel()
        if self._task is not None:
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)
        for run in self.runs.values():
            run.abort("the program is stopping")
        self.store.close()

    # -- drift ------------------------------------------------------------------------------
    def check_drift(self, device: str) -> list[dict]:
        """Drift of ``device``; while a checkout runs on it, what changed since the run started (the
        checkout's own writes, e.g. the HD-Lock's LockRequestSource) is listed as "checkout running",
        not as drift; the run checks again when it ends (its cleanup restores what it changed)."""
        state = self.runtime.store.devices[device]
        approved = self.approved.get(device)
        rows = [] if approved is None else drift_of(state, approved, self.snapshots.get(device))
        run = self.runs.get(device)
        during: list[dict] = []
        if run is not None and run.status == "running":
            during = [r for r in rows if r["key"] not in run.drift_before]
            rows = [r for r in rows if r["key"] in run.drift_before]
        drift = {"approved": approved is not None, "changed": rows}
        if during:
            drift["checkout"] = during
        if getattr(state, "drift", None) != drift:
            state.drift = drift
            text = ("no approved set" if approved is None else
                    "equal to the approved set" if not rows else
                    "changed since approved: " + ", ".join(f"{r['name']} {r['approved']} -> {r['now']}" for r in rows))
            if during:
                text += "; checkout running: " + ", ".join(f"{r['name']} {r['now']}" for r in during)
            state.publish(DRIFT_POINT, len(rows) if approved is not None else None, periodic=False, text=text)
        return rows

    # -- approved set and snapshots ---------------------------------------------------------
    async def read_set(self, device: str, *, user: str, role: str) -> tuple[dict, list[dict]]:
        """Identity and every parameter, read fresh through the worker (a read: no audit row)."""
        from app.backup import supports_backup

        adapter = self.runtime.worker.adapters[device]
        if not supports_backup(adapter):
            raise RecordError(f"{device}: this device has no parameter set to read")
        entries = await self.runtime.worker.invoke(device, READ_PARAMETERS, user=user, role=role)
        return adapter.backup_identity(), entries

    async def snapshot(self, device: str, *, user: str, role: str, title: str = "on demand") -> int:
        identity, entries = await self.read_set(device, user=user, role=role)
        params = param_set(entries)
        entry_id = await self.add(device, "snapshot", user=user, role=role, title=title,
                                  data={"identity": identity, "parameters": params})
        self.snapshots[device] = params
        self.check_drift(device)
        return entry_id

    async def approve(self, device: str, *, user: str, role: str, document: dict | None = None, title: str = "",
                      account: str = "") -> int:
        """Approve a set: a backup document's, or (None) the device's as read now. ``account``: the named
        account that approved (the page and the CLI ask for one); it is the row's user."""
        if document is not None:
            if document.get("device", {}).get("type") != self.runtime.store.devices[device].type:
                raise RecordError(f"the backup is of a {document.get('device', {}).get('type')!r}, not of {device}'s type")
            identity, params = document.get("identity") or {}, param_set(document["parameters"])
            source = f"backup of {document.get('time', '?')}"
        else:
            identity, entries = await self.read_set(device, user=user, role=role)
            params, source = param_set(entries), "the device as read at approval"
        previous = await self.store.run(self.store.latest, self.plant, device, "approved")
        entry_id = await self.add(device, "approved", user=account or user, role=role, title=title or f"approved from {source}",
                                  data={"identity": identity, "parameters": params, "source": source,
                                        **({"account": account} if account else {})},
                                  supersedes=previous.id if previous else None)
        self.approved[device] = params
        self.check_drift(device)
        return entry_id

    async def _follow_audit(self) -> None:
        """A write session ends with Save-Settings or a restore: take a snapshot then (by itself)."""
        audit = self.runtime.audit
        while True:
            await asyncio.sleep(AUDIT_FOLLOW_S)
            try:
                rows = await audit.aquery(since=self._audit_seen, limit=200)
            except Exception:  # noqa: BLE001 - the audit state is shown in the header
                continue
            due: dict[str, tuple[str, str, str]] = {}
            for row in sorted(rows, key=lambda r: r.time):
                self._audit_seen = max(self._audit_seen, row.time + 1e-6)
                if row.action in AUTO_SNAPSHOT_ACTIONS and row.result.startswith("ok") and row.device in self.runtime.store.devices:
                    due[row.device] = (row.user, row.role, row.action)
            for device, (user, role, action) in due.items():
                try:
                    await self.snapshot(device, user=user, role=role, title=f"after {action}")
                except Exception as exc:  # noqa: BLE001 - logged; the next write session tries again
                    log.warning("%s: automatic snapshot after %s failed: %s", device, action, exc)

    # -- checkouts --------------------------------------------------------------------------
    def new_run(self, device: str, **kwargs) -> CheckoutRun:
        current = self.runs.get(device)
        if current is not None and current.status == "running":
            raise RecordError(f"{device}: a checkout is running already")
        run = CheckoutRun(self.runtime, device, **kwargs)
        drift = getattr(self.runtime.store.devices[device], "drift", None) or {}
        run.drift_before = {r["key"] for r in drift.get("changed", [])}  # drift that was there before the run
        self.runs[device] = run
        return run

    # -- sign-off ---------------------------------------------------------------------------
    async def sign(self, device: str, *, user: str, role: str, name: str, signer_role: str, comment: str, content: dict,
                   account: str = "") -> int:
        """Freeze ``content`` (the report) with a signature; a newer sign-off supersedes this one.

        ``account``: the named account that signed (logged in at that moment, also on the loopback
        address): a sign-off without one is refused."""
        if not account or account == "local" or account.startswith("cli:"):
            raise RecordError("a sign-off needs a named account: log in with your account (create one with "
                              "'commission user add NAME --role engineer') and sign again")
        users = getattr(self.runtime, "users", None)
        known = None if users is None else users.users.get(account)
        if users is not None and (known is None or known.role != "engineer"):
            raise RecordError(f"{account} is no engineer account of this installation: a sign-off needs one "
                              "(commission user add NAME --role engineer)")
        previous = await self.store.run(self.store.latest, self.plant, device, "signoff")
        return await self.add(device, "signoff", user=account, role=role, title=f"signed by {name} ({signer_role}) as {account}",
                              supersedes=previous.id if previous else None,
                              data={"name": name, "role": signer_role, "account": account, "comment": comment, "time": time.time(),
                                    "sha256": content_sha256(content), "content": content})

    async def check(self) -> Check:
        """The record's chain, sign-offs and protection as ``commission verify --record`` checks them."""
        return await self.store.run(self.store.verify)
