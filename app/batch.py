"""Batch apply: one parameter set to N devices of one type (and variant), device by device.

Sources: a backup file, a device's approved set (``approved:NAME``), a sibling device read now
(``device:NAME``) or each device's own project (``project``, see app/project.py). Every device
gets its own identity check and dry-run diff first (restore's plan, app/backup.py); applying runs
device by device through restore's verified write (the gate, read-back, save step), stops at the
first failure and reports each device as written, unchanged, failed or skipped.
"""

from __future__ import annotations

import argparse
import asyncio
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from app import audit, backup, files, replace
from app import cli_lang
from app.cli_lang import YES, _
from app.i18n import N_, NP_, Lang
from app.message import Message, joined, message_of, said
from app.headless import write_options
from devices.commands import READ_PARAMETERS
from devices.errors import CommissionError

STATUS = "batch status"  # the catalogs' context of a device's status in a batch
WRITTEN, UNCHANGED, FAILED, SKIPPED, REFUSED = (NP_("batch status", "written"), NP_("batch status", "unchanged"),
                                                NP_("batch status", "failed"), NP_("batch status", "skipped"),
                                                NP_("batch status", "refused"))


def status_text(status: str, lang: Lang | None) -> str:
    """A device's status in a batch (:data:`WRITTEN` ...) in ``lang`` (None: as it is)."""
    return status if lang is None else lang.pgettext(STATUS, status)


@dataclass
class DevicePlan:
    device: str
    check: replace.IdentityCheck | None = None
    plan: backup.RestorePlan | None = None
    error: str = ""  # refused before anything is written (type, variant, unreadable device); a Message

    @property
    def changed(self) -> list[backup.DiffRow]:
        return [] if self.plan is None else [r for r in self.plan.rows if r.changed]


@dataclass
class BatchPlan:
    source: str
    device_type: str
    devices: list[DevicePlan]
    errors: list[str] = field(default_factory=list)  # the batch as a whole cannot run; each a Message

    @property
    def ready(self) -> bool:
        return not self.errors and all(not d.error for d in self.devices)


@dataclass
class DeviceResult:
    device: str
    status: str  # written, unchanged, failed, skipped, refused (a page words it)
    text: str = ""  # a Message
    report: backup.RestoreReport | None = None


async def source_document(runtime, source: str, device: str) -> dict:
    """The backup document ``source`` names, for ``device`` (only ``project`` depends on the device)."""
    if source == "project":
        from app import project

        return project.document(runtime, device)
    if source.startswith("approved:"):
        return (await replace.approved_document(runtime, source.split(":", 1)[1]))[0]
    if source.startswith("device:"):
        sibling = source.split(":", 1)[1]
        if sibling not in runtime.worker.adapters:
            raise backup.BackupError(Message(N_("no device named {name} in this plant"), name=repr(sibling)))
        adapter = runtime.worker.adapters[sibling]
        if not backup.supports_backup(adapter):
            raise backup.BackupError(Message(N_("{name} has no parameters to copy"), name=sibling))
        entries = await runtime.worker.gate.invoke(sibling, READ_PARAMETERS, user="batch", role="viewer")
        state = runtime.store.devices[sibling]
        return backup.make_document(runtime.plant.name, sibling, state.type, state.bus, adapter.backup_identity(), entries)
    path = Path(source.removeprefix("file:"))
    data = await asyncio.to_thread(files.read_regular, path, files.MAX_DOCUMENT_BYTES, "parameter file")
    return await asyncio.to_thread(backup.load_document, data, path.name)


def _variant(runtime, name: str) -> Any:
    config = runtime.plant.devices.get(name)
    return None if config is None else config.options.get("variant")


async def plan_batch(runtime, devices: list[str], source: str, progress=None) -> BatchPlan:
    """Identity check and dry-run diff of every device (reads only; nothing is written)."""
    errors = []
    unknown = [d for d in devices if d not in runtime.store.devices]
    if unknown:
        return BatchPlan(source, "", [], [Message(N_("no device named {name} in this plant"), name=", ".join(map(repr, unknown)))])
    if not devices:
        return BatchPlan(source, "", [], [Message(N_("choose at least one device"))])
    types = {runtime.store.devices[d].type for d in devices}
    variants = {str(_variant(runtime, d)) for d in devices}
    if len(types) > 1:
        errors.append(Message(N_("the devices are of {n} types ({types}): a batch takes one type"), n=len(types),
                              types=", ".join(sorted(types))))
    if len(variants) > 1:
        errors.append(Message(N_("the devices are of {n} variants ({variants}): a batch takes one variant"), n=len(variants),
                              variants=", ".join(sorted(variants))))
    if len(set(devices)) != len(devices):
        errors.append(Message(N_("a device is named twice")))
    result = BatchPlan(source, next(iter(types)), [DevicePlan(d) for d in devices], errors)
    if errors:
        return result
    for n, entry in enumerate(result.devices):
        try:
            document = await source_document(runtime, source, entry.device)
            state = runtime.store.devices[entry.device]
            if state.status != "online":
                raise backup.BackupError(Message(N_("not answering ({error})"),
                                                 error=state.last_error or Message(N_("no answer"))))
            adapter = runtime.worker.adapters[entry.device]
            current = {e["key"] for e in await adapter.backup_read()}
            entry.check = await replace.check_identity(runtime, entry.device, document, current)
            if not entry.check.ok:
                raise backup.BackupError(joined(entry.check.refusals, "; "))
            entry.plan = await backup.plan_restore(runtime, entry.device, document)
        except (CommissionError, OSError) as exc:  # each device says why it cannot take part
            entry.error = message_of(exc) or exc.__class__.__name__
        if progress:
            progress((n + 1) / len(result.devices))
    return result


async def apply_batch(runtime, plan: BatchPlan, *, user: str, role: str, confirmed: set[str] = frozenset(),
                      progress=None, on_device=None) -> list[DeviceResult]:
    """Device by device through restore's verified path; stops at the first failure, the rest skipped.

    :param confirmed: names (or keys) of risky parameters the engineer confirmed, for every device
    :param on_device: ``(DeviceResult) -> None`` after each device (the page's progress)
    """
    results: list[DeviceResult] = []
    if not plan.ready:
        return [DeviceResult(d.device, REFUSED, d.error or joined(plan.errors, "; ")) for d in plan.devices]
    stopped = ""
    total = max(1, len(plan.devices))
    for n, entry in enumerate(plan.devices):
        if stopped:
            result = DeviceResult(entry.device, SKIPPED, Message(N_("not started: {why}"), why=stopped))
        elif not entry.changed:
            result = DeviceResult(entry.device, UNCHANGED, Message(N_("already holds every value of the source")))
        else:
            selected = {r.key for r in entry.changed}
            keys = {r.key for r in entry.plan.risky(selected) if r.key in confirmed or r.name in confirmed}
            report = await backup.execute_restore(runtime, entry.plan, selected, user=user, role=role, confirmed=keys,
                                                  progress=(lambda f, n=n: progress((n + f) / total)) if progress else None)
            if report.ok:
                result = DeviceResult(entry.device, WRITTEN, report.summary(), report)
            else:
                why = joined([Message("{name}: {error}", name=p, error=e) for p, e in report.failed + report.refused], "; ") \
                    or report.save_error
                result = DeviceResult(entry.device, FAILED, Message("{summary} ({why})", summary=report.summary(), why=why), report)
                stopped = Message(N_("the batch stopped at {device}, which failed"), device=entry.device)
        results.append(result)
        if progress:
            progress((n + 1) / total)
        if on_device:
            on_device(result)
    summary = ", ".join(f"{r.device} {r.status}" for r in results)
    try:
        await runtime.audit.arecord(user=user, role=role, device=",".join(d.device for d in plan.devices), action="batch apply",
                                    new=plan.source, result=summary[:500])
    except audit.WRITE_ERRORS:  # each write has its own row; the header shows the audit state
        pass
    return results


# -- commission apply ------------------------------------------------------------------------------


def add_parser(sub) -> None:
    parser = sub.add_parser("apply", help=_("apply one parameter set to several devices of one type, headless"))
    parser.add_argument("--plant", type=Path, default=None, help=_("plant file (default: the built-in demo plant)"))
    parser.add_argument("--from", dest="source", required=True, metavar="SOURCE",
                        help=_("a backup file, approved:DEVICE (its approved set), device:DEVICE (a sibling read now) "
                             "or project (each device's project in the plant file)"))
    parser.add_argument("--devices", required=True, help=_("comma-separated device names, all of one type and variant"))
    write_options(parser)
    parser.add_argument("--no-sim", action="store_true", help=_("do not start simulated devices"))
    parser.add_argument("--data-dir", type=Path, default=None, help=_("data folder (default: the per-user data folder, docs/windows-macos.md)"))
    parser.set_defaults(func=run_cli)


def run_cli(args: argparse.Namespace) -> int:
    from app.headless import cli_user, run_headless

    args.device = [d.strip() for d in args.devices.split(",") if d.strip()]
    if not args.device:  # an empty selection must never mean "every device" (the headless runner's default)
        print(_("commission apply: no device named in --devices {devices}: name the devices to write, "
                "separated by commas (--devices door-1,door-2)").format(devices=repr(args.devices)), file=sys.stderr)
        return 2
    source = args.source
    if source not in ("project",) and not source.startswith(("approved:", "device:")):
        path = Path(source)
        try:
            files.read_regular(path, files.MAX_DOCUMENT_BYTES, "parameter file")
        except FileNotFoundError:
            print(_("commission apply: {source}: no such file").format(source=source), file=sys.stderr)
            return 2
        except OSError as exc:
            print(f"commission apply: {exc if isinstance(exc, files.FileRefused) else f'{source}: {exc.strerror or exc}'}",
                  file=sys.stderr)
            return 2
        source = str(path)

    async def work(runtime, names) -> int:
        plan = await plan_batch(runtime, names, source)
        lang = cli_lang.lang()
        for error in plan.errors:
            print(f"commission apply: {said(error, lang)}", file=sys.stderr)
        if plan.errors:
            return 2
        risky: dict[str, str] = {}
        for entry in plan.devices:
            print(f"{entry.device}:")
            if entry.error:
                print(_("  refused: {error}").format(error=said(entry.error, lang)))
                continue
            for note in entry.check.notes:
                print(_("  identity: {note}").format(note=said(note, lang)))
            for warning in entry.plan.warnings:
                print(_("  warning: {warning}").format(warning=said(warning, lang)))
            for row in entry.changed:
                mark = _("   [needs confirmation: {risk}]").format(risk=row.risk) if row.risk else ""
                print(f"  {row.name}: {row.current_text} -> {row.backup_text}{mark}")
                if row.risk:
                    risky[row.name] = row.risk
            if not entry.changed:
                print(_("  nothing to write"))
        if not plan.ready:
            print(_("commission apply: nothing written: every device must pass its identity check"), file=sys.stderr)
            return 2
        accepted = {n.lower() for n in args.accept_risk}
        confirmed = {n for n in risky if n.lower() in accepted}
        if not args.yes:
            if not sys.stdin.isatty():
                print(_("commission apply: add --yes to write without a terminal to confirm"), file=sys.stderr)
                return 2
            if input(_("apply to {n} device(s), one by one? [y/N] ").format(n=len(plan.devices))).strip().lower() not in YES:
                print(_("nothing written"))
                return 1
            for name_, risk in risky.items():
                if name_ not in confirmed and input(_("{name}: {risk} Write it? [y/N] ").format(name=name_, risk=risk)).strip().lower() in YES:
                    confirmed.add(name_)
        unconfirmed = [n for n in risky if n not in confirmed]
        if unconfirmed:
            for name_ in unconfirmed:
                print(_("commission apply: {name} needs a confirmation ({risk}); name it with --accept-risk {name} to write it").format(
                    name=name_, risk=risky[name_]), file=sys.stderr)
            print(_("nothing written"), file=sys.stderr)
            return 2

        def done(result: DeviceResult) -> None:
            print(f"{result.device}: {status_text(result.status, lang)}: {said(result.text, lang)}", flush=True)

        results = await apply_batch(runtime, plan, user=cli_user(), role="engineer", confirmed=confirmed, on_device=done)
        failed = [r for r in results if r.status in (FAILED, REFUSED)]
        if failed:
            print(_("commission apply: stopped at {device}: {error}").format(device=failed[0].device, error=said(failed[0].text, lang)),
                  file=sys.stderr)
        return 1 if failed else 0

    return asyncio.run(run_headless(args, work))
