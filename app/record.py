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

This module holds the service a running plant keeps (``runtime.record``); its parts live beside it:
the store (app/record_store.py), parameter sets, diffs and drift (app/record_sets.py) and the
checkout runner (app/checkout.py). Their names are importable from here too.
"""

from __future__ import annotations

import asyncio
import logging
import time
from pathlib import Path
from typing import NamedTuple

from app.aio import end_tasks
from app.audit import WRITE_ERRORS
from app.checkout import CheckoutRun, role_refusal
from app.i18n import N_
from app.message import Message
from app.record_sets import drift_of, param_set
from app.record_store import Entry, RecordError, RecordStore
from app.verify import Check, content_sha256
from devices.commands import READ_PARAMETERS
from devices.errors import CommissionError

log = logging.getLogger(__name__)

DRIFT_POINT = "Changed since approved"


# -- the service the runtime holds -------------------------------------------------------------
AUTO_SNAPSHOT_ACTIONS = ("Save-Settings", "restore: save step", "restore")  # the end of a write session
AUDIT_FOLLOW_S = 1.0
UNFINISHED_FORGET_S = 900.0  # an audit row still "started" after this long (its action never ended) is not waited for
SNAPSHOT_TRIES = 4  # an automatic snapshot that fails (the device busy storing, a timeout) is tried again ...
SNAPSHOT_RETRY_S = 3.0  # ... this long after, so that the record holds the set a write session ended with
STOP_WAIT_S = 2.0  # the longest stop() waits for the snapshot task to end


class _Due(NamedTuple):
    """An automatic snapshot to take: for whom (the audit row's user and role), after which action, how often it
    failed so far, and not before ``at`` (``time.monotonic()``)."""

    user: str
    role: str
    action: str
    tries: int = 0
    at: float = 0.0


class RecordService:
    """The commissioning record of one running plant (``runtime.record``)."""

    def __init__(self, runtime):
        self.runtime = runtime
        self.plant = runtime.plant.name
        self.store = RecordStore(Path(runtime.data_dir) / "record.sqlite")
        self.approved: dict[str, dict[str, dict]] = {}  # device -> approved parameter set
        self.snapshots: dict[str, dict[str, dict]] = {}  # device -> its last snapshot's set
        self.runs: dict[str, CheckoutRun] = {}  # device -> the checkout running or last run in this process
        self.rows_added: dict[str, int] = {}  # device ("" the plant) -> rows added for it in this process (pages follow it)
        self._watches = []
        self._task: asyncio.Task | None = None
        self._audit_seen = 0.0  # audit rows from this time on are read again: the oldest one still running, or newer
        self._audit_acted: dict[int, float] = {}  # rows from _audit_seen on that were acted on already: id -> time
        self._snapshots_due: dict[str, _Due] = {}  # device -> the automatic snapshot to take
        self.problem = ""

    # -- storage -----------------------------------------------------------------------------
    async def add(self, device: str, kind: str, *, user: str, role: str, data: dict, title: str = "",
                  supersedes: int | None = None) -> int:
        if role != "engineer":
            raise PermissionError(role_refusal(user, role, N_("{user} has the {role} role and may not add to the commissioning record"),
                                               N_("{user} has the no role and may not add to the commissioning record")))
        try:
            entry_id = await self.store.run(self.store.add, plant=self.plant, device=device, kind=kind, user=user, role=role,
                                            data=data, title=title, supersedes=supersedes)
        except RecordError as exc:
            self.problem = str(exc)
            raise
        self.rows_added[device] = self.rows_added.get(device, 0) + 1
        return entry_id

    async def timeline(self, device: str | None = None, kinds: tuple[str, ...] = ()) -> list[Entry]:
        return await self.store.run(self.store.list, self.plant, device, kinds)

    async def get(self, entry_id: int) -> Entry | None:
        return await self.store.run(self.store.get, entry_id)

    async def start(self, since: float | None = None) -> None:
        """Read the newest approved set and snapshot of each device and follow the audit from ``since`` (the wall time
        the program started: a write session that ended while the devices came up and this ran is acted on too)."""
        since = time.time() if since is None else since
        for name in self.runtime.store.devices:
            latest = await self.store.run(self.store.latest, self.plant, name, "approved")
            if latest is not None:
                self.approved[name] = latest.data["parameters"]
            snap = await self.store.run(self.store.latest, self.plant, name, "snapshot")
            if snap is not None:
                self.snapshots[name] = snap.data["parameters"]
            self._watches.append(self.runtime.store.watch(name, lambda n=name: self.check_drift(n), slow=True))
            self.check_drift(name)
        self._audit_seen = since
        self._task = asyncio.create_task(self._follow_audit(), name="record: auto snapshots")

    async def stop(self) -> None:
        for w in self._watches:
            w.cancel()
        if self._task is not None:
            # bounded and cancelled again: a stop must end even where the task's cancellation is not delivered (seen
            # once in ~10 test runs under load, the task left "cancelling" in its sleep); it holds nothing to close
            await end_tasks([self._task], "record: automatic snapshots", STOP_WAIT_S)
            self._task = None
        for run in self.runs.values():
            run.abort(Message(N_("the program is stopping")))
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
        if state.drift != drift:
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
            raise RecordError(Message(N_("{device}: this device has no parameter set to read"), device=device))
        entries = await self.runtime.worker.gate.invoke(device, READ_PARAMETERS, user=user, role=role)
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
                raise RecordError(Message(N_("the backup is of a {type!r}, not of {device}'s type"),
                                          type=document.get("device", {}).get("type"), device=device))
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
        self.runtime.replacements.approved(device, identity)
        self.check_drift(device)
        return entry_id

    async def _follow_audit(self) -> None:
        """A write session ends with Save-Settings or a restore: take a snapshot then (by itself), and again a few
        times while it fails (SNAPSHOT_TRIES, SNAPSHOT_RETRY_S apart: a device still storing, a timeout on a busy
        line), so that the record holds the set the session ended with."""
        audit = self.runtime.audit
        due = self._snapshots_due
        while True:
            await asyncio.sleep(AUDIT_FOLLOW_S)
            try:
                rows = await audit.aquery(since=self._audit_seen, limit=200)
            except WRITE_ERRORS:  # the audit state is shown in the header
                rows = []
            for row in self._finished_rows(rows):
                if row.action in AUTO_SNAPSHOT_ACTIONS and row.result.startswith("ok") and row.device in self.runtime.store.devices:
                    due[row.device] = _Due(row.user, row.role, row.action)  # a new session's end: tried afresh
            now = time.monotonic()
            for device, job in list(due.items()):
                if job.at > now:
                    continue
                del due[device]  # only this task changes what is due
                try:
                    await self.snapshot(device, user=job.user, role=job.role, title=f"after {job.action}")
                except (CommissionError, OSError) as exc:
                    tries = job.tries + 1
                    again = tries < SNAPSHOT_TRIES
                    log.warning("%s: automatic snapshot after %s failed (%d of %d)%s: %s", device, job.action, tries,
                                SNAPSHOT_TRIES, f"; tried again in {SNAPSHOT_RETRY_S:g} s" if again else "", exc)
                    if again:
                        due[device] = job._replace(tries=tries, at=time.monotonic() + SNAPSHOT_RETRY_S)

    def _finished_rows(self, rows: list) -> list:
        """The audit rows not acted on yet whose action has ended, oldest first.

        The gate writes a row before its action runs (result ``started``) and finishes it with the outcome: a row
        read while its action still ran (a Save-Settings that takes a while on a busy line) is read again until it
        has ended, so the session's end is never missed."""
        wall = time.time()
        running = {r.id: r.time for r in rows if r.result == "started" and wall - r.time < UNFINISHED_FORGET_S}
        finished = []
        for row in sorted(rows, key=lambda r: (r.time, r.id)):
            if row.id in self._audit_acted or row.id in running:
                continue
            self._audit_acted[row.id] = row.time
            finished.append(row)
        if rows:
            self._audit_seen = min(running.values()) if running else max(r.time for r in rows) + 1e-6
            self._audit_acted = {i: t for i, t in self._audit_acted.items() if t >= self._audit_seen}
        return finished

    # -- checkouts --------------------------------------------------------------------------
    def new_run(self, device: str, **kwargs) -> CheckoutRun:
        current = self.runs.get(device)
        if current is not None and current.status == "running":
            raise RecordError(Message(N_("{device}: a checkout is running already"), device=device))
        run = CheckoutRun(self.runtime, device, **kwargs)
        drift = self.runtime.store.devices[device].drift or {}
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
            raise RecordError(Message(N_("a sign-off needs a named account: log in with your account (create one with "
                                         "'commission user add NAME --role engineer') and sign again")))
        known = self.runtime.users.users.get(account)
        if known is None or known.role != "engineer":
            raise RecordError(Message(N_("{account} is no engineer account of this installation: a sign-off needs one "
                                         "(commission user add NAME --role engineer)"), account=account))
        previous = await self.store.run(self.store.latest, self.plant, device, "signoff")
        return await self.add(device, "signoff", user=account, role=role, title=f"signed by {name} ({signer_role}) as {account}",
                              supersedes=previous.id if previous else None,
                              data={"name": name, "role": signer_role, "account": account, "comment": comment, "time": time.time(),
                                    "sha256": content_sha256(content), "content": content})

    async def check(self) -> Check:
        """The record's chain, sign-offs and protection as ``commission verify --record`` checks them."""
        return await self.store.run(self.store.verify)
