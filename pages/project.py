"""The offline project (app/project.py) in the browser.

:class:`ProjectCard` shows the plant file's intended parameters of a device against the device and
reconciles per row: keep the device's value, apply the project's (restore's verified write through the
gate), or update the project (its entry rewritten atomically). The backup page shows it for every device
with a project, each device's page for its own (:func:`device_card`, compared when the device answers).

:func:`content` is the project editor (``/project/<device>``): every writable parameter of the device
type's parameter model with the project's value, edited and checked without the device (it may never have
answered), saved back into the plant file or the parameter file. Saving is an engineer's action, audited.
"""

from __future__ import annotations

import asyncio
import html

from nicegui import background_tasks, ui

from app import backup, i18n, project
from app import runtime as rt
from app.i18n import N_, Lang
from app.message import said
from devices.params import Param
from devices.registry import DEVICE_TYPES
from pages.diffrows import STATE_SLOT, WRAP, row_state, state_text
from pages.frame import ACTION_ERRORS, frame, notify_error
from pages.session import can_write, current_user
from pages.widgets import columns, follow
from pages.command_client import confirm, viewer_reason

PROJECT_COLUMNS = [
    {"name": "name", "label": N_("Parameter"), "field": "name", "align": "left"},
    {"name": "backup", "label": N_("Project"), "field": "backup", "align": "left", "style": WRAP + "; min-width: 5rem"},
    {"name": "current", "label": N_("Device now"), "field": "current", "align": "left", "style": WRAP + "; min-width: 5rem"},
    {"name": "state", "label": "", "field": "state", "align": "left", "style": WRAP},
    {"name": "actions", "label": N_("Reconcile"), "field": "key", "align": "left"},
]
# the state cell showing a row's state in the page's language (``state`` stays the English key)
STATE_TEXT_SLOT = STATE_SLOT.replace("props.row.state }}", "props.row.state_text }}")
# a differing row's project value in blue, the device's in orange (as the row's left edge)
VALUE_SLOTS = {
    name: f"""
    <q-td :props="props" :style="props.col.style">
      <span :class="props.row.changed ? '{colour} text-weight-medium' : ''">{{{{ props.value }}}}</span>
    </q-td>"""
    for name, colour in (("backup", "text-primary"), ("current", "text-deep-orange-9"))
}
PROJECT_ACTIONS = """
    <q-td :props="props">
      <div v-if="props.row.changed" class="row items-center q-gutter-x-sm">
        <q-btn dense flat no-caps icon="memory" label="{keep}" :data-project-keep="props.row.key"
               @click="$parent.$emit('keep', props.row.key)" />
        <q-btn dense flat no-caps color="negative" icon="upload" label="{apply}" :data-project-apply="props.row.key"
               :disable="!props.row.can_write" @click="$parent.$emit('apply', props.row.key)" />
        <q-btn dense flat no-caps icon="edit_note" label="{update}" :data-project-update="props.row.key"
               :disable="!props.row.can_write" @click="$parent.$emit('update', props.row.key)" />
      </div>
    </q-td>"""


def _where(plant, name: str, lang: Lang | None = None) -> str:
    """Where the project of ``name`` is kept, in words."""
    _ = (lang or i18n.get("en")).gettext
    path = project.project_file(plant, name)
    if path is not None:
        return _("the parameter file {file}").format(file=path.name)
    return plant.path.name if plant.path else _("the plant file")


def _state_text(row: backup.DiffRow, lang: Lang) -> str:
    return state_text(row, lang)


class ProjectCard:
    """The project of a device against the device, reconciled per row: keep the device's value, apply the
    project's (restore's verified write through the gate), or update the project (the plant file's or the
    parameter file's entry rewritten atomically).

    :param devices: the devices to choose from (the backup page); with ``compact`` the one device of its page,
        whose differing rows only are listed, compared by itself whenever the device comes to answer
    """

    def __init__(self, devices: list[str], *, compact: bool = False, lang: Lang | None = None):
        self.runtime = rt.current()
        self.lang = lang = lang or i18n.client_language()
        _ = lang.gettext
        self.compact = compact
        self.devices = devices
        self.plan: backup.RestorePlan | None = None
        self.kept: set[str] = set()
        self.device: ui.select | None = None
        self.may_write = can_write()  # the session's role now: the automatic compare runs without the page's context
        with ui.card().classes("w-full gap-2").props("data-testid=project-card") as self.card:
            self._head()
            self.problems = ui.column().classes("gap-0")
            self.table = ui.table(columns=columns(PROJECT_COLUMNS, lang), rows=[], row_key="key", pagination=0).classes(
                "w-full reg-table").props("dense flat bordered")
            self.table.add_slot("body-cell-state", STATE_TEXT_SLOT)
            self.table.add_slot("body-cell-actions", PROJECT_ACTIONS.replace("{keep}", html.escape(_("Keep device"))).replace(
                "{apply}", html.escape(_("Apply project"))).replace("{update}", html.escape(_("Update project"))))
            for column, slot in VALUE_SLOTS.items():
                self.table.add_slot(f"body-cell-{column}", slot)
            self.table.props(':table-row-class-fn="row => row.changed ? \'restore-differs\' : \'\'"')
            self.table.on("keep", lambda e: self.keep(e.args))
            self.table.on("apply", lambda e: self.apply(e.args))
            self.table.on("update", lambda e: self.update(e.args))
            self.table.set_visibility(False)
            if compact:
                self.table.props("hide-bottom")
            else:
                self.summary = ui.label().classes("text-body2").props("data-testid=project-summary")

    def _head(self) -> None:
        _ = self.lang.gettext
        if self.compact:
            with ui.row().classes("items-center w-full gap-x-4 gap-y-1"):
                ui.label(_("Project")).classes("text-subtitle1")
                self.summary = ui.label().classes("text-body2").props("data-testid=project-summary")
                ui.space()
                self.again = ui.button(_("Compare again"), icon="compare_arrows", on_click=self.compare).props(
                    "flat dense no-caps data-testid=project-compare")
                ui.link(_("Edit project"), f"/project/{self.devices[0]}").props("data-testid=project-edit")
            ui.label(_("The intended parameters {where} names for this device. Nothing is written until you press Apply "
                       "project on a row.").format(where=_where(self.runtime.plant, self.devices[0], self.lang))).classes(
                "text-caption text-grey-8")
            return
        ui.label(_("Project against the devices")).classes("text-subtitle1")
        where = self.runtime.plant.path.name if self.runtime.plant.path else _("the plant file")
        ui.label(_("The intended parameters {where} names for each device, checked by the parameter model. "
                   "Nothing is written until you press Apply project on a row.").format(where=where)).classes("text-caption text-grey-8")
        with ui.row().classes("items-center"):
            self.device = ui.select(self.devices, value=self.devices[0], label=_("Device")).props(
                "dense outlined data-testid=project-device").classes("w-56")
            ui.button(_("Compare project with the device"), icon="compare_arrows", on_click=self.compare).props(
                "data-testid=project-compare")
            edit = ui.link(_("Edit project"), f"/project/{self.devices[0]}").props("data-testid=project-edit")
            self.device.on_value_change(lambda e: edit.props(f'href="/project/{e.value}"'))

    @property
    def name(self) -> str:
        return self.device.value if self.device is not None else self.devices[0]

    async def compare(self) -> None:
        name = self.name
        self.problems.clear()
        problems = [e for e in await asyncio.to_thread(project.entries, self.runtime.plant, name) if e.error]
        with self.problems:
            for entry in problems:
                ui.label(f"✖ {entry.where}: {said(entry.error, self.lang)}").classes("text-negative text-body2")
        try:
            self.plan = await backup.plan_restore(self.runtime, name, project.document(self.runtime, name))
        except ACTION_ERRORS as exc:  # not answering, no parameter model ...
            if self.compact:
                self.summary.set_text(self.lang.gettext("not compared: {error}").format(error=said(exc, self.lang)))
            else:
                notify_error(self.lang.gettext("Cannot compare: {error}").format(error=said(exc, self.lang)))
            return
        self.kept = {k for k in self.kept if k.startswith(name + "/")}
        self.show()

    def show(self) -> None:
        name = self.plan.device
        lang = self.lang
        _ = lang.gettext
        rows = []
        for r in self.plan.rows:
            kept = f"{name}/{r.key}" in self.kept and r.changed
            state = "differs; the device's value kept" if kept else row_state(r)
            rows.append({"key": r.key, "name": r.name, "current": lang.with_unit(r.current_text, r.unit), "backup": lang.with_unit(r.backup_text, r.unit), "state": state,
                         "state_text": _("differs; the device's value kept") if kept else _state_text(r, lang),
                         "risk": bool(r.changed and r.risk), "changed": r.changed and not kept, "can_write": self.may_write})
        changed = sum(1 for row in rows if row["changed"])
        self.table.rows = [row for row in rows if row["changed"]] if self.compact else rows
        self.table.update()
        self.table.set_visibility(bool(self.table.rows))
        entries = lang.ngettext("{n} project entry", "{n} project entries", len(rows)).format(n=len(rows))
        differ = lang.ngettext("{changed} of {entries} differs from the device", "{changed} of {entries} differ from the device",
                               changed).format(changed=changed, entries=entries)
        if self.compact:
            self.summary.set_text(differ if changed else _("device and project agree ({entries})").format(entries=entries))
        else:
            self.summary.set_text(f"{name}: {differ}" + ("" if changed else ": " + _("device and project agree")))

    def _row(self, key: str) -> backup.DiffRow | None:
        return next((r for r in self.plan.rows if r.key == key), None) if self.plan else None

    def keep(self, key: str) -> None:
        if self._row(key) is not None:
            self.kept.add(f"{self.plan.device}/{key}")
            self.show()

    async def apply(self, key: str) -> None:
        row = self._row(key)
        if row is None or not row.changed:
            return
        _ = self.lang.gettext
        if not await confirm(_("Write {name} = {value} to {device}?").format(name=row.name, value=row.backup_text, device=self.plan.device),
                             _("The project's value is written, read back and saved in the device (now {value}).").format(
                                 value=row.current_text), ok=_("Write"), lang=self.lang):
            return
        confirmed = set()
        if row.risk:
            if not await confirm(_("Write {name} = {value}?").format(name=row.name, value=row.backup_text), said(row.risk, self.lang),
                                 ok=_("Write anyway"), lang=self.lang):
                return
            confirmed.add(key)
        user, role = current_user()
        report = await backup.execute_restore(self.runtime, self.plan, {key}, user=user, role=role, confirmed=confirmed)
        ui.notify(f"{row.name}: {said(report.summary(), self.lang)}", type="positive" if report.ok else "negative", multi_line=True)
        await self.compare()

    async def update(self, key: str) -> None:
        row = self._row(key)
        if row is None or not row.changed:
            return
        device = self.plan.device
        user, role = current_user()

        async def rewrite() -> None:
            await asyncio.to_thread(project.update_entry, self.runtime.plant, device, key, row.current_value)

        try:
            await self.runtime.worker.gate.run(rewrite, user=user, role=role, describe="update project",
                                               device=device, new=f"{row.name} = {row.current_text}", kind="write")
        except ACTION_ERRORS as exc:  # a file that cannot be written, a viewer ...
            notify_error(self.lang.gettext("Project not updated: {error}").format(error=said(exc, self.lang)))
            return
        ui.notify(self.lang.gettext("Project of {device}: {name} = {value}").format(device=device, name=row.name, value=row.current_text),
                  type="positive")
        await self.compare()

    def follow_device(self) -> None:
        """Compare whenever the device comes to answer (on connect); say what is known while it does not."""
        state = self.runtime.store.devices[self.name]
        answering = {"now": False, "said": False}

        def changed() -> None:
            online = state.status in ("online", "stale")  # a late answer is no new connection: no new compare
            if online and not answering["now"]:
                background_tasks.create(self.compare(), name=f"project {self.name}")
            elif not online and self.plan is None and not answering["said"]:
                answering["said"] = True  # said once: the project file is not read again on every push
                count = len(project.entries(self.runtime.plant, self.name))
                self.summary.set_text(self.lang.ngettext("{n} project entry", "{n} project entries", count).format(n=count)
                                      + "; " + self.lang.gettext("the device does not answer: compared when it does"))
            if online != answering["now"]:
                self.again.set_enabled(online)
            answering["now"] = online

        self.again.set_enabled(False)
        changed()
        follow(state, changed)


def page_column() -> ui.element | None:
    """The content column of the page being built (pages.frame.frame's), or None."""
    columns = [e for e in ui.context.client.elements.values()
               if isinstance(e, ui.column) and {"q-pa-md", "gap-4", "w-full"} <= set(e.classes)]
    return min(columns, key=lambda e: e.id) if columns else None


def device_card(name: str, lang: Lang | None = None) -> None:
    """On the page of device ``name``, below its title: its project against it (when the plant file names one),
    or the way to write one on its type's parameter model (at the page's end); in ``lang`` (by default the page's)."""
    runtime = rt.current()
    lang = lang or i18n.client_language()
    if name not in runtime.plant.devices:
        return
    column = page_column()
    if column is None:
        return
    has = project.has_project(runtime.plant, name)
    if not has and not project.editable(runtime.plant, name):
        return  # a type without a parameter model: nothing a project could name
    with column:
        if has:
            card = ProjectCard([name], compact=True, lang=lang)
            card.card.move(target_container=column, target_index=1)
            card.follow_device()
            return
        with ui.row().classes("items-center gap-2").props("data-testid=project-none"):
            ui.icon("edit_note", color="grey-7")
            ui.label(lang.gettext("The plant file names no project for this device.")).classes("text-body2 text-grey-8")
            ui.link(lang.gettext("Write one on its parameter model"), f"/project/{name}").props("data-testid=project-edit")


# -- the project editor (/project/<device>) -----------------------------------------------------------------

PARAM_ROW = ("display: grid; grid-template-columns: minmax(0, 1fr) minmax(10rem, 15rem); gap: 2px 16px; "
             "align-items: start; width: 100%; padding: 8px 0; border-top: 1px solid #e0e0e0")


def _shown(param: Param, value) -> str:
    """A project value as the editor's field holds it ("" when the project does not name the parameter)."""
    if value is None:
        return ""
    try:
        return str(param.decode(param.validate(value)))
    except ValueError:
        return str(value)  # an invalid entry is shown as written, so it can be corrected


class ProjectEditor:
    """Every writable parameter of the device type's parameter model with the project's value, checked as typed,
    saved into the project (an engineer's action, audited); read-only for a viewer."""

    def __init__(self, name: str, lang: Lang | None = None):
        self.runtime = rt.current()
        self.lang = lang or i18n.get("en")
        self.name = name
        self.params = project.editable(self.runtime.plant, name)
        # a type's parameter names are worded where they are the tool's words (DeviceType.worded_names), as its page does
        self.names_worded = DEVICE_TYPES[self.runtime.plant.devices[name].type].worded_names
        self.fields: dict[str, ui.input | ui.select] = {}
        self.values: dict[str, object] = {}
        self.read_only = viewer_reason(self.lang)

    def build(self) -> None:
        from pages.frame import status_text

        lang = self.lang
        _ = lang.gettext
        plant, state = self.runtime.plant, self.runtime.store.devices[self.name]
        title = lang.phrase(DEVICE_TYPES[state.type].title)
        where = _where(plant, self.name, lang) if project.has_project(plant, self.name) else \
            _("{file} (no project yet: saving adds one)").format(file=plant.path.name if plant.path else _("the plant file"))
        with ui.card().classes("w-full gap-1"):
            ui.label(_("{type} '{name}' on {bus}: the project is kept in {where}.").format(
                type=title, name=self.name, bus=state.bus, where=where)).classes("text-body1")
            status = state.status if lang.code == "en" else status_text(state.status, state.age, lang)
            ui.label(_("Edited on the {type} parameter model without the device (it is {status} now): nothing "
                       "is written to the device here. An empty field is not in the project.").format(type=title, status=status)).classes(
                "text-caption text-grey-8")
            with ui.row().classes("items-center gap-4"):
                ui.link(_("Device page"), f"/device/{self.name}")
                ui.link(_("Backup page"), "/backup")
            self.problems = ui.column().classes("gap-0").props("data-testid=project-problems")
        with ui.card().classes("w-full").props("data-testid=project-editor"):
            ui.label(_("{n} writable parameters").format(n=len(self.params))).classes("text-subtitle1")
            for param in self.params:
                self._field(param)
            with ui.row().classes("items-center"):
                self.save_button = ui.button(_("Save project"), icon="save", on_click=self.save).props(
                    "data-testid=project-save")
                self.status = ui.label().classes("text-body2").props("data-testid=project-status")
            if self.read_only:
                self.save_button.disable()
                self.status.set_text(self.read_only)
        self.load()

    def _field(self, param: Param) -> None:
        """One parameter: its name, what it allows, its risk and its doc text beside the project's value."""
        _ = self.lang.gettext
        with ui.element("div").style(PARAM_ROW):
            with ui.column().classes("gap-0"):
                label = param.label or param.name
                ui.label(_(label) if self.names_worded else label).classes("text-body2 text-weight-medium")
                allowed = _("one of the listed values") if param.enum is not None else self.lang.numbers_in(said(project.allowed(param), self.lang))
                ui.label(_("allowed: {allowed}").format(allowed=allowed)).classes("text-caption text-grey-9")
                if param.confirm:
                    ui.label("⚠ " + _("asks before it is written: {risk}").format(risk=said(param.confirm, self.lang))).classes("text-caption text-negative").style(WRAP)
                if param.description:
                    ui.label(said(param.description, self.lang)).classes("text-caption text-grey-7").style(WRAP)
            if param.enum is not None:
                options = {"": _("(not in the project)")} | {str(n): f"{self.lang.value_word(param.name, text)} ({n})" for n, text in param.enum.items()}
                field = ui.select(options, value="").props("dense outlined options-dense")
            else:
                field = ui.input(placeholder=_("not in the project"), suffix=self.lang.unit(param.unit) or None,
                                 validation=lambda v, p=param: self._error(p, v)).props("dense outlined")
        field.props(f'data-project-field="{param.key}"')
        if self.read_only:
            field.disable()
        self.fields[param.key] = field

    def _error(self, param: Param, text) -> str | None:
        if text is None or not str(text).strip():
            return None
        try:
            project.parse_value(param, str(text))
        except project.ProjectError as exc:
            return said(exc, self.lang)
        return None

    def load(self) -> None:
        """The project's values into the fields, and its invalid or unknown entries named with file:line."""
        entries = project.entries(self.runtime.plant, self.name)
        self.values = {e.key: e.value for e in entries if e.key}
        self.problems.clear()
        with self.problems:
            for entry in entries:
                if entry.error:
                    ui.label(f"✖ {entry.where}: {said(entry.error, self.lang)}").classes("text-negative text-body2")
        for param in self.params:
            self.fields[param.key].set_value(_shown(param, self.values.get(param.key)))

    def changes(self) -> tuple[dict[str, object], list[str]]:
        """What the fields change in the project (key -> value, None to drop) and what is wrong with them."""
        changes, errors = {}, []
        for param in self.params:
            text = str(self.fields[param.key].value or "").strip()
            old = self.values.get(param.key)
            if not text:
                if old is not None:
                    changes[param.key] = None
                continue
            try:
                value = project.parse_value(param, text)
            except project.ProjectError as exc:
                errors.append(said(exc, self.lang))
                continue
            if old is None or _shown(param, old) != str(value):
                changes[param.key] = value
        return changes, errors

    async def save(self) -> None:
        _ = self.lang.gettext
        changes, errors = self.changes()
        if errors:
            self.status.set_text(_("Not saved: {errors}").format(errors="; ".join(errors)))
            self.status.classes(replace="text-body2 text-negative")
            return
        if not changes:
            self.status.set_text(_("Nothing changed"))
            self.status.classes(replace="text-body2")
            return
        by_key = {p.key: p for p in self.params}
        words = "; ".join(f"{by_key[k].label or by_key[k].name} {_shown(by_key[k], self.values.get(k)) or '-'} -> "
                          f"{'-' if v is None else v}" for k, v in changes.items())
        user, role = current_user()
        shown = {k: self.values.get(k) for k in changes}  # what this page showed: refused if another save changed it
        self.save_button.disable()  # one save at a time: a second press waits for the first's values
        try:
            await self.runtime.worker.gate.run(
                lambda: asyncio.to_thread(project.save, self.runtime.plant, self.name, changes, shown), user=user, role=role,
                describe="edit project", device=self.name, parameter=", ".join(by_key[k].label or by_key[k].name
                                                                               for k in changes), new=words, kind="write")
        except ACTION_ERRORS as exc:  # a viewer, a file that cannot be written ...
            self.status.set_text(_("Not saved: {errors}").format(errors=said(exc, self.lang)))
            self.status.classes(replace="text-body2 text-negative")
            return
        finally:
            self.save_button.enable()
        self.load()
        self.status.set_text(_("Saved: {changes}").format(changes=words))
        self.status.classes(replace="text-body2 text-positive")


def content(name: str) -> None:
    runtime = rt.current()
    state = runtime.store.devices.get(name)
    lang = i18n.page_language()
    _ = lang.gettext
    with frame(_("Project of {name}").format(name=name)):
        if state is None or name not in runtime.plant.devices:
            ui.label(_("The plant has no device named '{name}'.").format(name=name))
            ui.link(_("Back to the overview"), "/")
            return
        if not project.editable(runtime.plant, name):
            title = lang.phrase(DEVICE_TYPES[state.type].title)
            refused = backup.restore_refused(runtime, name)
            ui.label(_("A {type} has no parameter model in this tool, so it has no parameters a project can name ({reason}).")
                     .format(type=title, reason=refused) if refused else
                     _("A {type} has no parameter model in this tool, so it has no parameters a project can name: its backup "
                       "keeps the device's own records, checked by the device when they are written.").format(type=title)).classes(
                "text-body1").props("data-testid=project-no-model")
            ui.link(_("Device page"), f"/device/{name}")
            return
        ProjectEditor(name, lang).build()
