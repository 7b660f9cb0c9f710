"""Parameter backup and restore, for every device type that offers it.

A device adapter takes part by providing:

- ``async backup_read(progress) -> list[dict]``: every parameter freshly read, each
  ``{key, name, space, address, raw, value, unit, writable}``;
- ``backup_identity() -> dict``: serial number, firmware and the like;
- ``async write_param(param, value, *, confirmed)`` where the device has a parameter
  model (``state.params``): restore writes through the same checked path as a manual
  entry; else ``async restore_entry(key, value) -> value``: write one writable entry
  with validation and return what was read back (raises when it did not take);
- ``async save_step() -> str | None``: make the written values permanent (the name
  of the step), or None when the device stores every write by itself.

Files: one JSON document per device (schema ``commission-backup`` version 1), written
atomically; a whole plant downloads as one zip archive.
"""

from __future__ import annotations

import asyncio
import json
import os
import tempfile
import time
import zipfile
from dataclasses import dataclass, field
from datetime import datetime, timezone
from functools import partial
from importlib import metadata
from pathlib import Path
from typing import Any

from app import audit, files, gate
from app.capabilities import takes_text
from app.i18n import N_
from app.message import Message, joined, message_of
from devices.adapter import BackupAdapter, EntryRestorer, ParamWriter, RestoreDescriber
from devices.commands import WRITE_PARAMETER
from devices.commands import find as find_command
from devices.errors import CommissionError
from devices.params import Accepted

SCHEMA = "commission-backup"
VERSION = 1


class BackupError(CommissionError, ValueError):
    """A backup that cannot be made, read or restored; the message says which and why."""


def tool_version() -> str:
    try:
        return metadata.version("commission")
    except metadata.PackageNotFoundError:
        return "unknown"


NOTHING_HERE = N_("nothing to back up in this configuration")


def supports_backup(adapter: Any) -> bool:
    """The adapter takes part, and (``backup_available``) this device has something to back up."""
    restores = isinstance(adapter, ParamWriter | EntryRestorer)
    return isinstance(adapter, BackupAdapter) and restores and bool(adapter.backup_available)


async def nothing_to_back_up(adapter: Any) -> str:
    """Why a device has nothing to back up, in words ("" when it has something; the adapter's own words, else a
    :class:`~app.message.Message`).

    An adapter that takes part but has no data in this configuration (``backup_available``
    False, e.g. an M3IO in unaddressed mode) names the reason when asked to read, without bus
    traffic; the question is bounded in time.
    """
    if supports_backup(adapter):
        return ""
    if isinstance(adapter, BackupAdapter) and adapter.backup_available is False:
        try:
            await asyncio.wait_for(adapter.backup_read(), timeout=2)
        except (CommissionError, TimeoutError) as exc:  # the refusal's reason is the message
            return message_of(exc) or Message(NOTHING_HERE)
        return Message(NOTHING_HERE)
    return Message(N_("this device type has no parameters to back up"))


# -- what pages ask of a device by name (they never hold an adapter: ARCHITECTURE.md rule 5) ----------------
def device_backs_up(runtime, name: str) -> bool:
    """Device ``name`` takes part in backup and restore and has something to back up (:func:`supports_backup`)."""
    return supports_backup(runtime.worker.adapters.get(name))


def backup_devices(runtime) -> list[str]:
    """The plant's devices that take part in backup, in the plant's order."""
    return [name for name in runtime.store.devices if device_backs_up(runtime, name)]


async def why_nothing_to_back_up(runtime, name: str) -> str:
    """:func:`nothing_to_back_up` of device ``name``."""
    return await nothing_to_back_up(runtime.worker.adapters.get(name))


def restore_refused(runtime, name: str) -> str:
    """Why device ``name``'s type takes no restore (its backup is a record only), or ""."""
    adapter = runtime.worker.adapters.get(name)
    return adapter.restore_refused if isinstance(adapter, BackupAdapter) else ""


def restore_wear(runtime, name: str) -> str:
    """What each restored write costs device ``name`` (an EEPROM's wear), or ""."""
    adapter = runtime.worker.adapters.get(name)
    return adapter.restore_wear if isinstance(adapter, BackupAdapter) else ""


def make_document(plant: str, device: str, device_type: str, bus: str, identity: dict, entries: list[dict], now: float | None = None,
                  *, user: str = "", role: str = "") -> dict:
    when = datetime.fromtimestamp(now or time.time(), tz=timezone.utc)
    return {
        "schema": SCHEMA,
        "version": VERSION,
        "device": {"name": device, "type": device_type, "bus": bus},
        "identity": identity,
        "plant": plant,
        "time": when.isoformat(timespec="seconds"),
        "taken_by": {"user": user, "role": role},  # who started the backup (the audit log has the same row)
        "tool": {"name": "commission", "version": tool_version()},
        "parameters": entries,
    }


def local_time(stamp: str) -> str:
    """A backup's time (ISO 8601, UTC in the file) in the local time of this machine, with its zone."""
    try:
        when = datetime.fromisoformat(stamp)
    except (TypeError, ValueError):
        return str(stamp or "?")
    if when.tzinfo is None:  # a file without a zone: written in UTC by this tool
        when = when.replace(tzinfo=timezone.utc)
    return when.astimezone().strftime("%Y-%m-%d %H:%M:%S %Z").strip()


def taken_by(document: dict) -> str:
    """Who started the backup ("" for files from before the name was kept)."""
    by = document.get("taken_by")
    if not isinstance(by, dict) or not by.get("user"):
        return ""
    return f"{by['user']} ({by['role']})" if by.get("role") else str(by["user"])


def file_name(device: str, now: float | None = None) -> str:
    return f"{device}-{datetime.fromtimestamp(now or time.time()):%Y%m%d-%H%M%S}.json"


def unused_path(path: Path) -> Path:
    """``path``, or with "-2", "-3", ... before the suffix when a file of that name exists
    (two backups of one device within a second must not replace each other)."""
    candidate, n = path, 1
    while candidate.exists():
        n += 1
        candidate = path.with_name(f"{path.stem}-{n}{path.suffix}")
    return candidate


def write_atomic(path: Path, text: str) -> Path:
    """Write ``text`` as a whole or not at all (:func:`app.files.replace_atomic`: a temporary file in the same
    folder, flushed to disk, then renamed), making the folder first. A crash or error part-way leaves at most a
    temporary file, never a partial file under the final name."""
    path.parent.mkdir(parents=True, exist_ok=True)
    files.replace_atomic(path, text)
    return path


async def backup_device(runtime, name: str, out_dir: Path | None = None, progress=None, *,
                        user: str = "local", role: str = "engineer") -> Path:
    """Read every parameter of one device and write its backup file (an engineer action,
    audited with the real user); returns the path."""
    adapter = runtime.worker.adapters[name]
    if not supports_backup(adapter):
        raise BackupError(Message(N_("{name}: this device type has no parameters to back up"), name=name))
    state = runtime.store.devices[name]
    path = await asyncio.to_thread(unused_path, (out_dir or runtime.backups_dir) / file_name(name))

    async def work() -> Path:
        entries = await adapter.backup_read(progress)
        document = make_document(runtime.plant.name, name, state.type, state.bus, adapter.backup_identity(), entries,
                                 user=user, role=role)
        await asyncio.to_thread(write_atomic, path, json.dumps(document, indent=2, ensure_ascii=False))
        return path

    return await runtime.worker.gate.run(work, user=user, role=role, describe="backup", device=name, new=path.name, kind="write")


def zip_files(paths: list[Path], target: Path) -> Path:
    """One archive of several backup files (whole-plant download)."""
    def build(tmp: Path) -> None:
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in paths:
                archive.write(path, path.name)

    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".part", dir=target.parent)
    os.close(fd)
    try:
        build(Path(tmp))
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target


MAX_BACKUP_BYTES = 5_000_000  # a backup of the largest register map is a few hundred kB (the Backup page says 5 MB)


def load_document(text: str | bytes, source: str = "backup") -> dict:
    """Parse and check a backup file; a corrupt, foreign, future or malicious file is refused by name
    (never with a traceback): too large, not UTF-8, not JSON, nested too deep, numbers too long,
    or fields of the wrong kind."""
    if len(text) > MAX_BACKUP_BYTES:
        raise BackupError(Message(N_("{source}: {size} MB is too large for a backup (at most {most} MB)"), source=source,
                                  size=f"{len(text) / 1e6:.1f}", most=f"{MAX_BACKUP_BYTES / 1e6:.0f}"))
    try:
        data = json.loads(text)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise BackupError(Message(N_("{source}: not a readable backup (truncated or not JSON: {error})"), source=source,
                                  error=exc)) from None
    except RecursionError:  # the decoder counts its depth: 200,000 nested brackets end here, not in a crash
        raise BackupError(Message(N_("{source}: not a backup: nested too deep"), source=source)) from None
    except ValueError as exc:  # e.g. a number of more than 4300 digits
        raise BackupError(Message(N_("{source}: not a readable backup: {error}"), source=source,
                                  error=str(exc).split(";")[0])) from None
    if not isinstance(data, dict) or data.get("schema") != SCHEMA:
        schema = data.get("schema") if isinstance(data, dict) else None
        raise BackupError(Message(N_("{source}: not a commission backup file (schema {schema!r})"), source=source,
                                  schema=str(schema)[:40]))
    if data.get("version") != VERSION:
        raise BackupError(Message(N_("{source}: backup schema version {version} is not supported (this tool reads version "
                                     "{supported})"), source=source, version=str(data.get("version"))[:20], supported=VERSION))
    device = data.get("device")
    params = data.get("parameters")
    if not isinstance(device, dict) or not isinstance(params, list):
        raise BackupError(Message(N_("{source}: the backup lacks its device or parameter list (damaged file)"), source=source))
    for key in ("name", "type", "bus"):
        if key in device and not isinstance(device[key], str):
            raise BackupError(Message(N_("{source}: the device's {key} is not a text (damaged file)"), source=source, key=key))
    for key in ("identity", "tool", "taken_by"):
        if data.get(key) is not None and not isinstance(data[key], dict):
            raise BackupError(Message(N_("{source}: \"{key}\" is not an object (damaged or edited file)"), source=source, key=key))
    for key in ("plant", "time"):
        if data.get(key) is not None and not isinstance(data[key], str):
            raise BackupError(Message(N_("{source}: \"{key}\" is not a text (damaged or edited file)"), source=source, key=key))
    for entry in params:
        if not isinstance(entry, dict) or not {"key", "name", "raw", "writable"} <= set(entry):
            raise BackupError(Message(N_("{source}: a parameter entry is incomplete (damaged file)"), source=source))
        if not isinstance(entry["key"], str) or not isinstance(entry["name"], str) or not isinstance(entry["writable"], bool):
            raise BackupError(Message(N_("{source}: a parameter entry's key, name or writable flag is of the wrong kind (damaged "
                                         "file)"), source=source))
        if "unit" in entry and not isinstance(entry["unit"], str):
            raise BackupError(Message(N_("{source}: parameter {name!r}: its unit is not a text (damaged file)"), source=source,
                                      name=entry["name"][:40]))
    return data


@dataclass
class DiffRow:
    """One writable parameter: the device now against the backup.

    What is written is derived from the entry's ``value`` alone, checked through the
    parameter model like a manual entry; ``backup_text`` shows exactly that value.
    """

    key: str
    name: str
    unit: str
    current_raw: Any
    current_value: Any
    backup_raw: Any  # what would be written (raw), derived from the entry's value
    backup_value: Any  # the entry's value as the file holds it
    current_text: str = ""
    backup_text: str = ""
    error: str = ""  # why the entry cannot be written (invalid in the file): never written
    risk: str = ""  # the confirmation a manual write of this value asks for
    param: Any = None
    accepted: Accepted | None = None  # what the parameter model accepted of the entry: what is written, unchecked again

    @property
    def changed(self) -> bool:
        return not self.error and self.current_raw != self.backup_raw


@dataclass
class RestorePlan:
    device: str
    document: dict
    rows: list[DiffRow]
    warnings: list[str] = field(default_factory=list)  # each a :class:`~app.message.Message`

    @property
    def invalid(self) -> list[DiffRow]:
        return [r for r in self.rows if r.error]

    def risky(self, selected: set[str]) -> list[DiffRow]:
        """Selected changes that need a confirmation (the same as a manual write would)."""
        return [r for r in self.rows if r.changed and r.risk and r.key in selected]


def _file_number(value: Any) -> int | float:
    """The entry's value as the file holds it, accepted only as a JSON number."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise BackupError(Message(N_("{value!r} in the file is not a number"), value=value))
    return value


def value_with_unit(value: Any, unit: str) -> str:
    """A value as a restore row shows it when no parameter model names it: with its unit
    ("1000 × 10 ms" where the unit is a step of its own)."""
    if not unit:
        return str(value)
    return f"{value} × {unit}" if unit[:1].isdigit() else f"{value} {unit}"


def _entry_text(adapter: Any, entry: dict, value: Any, now: dict) -> str:
    """The words for a value of a device without a parameter model: the adapter's own
    (``restore_text(key, value)``, names and units as its page shows them), the device's text
    when the value is the one it holds now, else the value with its unit. Never the file's
    ``text``: an edited file could name one value and hold another."""
    if isinstance(adapter, RestoreDescriber):
        try:
            return str(adapter.restore_text(entry["key"], value))
        except (CommissionError, LookupError, TypeError, ValueError):  # an edited file's value the adapter cannot describe:
            pass  # shown as it is
    if value == now.get("value") and now.get("text"):
        return str(now["text"])
    return value_with_unit(value, entry.get("unit", ""))


def _plan_row(params, entry: dict, now: dict, adapter: Any = None) -> DiffRow:
    key, name = entry["key"], entry["name"]
    value = entry.get("value")
    unit = entry.get("unit", "")
    row = DiffRow(key, name, unit, now["raw"], now.get("value"), None, value,
                  current_text=str(now.get("text") or value_with_unit(now.get("value"), unit)), backup_text=str(value))
    param = params.by_key.get(key) if params is not None else None
    if params is None:
        # no parameter model (e.g. M3IO customer records): the adapter checks the value on write
        row.backup_raw = value
        row.backup_text = _entry_text(adapter, entry, value, now)
        return row
    if param is None:
        row.error = Message(N_("not a parameter of this device type"))
        return row
    row.param = param
    row.current_text = param.display(int(now["raw"]))
    try:
        # a parameter whose value is text (an M3IO customer record's hex bytes) checks the text itself
        accepted = param.accept(value if takes_text(param) and isinstance(value, str) else _file_number(value))
    except (BackupError, ValueError) as exc:
        row.error = Message(N_("invalid in the file: {error}"), error=message_of(exc))
        return row
    raw = row.backup_raw = accepted.raw
    row.backup_text = param.display(raw)
    hex_raw = takes_text(param) and entry.get("raw") == param.display(raw)  # an older file's record bytes
    if "raw" in entry and entry["raw"] != raw and not hex_raw:
        row.error = Message(N_("the file's raw {raw!r} and value {value!r} disagree (edited or damaged file): not written"),
                            raw=entry["raw"], value=value)
        return row
    row.accepted, row.risk = accepted, accepted.risk
    return row


async def plan_restore(runtime, name: str, document: dict, progress=None) -> RestorePlan:
    """Check type and identity, read the device now, diff the writable parameters."""
    adapter = runtime.worker.adapters[name]
    state = runtime.store.devices[name]
    backup_type = document["device"].get("type")
    if backup_type != state.type:
        raise BackupError(Message(N_("the backup is of a {type!r}, but {name} is a {device_type!r}: refused"), type=backup_type,
                                  name=name, device_type=state.type))
    if not supports_backup(adapter):
        raise BackupError(Message(N_("{name}: this device type cannot be restored"), name=name))
    if adapter.restore_refused:
        raise BackupError(f"{name}: {adapter.restore_refused}")
    current = {e["key"]: e for e in await adapter.backup_read(progress)}
    warnings = []
    ident_now, ident_then = adapter.backup_identity(), document.get("identity") or {}
    for key in ("serial",):
        if key in ident_then and key in ident_now and str(ident_then[key]) != str(ident_now[key]):
            warnings.append(Message(N_("the backup was taken from serial number {then}, this device is {now} (a replaced "
                                       "device?): check before restoring"), then=ident_then[key], now=ident_now[key]))
    if document["device"].get("name") != name:
        warnings.append(Message(N_("the backup was taken from device '{device}' of plant '{plant}'"),
                                device=document["device"].get("name"), plant=document.get("plant")))
    rows = []
    for entry in document["parameters"]:
        if not entry.get("writable"):
            continue  # read-only parameters are kept for reference, never written
        model = state.params.by_key.get(entry["key"]) if state.params is not None else None
        if model is not None and not model.setting:
            continue  # measured by the device (a maximum so far): kept for reference, never copied (Param.setting)
        now = current.get(entry["key"])
        if now is None or not now.get("writable"):
            warnings.append(Message(N_("{name} is not writable on this device: skipped"), name=entry["name"]))
            continue
        rows.append(_plan_row(state.params, entry, now, adapter))
    for row in rows:
        row.risk = _declared_risk(runtime, name, row)
        if row.error:
            warnings.append(Message("{name}: {error}", name=row.name, error=row.error))
    return RestorePlan(name, document, rows, warnings)


def unsaved_lines(state, skip: set[str] = frozenset()) -> list[str]:
    """The device's changes written earlier and not saved yet (``state.unsaved``), each with the value it
    has now: a restore's save step makes them permanent along with the restored values."""
    params = state.params
    lines = []
    for key in sorted(state.unsaved - set(skip),
                      key=lambda k: (params.by_key[k].address if params is not None and k in params.by_key else 1 << 20, k)):
        p = params.by_key.get(key) if params is not None else None
        if p is None:
            lines.append(key)
            continue
        try:
            raw = state.raw(p)
            value = "not read" if raw is None else p.display(raw)
        except ValueError:  # a value the model cannot show (a codec's refusal) is named without it
            value = "not read"
        lines.append(f"{p.label or p.name} ({p.space} {p.address}) = {value}")
    return lines


NEEDS_CONFIRMATION = N_("{value} needs a confirmation: {risk}")


@dataclass
class RestoreReport:
    written: list[str] = field(default_factory=list)
    unchanged: list[str] = field(default_factory=list)
    failed: list[tuple[str, str]] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    refused: list[tuple[str, str]] = field(default_factory=list)  # invalid in the file, or risky and not confirmed
    saved: str | None = None
    save_error: str = ""

    @property
    def ok(self) -> bool:
        return not self.failed and not self.save_error and not self.refused

    def summary(self) -> Message:
        """What the restore did, in one line (written in the audit row as English)."""
        parts = [Message(N_("{written} written, {unchanged} unchanged, {failed} failed, {skipped} skipped"),
                         written=len(self.written), unchanged=len(self.unchanged), failed=len(self.failed),
                         skipped=len(self.skipped))]
        if self.refused:
            parts[0] = Message(N_("{counts}, {n} refused"), counts=parts[0], n=len(self.refused))
        if self.saved:
            parts.append(Message(N_("{step} done"), step=self.saved))
        elif self.written and (self.failed or self.refused):
            parts.append(Message(N_("not saved because a write failed or was refused")))
        if self.save_error:
            parts.append(Message(N_("saving failed: {error}"), error=self.save_error))
        return joined(parts, "; ")


def _declares_write(runtime, device: str) -> bool:
    config = runtime.plant.devices.get(device)
    return config is not None and find_command(config.type, WRITE_PARAMETER) is not None


def _declared_risk(runtime, device: str, row: DiffRow) -> str:
    """The confirmation the device type's declared write asks for this value (its send policy), as the
    device's page asks it; the parameter's own where the type declares no write."""
    if row.param is None or row.error or not _declares_write(runtime, device):
        return row.risk
    try:
        return runtime.worker.gate.question(device, WRITE_PARAMETER, {"param": row.param, "value": row.accepted})
    except ValueError as exc:  # refused by the declaration: never written
        row.error = message_of(exc)
        return ""


async def execute_restore(runtime, plan: RestorePlan, selected: set[str], *, user: str = "local", role: str = "engineer",
                          confirmed: set[str] = frozenset(), progress=None) -> RestoreReport:
    """Write the selected changed parameters through the worker (role checked, audited) and
    the parameter model's checks (range, type, confirmation: ``confirmed`` holds the keys of
    risky values the user confirmed), read each back, and run the save step only when every
    write verified."""
    report = RestoreReport()
    rows = plan.rows
    total = max(1, len(rows))
    for n, row in enumerate(rows, 1):
        if row.error:
            report.refused.append((row.name, row.error))
        elif not row.changed:
            report.unchanged.append(row.name)
        elif row.key not in selected:
            report.skipped.append(row.name)
        elif row.risk and row.key not in confirmed:
            report.refused.append((row.name, Message(NEEDS_CONFIRMATION, value=row.backup_text, risk=row.risk)))
        else:
            try:
                if row.param is not None and _declares_write(runtime, plan.device):
                    # the device type's declared write: range, send policy and confirmation as on its page
                    await runtime.worker.gate.invoke(plan.device, WRITE_PARAMETER, {"param": row.param, "value": row.accepted},
                                                     user=user, role=role, confirmed=row.key in confirmed, action="restore")
                else:
                    if row.param is not None:
                        def action(a, row=row):
                            return a.write_accepted(row.accepted, confirmed=row.key in confirmed)
                    else:
                        def action(a, row=row):
                            return a.restore_entry(row.key, row.backup_raw)
                    await runtime.worker.gate.run(
                        partial(action, runtime.worker.gate.adapter(plan.device)), device=plan.device, role=role, user=user,
                        describe="restore", parameter=row.name, old=row.current_text, new=row.backup_text,
                    )
                report.written.append(row.name)
            except gate.NeedsConfirmation as question:
                report.refused.append((row.name, Message(NEEDS_CONFIRMATION, value=row.backup_text, risk=question.question)))
            except CommissionError as exc:  # every refusal is reported per parameter
                report.failed.append((row.name, message_of(exc)))
                if exc.__class__.__name__ in ("PermissionDenied", "AuditUnavailable"):
                    break
        if progress:
            progress(n / total)
    if report.written and not report.failed and not report.refused:
        permanent = "; ".join(unsaved_lines(runtime.store.devices[plan.device]))  # restored and earlier changes alike
        try:
            adapter = runtime.worker.gate.adapter(plan.device)
            report.saved = await runtime.worker.gate.run(
                lambda: adapter.save_step(), device=plan.device, role=role, user=user,
                describe="restore: save step", new=permanent or "no unsaved changes",
            )
        except CommissionError as exc:
            report.save_error = message_of(exc)
    try:
        await runtime.audit.arecord(user=user, role=role, device=plan.device, action="restore", result=report.summary())
    except audit.WRITE_ERRORS:  # every write above has its own row; the header shows the audit state
        pass
    return report
