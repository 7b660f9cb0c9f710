"""Replaced devices: detection from the live identity, and the replacement assistant's steps.

Detection is generic: every device whose adapter takes part in backup publishes its identity
(``backup_identity()``, read from the live store: serial number, firmware, hardware or product).
Each device is compared with its *known* identity, the newest of

- the identity recorded with its approved set (app/record.py),
- the identity an engineer accepted at the end of a replacement (``identities.json`` in the data
  folder), or, when neither exists, the first identity seen (kept there too).

The comparison costs O(1) per device while nothing changes: on every push of the store the watch
builds a cheap key of what the identity is made of (the register words or live points it was read
from, found once by matching the identity's values against the store; or, for an adapter whose
identity is not in the store under its names, the few values ``backup_identity()`` returns, asked at
most every CHECK_PERIOD_S) and reads and compares the whole identity only when that key moved.

A device answering at its address with another serial number, firmware or variant than known
carries ``DeviceState.replaced`` (old and new identity, what differs): the overview and the
device page say "replaced?", and the event log has a line.

The assistant (pages/replace.py) checks the identity (type and variant must match; a firmware or
hardware difference is named, with the parameters the new device lacks or adds against the
approved set), shows the approved set against the new device as restore's diff, writes through
restore's verified path (app/backup.py, the gate), runs the save step, and records the whole
replacement in the device's timeline (kind ``restore``) and the audit log.
"""

from __future__ import annotations

import asyncio
import json
import logging
import re
import time
from dataclasses import dataclass, field
from typing import Any

from app import audit, backup
from app.i18n import N_
from app.message import Message, joined
from app.record_store import Entry
from devices.adapter import BackupAdapter
from devices.errors import CommissionError

log = logging.getLogger(__name__)

IDENTITY_FILE = "identities.json"
CHECK_PERIOD_S = 0.25  # an identity the store does not hold is asked of its adapter at most this often (and every half poll)
SERIAL_KEYS = ("serial", "SerialNumber")
FIRMWARE_KEYS = ("FirmwareVersion", "firmware", "version", "sw_version")
HARDWARE_KEYS = ("HardwareVersion", "hardware")
VARIANT_KEYS = ("variant", "product", "model")
FACET_KEYS = (SERIAL_KEYS, FIRMWARE_KEYS, HARDWARE_KEYS, VARIANT_KEYS)
# The keys of the identities the device types give (``backup_identity``) besides the facets' words (app/report.py's
# WORDS): labelled in the catalogs, so the record page's preview, the report and the backup page name them in the
# reader's language; the record and the backup files keep the keys as they are.
IDENTITY_KEYS = (N_("FirmwareVersion"), N_("HardwareVersion"), N_("actuators"), N_("configuration"), N_("port"),
                 N_("baudrate"), N_("product"), N_("version"), N_("sw1"), N_("device code"), N_("program version"),
                 N_("mac"), N_("transport"))
# Where a known identity came from: kept in the watch's file as the English, and read back as the message it was
APPROVED_SET, FIRST_SEEN, REPLACED_BY = N_("approved set"), N_("first seen"), N_("replacement by {user}")
SOURCES = (APPROVED_SET, FIRST_SEEN, REPLACED_BY)
_MISSING = object()


def _pick(identity: dict, keys: tuple[str, ...]) -> Any:
    for key in keys:
        if identity.get(key) not in (None, ""):
            return identity[key]
    return None


def facets(identity: dict | None) -> dict[str, Any]:
    """An identity's serial, firmware, hardware and variant, whatever the device type calls them."""
    identity = identity or {}
    return {"serial": _pick(identity, SERIAL_KEYS), "firmware": _pick(identity, FIRMWARE_KEYS),
            "hardware": _pick(identity, HARDWARE_KEYS), "variant": _pick(identity, VARIANT_KEYS)}


FACET_WORDS = {"serial": N_("serial {value}"), "firmware": N_("firmware {value}"), "hardware": N_("hardware {value}"),
               "variant": N_("variant {value}")}


def source_message(text: object) -> str:
    """Where a known identity came from, as the watch's file holds it (the English of one of :data:`SOURCES`), as
    the :class:`Message` it was written from, so a page words it after a restart; any other text as it is."""
    text = str(text or "")
    for template in SOURCES:
        pattern = re.sub(r"\\\{(\w+)\\\}", r"(?P<\1>.+)", re.escape(template))
        found = re.fullmatch(pattern, text)
        if found is not None:
            return Message(template, **found.groupdict())
    return text


def identity_text(identity: dict | None) -> Message:
    """"serial 660020, firmware 57" (English as stored in the record and the audit log; a page words it)."""
    f = facets(identity)
    parts = [Message(FACET_WORDS[k], value=v) for k, v in f.items() if v is not None]
    return joined(parts) if parts else Message(N_("unknown"))


def differences(old: dict | None, new: dict | None) -> list[str]:
    """The facets that differ between two identities (only those both name)."""
    a, b = facets(old), facets(new)
    return [k for k in a if a[k] is not None and b[k] is not None and str(a[k]) != str(b[k])]


def live_identity(runtime, name: str) -> dict | None:
    """The identity the device publishes now (None while it is not online or has not told it yet)."""
    adapter = runtime.worker.adapters.get(name)
    state = runtime.store.devices.get(name)
    if adapter is None or state is None or state.online is not True or not backup.supports_backup(adapter):
        return None
    identity = adapter.backup_identity()  # an identity not read yet has no serial number
    if not isinstance(identity, dict) or facets(identity)["serial"] is None:
        return None
    return dict(identity)


def identity_sources(state, identity: dict) -> tuple | None:
    """Where in the store each value of ``identity`` comes from: ``("point", name)`` or ``("words", ((space,
    address), ...))`` of a register parameter, found by name (or a name of the same facet, e.g. "serial" for
    "SerialNumber") and checked against the value. None when a value is found nowhere (the adapter keeps it)."""
    points = state.points
    params = state.params
    sources = []
    for key, value in identity.items():
        if value is None:
            return None
        names = (key, *next((g for g in FACET_KEYS if key in g), ()))
        for candidate in names:
            point = points.get(candidate)
            if point is not None:
                if point.value == value:
                    sources.append(("point", candidate))
                    break
                continue
            param = params.by_name.get(candidate) if params is not None else None
            if param is not None and state.value(candidate) == value:
                sources.append(("words", tuple((param.space, a) for a in param.addresses)))
                break
        else:
            return None
    return tuple(sources)


class ReplacementWatch:
    """Follows every device's published identity against its known one (``runtime.replacements``)."""

    def __init__(self, runtime):
        self.runtime = runtime
        self.path = runtime.data_dir / IDENTITY_FILE
        self.known: dict[str, dict] = {}  # device -> {"identity", "time", "source"}
        self._watches: list = []
        self._writing: asyncio.Task | None = None
        self._checked: dict[str, float] = {}  # device -> monotonic time its adapter was last asked (identity not in the store)
        self._keys: dict[str, tuple] = {}  # device -> the cheap key of its identity at the last comparison
        self._sources: dict[str, tuple | None] = {}  # device -> identity_sources() of its last identity
        # devices whose twin runs in this process and has not told its identity yet: a twin starts from the plant
        # file at every start, so another identity than the last run left is the simulated plant reset, no swap
        self._fresh_twins: set[str] = set()

    def _load(self) -> dict:
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return {}
        plant = data.get(self.runtime.plant.name) if isinstance(data, dict) else None
        return plant if isinstance(plant, dict) else {}

    def _save(self, known: dict) -> None:
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
            if not isinstance(data, dict):
                data = {}
        except (OSError, ValueError):
            data = {}
        data[self.runtime.plant.name] = known
        backup.write_atomic(self.path, json.dumps(data, indent=1, default=str))

    def _persist(self) -> None:
        known = json.loads(json.dumps(self.known, default=str))

        async def write() -> None:
            try:
                await asyncio.to_thread(self._save, known)
            except OSError as exc:
                log.error("cannot keep the known device identities in %s: %s", self.path, exc)

        self._writing = asyncio.get_running_loop().create_task(write(), name="known identities")

    async def start(self) -> None:
        stored = await asyncio.to_thread(self._load)
        record = self.runtime.record
        for name in self.runtime.store.devices:
            if not backup.supports_backup(self.runtime.worker.adapters.get(name)):
                continue
            ref = stored.get(name) if isinstance(stored.get(name), dict) else None
            if ref is not None:
                ref = {**ref, "source": source_message(ref.get("source"))}
            approved: Entry | None = await record.store.run(record.store.latest, record.plant, name, "approved")
            if approved is not None and approved.data.get("identity") and facets(approved.data["identity"])["serial"] is not None:
                if ref is None or float(ref.get("time") or 0) < approved.time:
                    ref = {"identity": approved.data["identity"], "time": approved.time, "source": Message(APPROVED_SET)}
            if ref is not None:
                self.known[name] = ref
            if name in self.runtime.twins:
                self._fresh_twins.add(name)
            self._watches.append(self.runtime.store.watch(name, lambda n=name: self._maybe_check(n)))
            self.check(name)

    async def stop(self) -> None:
        for w in self._watches:
            w.cancel()
        if self._writing is not None:
            await asyncio.gather(self._writing, return_exceptions=True)

    def _key(self, name: str) -> tuple:
        """What the published identity is made of, cheaply (O(1) per device): the identity is read and
        compared again only when this moved. Covers every input of :func:`live_identity`: online, the
        adapter taking part, and the identity's register words or points (new ones appearing too)."""
        state = self.runtime.store.devices[name]
        adapter = self.runtime.worker.adapters.get(name)
        if adapter is None or state.online is not True:
            return (False,)
        sources = self._sources.get(name)
        if sources is None:  # not in the store under its names: the adapter's own few values
            identity = adapter.backup_identity() if isinstance(adapter, BackupAdapter) else _MISSING
            return (True, (not isinstance(adapter, BackupAdapter) or adapter.backup_available), id(state.params), identity)
        points, registers = state.points, state.registers
        key = [True, (not isinstance(adapter, BackupAdapter) or adapter.backup_available), id(state.params), len(points), len(registers)]
        for kind, where in sources:
            if kind == "point":
                point = points.get(where)
                key.append(_MISSING if point is None else point.value)
            else:
                for address in where:
                    entry = registers.get(address)
                    key.append(_MISSING if entry is None else entry[0])
        return tuple(key)

    def _period(self, name: str) -> float:
        bus = self.runtime.plant.buses.get(self.runtime.store.devices[name].bus)
        poll = bus.options.get("poll_period") if bus is not None else None
        return min(CHECK_PERIOD_S, poll / 2) if isinstance(poll, int | float) and poll > 0 else CHECK_PERIOD_S

    def _maybe_check(self, name: str) -> None:
        """From the store's push: the identity is read and compared only when its key moved (an identity
        the store does not hold: its adapter is asked at most every CHECK_PERIOD_S, as before)."""
        if self._sources.get(name) is None:
            now = time.monotonic()
            if now - self._checked.get(name, 0.0) < self._period(name):
                return
            self._checked[name] = now
        key = self._key(name)
        if self._keys.get(name, _MISSING) != key:
            self.check(name)

    def check(self, name: str) -> dict | None:
        """Compare the published identity with the known one; sets ``state.replaced`` (or clears it)."""
        state = self.runtime.store.devices[name]
        now = live_identity(self.runtime, name)
        self._sources[name] = None if now is None else identity_sources(state, now)
        self._keys[name] = self._key(name)
        if now is None:
            return state.replaced
        ref = self.known.get(name)
        if name in self._fresh_twins:
            self._fresh_twins.discard(name)
            if ref is not None and differences(ref["identity"], now):
                state.event("info", Message(N_("simulated plant started afresh: the twin has the plant file's identity "
                                               "({now}) and factory settings again, not those of the last run ({known}); "
                                               "taken as known"), now=identity_text(now), known=identity_text(ref["identity"])))
                ref = None
        if ref is None:  # first seen: this is the device as installed
            self.known[name] = {"identity": now, "time": time.time(), "source": Message(FIRST_SEEN)}
            self._persist()
            return None
        differ = differences(ref["identity"], now)
        replaced = {"old": ref["identity"], "new": now, "differs": differ, "source": ref.get("source", ""),
                    "since": time.time()} if differ else None
        before = state.replaced
        if (before or {}).get("new") == (replaced or {}).get("new") and bool(before) == bool(replaced):
            return before
        version = state.version
        state.replaced = replaced
        if replaced:
            state.event("warning", Message(N_("replaced? {facets} differ: known {known} ({source}), now {now}"),
                                           facets=joined([Message(facet) for facet in differ]),  # the facets' words (app/report.py)
                                           known=identity_text(ref["identity"]), source=ref.get("source", ""),
                                           now=identity_text(now)))
        elif before:
            state.event("info", Message(N_("identity as known again: {identity}"), identity=identity_text(now)))
        state.version = version  # the events above and the record's change: one change for its readers
        state.touch()
        return replaced

    def approved(self, name: str, identity: dict) -> None:
        """A set was approved: its identity is the reference from now on, as at start-up (:meth:`start`), so a
        unit swapped after the approval is named even where this watch had not compared the unit yet."""
        if name in self.runtime.store.devices and identity and facets(identity)["serial"] is not None:
            self._fresh_twins.discard(name)
            self.accept(name, identity, Message(APPROVED_SET))

    def accept(self, name: str, identity: dict, source: str) -> None:
        """The engineer took the device as it is now (end of a replacement): its identity becomes the known one."""
        self.known[name] = {"identity": dict(identity), "time": time.time(), "source": source}
        self._persist()
        self.check(name)


def watch_of(runtime) -> ReplacementWatch | None:
    return runtime.replacements


# -- the assistant ---------------------------------------------------------------------------------


@dataclass
class IdentityCheck:
    device: str
    device_type: str
    old: dict
    new: dict
    ok: bool
    refusals: list[str] = field(default_factory=list)  # type or variant do not match: nothing is written (Messages)
    notes: list[str] = field(default_factory=list)  # serial, firmware, hardware differences named (Messages)
    lacks: list[str] = field(default_factory=list)  # approved parameters the new device does not have
    adds: list[str] = field(default_factory=list)  # parameters of the new device the approved set does not name

    def as_dict(self) -> dict:
        return {"device": self.device, "type": self.device_type, "old": self.old, "new": self.new, "ok": self.ok,
                "refusals": self.refusals, "notes": self.notes, "lacks": self.lacks, "adds": self.adds}


async def approved_document(runtime, name: str) -> tuple[dict, str]:
    """The device's approved set as a backup document (what the assistant restores), and its source."""
    record = runtime.record
    entry = await record.store.run(record.store.latest, record.plant, name, "approved")
    source = Message(N_("approved set"))
    if entry is None:
        entry = await record.store.run(record.store.latest, record.plant, name, "snapshot")
        source = Message(N_("last snapshot (no approved set)"))
    if entry is None:
        raise backup.BackupError(Message(N_("{name}: the record holds no approved set and no snapshot to restore from"), name=name))
    return set_document(runtime, name, entry.data.get("parameters") or {}, entry.data.get("identity") or {},
                        Message("{source} #{id}", source=source, id=entry.id)), \
        Message("{source} #{id} ({title})", source=source, id=entry.id, title=entry.title)


def set_document(runtime, name: str, params: dict[str, dict], identity: dict, source: str) -> dict:
    """A parameter set of the record (``{key: {name, raw, text, unit, writable}}``) as a backup document:
    each value derived from its raw word through the device type's parameter model."""
    state = runtime.store.devices[name]
    model = state.params
    entries = []
    for key, ref in params.items():
        param = model.by_key.get(key) if model is not None else None
        raw = ref.get("raw")
        value = param.decode(int(raw)) if param is not None and isinstance(raw, int) else raw
        entries.append({"key": key, "name": ref.get("name", key), "raw": raw, "value": value, "text": ref.get("text", ""),
                        "unit": ref.get("unit", ""), "writable": bool(ref.get("writable"))})
    document = backup.make_document(runtime.plant.name, name, state.type, state.bus, identity, entries)
    document["source"] = source
    return document


def _variant_of(runtime, name: str) -> Any:
    config = runtime.plant.devices.get(name)
    return None if config is None else config.options.get("variant")


async def check_identity(runtime, name: str, document: dict, current_keys: set[str] | None = None) -> IdentityCheck:
    """Type and variant must match; serial, firmware and hardware differences are named, with the
    parameters the device lacks or adds against the set (``current_keys``: the device's parameter keys)."""
    state = runtime.store.devices[name]
    new = live_identity(runtime, name) or {}
    old = document.get("identity") or {}
    check = IdentityCheck(name, state.type, old, new, True)
    doc_type = (document.get("device") or {}).get("type")
    if doc_type != state.type:
        check.refusals.append(Message(N_("the set is of a {type!r}, the device is a {device_type!r}"), type=doc_type,
                                      device_type=state.type))
    a, b = facets(old), facets(new)
    variant_now = b["variant"] if b["variant"] is not None else _variant_of(runtime, name)
    if a["variant"] is not None and variant_now is not None and str(a["variant"]) != str(variant_now):
        check.refusals.append(Message(N_("variant {then} in the set, {now} on the device"), then=a["variant"], now=variant_now))
    if not new:
        check.refusals.append(Message(N_("the device has not told its identity (not answering?)")))
    # a set taken from another device (a batch's source) has that device's serial: no sign of a replacement
    own = (document.get("device") or {}).get("name") in (None, name)
    if own and a["serial"] is not None and b["serial"] is not None and str(a["serial"]) != str(b["serial"]):
        check.notes.append(Message(N_("serial number {then} -> {now} (the replacement)"), then=a["serial"], now=b["serial"]))
    for facet, words in (("firmware", N_("firmware version {then} -> {now}")), ("hardware", N_("hardware version {then} -> {now}"))):
        if a[facet] is not None and b[facet] is not None and str(a[facet]) != str(b[facet]):
            check.notes.append(Message(words, then=a[facet], now=b[facet]))
    if current_keys is not None:
        names = {e["key"]: e["name"] for e in document.get("parameters", [])}
        check.lacks = [names[k] for k in names if k not in current_keys]
        model = state.params
        check.adds = [(p.label or p.name) for p in (model or []) if p.key in current_keys and p.key not in names and p.setting]
    if any(n.startswith("firmware") for n in check.notes):
        if check.lacks or check.adds:
            check.notes.append(Message(N_("with the new firmware the device lacks {lacks} and adds {adds} parameter(s) against "
                                          "the set (listed below)"), lacks=len(check.lacks), adds=len(check.adds)))
        else:
            check.notes.append(Message(N_("the parameter model knows no parameter that this firmware lacks or adds: the same "
                                          "parameters on both")))
    check.ok = not check.refusals
    return check


@dataclass
class ReplacementPlan:
    check: IdentityCheck
    plan: backup.RestorePlan | None
    source: str


async def plan_replacement(runtime, name: str, progress=None) -> ReplacementPlan:
    """Identity check and the approved set against the new device as restore's diff (reads only)."""
    document, source = await approved_document(runtime, name)
    adapter = runtime.worker.adapters[name]
    check = await check_identity(runtime, name, document)
    if not check.ok:
        return ReplacementPlan(check, None, source)
    plan = await backup.plan_restore(runtime, name, document, progress)
    current = {e["key"] for e in await adapter.backup_read()}
    check = await check_identity(runtime, name, document, current)
    return ReplacementPlan(check, plan, source)


async def execute_replacement(runtime, rp: ReplacementPlan, selected: set[str], *, user: str, role: str,
                              confirmed: set[str] = frozenset(), progress=None) -> backup.RestoreReport:
    """Write the selected rows through restore's verified path (gate, read-back, save step), then record
    the replacement in the device's timeline and the audit log and take the new identity as known."""
    if rp.plan is None or not rp.check.ok:
        raise backup.BackupError(joined(rp.check.refusals, "; ") or Message(N_("no plan")))
    name = rp.plan.device
    report = await backup.execute_restore(runtime, rp.plan, selected, user=user, role=role, confirmed=confirmed,
                                          progress=progress)
    summary = f"replacement: {identity_text(rp.check.old)} -> {identity_text(rp.check.new)}: {report.summary()}"
    try:
        await runtime.audit.arecord(user=user, role=role, device=name, action="replacement",
                                    old=identity_text(rp.check.old), new=identity_text(rp.check.new), result=summary[:500])
    except audit.WRITE_ERRORS:  # every write has its own row; the header shows the audit state
        pass
    data = {"replacement": rp.check.as_dict(), "source": rp.source, "selected": sorted(selected),
            "written": report.written, "unchanged": report.unchanged, "failed": report.failed, "skipped": report.skipped,
            "refused": report.refused, "saved": report.saved, "save_error": report.save_error, "summary": report.summary(),
            "identity": rp.check.new}
    try:
        await runtime.record.add(name, "restore", user=user, role=role, data=data,
                                 title=f"replacement {identity_text(rp.check.old)} -> {identity_text(rp.check.new)}")
    except (CommissionError, OSError) as exc:  # said in the report; the writes are in the audit log
        report.save_error = report.save_error or ""
        log.error("%s: the replacement could not be added to the record: %s", name, exc)
    if report.ok:
        watch = watch_of(runtime)
        if watch is not None:
            watch.accept(name, rp.check.new, Message(REPLACED_BY, user=user))
    return report
