"""Replacement assistant (/replace/<device>): identity check, the approved set against the new device
as a diff with rows to deselect, verified write and save, the checkout offered, all recorded.

Also the "replaced?" notice every device page shows (:func:`notice`)."""

from __future__ import annotations

from nicegui import ui

from app import backup, i18n, replace
from app import runtime as rt
from app.i18n import N_, Lang
from app.message import said
from pages.backup import DIFF_COLUMNS, STATE_TEXT_SLOT, confirm_restore, confirm_risky, differ_text, state_text
from pages.diffrows import row_state
from pages.frame import ACTION_ERRORS, frame, notify_error
from pages.overview import replaced_of
from pages.session import can_write, current_user
from pages.simcontrols import sim_card
from pages.widgets import columns, follow


def notice(name: str, lang: Lang | None = None) -> None:
    """A "replaced?" notice on the device page, with old and new identity and the way to the assistant; in ``lang``
    (by default the page's)."""
    runtime = rt.current()
    lang = lang or i18n.client_language()
    _ = lang.gettext
    state = runtime.store.devices.get(name)
    if state is None:
        return
    with ui.page_sticky(position="bottom-left", x_offset=16, y_offset=16):
        with ui.card().classes("bg-red-1 q-pa-sm").props("data-testid=replaced-notice") as card:
            with ui.row().classes("items-center no-wrap gap-2"):
                ui.icon("swap_horiz", color="negative")
                text = ui.label().classes("text-body2 text-negative text-weight-medium")
                ui.link(_("Replacement assistant"), f"/replace/{name}").props("data-testid=replaced-open")

    def update() -> None:
        replaced = replaced_of(state)
        card.set_visibility(bool(replaced))
        if replaced:
            text.set_text(_("replaced? known {old}, now {new}").format(
                old=said(replace.identity_text(replaced["old"]), lang), new=said(replace.identity_text(replaced["new"]), lang)))

    update()
    follow(state, update)
    if backup.device_backs_up(runtime, name):
        _offer(name, lang)


def _offer(name: str, lang: Lang) -> None:
    """The way to the replacement assistant on every device page that keeps parameters (at the page's end),
    not only once a swap was detected."""
    from pages.project import page_column

    column = page_column()
    if column is None:
        return
    with column, ui.row().classes("items-center gap-2").props("data-testid=replace-offer"):
        ui.icon("swap_horiz", color="grey-7")
        _ = lang.gettext
        ui.label(_("Swapped this device for a new one?")).classes("text-body2 text-grey-8")
        ui.link(_("Replacement assistant"), f"/replace/{name}").props("data-testid=replace-link")
        ui.label(_("checks the new one's identity and writes the approved set to it")).classes("text-caption text-grey-8")


def content(name: str) -> None:
    runtime = rt.current()
    lang = i18n.page_language()
    _ = lang.gettext
    state = runtime.store.devices.get(name)
    with frame(_("Replace {name}").format(name=name)):
        if state is None or not backup.device_backs_up(runtime, name):
            ui.label(_("The plant has no device named '{name}' that keeps parameters.").format(name=name)).classes("text-negative")
            return
        Assistant(name, lang)
        sim_card(name, only=("swap for a new device",))  # a simulated device: the service swap, through the gate


class Assistant:
    """Identity, diff, go, verified write, save, checkout, record."""

    def __init__(self, name: str, lang: Lang | None = None):
        self.runtime = rt.current()
        self.lang = lang = lang or i18n.get("en")
        _ = lang.gettext
        self.name = name
        self.state = self.runtime.store.devices[name]
        self.rp: replace.ReplacementPlan | None = None
        with ui.card().classes("w-full").props("data-testid=replace-identity"):
            ui.label(_("1. Identity")).classes("text-subtitle1")
            self.identity = ui.label().classes("text-body1").props("data-testid=replace-state")
            ui.label(_("Type and variant must match the approved set; a firmware or hardware difference is named. "
                       "Nothing is written until you press Write.")).classes("text-caption text-grey-8")
            with ui.row().classes("items-center"):
                ui.button(_("Check identity and compare"), icon="compare_arrows", on_click=self.compare).props(
                    "data-testid=replace-compare")
            self.progress = ui.linear_progress(value=0, show_value=False).classes("w-full")
            self.check = ui.column().classes("gap-0").props("data-testid=replace-check")
        with ui.card().classes("w-full") as self.diff_card:
            ui.label(_("2. The approved set against the new device")).classes("text-subtitle1")
            self.source = ui.label().classes("text-caption text-grey-8")
            self.table = ui.table(columns=columns(DIFF_COLUMNS, lang), rows=[], row_key="key", selection="multiple", pagination=0) \
                .classes("w-full reg-table").props("dense flat bordered")
            self.table.columns[2]["label"] = _(N_("Approved"))
            self.table.add_slot("body-cell-state", STATE_TEXT_SLOT)
            self.table.props(':table-row-class-fn="row => row.state.startsWith(\'differs\') ? \'restore-differs\''
                             ' : (row.state.startsWith(\'not written\') ? \'restore-invalid\' : \'\')"')
            with ui.row().classes("items-center"):
                self.write = ui.button(_("Write selected"), icon="upload", color="negative", on_click=self.execute).props(
                    "data-testid=replace-write")
                self.summary = ui.label().classes("text-body2")
        self.diff_card.set_visibility(False)
        with ui.card().classes("w-full") as self.done_card:
            ui.label(_("3. Result")).classes("text-subtitle1")
            self.report = ui.column().classes("gap-0")
            with ui.row():
                ui.link(_("Run the checkout and see the timeline"), f"/record/{name}").props("data-testid=replace-checkout")
        self.done_card.set_visibility(False)
        self.show_identity()
        follow(self.state, self.show_identity)

    def show_identity(self) -> None:
        replaced = replaced_of(self.state)
        watch = replace.watch_of(self.runtime)
        known = (watch.known.get(self.name) or {}) if watch else {}
        now = replace.live_identity(self.runtime, self.name)
        _ = self.lang.gettext
        if replaced:
            text = _("replaced? known {old} ({source}), now {new}").format(
                old=said(replace.identity_text(replaced["old"]), self.lang), source=said(replaced.get("source") or _("known"), self.lang),
                new=said(replace.identity_text(replaced["new"]), self.lang))
        else:
            text = (_("identity as known: {identity}").format(identity=said(replace.identity_text(now or known.get("identity")), self.lang))
                    + (f" ({said(known['source'], self.lang)})" if known.get("source") else ""))
        if self.identity.text != text:
            self.identity.set_text(text)
            self.identity.classes(replace="text-body1 " + ("text-negative text-weight-medium" if replaced else ""))

    async def compare(self) -> None:
        _ = self.lang.gettext
        self.check.clear()
        self.progress.set_value(0)
        try:
            self.rp = await replace.plan_replacement(self.runtime, self.name, self.progress.set_value)
        except ACTION_ERRORS as exc:  # no approved set, device not answering ...
            notify_error(_("Cannot compare: {error}").format(error=said(exc, self.lang)))
            return
        self.progress.set_value(1)
        check = self.rp.check
        with self.check:
            ui.label(_("known {old}; the device now {new}").format(old=said(replace.identity_text(check.old), self.lang),
                                                                    new=said(replace.identity_text(check.new), self.lang))) \
                .classes("text-body2")
            for refusal in check.refusals:
                ui.label("✖ " + _("refused: {reason}").format(reason=said(refusal, self.lang))).classes("text-negative text-body1").props("data-testid=replace-refused")
            for note in check.notes:
                ui.label(f"⚠ {said(note, self.lang)}").classes("text-warning text-body1").props("data-testid=replace-note")
            if check.lacks:
                ui.label(_("the device lacks: {names}").format(names=", ".join(check.lacks))).classes("text-body2")
            if check.adds:
                ui.label(_("the device adds (not in the set, left as they are): {names}").format(names=", ".join(check.adds))).classes("text-body2")
            if check.ok and not check.notes:
                ui.label("✔ " + _("same type and identity as the approved set")).classes("text-positive text-body1")
        if self.rp.plan is None:
            self.diff_card.set_visibility(False)
            return
        warnings = [said(w, self.lang) for w in self.rp.plan.warnings]
        self.source.set_text(_("from the {source}").format(source=said(self.rp.source, self.lang)) + ("; " + "; ".join(warnings) if warnings else ""))
        self._show_rows()
        self.diff_card.set_visibility(True)

    def _show_rows(self) -> None:
        rows = [{"key": r.key, "name": r.name, "current": self.lang.with_unit(r.current_text, r.unit), "backup": self.lang.with_unit(r.backup_text, r.unit), "state": row_state(r),
                 "state_text": state_text(r, self.lang), "risk": bool(r.changed and r.risk)} for r in self.rp.plan.rows]
        self.table.rows = rows
        self.table.selected = [row for row in rows if row["state"].startswith("differs")]
        self.table.update()
        changed = sum(1 for r in self.rp.plan.rows if r.changed)
        self.summary.set_text(self.lang.gettext("{differ} from the approved set").format(differ=differ_text(changed, len(rows), self.lang)))
        self.write.set_visibility(changed > 0)
        self.write.set_enabled(can_write())

    async def execute(self) -> None:
        if self.rp is None or self.rp.plan is None:
            return
        lang = self.lang
        _ = lang.gettext
        selected = {row["key"] for row in self.table.selected}
        to_write = [r for r in self.rp.plan.rows if r.key in selected and r.changed]
        if not to_write:
            ui.notify(_("No differing parameter is selected"), type="warning")
            return
        others = backup.unsaved_lines(self.state, skip={r.key for r in to_write})
        if not await confirm_restore(self.name, to_write, others, "", lang):
            return
        confirmed = await confirm_risky(self.rp.plan.risky(selected), _("Write {name} = {value}?"),
                                        _("{name} not confirmed: deselect it to write the others"), lang)
        if confirmed is None:
            return
        user, role = current_user()
        self.write.disable()
        try:
            report = await replace.execute_replacement(self.runtime, self.rp, selected, user=user, role=role,
                                                       confirmed=confirmed, progress=self.progress.set_value)
        except ACTION_ERRORS as exc:  # refused before any write (each write's own refusal is in the report)
            notify_error(_("Not written: {error}").format(error=said(exc, lang)))
            return
        finally:
            self.write.enable()
        self.report.clear()
        with self.report:
            ui.label(said(report.summary(), lang)).classes("text-body1 " + ("text-positive" if report.ok else "text-negative")).props(
                "data-testid=replace-report")
            for name, error in report.failed + report.refused:
                ui.label(_("failed: {name}: {error}").format(name=name, error=said(error, lang))).classes("text-negative")
            if report.written:
                ui.label(_("written and read back: {names}").format(names=", ".join(report.written))).classes("text-caption")
            ui.label(_("Recorded in the device's timeline and the audit log; the new identity is the known one now.") if report.ok
                     else _("Recorded in the device's timeline and the audit log.")).classes("text-caption")
        self.done_card.set_visibility(True)
        try:
            self.rp = await replace.plan_replacement(self.runtime, self.name)
            if self.rp.plan is not None:
                self._show_rows()
        except ACTION_ERRORS:  # the report above says what happened
            pass
