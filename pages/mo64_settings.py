"""The MO 64 page's settings card: each setting of the parameter model (devices/mo64/params.py) with its value,
an entry in its range or of its named choices and Write."""

from __future__ import annotations

import html
from collections.abc import Callable

from nicegui import ui

from app import i18n
from app.i18n import N_
from app.message import Message, message_of, said
from app.project import allowed
from app.state import LiveValue
from devices.mo64 import adapter as facts
from devices.mo64 import codec
from devices.commands import WRITE_PARAMETER
from devices.mo64.params import PARAMS, Mo64Param
from devices.params import Accepted
from devices.mo64.policy import EEPROM_RISK, setting_name
from pages.cards import DeviceCard
from pages.device_page import DeviceView
from pages.widgets import columns, entry_age, quality_note, range_number, ValueLine
from pages.command_client import checked_value, refuse

EEPROM_WARNING = EEPROM_RISK  # the declared risk of every setting write (devices/mo64/policy.py)
TIME_KEYS = ("t_open", "t_prewarn_open", "t_prewarn_close")
INT_KEYS = ("maintenance_interval", "vehicle_counter")
PIECE_KEYS = ("multi_relays", "config_flags")  # settings of several named pieces: a table and one entry, and raw
PIECES = tuple(p for p in PARAMS if p.writable and p.setting_key in PIECE_KEYS)
PIECE_COLUMNS = [{"name": k, "label": label, "field": k, "align": "left"} for k, label in
                 (("name", N_("Setting")), ("value", N_("Value")), ("allowed", N_("Allowed")))]
SETTING_POINTS = {"t_open": N_("Open time"), "t_prewarn_open": N_("Pre-warning before opening"),
                  "t_prewarn_close": N_("Pre-warning before closing"), "change_monitoring": N_("Change monitoring"),
                  "status_mask": N_("Status mask"), "multi_relays": N_("Multi-relay modes"),
                  "config_flags": N_("Configuration flags"), "maintenance_interval": N_("Maintenance interval"),
                  "vehicle_counter": N_("Vehicle counter")}
SETTINGS_INPUTS = (*SETTING_POINTS.values(), facts.P_EEPROM, "Change monitoring", facts.P_MONITORING)


def value_line(classes: str = "") -> ValueLine:
    """A value with its age next to it (shown while the value is stale or offline), in one element."""
    return ValueLine(classes)


def show_line(line: ValueLine, text: str, value: LiveValue | None, lang=None) -> bool:
    """Show a value with its quality (greyed, with its age, while stale or offline); True when it is shown stale or offline (with an age)."""
    quality = "unknown" if value is None else value.quality
    line.show(text, quality, quality_note(quality, entry_age(value), lang) if quality in ("stale", "offline") else "")
    return quality in ("stale", "offline")



def piece_value(p: Mo64Param, raw: int, lang) -> str:
    """A relay mode or a configuration flag as the table shows it: a relay mode's name as the device vocabulary words it
    (``multi1``'s ``fault``: ``Störung (1)``), a flag's value as the document names it (``Stopp und öffnen (0)``)."""
    if p.names is not None and p.enum is None and (name := p.names.get(value := int(p.decode(raw)))):
        return f"{lang.value_word(p.name, name)} ({value})"
    return lang.numbers_in(p.display(raw))


class SettingsCard(DeviceCard):
    """Settings (chapter 5.2.4-5.2.8) by the parameter model (devices/mo64/params.py): each named setting with its
    value, an entry in its range or of its named choices and Write (the declared "write parameter": a flag that
    switches a safety function off asks a question naming it); the whole relay modes and configuration words raw;
    change monitoring."""

    view: DeviceView

    def __init__(self, view: DeviceView):
        super().__init__(view)
        self.values: dict[str, ValueLine] = {}
        self.pieces: ui.table | None = None

    def build(self) -> None:
        lang = self.view.lang
        _ = lang.gettext
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-4"):
                ui.label(_("Settings (chapter 5.2.4-5.2.8)")).classes("text-subtitle1")
                self.writes = ui.label().classes("text-body2").props("data-testid=eeprom-writes")
            ui.label(_(EEPROM_WARNING) + " " + _("Busy means the motor runs: try again when it stands. A setting is read "
                                                 "from the barrier, the one value changed, written whole and read back.")).classes("text-caption text-warning")
            with ui.row().classes("items-center gap-2"):
                ui.label(_("Change monitoring (TCP: changes are sent by the barrier, polling slows down):")).classes("text-body2")
                self.guard.add(ui.button(_("On"), on_click=lambda: self.monitoring(True)).props("outline dense data-testid=monitoring-on"),
                               ui.button(_("Off"), on_click=lambda: self.monitoring(False)).props("outline dense data-testid=monitoring-off"))
                self.mon = ui.label().classes("text-body2").props("data-testid=monitoring")
            with ui.grid(columns=3).classes("w-full gap-x-4 items-center") \
                    .style("grid-template-columns: minmax(120px, 220px) minmax(0, 1fr) 300px; row-gap: 28px"):  # room for each entry's range
                for param in PARAMS:
                    if param.writable and param.setting_key not in PIECE_KEYS and param.setting_key != "change_monitoring":
                        self._param_row(param)
                for key in PIECE_KEYS:
                    self._raw_row(key, codec.SETTINGS[key])
            ui.label(_("Relay modes and configuration flags by name (chapter 5.1.24, 5.1.25)")).classes("text-subtitle2")
            self.pieces = ui.table(columns=columns(PIECE_COLUMNS, lang), rows=[], row_key="key").classes("w-full text-caption") \
                .props("dense flat wrap-cells data-testid=setting-pieces")
            self.pieces.add_slot("body-cell-name", '<q-td :props="props" :title="props.row.description" '
                                                   'style="cursor: help">{{ props.value }}</q-td>')
            with ui.row().classes("items-center gap-2"):
                self.piece = ui.select({p.key: p.name for p in PIECES}, label=_("setting"), with_input=True,
                                       on_change=lambda e: self._chosen(e.value)).classes("w-96") \
                    .props("dense outlined data-testid=piece-param")
                self.piece_value = ui.input(_("value or choice")).classes("w-64") \
                    .props("dense outlined data-testid=piece-value")
                self.guard.add(ui.button(_("Write"), on_click=self.write_piece).props("outline dense data-testid=piece-write"))

    def _chosen(self, key: str | None) -> None:
        param = PARAMS.by_key.get(key or "")
        self.piece_value.props(f'hint="{html.escape(said(allowed(param), self.view.lang))}"' if param is not None else 'hint=""')

    async def write_piece(self) -> None:
        param = PARAMS.by_key.get(self.piece.value or "")
        if param is None:
            self.piece.error = self.view.lang.gettext("choose a setting first")
            return
        self.piece.error = None
        await self.write_param(param, self.piece_value)

    def _param_row(self, param: Mo64Param) -> None:
        lang = self.view.lang
        _ = lang.gettext
        notes = [n for n in (_("assumed selector") if param.selector_assumed else "",
                             _("assumed bit position") if param.assumed and not param.selector_assumed else "") if n]
        assumption = " " + _("Assumption: {text}").format(text=said(param.assumed, lang)) if param.assumed else ""
        ui.label(_(param.name) + (f" ({', '.join(notes)})" if notes else "")).classes("text-body2") \
            .props(f'title="{html.escape(said(param.description, lang) + assumption)}"')
        self.values[param.key] = value_line("mono text-body2")
        with ui.row().classes("items-center gap-1 no-wrap"):
            low, high = param.limits()
            if param.scale != 1:
                field = range_number(_("seconds"), low, high, unit=param.unit, step=param.scale, lang=lang).classes("w-40")
            elif param.fields:
                field = ui.input(_("number (0x.. allowed)"), validation=lambda text, p=param: _number_problem(p, text, lang)) \
                    .classes("w-48").props("dense outlined")
            else:
                field = _whole_number(_("value"), int(low), int(high), lang).classes("w-48")
            field.props(f"data-testid=entry-{param.space}")
            self.guard.add(ui.button(_("Write"), on_click=lambda p=param, f=field: self.write_param(p, f))
                           .props(f"outline dense data-testid=write-{param.space}"))

    def _raw_row(self, key: str, setting: codec.Setting) -> None:
        _ = self.view.lang.gettext
        ui.label(_(setting.name)).classes("text-body2")
        self.values[key] = value_line("mono text-body2")
        with ui.row().classes("items-center gap-1 no-wrap"):
            field = ui.input(_("raw (as shown, e.g. 1,0,0,0,0,0)"),
                             validation=lambda text, k=key: _raw_problem(k, text)).classes("w-48") \
                .props(f"dense outlined data-testid=entry-{key}")
            self.guard.add(ui.button(_("Write"), on_click=lambda k=key, f=field: self.write(k, f))
                           .props(f"outline dense data-testid=write-{key}"))

    async def write_param(self, param: Mo64Param, field) -> None:
        """One named setting through the declared write: the gate asks what the model names (a safety flag by its
        name, an assumed selector) and the page's session counts the EEPROM write."""
        accepted = await _param_value(self.view.name, param, field)
        if accepted is None:
            return
        _ = self.view.lang.gettext
        shown = accepted.text
        await self.view.act(WRITE_PARAMETER, {"param": param.key, "value": accepted},
                            success=_("{name} = {value} written and read back").format(name=param.name, value=shown),
                            title=_("Write {name} = {value}?").format(name=param.name, value=shown), ok=_("Write anyway"),
                            parameter=param.name, new=shown)

    async def write(self, key: str, field) -> None:
        setting = codec.SETTINGS[key]
        value = await _entry_value(self.view.name, key, field)
        if value is None:
            return
        # the declared "set ..." asks the EEPROM wear and names every safety flag this value switches off
        await self.view.act(setting_name(key), codec.setting_to_fields(key, value),
                            success=self.view.lang.gettext("{name} written and read back").format(name=setting.name))

    async def monitoring(self, on: bool) -> None:
        _ = self.view.lang.gettext
        await self.view.act("change monitoring", {"on": int(on)},
                            success=_("change monitoring on") if on else _("change monitoring off"))

    def refresh(self) -> None:
        view = self.view
        if self.unchanged(view.inputs(SETTINGS_INPUTS), lambda: view.qualities(SETTING_POINTS.values())):
            return
        aging = False
        state = view.state
        for key, line in self.values.items():
            param = PARAMS.by_key.get(key)
            if param is None:
                aging = show_line(line, view.text(SETTING_POINTS[key]), view.live(SETTING_POINTS[key]), view.lang) or aging
                continue
            raw = state.raw(param)
            point = SETTING_POINTS.get(param.setting_key)
            aging = show_line(line, "-" if raw is None else param.display(raw),
                               view.live(point) if point else None, view.lang) or aging
        self.aging = aging
        _ = view.lang.gettext
        rows = [{"key": p.key, "name": p.name + (" " + _("(assumed bit position)") if p.assumed else ""),
                 "value": "-" if (raw := state.raw(p)) is None else piece_value(p, raw, view.lang), "allowed": said(allowed(p), view.lang),
                 "description": said(p.description, view.lang)} for p in PIECES]
        if self.pieces is not None and rows != self.pieces.rows:
            self.pieces.rows = rows
            self.pieces.update()
        writes = view.fact(facts.P_EEPROM)
        mine, total = (0, 0) if writes is None else (writes.of(view.session), writes.total)
        self.writes.set_text(_("EEPROM writes this session: {mine} (all sessions: {total})").format(mine=mine, total=total))
        self.mon.set_text(f"{view.text('Change monitoring')}; {view.text(facts.P_MONITORING)}")


def _whole_number(label: str, low: int, high: int, lang=None) -> ui.number:
    """A whole-number entry whose range reads as whole numbers (not 2.14748e+09)."""
    _ = (lang or i18n.get("en")).gettext
    rule = _("allowed {low} .. {high}").format(low=f"{low:,}".replace(",", "\u2009"), high=f"{high:,}".replace(",", "\u2009"))

    def check(v) -> str | None:
        if v is None:
            return None
        if float(v) != int(float(v)):
            return _("whole numbers only, {rule}").format(rule=rule)
        if not low <= float(v) <= high:
            return _("out of range: {rule}").format(rule=rule)
        return None

    field = ui.number(label, step=1, format="%d", validation=check)
    field.props(f'hint="{rule}" dense outlined')
    field.rule = rule  # type: ignore[attr-defined]
    return field


def _number_problem(param: Mo64Param, text: str | None, lang=None) -> str | None:
    if not (text or "").strip():
        return None
    try:
        param.validate(text.strip())
    except ValueError as exc:
        return said(exc, lang)
    return None


async def _param_value(device: str, param: Mo64Param, field) -> Accepted | None:
    """What the model accepts of a named setting's entry (checked once, carried to the gate), or None: the entry
    keeps what was typed, marked with the reason, and the refusal is audited; nothing is sent."""
    action = f"write {param.name}"
    if isinstance(field, ui.number):
        value = await checked_value(field, device, action, parameter=param.name)
        if value is None:
            return None
        try:
            return param.accept(value if param.scale != 1 else int(value))
        except ValueError as exc:
            field.error = said(exc, i18n.client_language())
            await refuse(device, action, f"{value:g}: {exc}", parameter=param.name, new=value)
            return None
    text = (field.value or "").strip()
    accepted, problem = None, None
    if text:
        try:
            accepted = param.accept(text)
        except ValueError as exc:
            problem = message_of(exc)
    if await _text_refused(device, action, param.name, field, lambda _text: problem):
        return None
    return accepted


def _limits(key: str) -> tuple[int, int]:
    """The raw range a setting accepts: its document limits, else its wire type's (codec.SETTINGS)."""
    setting = codec.SETTINGS[key]
    return setting.limits if setting.limits is not None else setting.vtype.limits


def _raw_problem(key: str, text: str | None) -> str | None:
    """Why a raw entry cannot be written (the codec's own check), or None."""
    if not (text or "").strip():
        return None
    try:
        codec.encode_setting(key, _parse(key, text))
    except (ValueError, codec.CodecError) as exc:
        return str(exc) or "not a number"
    return None


async def _entry_value(device: str, key: str, field):
    """The raw value of a setting's entry, or None: the entry keeps what was typed, marked with the reason, and
    the refusal is audited; nothing is sent."""
    setting = codec.SETTINGS[key]
    if key in TIME_KEYS or key in INT_KEYS:
        value = await checked_value(field, device, f"set {setting.name}", parameter=setting.name)
        if value is None:
            return None
        return round(float(value) / codec.TIME_STEP_S) if key in TIME_KEYS else int(value)
    if await _text_refused(device, f"set {setting.name}", setting.name, field, lambda text: _raw_problem(key, text)):
        return None
    return _parse(key, field.value)


async def _text_refused(device: str, action: str, name: str, field, problem_of: Callable[[str], str | None]) -> bool:
    """Whether the text entry of setting ``name`` is refused: empty, or ``problem_of(text)`` names a problem. A
    refused entry keeps what was typed, marked with the reason, and the refusal is audited as ``action``."""
    text = field.value
    problem = "enter a value first" if not (text or "").strip() else problem_of(text)
    if problem:
        lang = i18n.client_language()  # the audit row below stays as written: English
        field.error = said(problem, lang) if isinstance(problem, Message) else lang.gettext(problem)
        await refuse(device, action, f"{text!r}: {problem}", parameter=name, new=text or "")
        return True
    field.error = None
    return False


def _parse(key: str, text: str | None):
    """A raw entry: a number (0x.. allowed) or a comma-separated list for relay modes and configuration flags."""
    text = (text or "").strip()
    if key in ("multi_relays", "config_flags"):
        numbers = [int(x.strip(), 0) for x in text.split(",") if x.strip()]
        if key == "config_flags":
            return dict(zip(("konfig0", "konfig1", "konfig2", "konfig3"), numbers))
        return numbers
    return int(text, 0) if text else 0
