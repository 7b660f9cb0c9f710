"""Batch apply (/fleet): one parameter set to several devices of one type, each with its own identity
check and dry-run diff first, then device by device with progress, stopping at the first failure."""

from __future__ import annotations

import asyncio

from nicegui import ui

from app import backup, batch, i18n, project
from app import runtime as rt
from app.i18n import N_, Lang
from app.message import said
from pages.frame import ACTION_ERRORS, frame, notify_error
from pages.session import can_write, current_user
from pages.command_client import confirm

STATUS_CLASS = {batch.WRITTEN: "text-positive", batch.UNCHANGED: "text-grey-8", batch.FAILED: "text-negative",
                batch.SKIPPED: "text-warning", batch.REFUSED: "text-negative"}


def _backup_files(directory, device_type: str, lang: Lang | None = None) -> dict[str, str]:
    _ = (lang or i18n.get("en")).gettext
    found = {}
    if not directory.is_dir():
        return found
    for path in sorted(directory.glob("*.json"), key=lambda p: p.stat().st_mtime, reverse=True):
        try:
            doc = backup.load_document(path.read_bytes(), path.name)
        except backup.BackupError:
            continue
        if doc["device"].get("type") == device_type:
            found[str(path)] = _("backup {file}").format(file=path.name)
    return found


class FleetView:
    """The batch page: the chosen type, source and devices, the dry-run plan and its result labels."""

    def __init__(self, by_type: dict[str, list[str]], lang: Lang | None = None):
        self.runtime = rt.current()
        self.lang = lang or i18n.get("en")
        self.by_type = by_type
        self.boxes: dict[str, ui.checkbox] = {}
        self.plan: batch.BatchPlan | None = None
        self.labels: dict[str, ui.label] = {}

    def build(self) -> None:
        _ = self.lang.gettext
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-4"):
                self.kind = ui.select(list(self.by_type), value=next(iter(self.by_type)), label=_("Device type")).props(
                    "dense outlined data-testid=fleet-type").classes("w-40")
                self.source = ui.select({}, label=_("Source")).props("dense outlined data-testid=fleet-source").classes("w-96")
            self.boxes_row = ui.row().classes("gap-4").props("data-testid=fleet-devices")
            with ui.row().classes("items-center"):
                self.compare = ui.button(_("Check and compare"), icon="compare_arrows").props("data-testid=fleet-compare")
                self.apply = ui.button(_("Apply device by device"), icon="upload", color="negative").props(
                    "data-testid=fleet-apply")
                self.apply.set_visibility(False)
            self.progress = ui.linear_progress(value=0, show_value=False).classes("w-full")
            self.summary = ui.label().classes("text-body1").props("data-testid=fleet-summary")
        self.results = ui.column().classes("w-full gap-2")

    def wire(self) -> None:
        self.kind.on_value_change(self.fill)
        ui.timer(0, self.fill, once=True)
        self.compare.on_click(self.run_compare)
        self.apply.on_click(self.run_apply)

    async def fill(self) -> None:
        runtime = self.runtime
        _ = self.lang.gettext
        devices = self.by_type.get(self.kind.value, [])
        self.boxes_row.clear()
        self.boxes.clear()
        with self.boxes_row:
            for name in devices:
                variant = runtime.plant.devices[name].options.get("variant")
                self.boxes[name] = ui.checkbox(f"{name}" + (f" ({variant})" if variant else ""), value=True).props(
                    f'data-fleet-device="{name}"')
        options = {}
        for name in devices:
            if name in runtime.record.approved:
                options[f"approved:{name}"] = _("approved set of {name}").format(name=name)
        if any(project.has_project(runtime.plant, n) for n in devices):
            options["project"] = _("each device's project (plant file)")
        options.update(await asyncio.to_thread(_backup_files, runtime.backups_dir, self.kind.value, self.lang))
        for name in devices:
            options[f"device:{name}"] = _("{name} as it is now (sibling)").format(name=name)
        self.source.set_options(options, value=next(iter(options), None))
        self.apply.set_visibility(False)
        self.results.clear()
        self.summary.set_text("")

    async def run_compare(self) -> None:
        _ = self.lang.gettext
        chosen = [n for n, box in self.boxes.items() if box.value]
        if not chosen or not self.source.value:
            ui.notify(_("Choose devices and a source"), type="warning")
            return
        self.compare.disable()
        self.progress.set_value(0)
        try:
            plan = await batch.plan_batch(self.runtime, chosen, self.source.value, self.progress.set_value)
        except ACTION_ERRORS as exc:  # an unreadable source, a device not answering
            notify_error(_("Cannot compare: {error}").format(error=said(exc, self.lang)))
            return
        finally:
            self.compare.enable()
        self.plan = plan
        self.results.clear()
        self.labels = {}
        with self.results:
            ui.label(self._source_line(plan)).classes("text-body2").props("data-testid=fleet-source-line")
            for error in plan.errors:
                ui.label(f"✖ {said(error, self.lang)}").classes("text-negative text-body1")
            for entry in plan.devices:
                self._show_entry(entry)
        ready = plan.ready and any(e.changed for e in plan.devices)
        self.summary.set_text((_("ready: ") if plan.ready else _("cannot apply: "))
                              + ", ".join(f"{e.device} " + (_("refused") if e.error else _("{n} to write").format(n=len(e.changed)))
                                          for e in plan.devices))
        self.summary.classes(replace="text-body1 " + ("" if plan.ready else "text-negative"))
        self.apply.set_visibility(ready)
        self.apply.set_enabled(can_write())

    def _source_line(self, plan: batch.BatchPlan) -> str:
        """Where the set comes from, said once (not as a warning on every device it goes to)."""
        _ = self.lang.gettext
        line = _("Set: {source}").format(source=self.source.options.get(self.source.value, self.source.value))
        document = next((e.plan.document for e in plan.devices if e.plan is not None), None)
        if document is not None and self.source.value != "project":
            device = document.get("device") or {}
            serial = (document.get("identity") or {}).get("serial")
            words = _(", taken from {device} (serial {serial}) of plant '{plant}'") if serial is not None else \
                _(", taken from {device} of plant '{plant}'")
            line += words.format(device=device.get("name", "?"), serial=serial, plant=document.get("plant", "?"))
        return line

    def _show_entry(self, entry) -> None:
        """One device's card of the dry run: its status, the identity notes and the rows to write."""
        _ = self.lang.gettext
        with ui.card().classes("w-full q-pa-sm").props(f'data-fleet-result="{entry.device}"'):
            with ui.row().classes("items-center gap-3"):
                ui.label(entry.device).classes("text-subtitle1 text-weight-bold")
                self.labels[entry.device] = ui.label(
                    _("refused: {reason}").format(reason=said(entry.error, self.lang)) if entry.error else
                    _("{n} to write (dry run)").format(n=len(entry.changed))) \
                    .classes("text-body1 " + ("text-negative" if entry.error else "")).props("data-fleet-status")
            if entry.check is not None:
                for note in entry.check.notes:
                    ui.label(f"⚠ {said(note, self.lang)}").classes("text-caption text-warning")
            if entry.plan is not None:
                for warning in entry.plan.warnings:
                    # another device's serial and name are what a batch from it means, not a warning
                    if not warning.startswith(("the backup was taken from serial number", "the backup was taken from device")):
                        ui.label(f"⚠ {said(warning, self.lang)}").classes("text-caption text-warning")
                for row in entry.changed:
                    risk = "  " + _("(needs confirmation: {risk})").format(risk=said(row.risk, self.lang)) if row.risk else ""
                    ui.label(f"{row.name}: {row.current_text} → {row.backup_text}{risk}").classes(
                        "text-body2 mono" + (" text-negative" if row.risk else ""))

    async def _confirmed_risks(self, writing: list) -> set[str] | None:
        """Ask the batch once, then each risky parameter once; None when any answer is no."""
        _ = self.lang.gettext
        if not await confirm(_("Apply to {n} device(s), one by one?").format(n=len(writing)),
                             _("Each device: its differing parameters written, read back and saved; the batch stops at the "
                               "first device that fails.") + " " + "; ".join(f"{e.device}: {len(e.changed)}" for e in writing),
                             ok=_("Apply"), lang=self.lang):
            return None
        confirmed: set[str] = set()
        for entry in writing:
            for row in entry.plan.risky({r.key for r in entry.changed}):
                if row.name in confirmed:
                    continue
                if not await confirm(_("Write {name} = {value}?").format(name=row.name, value=row.backup_text), row.risk,
                                     ok=_("Write anyway"), lang=self.lang):
                    ui.notify(_("{name} not confirmed: nothing written").format(name=row.name), type="warning")
                    return None
                confirmed.add(row.name)
        return confirmed

    def _said(self, result: batch.DeviceResult) -> None:
        label = self.labels.get(result.device)
        if label is not None:
            label.set_text(f"{batch.status_text(result.status, self.lang)}: {said(result.text, self.lang)}")
            label.classes(replace="text-body1 " + STATUS_CLASS.get(result.status, ""))

    async def run_apply(self) -> None:
        plan = self.plan
        if plan is None or not plan.ready:
            return
        writing = [e for e in plan.devices if e.changed]
        confirmed = await self._confirmed_risks(writing)
        if confirmed is None:
            return
        user, role = current_user()
        self.apply.disable()
        self.compare.disable()
        for entry in plan.devices:
            label = self.labels.get(entry.device)
            if label is not None and entry.changed:
                label.set_text(self.lang.gettext("waiting"))
        try:
            done = await batch.apply_batch(self.runtime, plan, user=user, role=role, confirmed=confirmed,
                                           progress=self.progress.set_value, on_device=self._said)
        finally:
            self.compare.enable()
        failed = [r for r in done if r.status in (batch.FAILED, batch.REFUSED)]
        self.summary.set_text(", ".join(f"{r.device} {batch.status_text(r.status, self.lang)}" for r in done)
                              + (": " + self.lang.gettext("stopped at {device}, {reason}").format(
                                  device=failed[0].device, reason=said(failed[0].text, self.lang)) if failed else ""))
        self.summary.classes(replace="text-body1 " + ("text-negative" if failed else "text-positive"))
        self.apply.set_visibility(False)


def content() -> None:
    runtime = rt.current()
    by_type: dict[str, list[str]] = {}
    for name, state in runtime.store.devices.items():
        if backup.device_backs_up(runtime, name):
            by_type.setdefault(state.type, []).append(name)
    lang = i18n.page_language()
    _ = lang.gettext
    with frame(N_("Apply to several devices")):
        ui.label(_("One set to several devices of one type and variant: each device is checked (type, variant, "
                   "identity) and compared first; nothing is written before you press Apply. Applying runs device by "
                   "device through the same checked, verified write as a restore, and stops at the first failure.")) \
            .classes("text-body2 text-grey-9")
        if not by_type:
            ui.label(_("No device of this plant keeps parameters."))
            return
        view = FleetView(by_type, lang)
        view.build()
    view.wire()
