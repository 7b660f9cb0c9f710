"""Backup and restore page: back up devices with progress, list and download backups,
restore one with a diff of the writable parameters and a report."""

from __future__ import annotations

import asyncio
import html
from datetime import datetime
from pathlib import Path

from nicegui import events, ui

from app import backup, i18n, project
from app import runtime as rt
from app.i18n import english, N_, Lang
from app.message import said
from pages.frame import ACTION_ERRORS, frame, notify_error
from pages.session import can_write, current_user
from pages.diffrows import DIFF_COLUMNS, STATE_SLOT, WRAP
from pages.diffrows import count as _count  # noqa: F401 - its tests count with it
from pages.diffrows import row_state
from pages.diffrows import state_text
from pages.project import ProjectCard
from pages.widgets import column, columns, upload_button
from pages.command_client import confirm, enable_unless, viewer_reason

FILE_COLUMNS = [
    column("name", N_("File"), style=WRAP),
    column("device", N_("Device")),
    column("type", N_("Type")),
    column("time", N_("Taken (local time)")),
    column("by", N_("By")),
    column("size", N_("Size")),
    {"name": "actions", "label": "", "field": "name"},
]
DIFF_WORDS = (N_("Parameter"), N_("Device now"), N_("In the backup"))  # the labels of pages/diffrows.py's columns
# the state cell of pages/diffrows.py, showing a row's state in the page's language (``state`` stays the English key)
STATE_TEXT_SLOT = STATE_SLOT.replace("props.row.state }}", "props.row.state_text }}")



def differ_text(changed: int, total: int, lang: Lang) -> str:
    """``1 of 5 writable parameters differs``, ``2 of 5 ... differ``."""
    parameters = lang.ngettext("{n} writable parameter", "{n} writable parameters", total).format(n=total)
    return lang.ngettext("{changed} of {parameters} differs", "{changed} of {parameters} differ", changed).format(
        changed=changed, parameters=parameters)
# the uploader's own header shows "0.0B / 0.00%" before any file: a plain pick button instead
def _files(directory: Path, lang: Lang | None = None) -> list[dict]:
    lang = english(lang)
    rows = []
    for path in sorted(directory.glob("*.json"), key=lambda p: p.stat().st_mtime, reverse=True):
        try:
            doc = backup.load_document(path.read_bytes(), path.name)
            device, dtype, when = doc["device"].get("name", "?"), doc["device"].get("type", "?"), doc.get("time", "")
            when, by = backup.local_time(when), backup.taken_by(doc)
        except backup.BackupError as exc:
            device, dtype, when, by = "-", lang.gettext("unreadable"), said(exc, lang)[:60], ""
        rows.append({"name": path.name, "device": device, "type": dtype, "time": when, "by": by,
                     "size": f"{lang.number(path.stat().st_size / 1024, 1)} kB"})
    return rows


def _identity_words(identity: object, lang: Lang | None = None) -> str:
    """A backup's device identity as words (``serial 660020, FirmwareVersion 57``), not as JSON; its keys as the
    catalogs label them in ``lang`` (app/replace.py, ``IDENTITY_KEYS``)."""
    lang = english(lang)
    if not isinstance(identity, dict) or not identity:
        return lang.gettext("not recorded")
    return ", ".join(f"{lang.gettext(key)} {value}" for key, value in identity.items() if value not in (None, ""))


class BackupCard:
    """Back up the chosen devices with progress, say why the others are left out, offer the archive."""

    def __init__(self, directory: Path, devices: list[str], without: list[str], lang: Lang | None = None):
        self.runtime = rt.current()
        self.lang = english(lang)
        self.directory = directory
        self.devices = devices
        self.without = without
        self.made: list[Path] = []
        self.written = None  # called after a backup run (the file list reloads)
        self.archive_path: Path | None = None  # the last archive downloaded

    def build(self) -> None:
        store = self.runtime.store
        _ = self.lang.gettext
        with ui.card().classes("w-full"):
            ui.label(_("Back up")).classes("text-subtitle1")
            with ui.row().classes("gap-4"):
                self.boxes = {name: ui.checkbox(f"{name} ({store.devices[name].type})", value=True)
                              for name in self.devices}
            # devices left out, each with why
            self.reasons = ui.column().classes("gap-0").props("data-testid=backup-nothing")
            with ui.row().classes("items-center"):
                self.start = ui.button(_("Back up selected"), icon="save_alt").props("data-testid=backup-start")
                enable_unless(self.start, viewer_reason(self.lang))  # reading every parameter and writing files: an engineer's action
                self.archive = ui.button(_("Download as one archive"), icon="folder_zip").props("outline")
                self.archive.set_visibility(False)
            self.progress = ui.linear_progress(value=0, show_value=False).classes("w-full")
            self.status = ui.label().classes("text-body2")

    async def explain_left_out(self) -> None:
        for name in self.without:
            reason = said(await backup.why_nothing_to_back_up(self.runtime, name), self.lang).removeprefix("nothing to back up: ")
            with self.reasons:
                ui.label(self.lang.gettext("{name} ({type}): nothing to back up: {reason}").format(
                    name=name, type=self.runtime.store.devices[name].type, reason=reason)).classes(
                    "text-body2 text-grey-8")

    async def run_backup(self) -> None:
        _ = self.lang.gettext
        chosen = [name for name, box in self.boxes.items() if box.value]
        if not chosen:
            ui.notify(_("Select at least one device"), type="warning")
            return
        user, role = current_user()
        self.start.disable()
        self.made.clear()
        failures = []
        for n, name in enumerate(chosen):
            self.status.set_text(_("reading {name} ({n} of {total}) ...").format(name=name, n=n + 1, total=len(chosen)))

            def step(fraction: float, n=n) -> None:
                self.progress.set_value((n + fraction) / len(chosen))

            try:
                self.made.append(await backup.backup_device(self.runtime, name, self.directory, step,
                                                            user=user, role=role))
            except ACTION_ERRORS as exc:  # one device's refusal must not stop the others
                failures.append(f"{name}: {said(exc, self.lang)}")
            self.progress.set_value((n + 1) / len(chosen))
        self.start.enable()
        self.status.set_text(_("{n} backup file(s) written").format(n=len(self.made))
                             + ("; " + _("failed: {failures}").format(failures="; ".join(failures)) if failures else ""))
        self.status.classes(replace="text-body2 " + ("text-negative" if failures else "text-positive"))
        self.archive.set_visibility(len(self.made) > 1)  # to download the archive again
        if len(self.made) == 1:
            ui.download(self.made[0])
        elif self.made:  # several devices: their files as one archive, downloaded at once as one file is
            await self.download_archive()
        if self.written is not None:
            await self.written()

    async def download_archive(self) -> None:
        target = self.directory / f"plant-{self.runtime.plant.name}-{datetime.now():%Y%m%d-%H%M%S}.zip"
        archive = await asyncio.to_thread(backup.zip_files, self.made, target)
        self.archive_path = archive
        ui.download(archive)

    def wire(self) -> None:
        self.start.on_click(self.run_backup)
        self.archive.on_click(self.download_archive)


class FilesCard:
    """The backups in the folder, each to download or restore, and the upload of a file to restore."""

    def __init__(self, directory: Path, lang: Lang | None = None):
        self.directory = directory
        self.lang = english(lang)
        self.restore_box: ui.column | None = None  # where a restore opens (placed by the page, below the cards)

    def build(self) -> None:
        _ = self.lang.gettext
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center w-full"):
                ui.label(_("Backups in the folder")).classes("text-subtitle1")
                ui.space()
                upload = ui.upload(auto_upload=True, max_file_size=5_000_000,
                                   on_upload=lambda e: self._uploaded(e)).props(
                    "accept=.json flat bordered hide-upload-btn").classes("w-64")
                upload.add_slot("header", upload_button(_("Restore from a file"), "restore-upload"))
            self.table = ui.table(columns=columns(FILE_COLUMNS, self.lang), rows=[], row_key="name", pagination=20).classes(
                "w-full reg-table").props("dense flat bordered")
            self.table.add_slot("body-cell-actions", """
                <q-td :props="props">
                  <q-btn flat dense icon="download" @click="$parent.$emit('download', props.row.name)" />
                  <q-btn flat dense icon="settings_backup_restore" label="%s" @click="$parent.$emit('restore', props.row.name)" />
                </q-td>""" % html.escape(_("Restore")))

    async def refresh(self) -> None:
        self.table.rows = await asyncio.to_thread(_files, self.directory, self.lang) if self.directory.is_dir() else []
        self.table.update()

    def wire(self) -> None:
        self.table.on("download", lambda e: ui.download(self.directory / Path(e.args).name))
        self.table.on("restore", lambda e: self._restore_file(e.args))

    async def _restore_file(self, name: str) -> None:
        await self._open_restore(await asyncio.to_thread((self.directory / Path(name).name).read_bytes),
                                 Path(name).name)

    async def _uploaded(self, event: events.UploadEventArguments) -> None:
        await self._open_restore(await event.file.read(), event.file.name)

    async def _open_restore(self, data: bytes, source: str) -> None:
        restore_box = self.restore_box
        restore_box.clear()
        try:
            document = await asyncio.to_thread(backup.load_document, data, source)  # off the event loop
        except backup.BackupError as exc:
            notify_error(said(exc, self.lang))
            return
        with restore_box:
            flow = RestoreFlow(document, source, self.lang)
        restore_box.style("min-height: calc(100vh - 96px)")  # room below, so the restore can come up to the top
        # the restore opens below the file list: bring it into sight (below the fixed header)
        ui.run_javascript(
            f"(function show(n) {{ const e = getHtmlElement({flow.card.id});"
            " if (e) e.scrollIntoView({behavior: 'smooth', block: 'start'}); else if (n) setTimeout(() => show(n - 1), 50); })(40)")


def content() -> None:
    runtime = rt.current()
    lang = i18n.page_language()
    _ = lang.gettext
    directory = runtime.backups_dir
    devices = backup.backup_devices(runtime)
    without = [name for name in runtime.store.devices if name not in devices]
    backups = BackupCard(directory, devices, without, lang)
    files = FilesCard(directory, lang)
    with frame(N_("Backup and restore")):
        ui.label(_("Backups are written to {directory}").format(directory=directory)).classes("text-caption text-grey-8")
        backups.build()
        files.build()
        with ui.row().classes("items-center"):
            ui.link(_("Apply one set to several devices of a type"), "/fleet").props("data-testid=open-fleet")
        projects = [name for name in devices if project.has_project(runtime.plant, name)]
        if projects:
            ProjectCard(projects, lang=lang)
        files.restore_box = ui.column().classes("w-full")
    ui.timer(0, files.refresh, once=True)
    if without:
        ui.timer(0, backups.explain_left_out, once=True)
    backups.written = files.refresh
    backups.wire()
    files.wire()


class RestoreFlow:
    """Pick the device, see the diff, deselect rows, write, read back, save, report."""

    def __init__(self, document: dict, source: str, lang: Lang | None = None):
        runtime = rt.current()
        self.runtime = runtime
        self.lang = english(lang)
        _ = self.lang.gettext
        self.document = document
        self.plan: backup.RestorePlan | None = None
        dtype = document["device"].get("type")
        candidates = [n for n, s in runtime.store.devices.items() if s.type == dtype and backup.device_backs_up(runtime, n)]
        default = document["device"].get("name") if document["device"].get("name") in candidates else (candidates[0] if candidates else None)
        with ui.card().classes("w-full").style("scroll-margin-top: 72px").props("data-testid=restore-card") as self.card:
            ui.label(_("Restore from {source}").format(source=source)).classes("text-subtitle1")
            by = backup.taken_by(document)
            ui.label(
                (_("{type} '{device}' of plant '{plant}', taken {time} by {by} with commission {version}; identity: {identity}")
                 if by else _("{type} '{device}' of plant '{plant}', taken {time} with commission {version}; identity: {identity}"))
                .format(type=dtype, device=document["device"].get("name"), plant=document.get("plant"),
                        time=backup.local_time(document.get("time")), by=by,
                        version=document.get("tool", {}).get("version", "?"),
                        identity=_identity_words(document.get("identity"), self.lang))
            ).classes("text-caption text-grey-8")
            if not candidates:
                ui.label(_("This plant has no {type}: the backup cannot be restored here.").format(type=repr(dtype))).classes("text-negative")
                return
            refused = backup.restore_refused(runtime, candidates[0])
            if refused:  # the device type keeps a snapshot for the record, but takes nothing back
                ui.label(_("A {type} backup is a record, not restorable: {reason}").format(type=dtype, reason=refused)).classes(
                    "text-body1 text-grey-9")
                return
            with ui.row().classes("items-center"):
                self.device = ui.select(candidates, value=default, label=_("Restore to")).props("dense outlined").classes("w-56")
                compare = ui.button(_("Compare with the device"), icon="compare_arrows", on_click=self.compare).props(
                    "data-testid=restore-compare")
                enable_unless(compare, viewer_reason(self.lang))  # the first step of a restore: an engineer's action
            self.progress = ui.linear_progress(value=0, show_value=False).classes("w-full")
            self.warnings = ui.column().classes("gap-0")
            self.table = ui.table(columns=columns(DIFF_COLUMNS, self.lang), rows=[], row_key="key", selection="multiple",
                                  pagination=0).classes("w-full reg-table").props("dense flat bordered")
            self.table.add_slot("body-cell-state", STATE_TEXT_SLOT)
            # differing rows stand out (what a write changes), unwritable ones in red
            self.table.props(':table-row-class-fn="row => row.state.startsWith(\'differs\') ? \'restore-differs\''
                             ' : (row.state.startsWith(\'not written\') ? \'restore-invalid\' : \'\')"')
            self.table.set_visibility(False)
            with ui.row().classes("items-center"):
                self.write = ui.button(_("Write selected"), icon="upload", color="negative", on_click=self.execute).props("data-testid=restore-write")
                self.write.set_visibility(False)
                self.summary = ui.label().classes("text-body2")
            self.report = ui.column().classes("gap-0")

    async def compare(self) -> None:
        self.warnings.clear()
        self.report.clear()
        self.progress.set_value(0)
        try:
            self.plan = await backup.plan_restore(self.runtime, self.device.value, self.document, self.progress.set_value)
        except ACTION_ERRORS as exc:  # type mismatch, unreadable device ...
            notify_error(self.lang.gettext("Cannot restore: {error}").format(error=said(exc, self.lang)))
            return
        self.progress.set_value(1)
        with self.warnings:
            for warning in self.plan.warnings:
                ui.label(f"⚠ {said(warning, self.lang)}").classes("text-warning text-body1")
        rows = [
            {"key": r.key, "name": r.name, "current": self.lang.with_unit(r.current_text, r.unit), "backup": self.lang.with_unit(r.backup_text, r.unit), "state": row_state(r),
             "state_text": state_text(r, self.lang), "risk": bool(r.changed and r.risk)}
            for r in self.plan.rows
        ]
        self.table.rows = rows
        self.table.selected = [row for row in rows if row["state"].startswith("differs")]
        self.table.set_visibility(True)
        self.table.update()
        changed = sum(1 for r in self.plan.rows if r.changed)
        self.summary.set_text(differ_text(changed, len(rows), self.lang) + "; " + self.lang.gettext("read-only ones are never written"))
        self.write.set_visibility(changed > 0)
        self.write.set_enabled(can_write())

    async def execute(self) -> None:
        if self.plan is None:
            return

        selected = {row["key"] for row in self.table.selected}
        to_write = [r for r in self.plan.rows if r.key in selected and r.changed]
        lang = self.lang
        _ = lang.gettext
        if not to_write:
            ui.notify(_("No differing parameter is selected"), type="warning")
            return
        wear = backup.restore_wear(self.runtime, self.plan.device)
        wear_text = lang.ngettext("Note: {wear}: this restore makes {n} such write.", "Note: {wear}: this restore makes {n} such writes.",
                                  len(to_write)).format(wear=said(wear, lang), n=len(to_write)) if wear else ""
        state = self.runtime.store.devices[self.plan.device]
        others = backup.unsaved_lines(state, skip={r.key for r in to_write})
        if not await confirm_restore(self.plan.device, to_write, others, wear_text, lang):
            return
        confirmed = await confirm_risky(self.plan.risky(selected), _("Restore {name} = {value}?"),
                                        _("{name} not confirmed: deselect it to restore the others"), lang)
        if confirmed is None:
            return
        user, role = current_user()
        self.write.disable()
        report = await backup.execute_restore(self.runtime, self.plan, selected, user=user, role=role, confirmed=confirmed,
                                              progress=self.progress.set_value)
        self.write.enable()
        self.report.clear()
        with self.report:
            ui.label(said(report.summary(), lang)).classes("text-body1 " + ("text-positive" if report.ok else "text-negative")).props(
                "data-testid=restore-report"
            )
            for name, error in report.failed:
                ui.label(_("failed: {name}: {error}").format(name=name, error=said(error, lang))).classes("text-negative")
            for name, error in report.refused:
                ui.label(_("refused: {name}: {error}").format(name=name, error=said(error, lang))).classes("text-negative")
            if report.written:
                ui.label(_("written: {names}").format(names=", ".join(report.written))).classes("text-caption")
        await self.compare_quietly()

    async def compare_quietly(self) -> None:
        try:
            self.plan = await backup.plan_restore(self.runtime, self.plan.device, self.document)
        except ACTION_ERRORS:  # the report above already says what happened
            return
        rows = {r.key: r for r in self.plan.rows}
        for row in self.table.rows:
            r = rows.get(row["key"])
            if r is not None:
                row["current"] = self.lang.with_unit(r.current_text, r.unit)
                row["state"] = row_state(r)
                row["state_text"] = state_text(r, self.lang)
                row["risk"] = bool(r.changed and r.risk)
        self.table.selected = [row for row in self.table.rows if row["state"].startswith("differs")]
        self.table.update()
        changed = sum(1 for r in self.plan.rows if r.changed)
        n = len(self.plan.rows)
        self.summary.set_text(differ_text(changed, n, self.lang) + ("" if changed else ": " + self.lang.gettext("the device matches the backup")))
        self.write.set_visibility(changed > 0)


async def confirm_risky(rows, question: str, unconfirmed: str, lang: Lang) -> set[str] | None:
    """Ask for each of ``rows`` (the risky rows of a plan) the confirmation a manual write of its value asks for:
    ``question`` and ``unconfirmed`` are texts in ``lang`` with ``{name}`` (and the question ``{value}``). The keys
    of the confirmed rows, or None at the first one not confirmed (said with ``unconfirmed``)."""
    _ = lang.gettext
    confirmed: set[str] = set()
    for row in rows:
        if not await confirm(question.format(name=row.name, value=row.backup_text), row.risk, ok=_("Write anyway"), lang=lang):
            ui.notify(unconfirmed.format(name=row.name), type="warning")
            return None
        confirmed.add(row.key)
    return confirmed


async def confirm_restore(device: str, to_write: list, others: list[str], wear_text: str, lang: Lang | None = None) -> bool:
    """Ask before a restore writes, naming every value the device's save step makes permanent: the
    restored ones and every earlier change not saved yet (as the device page's Save dialog does)."""
    lang = english(lang)
    _ = lang.gettext
    with ui.dialog() as dialog, ui.card().classes("max-w-xl").props("data-testid=restore-confirm"):
        ui.label(lang.ngettext("Write {n} parameter to {device}?", "Write {n} parameters to {device}?", len(to_write)).format(
            n=len(to_write), device=device)).classes("text-h6")
        ui.label(_("Each value is written, read back and, when all took, saved in the device:")).classes("text-body1")
        with ui.column().classes("gap-0 q-pl-md").props("data-testid=restore-confirm-writes"):
            for r in to_write:
                ui.label(f"{r.name} {r.current_text} -> {r.backup_text}").classes("text-body2 mono")
        if others:
            ui.label(lang.ngettext("The save also makes {n} earlier change permanent that is not saved yet (not part of this restore):",
                                   "The save also makes {n} earlier changes permanent that are not saved yet (not part of this restore):",
                                   len(others)).format(n=len(others))).classes(
                "text-body1 text-negative text-weight-medium")
            with ui.column().classes("gap-0 q-pl-md").props("data-testid=restore-confirm-unsaved"):
                for line in others:
                    ui.label(line).classes("text-body2 mono")
            ui.label(_("To keep them out of the device's permanent settings, cancel and discard them on the device's "
                       "page first (Restore-Settings).")).classes("text-caption text-grey-8")
        if wear_text:
            ui.label(wear_text).classes("text-body2 text-negative")
        with ui.row().classes("justify-end w-full"):
            ui.button(_("Cancel"), on_click=lambda: dialog.submit(False)).props("flat")
            ui.button(_("Write"), color="negative", on_click=lambda: dialog.submit(True)).props("data-testid=restore-confirm-ok").mark(
                "restore-confirm-ok")
    result = await dialog
    dialog.delete()
    return bool(result)
