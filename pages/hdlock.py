"""HD-Lock page: status lamps, live chart, parameters, system commands, register tables.

Reads only the live store (the registers and the facts :mod:`devices.hdlock.adapter` publishes: the
address or device ID, the status frame, the FWU status, the locks found on the line) and invokes the
declared commands (devices/hdlock/policy.py) through the worker's gate. Each card is a small class with
``build()`` (in the page's layout) and ``refresh()`` (on every change the store pushes)."""

from __future__ import annotations

import time

from nicegui import ui

from app import i18n
from app import runtime as rt
from app.i18n import N_
from app.message import said
from app.state import LiveValue
from devices.hdlock import codec
from devices.hdlock.adapter import (
    HISTORY_CAN,
    HISTORY_MODBUS,
    P_ADDRESS,
    P_DEVICE_ID,
    P_LINE_LOCKS,
)
from devices.hdlock.params import HOLDING, INPUT, LOCK_STATUS_BITS, PARAMS
from devices.hdlock.policy import unsaved_changes
from devices.params import Param
from pages.hdlock_can import CanStatusCard, can_commands_card
from pages.cards import DeviceCard, point_values, titled_card
from pages.device_page import DeviceView, StatusRow, device_page
from pages.frame import fmt_age, status_text
from pages.simcontrols import sim_card
from pages.widgets import entry_age, Lamp, RegisterTable, ValueLine
from pages.command_client import checked_value, confirm, WriteGuard
from pages.charts import HistoryChart
from pages.widgets import mark_quality, quality_note, range_number, RangeNumber
from pages.command_client import cancelled, enable_unless, refuse, run_command, write_from_page

DEVICE_TYPE = "hdlock"

# the LockRequestSource shown is holding 4, the one the lock uses (section 6.5.1)
ENUM_VALUES = ("DoorState", "StateMachineState", "MotorState", "MotorState (IR53)", "MotorResult", "LockRequestSource (HR4)")
LAMP_KIND = {"ProximityOverrange": "warn", "ForceActive": "warn"}
CHART_AXES = {"MotorCurrent": "y2"}  # increments on the left axis, mA on the right
# Both axes start at 0 so the lines meet the same baseline: a current of 0 mA is at the bottom, not level with
# half the bolt's travel; a motor current is never negative, and at rest (0 mA) the axis still spans whole mA.
CHART_Y = {"rangemode": "tozero"}
CHART_Y2 = {"rangemode": "nonnegative", "tickformat": "d", "autorangeoptions": {"include": [0, 10]}}
# the legend under the time axis, the mode bar (shown on hover, top right) in a row of its own above the plot
LEGEND_BELOW = {"orientation": "h", "x": 0, "xanchor": "left", "y": 0, "yanchor": "bottom", "yref": "container"}
LEGEND_MARGIN_B = 80  # the time axis with its date line, then one or two rows of legend
MODE_BAR_MARGIN_T = 30
CHART_WINDOWS = (30, 300)  # the bolt moves in about half a second: 30 s by default, 5 min on demand
# cards beside each other as the width allows, each as tall as its row (no blank area under a short one)
CARD_GRID = "display: grid; grid-template-columns: repeat(auto-fit, minmax(420px, 1fr)); gap: 16px; width: 100%"
# the Parameters card's grid: register, name, current value, new value, Write
PARAM_COLUMNS = "auto minmax(8rem, max-content) minmax(7rem, max-content) auto auto"
NAME_WRAP = "overflow-wrap: anywhere; min-width: 0"  # "SettingsProximityThresholdUnlock" wraps in its column
LOCK_STATUS_ADDRESS = PARAMS.by_name["LockStatus"].address  # holding 1000, one word
HEALTH_INPUTS = ("SerialNumber", "FirmwareVersion", P_ADDRESS, P_DEVICE_ID)
LAMP_INPUTS = ("LockStatus", *ENUM_VALUES)
# simulation actions shown elsewhere: the service swap on the replacement page, refused writes in tests
SIM_ELSEWHERE = ("swap for a new device", "refuse writes")


class HdLockView(DeviceView):
    """What every card of one page shares: the lock's live record, its bus and the write guard."""

    def __init__(self, name: str):
        super().__init__(name)
        self.is_can = self.runtime.plant.buses[self.state.bus].type == "can"  # the plant file says how the lock is reached
        self.guard = WriteGuard(self.state, lang=self.lang)  # every write and command button, disabled with the reason while silent


def content(name: str) -> None:
    view = HdLockView(name)
    _ = view.lang.gettext
    with device_page(view, _("HD-Lock {name}").format(name=name)):
        view.add(HealthCard(view))
        view.add(LampsCard(view))
        with ui.card().classes("w-full gap-1"):
            ui.label(_("Bolt, motor current and proximity")).classes("text-subtitle1")
            chart = HistoryChart(view.state, list(HISTORY_CAN if view.is_can else HISTORY_MODBUS),
                                 window_s=CHART_WINDOWS[0], axes=CHART_AXES, windows=CHART_WINDOWS, lang=view.lang)
            chart.figure["layout"]["yaxis"].update(CHART_Y)
            chart.figure["layout"]["yaxis2"].update(CHART_Y2)
            chart.figure["layout"]["legend"] = LEGEND_BELOW  # above the plot plotly's mode bar covered it (768 px)
            chart.figure["layout"]["margin"].update(t=MODE_BAR_MARGIN_T, b=LEGEND_MARGIN_B)
            chart.plot.update()
        with ui.element("div").style(CARD_GRID).props("data-testid=hdlock-cards"):
            sim_card(name, skip=SIM_ELSEWHERE)
            if view.is_can:
                view.add(CanStatusCard(view))
                can_commands_card(name, view.state, view.guard, view.lang)
            else:
                view.add(SetAddressCard(view))
                view.add(BroadcastAddressCard(view))
        view.add(ParameterCard(view))  # the writable parameters
        with ui.card().classes("w-full"):
            with ui.tabs() as tabs:
                t_in = ui.tab(_("Input registers"))
                t_hold = ui.tab(_("Holding registers"))
            with ui.tab_panels(tabs, value=t_in).classes("w-full"):
                with ui.tab_panel(t_in):
                    RegisterTable(view.state, PARAMS.space(INPUT), lang=view.lang)  # follows the store itself: values, ages, greyed rows
                with ui.tab_panel(t_hold):
                    RegisterTable(view.state, PARAMS.space(HOLDING), lang=view.lang)


def modbus_counters(c, lang=None) -> str:
    """The Modbus line's counters of this lock: CRC errors and exception answers are Modbus RTU's own."""
    return (lang or i18n.get("en")).gettext("requests {requests} · timeouts {timeouts} · CRC {crc} · exceptions {exceptions} · "
                                            "write errors {write_errors}").format(
        requests=c.requests, timeouts=c.timeouts, crc=c.crc_errors, exceptions=c.exceptions, write_errors=c.write_errors)


def can_counters(c, lang=None) -> str:
    """The CAN counters of this lock: its requests (0x700-0x705) and their timeouts, the frames heard from it
    (status frames and register answers), frames that did not decode, and writes not confirmed. CAN has no
    CRC errors or exception answers to count here (the controller drops bad frames)."""
    return (lang or i18n.get("en")).gettext("requests {requests} · frames heard {responses} · timeouts {timeouts} · "
                                            "malformed {malformed} · write errors {write_errors}").format(
        requests=c.requests, responses=c.responses, timeouts=c.timeouts, malformed=c.malformed, write_errors=c.write_errors)


class HealthCard(DeviceCard):
    """Address or device ID, serial, firmware, status, last seen, the line's counters and the last error."""

    view: HdLockView

    def build(self) -> None:
        lang = self.view.lang
        counters = can_counters if self.view.is_can else modbus_counters
        self.status = StatusRow(self.view.state, lambda c: counters(c, lang), lang)
        with ui.card().classes("w-full"):
            with self.status.build():
                self.ident = ui.label().classes("text-body2")
                self.seen = ui.label().classes("text-body2")
            self.error = ui.label().classes("text-negative text-body2")

    def refresh(self) -> None:
        view, state = self.view, self.view.state
        if self.unchanged((state.status, state.last_error, view.inputs(HEALTH_INPUTS)),
                          lambda: status_text(state.status, state.age, view.lang) + fmt_age(state.age, view.lang)):
            return  # status, error, address and identity as drawn: the ages move on the once-a-second round
        _ = view.lang.gettext
        self.status.refresh()
        serial, fw = state.value("SerialNumber"), state.value("FirmwareVersion")
        if view.is_can:
            device_id = state.live(P_DEVICE_ID)
            where = _("CAN device ID {id}").format(id=device_id.shown if device_id is not None else None)
        else:
            where = _("Modbus address {address}").format(address=view.fact(P_ADDRESS))
        self.ident.set_text(_("{where} · serial {serial} · firmware V{firmware}").format(
            where=where, serial=serial if serial is not None else "-", firmware=fw if fw is not None else "-"))
        self.seen.set_text(_("last seen {age}").format(age=fmt_age(state.age, view.lang)))
        self.error.set_text(said(state.last_error, view.lang) if state.status != "online" else "")


class LampsCard(DeviceCard):
    """LockStatus (holding 1000) as lamps, and the enumerated values with their quality."""

    def build(self) -> None:
        _ = self.view.lang.gettext
        with ui.card().classes("w-full"):
            with ui.row().classes("items-baseline gap-2"):
                ui.label(_("LockStatus (holding 1000)")).classes("text-subtitle1")
                self.note = ui.label().classes("q-age").props("data-testid=lockstatus-quality")
            with ui.row().classes("gap-5"):
                self.lamps = {f.name: Lamp(f.name, LAMP_KIND.get(f.name, "ok"), said(f.description, self.view.lang), light=True)
                              for f in LOCK_STATUS_BITS}
            with ui.row().classes("gap-8 q-mt-sm"):
                self.labels, self.notes = {}, {}
                for key in ENUM_VALUES:
                    with ui.column().classes("gap-0"):
                        ui.label(key).classes("text-caption text-grey-8")
                        self.labels[key] = ui.label("-").classes("text-body1 text-weight-medium")
                        self.labels[key].props(f'data-value="{key}"')
                        self.notes[key] = ui.label().classes("q-age q-ml-none")

    def refresh(self) -> None:
        state = self.view.state
        if self.unchanged(self.view.inputs(LAMP_INPUTS), lambda: self.view.qualities(LAMP_INPUTS)):
            return  # the same words, nothing shown stale: no record built, no element touched
        status = state.live("LockStatus")
        aging = status is not None and status.quality in ("stale", "offline")
        for field_name, lamp in self.lamps.items():
            lamp.show(status, None if status is None else status.fields[field_name])
        lang = self.view.lang
        self.note.set_text(_note(status, lang))
        for key, label in self.labels.items():
            entry = state.live(key)
            context = key.split(" ")[0]  # the enumeration's register: DoorState, StateMachineState ...
            name = entry.enum if entry else None
            # the states the catalog words (DoorState, StateMachineState); the others as the register map names them
            known = bool(name) and (lang.has(name, context) or lang.has(name))
            label.set_text((lang.phrase(name, context) if known else name
                            or lang.gettext("undefined ({value})").format(value=entry.value)) if entry else "-")
            mark_quality(label, entry.quality if entry else "unknown")
            self.notes[key].set_text(_note(entry, lang))
            aging = aging or (entry is not None and entry.quality in ("stale", "offline"))
        self.aging = aging


def _note(value: LiveValue | None, lang=None) -> str:
    """``stale 4 s`` / ``offline, last 1 min`` under a value that is not good."""
    if value is None or value.quality not in ("stale", "offline"):
        return ""
    return quality_note(value.quality, entry_age(value), lang)


class ParameterCard(DeviceCard):
    """Editable RW holding registers with validation, unsaved marks, Save/Restore-Settings."""

    def __init__(self, view: HdLockView):
        super().__init__(view)
        self.rows: dict[str, tuple] = {}
        self.params: list[Param] = []  # the rows' parameters, in order
        self.entries: dict[str, ui.element] = {}
        self.shown: dict[str, object] = {}  # the device value each field was last given
        self.badges: dict[str, ui.badge] = {}  # parameter key -> its "unsaved" badge, built when first shown

    def build(self) -> None:
        name, state, guard = self.view.name, self.view.state, self.view.guard
        _ = self.view.lang.gettext
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center w-full"):
                ui.label(_("Parameters (RW holding registers)")).classes("text-subtitle1")
                self.unsaved_label = ui.badge("", color="orange")
                ui.space()
                self.save = ui.button("Save-Settings", icon="save", on_click=lambda: _save(name, state)) \
                    .props("data-testid=save-settings")
                restore = ui.button("Restore-Settings", icon="restore", on_click=lambda: _restore(name)).props(
                    "outline data-testid=restore-settings")
                guard.add(self.save, restore)
            ui.label(
                _("Writes are volatile until Save-Settings; Restore-Settings reloads the saved values and discards unsaved changes.")
            ).classes("text-caption text-grey-8")
            # register, name, current, entry, button: each column as wide as its content needs, the name and
            # current columns never narrower than their minimum (a long name wraps inside its column instead of
            # running into the value), and the table left-aligned (no gap between Current and New value)
            with ui.grid(columns=PARAM_COLUMNS).classes("w-full items-center gap-x-4 gap-y-1") \
                    .style("justify-content: start").props("data-testid=param-grid"):
                for h in (N_("Register"), N_("Name"), N_("Current"), N_("New value"), ""):
                    ui.label(_(h) if h else "").classes("text-caption text-grey-8")
                for p in (p for p in PARAMS.space(HOLDING) if p.writable):
                    self._row(p)

    def _row(self, p: Param) -> None:
        name = self.view.name
        _ = self.view.lang.gettext
        ui.label(str(p.address)).classes("mono")
        key = param_key(p)
        with ui.row().classes("items-center gap-1").style("min-width: 0") as mark:
            label = p.label or p.name
            ui.label(label).style(NAME_WRAP).props(f'data-param-name="{key}"') \
                .tooltip(f"{label}: {said(p.description, self.view.lang)}" if p.description else label)
            if not p.setting:  # the lock measures it (Param.setting): written only to reset it, never from a set
                ui.badge(_("measured"), color="grey-6").props(f'data-measured="{key}" outline').tooltip(
                    _("Measured by the lock, not a setting: write it only to reset it. Restore, batch apply and the "
                      "replacement assistant never copy it, and it is no drift."))
            # its "unsaved" badge is built when the parameter is first written (most never are)
        current = ValueLine("mono")  # the value, greyed with its age while stale or offline: one element
        if p.enum is not None:
            entry = ui.select({k: f"{self.view.lang.value_word(p.name, v)} ({k})" for k, v in p.enum.items()}, value=None) \
                .props("dense outlined options-dense").classes("w-64")
        else:
            low, high = p.limits()
            entry = range_number("", low, high, unit=p.unit, integer=p.scale == 1, lang=self.view.lang).classes("w-48")
        entry.props(f'data-param="{key}"')
        entry.on("keydown.enter", lambda p=p, entry=entry: _write(name, p, entry))  # Enter writes, as the button does
        button = ui.button(_("Write"), on_click=lambda p=p, entry=entry: _write(name, p, entry)).props(f'dense data-write="{key}"')
        self.view.guard.add(button)
        self.rows[p.key] = (p, current, mark)
        self.params.append(p)
        self.entries[p.key] = entry

    def follow_entry(self, key: str, p: Param, raw: int | None) -> None:
        """A field shows the device's value until the engineer types; after a write, the value read back."""
        if raw is None:
            return
        value = p.decode(raw)
        entry = self.entries[key]
        if (entry.value is None and key not in self.shown) or entry.value in (self.shown.get(key), value):  # untouched
            if entry.value != value:
                entry.value = value
            self.shown[key] = value

    def show_unsaved(self, key: str, row: ui.row, unsaved: bool) -> None:
        """Show or hide the "unsaved" badge at the end of a parameter's name ``row``, built when first shown."""
        badge = self.badges.get(key)
        if badge is None:
            if not unsaved:
                return
            with row:
                badge = self.badges[key] = ui.badge(self.view.lang.gettext("unsaved"), color="orange")
        badge.set_visibility(unsaved)

    def refresh(self) -> None:
        state, now = self.view.state, time.time()
        if self.unchanged((self.view.words(self.params), frozenset(state.unsaved)),
                          lambda: tuple(state.param_quality(p, now) for p in self.params)):
            return  # the same words and unsaved marks, nothing shown stale
        aging = False
        for key, (p, current, mark) in self.rows.items():
            raw = state.raw(p)
            self.follow_entry(key, p, raw)
            read = state.read_time(p)
            quality = state.param_quality(p, now)  # aged by its own read period (settings: every 10 s)
            aging = aging or quality in ("stale", "offline")
            # greyed with the age of its value while stale or offline
            lang = self.view.lang
            current.show("-" if raw is None else lang.numbers_in(p.display(raw)), quality,
                         quality_note(quality, None if read is None else now - read, lang) if quality in ("stale", "offline") else "")
            self.show_unsaved(key, mark, key in state.unsaved)
        self.aging = aging
        count = len(state.unsaved)
        self.unsaved_label.set_text(self.view.lang.ngettext("{n} unsaved change", "{n} unsaved changes", count).format(n=count))
        self.unsaved_label.set_visibility(count > 0)
        if self.save.props.get("color") != ("orange" if count else "primary"):
            self.save.props(f"color={'orange' if count else 'primary'}")


def param_key(p: Param) -> str:
    """A parameter's own key on the page (``data-param``, ``data-write``): its label where it has one, as the
    register map keys it, since two registers share a name (LockRequestSource, holding 4 and 1002)."""
    return p.label or p.name


async def _write(name: str, param: Param, entry) -> None:
    await write_from_page(name, param, entry.value,
                          success=i18n.client_language().gettext("{name} = {value} written and read back (not yet saved)"),
                          field=entry)


async def _save(name: str, state) -> None:
    """Save-Settings writes the lock's flash (section 4.1): ask first, naming what becomes permanent."""
    changes = unsaved_changes(state)
    lang = i18n.client_language()
    _ = lang.gettext
    with ui.dialog() as dialog, ui.card().classes("max-w-lg").props("data-testid=save-dialog"):
        ui.label(_("Save-Settings: write the settings to the lock's flash?")).classes("text-h6")
        if changes:
            ui.label(lang.ngettext("{n} unsaved change becomes permanent (kept after a reset):",
                                   "{n} unsaved changes become permanent (kept after a reset):", len(changes)).format(
                n=len(changes))).classes("text-body1")
            with ui.column().classes("gap-0 q-pl-md").props("data-testid=save-changes"):
                for line in changes:
                    ui.label(line).classes("text-body2 mono")
        else:
            ui.label(_("No unsaved changes are known here: the lock's current settings are written to its flash again.")).classes(
                "text-body1")
        ui.label(_("Each save is counted in SavedSettings (input 101).")).classes("text-caption text-grey-8")
        with ui.row().classes("justify-end w-full"):
            ui.button(_("Cancel"), on_click=lambda: dialog.submit(False)).props("flat")
            ui.button(_("Save to flash"), icon="save", on_click=lambda: dialog.submit(True)).props("data-testid=save-confirm")
    confirmed = await dialog
    dialog.delete()
    if not confirmed:
        await cancelled(name, "Save-Settings", parameter="Save-Settings", new="; ".join(changes))
        return
    # the declaration's audit row lists what became permanent, as read when the command runs
    await run_command(name, "Save-Settings", success=_("Settings saved to the lock's flash"))


async def _restore(name: str) -> None:
    # the declared command names its risk (all unsaved changes are lost): run_command asks it
    await run_command(name, "Restore-Settings", success=i18n.client_language().gettext("Saved settings restored"))


def _parse_word(text) -> int | None:
    """A 16-bit mask typed as decimal or 0x hex, else None."""
    try:
        value = int(str(text).strip(), 0)
    except ValueError:
        return None
    return value if 0 <= value <= 0xFFFF else None


def _bit_names(mask: int, lang=None) -> str:
    return ", ".join(f.name for f in LOCK_STATUS_BITS if mask >> f.shift & 1) or (lang or i18n.get("en")).gettext("no bits")


def _condition_text(m: int, e: int, lang=None) -> str:
    _ = (lang or i18n.get("en")).gettext
    return _("checks: {bits}; must be set: {set}").format(bits=_bit_names(m, lang),
                                                          set=_bit_names(e & m, lang) if e & m else _("none"))


MASK_RULE = N_("16-bit number, e.g. 0x010C")


def _mask_inputs(prefix: str, lang=None):
    """P1 and P2 of section 4.3; a wrong entry stays as typed, marked with what is allowed."""
    _ = (lang or i18n.get("en")).gettext

    def check(text) -> str | None:
        return None if _parse_word(text) is not None else _(MASK_RULE)

    p1 = ui.input(_("P1 mask (hex)"), value="0x0000", validation=check).props(
        f"dense outlined data-testid={prefix}-p1").classes("w-44 mono")
    p2 = ui.input(_("P2 expected (hex)"), value="0x0000", validation=check).props(
        f"dense outlined data-testid={prefix}-p2").classes("w-44 mono")
    return p1, p2


async def _checked_masks(name: str, describe: str, p1, p2) -> tuple[int, int] | None:
    """P1 and P2 as numbers, or None with the wrong field marked and the refusal audited (nothing sent)."""
    bad = [(label, field) for label, field in (("P1", p1), ("P2", p2)) if _parse_word(field.value) is None]
    for _, field in bad:
        field.validate()
    if bad:
        await refuse(name, describe, "; ".join(f"{label} {field.value!r}: {MASK_RULE}" for label, field in bad))
        return None
    return _parse_word(p1.value), _parse_word(p2.value)


def _gate_send(view: HdLockView, button: ui.button, address: RangeNumber) -> None:
    """A Send button of an address change: disabled with the reason while the lock does not answer (or the
    session may not write), while no new address is entered, and while the entry is one the field refuses."""
    view.guard.update()
    reason = view.guard.reason
    if not reason and address.value in (None, ""):
        reason = view.lang.gettext("enter the new address first ({rule})").format(rule=address.rule)
    elif not reason:
        refused = address.validation(address.value) if callable(address.validation) else None  # the field's own rule
        if refused:  # (checked without touching the field's message: a refusal set on Send stays shown)
            reason = view.lang.gettext("address {address} is refused: {reason}").format(address=f"{address.value:g}",
                                                                                         reason=refused)
    enable_unless(button, reason)


class _AddressCard(DeviceCard):
    """What the two Set Modbus Address cards share (section 4.3): the new address and the condition masks P1 and
    P2, their Send gated on the lock answering and the new address being valid."""

    new: RangeNumber
    p1: ui.input
    p2: ui.input
    button: ui.button

    def follow_entries(self) -> None:
        """Redraw on every change of the entries; gate Send now."""
        for element in (self.new, self.p1, self.p2):
            element.on_value_change(self.refresh)
        _gate_send(self.view, self.button, self.new)

    def entries_unchanged(self, shown: object) -> bool:
        """:meth:`unchanged` on the entries, the lock's state and ``shown`` (what else the card is drawn from); where
        they changed, Send is gated anew."""
        state = self.view.state
        if self.unchanged((state.status, state.last_error, self.new.value, self.p1.value, self.p2.value, shown),
                          lambda: None):
            return True
        _gate_send(self.view, self.button, self.new)
        return False

    async def entries(self, describe: str) -> tuple[int, int, int] | None:
        """The new address and the masks P1 and P2, or None where an entry is refused (marked on the entry and
        audited as ``describe``)."""
        name = self.view.name
        value = await checked_value(self.new, name, describe, parameter="DeviceAddress")
        masks = await _checked_masks(name, describe, self.p1, self.p2)
        if value is None or masks is None:
            return None
        return int(value), *masks


class SetAddressCard(_AddressCard):
    """Set Modbus Address (command 3) with its two condition masks and a live preview."""

    def build(self) -> None:
        lang = self.view.lang
        _ = lang.gettext
        with titled_card(_("Set Modbus Address (command 3)")):
            ui.label(_("Taken only if (P1 & LockStatus) ^ P2 == 0 (section 4.3).")).classes("text-caption text-grey-8")
            with ui.row().classes("items-center"):
                self.new = range_number(_("New address"), 1, 254, integer=True, lang=lang).classes("w-56")
                self.p1, self.p2 = _mask_inputs("sa", lang)
            self.bits = ui.label().classes("text-caption")
            self.preview = ui.label().classes("text-body2")
            self.button = ui.button(_("Send Set Modbus Address"), icon="pin", on_click=self.send).props("data-testid=sa-send")
        self.follow_entries()

    def refresh(self) -> None:
        if self.entries_unchanged(self.view.inputs(("LockStatus",))):
            return  # the gate of Send and the preview are drawn from these alone
        lang = self.view.lang
        _ = lang.gettext
        m, e = _parse_word(self.p1.value), _parse_word(self.p2.value)
        preview = self.preview
        if m is None or e is None:
            preview.set_text(_("P1 and P2 must be 16-bit numbers, e.g. 0x010C"))
            preview.classes(replace="text-body2 text-negative")
            return
        self.bits.set_text(_condition_text(m, e, lang))
        status = self.view.state.value("LockStatus")
        if status is None:
            preview.set_text(_("LockStatus not read yet"))
            return
        result = codec.set_address_condition(m, e, int(status))
        ok = result == 0
        preview.set_text(
            _("now: {formula} -> ").format(formula=f"(0x{m:04X} & 0x{int(status):04X}) ^ 0x{e:04X} = 0x{result:04X}")
            + (_("condition holds, the lock would take the address") if ok else _("condition fails, the lock would refuse"))
        )
        preview.classes(replace="text-body2 " + ("text-positive" if ok else "text-negative"))

    async def send(self) -> None:
        entries = await self.entries("Set Modbus Address")
        if entries is None:
            return
        target, m, e = entries
        name = self.view.name
        # the declared risk (the lock answers only at the new address) is asked by run_command
        ok, outcome = await run_command(name, "Set Modbus Address", args={"new_address": target, "mask": m, "expected": e},
                                        title=self.view.lang.gettext("Change the Modbus address to {address}?").format(
                                            address=target))
        if ok:
            ui.notify(said(outcome.text, self.view.lang), type="positive" if outcome.taken else "warning", multi_line=True,
                      close_button="OK", timeout=15000)


def _line_locks(name: str, state) -> tuple[dict[int, str], dict[str, int | None], int, int]:
    """Locks known on this lock's line: address -> name, name -> last LockStatus, and how many
    are in the plant file and how many only in scans of the line."""
    runtime = rt.current()
    known: dict[int, str] = {}
    statuses: dict[str, int | None] = {}
    for dev in runtime.plant.devices_on(state.bus):
        if dev.type != DEVICE_TYPE:
            continue
        address = runtime.store.devices[dev.name].live(P_ADDRESS)
        known[dev.options.get("address") if address is None else address.value] = dev.name
        status = runtime.store.devices[dev.name].value("LockStatus")
        statuses[dev.name] = None if status is None else int(status)
    in_plant = len(known)
    found = state.live(P_LINE_LOCKS)
    for entry in found.value if found is not None and found.value else ():
        if entry.address not in known:
            label = f"address {entry.address}" + (f" (serial {entry.serial})" if entry.serial is not None else "")
            known[entry.address] = label
            statuses[label] = None
    return known, statuses, in_plant, len(known) - in_plant


def _line_inputs(view: HdLockView) -> tuple:
    """What :func:`_line_locks` is drawn from, without building it: each lock's address and LockStatus word
    on this line (in the plant file), and the locks a scan found."""
    store, bus = view.store, view.state.bus
    out: list = [view.fact(P_LINE_LOCKS)]
    for dev in view.runtime.plant.devices_on(bus):
        if dev.type == DEVICE_TYPE:
            other = store.devices[dev.name]
            (address,), status = point_values(other, (P_ADDRESS,)), other.registers.get((HOLDING, LOCK_STATUS_ADDRESS))
            out.append((dev.name, None if address is None else address[0], None if status is None else status[0]))
    return tuple(out)


class BroadcastAddressCard(_AddressCard):
    """Set Modbus Address to broadcast address 255 (section 4.3): every lock on the line at once."""

    def build(self) -> None:
        lang = self.view.lang
        _ = lang.gettext
        with titled_card(_("Set Modbus Address on every lock of {bus} (broadcast 255)").format(bus=self.view.state.bus)):
            ui.label(
                _("Every lock on the line gets the command and none answers; each lock whose LockStatus meets "
                  "(P1 & LockStatus) ^ P2 == 0 takes the new address (section 4.3).")
            ).classes("text-caption text-grey-8")
            with ui.row().classes("items-center"):
                self.new = range_number(_("New address"), 1, 254, integer=True, lang=lang).props("data-testid=bc-address").classes("w-56")
                self.p1, self.p2 = _mask_inputs("bc", lang)
            self.bits = ui.label().classes("text-caption")
            self.known = ui.label().classes("text-body2").props("data-testid=bc-known")
            self.button = ui.button(_("Send to all locks (255)"), icon="campaign", on_click=self.send) \
                .props("color=negative data-testid=bc-send")
        self.follow_entries()

    def refresh(self) -> None:
        if self.entries_unchanged(_line_inputs(self.view)):
            return  # the entries, the gate of Send and the locks of the line (their addresses and LockStatus) as drawn
        state = self.view.state
        m, e = _parse_word(self.p1.value), _parse_word(self.p2.value)
        known, statuses, in_plant, scanned = _line_locks(self.view.name, state)
        lang = self.view.lang
        _ = lang.gettext
        listed = ", ".join(f"{label} @{address}" if not label.startswith("address") else label for address, label in sorted(known.items()))
        text = lang.ngettext("{n} lock known on {bus} ({in_plant} in the plant, {scanned} found by a scan): {list}",
                             "{n} locks known on {bus} ({in_plant} in the plant, {scanned} found by a scan): {list}",
                             len(known)).format(n=len(known), bus=state.bus, in_plant=in_plant, scanned=scanned, list=listed)
        if m is None or e is None:
            self.bits.set_text(_("P1 and P2 must be 16-bit numbers, e.g. 0x010C"))
        else:
            self.bits.set_text(_condition_text(m, e, lang))
            takers, unknown = codec.broadcast_takers(m, e, statuses)
            text += _(". By the last LockStatus read: {list} would take it").format(list=", ".join(takers) or _("none"))
            if unknown:
                text += _("; unknown for {list}").format(list=", ".join(unknown))
        self.known.set_text(text)

    async def send(self) -> None:
        describe = "Broadcast Set Modbus Address (255)"
        entries = await self.entries(describe)
        if entries is None:
            return
        target, m, e = entries
        name, bus = self.view.name, self.view.state.bus
        known, statuses, in_plant, scanned = _line_locks(name, self.view.state)
        lang = self.view.lang
        _ = lang.gettext
        if target in known:
            used = N_("address {address} is {lock}: choose an address no lock uses")
            self.new.error = _(used).format(address=target, lock=known[target])
            await refuse(name, describe, used.format(address=target, lock=known[target]), parameter="DeviceAddress", new=target)
            return
        takers, unknown = codec.broadcast_takers(m, e, statuses)
        if len(takers) > 1:
            ui.notify(
                _("{locks} would all take address {address} and then answer together: narrow the condition (P1/P2) so "
                  "that only one lock meets it").format(locks=_(" and ").join(takers), address=target),
                type="warning", multi_line=True,
            )
            return
        count = len(known)
        if not await confirm(
            lang.ngettext("Up to {n} lock on {bus} may take address {address}",
                          "Up to {n} locks on {bus} may take address {address}", count).format(n=count, bus=bus, address=target),
            lang.ngettext("{n} lock known on {bus} may be affected ({in_plant} in the plant, {scanned} found by a scan): "
                          "{list}.", "{n} locks known on {bus} may be affected ({in_plant} in the plant, {scanned} found "
                          "by a scan): {list}.", count).format(n=count, bus=bus, in_plant=in_plant, scanned=scanned,
                                                              list=", ".join(sorted(known.values())))
            + " " + _("Every lock whose LockStatus meets the condition ({condition}) takes address {address} at once; by "
                      "the last status read {takers} would").format(condition=_condition_text(m, e, lang), address=target,
                                                                    takers=", ".join(takers) or _("none of them"))
            + (_(", unknown for {list}").format(list=", ".join(unknown)) if unknown else "")
            + ". " + _("Locks on the line that are not known here take it too if they meet the condition. Afterwards send "
                       "Save-Settings at address {address} and change the plant file.").format(address=target),
            ok=_("Send to all ({n})").format(n=count), lang=lang,
        ):
            return
        # the question above names the declared risk, with the locks known here
        ok, outcome = await run_command(name, "Broadcast Set Modbus Address (255)", confirmed=True,
                                        args={"new_address": target, "mask": m, "expected": e, "known": known})
        if ok:
            ui.notify(said(outcome.text, lang), type="positive" if outcome.taken else "warning", multi_line=True,
                      close_button="OK", timeout=20000)
        self.refresh()
