"""The Electrak page's service parameters (0x0A / 0x0B) of every actuator: value, age, the answers of each
actuator, write with read-back, save (0xF0). Each read and write goes to every actuator on the network and
fails unless every one answers alike; the password is written to 0xFF before each (the adapter's)."""

from __future__ import annotations

import html
import logging
import time

from nicegui import background_tasks, ui

from app import i18n
from app.i18n import N_
from app.message import said
from devices.electrak import adapter as facts
from devices.electrak import codec
from devices.electrak.params import BITRATE_SPECIFIER, PARAMS, length_of, refusal
from pages.cards import DrawnCard, point_values
from pages.command_client import checked_value, refuse, write_from_page
from pages.device_page import DeviceView
from pages.frame import fmt_time
from pages.session import current_user
from pages.widgets import LampStrip, mark_quality, quality_note, range_number

log = logging.getLogger(__name__)



def _answers_text(report: facts.ServiceReport | None, lang=None) -> tuple[str, str]:
    """Short text and tooltip of the last exchange of one parameter with every actuator."""
    if not report:
        return "", ""
    _ = (lang or i18n.get("en")).gettext
    if report.ok:
        return _("{n} of {expected} agree").format(n=len(report.answers), expected=report.expected), _answered(report, lang)
    return "; ".join(said(p, lang) for p in report.problems), _answered(report, lang)


def _answered(report: facts.ServiceReport, lang=None) -> str:
    """Each actuator's answer to the last service telegram (``answer 1: value 12; answer 2: value 12``)."""
    _ = (lang or i18n.get("en")).gettext
    return "; ".join(_("answer {n}: {text}").format(n=n, text=said(a, lang))
                     for n, a in enumerate(report.answers, 1)) or _("no answer")


class ServiceCard(DrawnCard):
    """The service parameters (0x0A / 0x0B) of every actuator: value, age, answers, write, save."""

    def __init__(self, view: DeviceView):
        super().__init__(view)
        self.rows: dict = {}
        self.entries: dict = {}  # parameter key -> its entry field
        self.shown: dict = {}  # parameter key -> the device value the field was last set to
        self.auto_read = False

    def build(self) -> None:
        view, guard = self.view, self.guard
        _ = view.lang.gettext
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center w-full"):
                ui.label(_("Service parameters (0x0A / 0x0B)")).classes("text-subtitle1")
                self.unsaved = ui.badge("", color="orange")
                ui.space()
                guard.add(
                    ui.button(_("Read all"), icon="refresh", on_click=lambda: view.act("read service parameters")).props("outline"),
                    ui.button(_("Save parameters (0xF0)"), icon="save", on_click=lambda: save_parameters(view)).props("data-testid=save-params"),
                )
            ui.label(_("The right password is written to 0xFF before each read or write. Each of the {n} actuators answers "
                       "for itself: a read or write fails unless every one answers alike. Changes hold until power-off unless "
                       "saved.").format(n=len(view.fact(facts.P_ACTUATORS, ())))).classes("text-caption text-grey-8")
            # specifier, name, value, entry, Write: the entry takes what is left up to 12rem, never over the button
            with ui.grid(columns="auto minmax(7rem, 1fr) minmax(7rem, 1fr) minmax(7rem, 12rem) auto") \
                    .classes("w-full items-center gap-x-4 gap-y-1"):
                for h in (N_("Specifier"), N_("Parameter"), N_("Value (every actuator)"), N_("New value"), ""):
                    ui.label(_(h) if h else "").classes("text-caption text-grey-8")
                for p in PARAMS:
                    self._row(p)
            self.last = ui.label().classes("text-caption mono text-grey-8")
            self.form = ui.label().classes("text-caption text-grey-8")

    def _row(self, p) -> None:
        _ = self.view.lang.gettext
        ui.html(f'<div class="mono text-caption">0x{p.address:02X}</div>'  # static: one element
                f'<div class="text-caption text-grey-8">{html.escape(specifier_note(p, self.view.lang))}</div>', sanitize=False) \
            .classes("nicegui-column gap-0").props(f'data-specifier="{p.address:02X}"')
        with ui.row().classes("items-center gap-1"):
            ui.label(_(p.name)).tooltip(said(p.description, self.view.lang))
            mark = ui.badge(_("unsaved"), color="orange")
        cell = LampStrip("nicegui-column gap-0")  # value, read time or age, the answers: one element, drawn on change
        if p.address == BITRATE_SPECIFIER:
            ui.label(_("change it step by step below")).classes("text-caption text-grey-8")
            ui.element("span")
        else:
            entry = service_entry(p, self.view.state.raw(p), self.view.lang)
            entry.props(f"data-testid=entry-{p.address:02X}")
            self.shown[p.key] = entry.value
            entry.on("keydown.enter", lambda: self.write(p, entry))  # Enter writes, as the button does (same question)
            self.guard.add(ui.button(_("Write"), on_click=lambda: self.write(p, entry))
                           .props(f"data-testid=write-{p.address:02X}"))
            self.entries[p.key] = entry
        self.rows[p.key] = (p, mark, cell)

    async def write(self, param, entry) -> None:
        """Write the entry; afterwards the field shows the value read back from the actuators, not what was typed."""
        state = self.view.state
        before = state.read_time(param)
        await _write_service(self.view.name, param, entry, self.view.lang)
        read = state.read_time(param)
        raw = state.raw(param)
        if read is not None and read != before and raw is not None:
            value = param.decode(raw)
            _show(entry, value)
            entry.error = None
            self.shown[param.key] = value

    def follow_entry(self, key: str, p, raw: int | None) -> None:
        """A field shows the actuators' value until the engineer types into it (hdlock's rule)."""
        entry = self.entries.get(key)
        if entry is None or raw is None:
            return
        value = p.decode(raw)
        if entry.value is None or entry.value in (self.shown.get(key), value):  # untouched
            _show(entry, value)
            self.shown[key] = value

    def read_once(self) -> None:
        """Run what the device type declares a page reads by itself on opening (the service parameters, when the
        network answers and none was ever read: the fields then start at the actuators' values; app/open_reads.py),
        once per page."""
        view = self.view
        if self.auto_read or not view.runtime.open_reads.never_read(view.name):
            return
        self.auto_read = True
        user, role = current_user()
        background_tasks.create(view.runtime.open_reads.run(view.name, user=user, role=role, session=view.session),
                                name=f"open reads {view.name}")

    def refresh(self) -> None:
        self.read_once()
        state = self.view.state
        for key, entry in self.entries.items():
            if entry.value is None:  # a field left empty shows the actuators' value again (a new value: in draw())
                self.follow_entry(key, self.rows[key][0], state.raw(self.rows[key][0]))
        super().refresh()

    def inputs(self) -> tuple:
        state = self.view.state
        return (state.status, self.view.readings(PARAMS),
                frozenset(state.unsaved),
                point_values(state, (facts.P_SERVICE_REPORTS, facts.P_SERVICE_LAST, facts.P_SAVE_FORM)))

    def draw(self) -> None:
        view, state = self.view, self.view.state
        lang = view.lang
        _ = lang.gettext
        reports = {r.key: r for r in view.fact(facts.P_SERVICE_REPORTS, ())}
        now = time.time()
        for key, (p, mark, cell) in self.rows.items():
            raw = state.raw(p)
            self.follow_entry(key, p, raw)
            report = reports.get(key)
            value = (_("not read") if not report or report.ok else _("no common value")) if raw is None \
                else lang.numbers_in(p.display(raw))
            read = state.read_time(p)
            quality = state.quality(read, False, now)  # read on demand: good while the network answers
            mark_quality(cell.element, quality if raw is not None else "unknown")
            note = quality_note(quality, None if read is None else now - read, lang) if quality in ("stale", "offline") else ""
            age = note or (_("read {time}").format(time=fmt_time(read)) if read is not None and raw is not None else "")
            text, tip = _answers_text(report, lang)
            cell.show(['<div class="nicegui-row row items-baseline gap-0 no-wrap">'
                       f'<div class="mono">{html.escape(value)}</div><div class="q-age" data-testid="age-{p.address:02X}">'
                       f'{html.escape(age)}</div></div><div class="text-caption '
                       + ("text-grey-8" if not report or report.ok else "text-negative") + '"'
                       + (f' data-tip="{html.escape(tip, quote=True)}"' if tip else "") + f'>{html.escape(text)}</div>'])
            mark.set_visibility(key in state.unsaved)
        self.unsaved.set_text(_("{n} unsaved").format(n=len(state.unsaved)))
        self.unsaved.set_visibility(bool(state.unsaved))
        report = view.fact(facts.P_SERVICE_LAST)
        self.last.set_text("" if not report else _("last service telegram: {what} at {time}: ").format(
                               what=said(report.what, lang), time=fmt_time(report.time))
                           + _answered(report, lang)
                           + ("" if report.ok else " - " + "; ".join(said(p, lang) for p in report.problems)))
        form = view.fact(facts.P_SAVE_FORM)
        self.form.set_text(_("last save: the network accepted the {form}").format(form=_(form)) if form else
                           _("Save sends the {first} and, on WRONG_SIZE, once the {second}.").format(
                               first=_(codec.SAVE_FORMS[codec.SAVE_LENGTHS[0]]), second=_(codec.SAVE_FORMS[codec.SAVE_LENGTHS[1]])))


SAVE_FORM_WORDS = (N_("4-byte form (parameter table)"), N_("1-byte form (document example)"))  # codec.SAVE_FORMS


def specifier_note(p, lang=None) -> str:
    """What the parameter is beside its specifier: its length and unit, and that its password goes to 0xFF first.
    The password itself is a key, not data: it is never shown (it is in the register map for the adapter only)."""
    unit = "" if p.enum is not None else f", {p.unit}" if p.unit else ""
    n = length_of(p)
    return (lang or i18n.get("en")).ngettext("{n} byte{unit}, password-protected", "{n} bytes{unit}, password-protected",
                                             n).format(n=n, unit=unit)


async def save_parameters(view: DeviceView) -> None:
    ok, form = await view.act("save parameters")
    if ok:
        _ = view.lang.gettext
        ui.notify(_("parameters saved: the network accepted the {form}").format(form=_(form)), type="positive")


def _show(entry: ui.number, value) -> None:
    """Put the device's ``value`` in the field as the device has it: 321, not the 321.0 a field shows after
    it held a fraction (the number element keeps the form of what it held before)."""
    text = str(int(value)) if float(value).is_integer() else str(value)
    if entry.value == value and entry.props.get(entry.VALUE_PROP) == text:
        return
    entry.value = None  # the element takes the integer form from an empty field
    entry.value = value


def service_entry(param, raw: int | None, lang=None) -> ui.number:
    """The entry of one service parameter, starting at the actuators' value when it is known: a fraction where
    the parameter takes whole numbers, a finer step than its unit (0.1 mm) or a value out of its range is
    marked on the field with what is allowed (never rounded, never clamped)."""
    low, high = param.limits()
    value = None if raw is None else param.decode(raw)
    entry = range_number("", low, high, unit=param.unit, integer=param.scale == 1, value=value, lang=lang).classes("w-full")
    whole = entry.validation  # range_number's check: whole numbers and the range

    def check(v) -> str | None:
        if v is None:
            return None
        error = whole(v) if callable(whole) else None
        if error:
            return error
        steps = float(v) / param.scale
        if param.scale != 1 and abs(steps - round(steps)) > 1e-6:
            return (lang or i18n.get("en")).gettext("steps of {step} {unit} only, {rule}").format(
                step=f"{param.scale:g}", unit=param.unit, rule=entry.rule).replace("  ", " ")
        return None

    entry.validation = check
    return entry


async def _write_service(name: str, param, entry, lang=None) -> None:
    value = await checked_value(entry, name, f"write {param.name}", parameter=param.name)
    if value is None:
        return
    reason = refusal(param, value)  # beyond the range: the document's own refusals (params.refusal)
    _ = (lang or i18n.get("en")).gettext
    if reason:
        entry.error = said(reason, lang)  # the audit row below stays as written: English
        await refuse(name, f"write {param.name}", reason, parameter=param.name, new=value)
        return
    await write_from_page(name, param, value, success=_("{name} = {value} written and read back from every actuator"),
                          title=_("Set {name} to {value}?"), field=entry, lang=lang,
                          ok=_("Change bit rate") if param.address == BITRATE_SPECIFIER else _("Write"))


__all__ = ["ServiceCard", "save_parameters", "service_entry"]
