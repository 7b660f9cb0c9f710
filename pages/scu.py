"""Ewellix SCU page: live positions and status, remote session, drive by function, data directory, service table
(the cards of data read on demand are in :mod:`pages.scu_data`, what every card shares in :mod:`pages.scu_view`).

Reads only the live store (the points and records :mod:`devices.scu.adapter` publishes: session, watching
mode, control, running functions, emergency stop, scales, line) and invokes the declared commands
(devices/scu/policy.py) through the worker's gate. Each card is a small class with ``build()`` (in the
page's layout) and ``refresh()`` (on every change the store pushes)."""

from __future__ import annotations

import html
import time
from datetime import datetime

from nicegui import ui

from app import i18n
from app import worker as worker_module
from app.i18n import N_
from app.message import Message, said
from app.state import LiveValue
from devices.scu import facts
from devices.scu import codec
from devices.scu import params as p
from devices.scu.adapter import chart_points
from pages.cards import DrawnCard, point_values, titled_card
from pages.device_page import StatusRow, motion_page
from pages.scu_data import DirectoryCard, ServiceCard, SettingsCard
from pages.scu_view import Access, ScuView
from pages.frame import fmt_age
from pages.simcontrols import sim_card
from pages.widgets import entry_age, follow
from pages.command_client import checked_value, confirm, enable_unless
from pages.charts import HistoryChart
from pages.widgets import html_attr, INT32_LIMIT, lamp_html, LampStrip, mark_quality, quality_note, range_number
from pages.widgets import value_html

# Actuator status 1 (0x0171..) and 2 (0x00E1..): point key -> its words in table 6 (the adapter publishes one point per bit)
STATUS_BITS = {f.name: f.description for f in p.ACTUATOR_STATUS_1.fields + p.ACTUATOR_STATUS_2.fields}
SWITCHES = ((codec.Function.BUZZER, N_("Buzzer")), (codec.Function.BINARY_OUTPUT_1, N_("Binary output 1")),
            (codec.Function.BINARY_OUTPUT_2, N_("Binary output 2")), (codec.Function.LED_1, N_("Operating unit LED1")),
            (codec.Function.LED_2, N_("Operating unit LED2")))
SUPPLY_LAMPS = ("Mains", "Battery", "Charger on", "Charging", "Output 1", "Output 2", "Buzzer", "Sensor supply")
SUPPLY_WORDS = (N_("Mains"), N_("Battery"), N_("Charger on"), N_("Charging"), N_("Output 1"), N_("Output 2"),
                N_("Sensor supply"))  # the lamps' names (data 0x0100 Battery Mains, 0x0110 outputs)
# the I/O lines: point key (as the adapter publishes it) -> data ID, whose declaration names and words it
IO_POINTS = {N_("Battery voltage"): 0x0164, "Actual_State_Binary Inputs 1 ... 4": 0x0020, N_("Analogue input 1"): 0x0031,
             N_("Analogue input 2"): 0x0032, N_("Analogue input 3"): 0x0033, N_("Analogue input 4"): 0x0034,
             "Binary Output Status": 0x0110, "LED HS": 0x0120, "LED LB": 0x0130, "Lock Status": 0x0162,
             "Locking Box detected": 0x0165, "Benutzer": 0x0166}
ERROR_POINTS = {"Error code": N_("Error code (last)"), "Error history 1": N_("Error history 1"),
                "Error history 2": N_("Error history 2"), "Error history 3": N_("Error history 3"),
                "Error history 4": N_("Error history 4 (oldest)")}
RAW_NOTE = N_("the raw value as the unit sends it, for the vendor")


def _stop_rule(lang=None) -> str:
    return (lang or i18n.get("en")).gettext(
        "Every RE (Go, jog, function on) is followed by its RS: on Stop, on release of a jog button, on release "
        "of control, and within {bound} s when this browser closes, disconnects or "
        "freezes (dead-man rule), and after a lost session, even when the actuator stopped at its end position "
        "(section 4.6). Without RC for 500 ms the unit itself stops and leaves remote mode.").format(
        bound=f"{worker_module.DEADMAN_BOUND_S:g}")


def io_text(key: str, live: LiveValue, lang=None) -> tuple[str, str]:
    """An I/O line in words, named as its declaration says, and the raw value beside it ("" when the words are the
    number itself); table 6's words in ``lang``."""
    data_id = IO_POINTS[key]
    item = p.item(data_id)
    title = item.label or key  # the labels of table 6's I/O items are marked where they are declared
    if lang is not None:
        title = lang.gettext(title)
    value = live.value
    raw = live.raw if live.raw is not None else value
    if data_id in p.FLAG_WORDS:
        return f"{title}: {said(p.flags_text(data_id, int(raw)), lang)}", f"0x{int(raw):0{2 * item.size}X}"
    if data_id == 0x0166:
        return f"{title}: {said(p.user_text(int(value)), lang)}", f"raw {int(value)}"
    number = f"{value:g}" if isinstance(value, float) else str(value)
    if lang is not None:
        number = lang.numbers_in(number)
    unit = live.unit or item.unit
    return f"{title}: {number} {lang.unit(unit) if lang is not None else unit}".strip(), ""


def _error_names(code: int) -> str:
    """The causes of the set bits, short: the details (condition, behaviour) are listed under the line."""
    names = [b.cause for b in codec.error_bits(code)] + [f"bit {n} (not in table 10)" for n in codec.unknown_error_bits(code)]
    return "; ".join(names)


def _labels(functions) -> list[str]:
    return [codec.FUNCTIONS[codec.Function(f)].label for f in sorted(functions)]


def _aging(quality: str) -> bool:
    return quality in ("stale", "offline")


class SessionCard(DrawnCard):
    """The remote session, how the unit is watched, the RC timing, the last error answer and the line."""

    view: ScuView
    POINTS = (facts.P_SESSION, facts.P_SESSION_REASON, facts.P_WATCH, facts.P_CYCLIC, facts.P_REFUSAL)

    def build(self) -> None:
        view, state = self.view, self.view.state
        lang = view.lang
        _ = lang.gettext
        self.status = StatusRow(state, lambda c: _("requests {requests} · answers {answers} · timeouts {timeouts} · bad CRC "
                                                   "{crc} (retried) · error answers {exceptions} · seen {age}").format(
            requests=c.requests, answers=c.responses, timeouts=c.timeouts, crc=c.crc_errors, exceptions=c.exceptions,
            age=fmt_age(state.age, lang)), lang)
        with ui.card().classes("w-full"):
            with self.status.build():
                self.session = ui.label().classes("text-body1").props("data-testid=session")
                self.period = ui.label().classes("text-body2").props("data-testid=rc-period")
            self.cyclic = ui.label().classes("text-caption")
            self.refusal = ui.label().classes("text-warning text-body2").props("data-testid=refusal")
            self.error_line = ui.label().classes("text-negative text-body2")
            line = view.fact(facts.P_LINE)
            ui.label(_("Line {port} at {baud} baud 8N1. DTR and RTS are switched on when the port opens and kept on: they "
                       "power the unit's RS232 converter (section 3).").format(port=line.port, baud=line.baudrate)).classes("text-caption text-grey-8")
            safety_id = view.fact(facts.P_SAFETY_ID)
            with ui.expansion(_("Safety_ID {id} (RO): what the unit does on a communication timeout").format(id=safety_id)) \
                    .classes("w-full text-caption"):
                for sid, text in codec.SAFETY_MODES.items():
                    ui.label(f"{int(sid)}: {_(text)}" + ("  ← " + _("this plant") if sid == safety_id else "")) \
                        .classes("text-caption" + (" text-weight-bold" if sid == safety_id else ""))
            with ui.row():
                self.release_scu = ui.button(_("Release the SCU (RA)"), icon="pan_tool", on_click=lambda: view.act(
                    "release the SCU (RA)", success=_("released: the hand switch has the unit"))) \
                    .props("outline data-testid=release-scu")
                self.reopen = ui.button(_("Open the remote session"), icon="link",
                                        on_click=lambda: view.act("open remote session")).props("outline")
        follow(state, self.show_period, slow=True)
        self.show_period()

    def show_period(self) -> None:  # a statistic of every RC: once a second
        period, gap = self.view.fact(facts.P_RC_PERIOD), self.view.fact(facts.P_RC_GAP)
        lang = self.view.lang
        self.period.set_text(lang.gettext("RC period {period} ms, longest gap {gap} ms").format(
            period=lang.number(period), gap=lang.number(gap)) if period is not None and gap is not None
            else lang.gettext("RC period: -"))

    def inputs(self, access: Access) -> tuple:
        return super().inputs(access), self.view.state.last_error

    def draw(self, access: Access) -> None:
        view, state = self.view, self.view.state
        _ = view.lang.gettext
        self.status.refresh()
        reason = view.fact(facts.P_SESSION_REASON, "")
        self.session.set_text(_("remote session: {text}").format(text=view.lang.phrase(view.fact(facts.P_SESSION, "closed"), "Session"))
                              + (f" ({said(reason, view.lang)})" if reason else ""))
        watch = state.live(facts.P_WATCH)
        self.cyclic.set_text(" · ".join(_(x) for x in (watch.text if watch else "", view.fact(facts.P_CYCLIC, "")) if x))
        refusal = state.live(facts.P_REFUSAL)
        self.refusal.set_text(_("last error answer: {text}").format(text=said(refusal.text, view.lang)) if refusal is not None and refusal.value else "")
        self.error_line.set_text(said(state.last_error, view.lang) if state.online is False else "")
        # opening again is how a session recovers; RA hands the unit back
        enable_unless(self.reopen, access.role or (_("the remote session is open") if view.fact(facts.P_SESSION) == "open" else ""))
        enable_unless(self.release_scu, access.role)


class EstopCard(DrawnCard):
    """The emergency stop in red at the top of the page while it is on: who pressed it, when, and whether the
    unit confirmed it; nothing at all while it is off."""

    view: ScuView
    POINTS = (facts.P_ESTOP,)

    def build(self) -> None:
        # sticky under the header: seen wherever the page is scrolled to (the button is half-way down)
        self.banner = ui.card().classes("w-full bg-negative text-white").props("data-testid=estop-banner") \
            .style("position: sticky; top: 64px; z-index: 5")
        with self.banner, ui.row().classes("items-center gap-3 no-wrap"):
            ui.icon("emergency", size="md")
            self.text = ui.label().classes("text-h6")
        self.banner.set_visibility(False)

    def draw(self, access: Access) -> None:
        estop = self.view.state.live(facts.P_ESTOP)
        on = bool(estop is not None and estop.value)
        self.banner.set_visibility(on)
        lang = self.view.lang
        details = "" if not on else said(estop.text, lang) if isinstance(estop.text, Message) else lang.phrase(estop.text)
        self.text.set_text(lang.gettext("EMERGENCY STOP (F20) {text}").format(text=details) if on else "")


class PositionsCard(DrawnCard):
    """Each actuator's position as a bar between its end positions, and the positions' chart."""

    def __init__(self, view: ScuView):
        super().__init__(view)
        self.rows: list[tuple] = []
        self.POINTS = tuple(f"A{s.number} {what}" for s in view.scales for what in ("position", "in end", "out end"))

    def build(self) -> None:
        with titled_card(self.view.lang.gettext("Positions")):
            with ui.grid(columns=3).classes("w-full gap-x-4 gap-y-1 items-center").style("grid-template-columns: 60px 1fr 280px"):
                for s in self.view.scales:
                    ui.label(f"A{s.number}").classes("text-body1")
                    bar = ui.linear_progress(value=0, show_value=False).props("size=14px rounded")
                    with ui.row().classes("items-baseline gap-0 no-wrap") as cell:
                        text = ui.label("-").classes("mono").props(f"data-testid=pos-A{s.number}")
                        age = ui.label().classes("q-age")
                    self.rows.append((s.number, bar, text, cell, age))
            HistoryChart(self.view.state, list(chart_points(self.view.scales)), window_s=60, height=260, lang=self.view.lang)

    def inputs(self, access: Access) -> tuple:
        state = self.view.state
        return state.status, point_values(state, self.POINTS)

    def draw(self, access: Access) -> bool:
        point = self.view.live
        good = True
        for number, bar, text, cell, age in self.rows:
            e = point(f"A{number} position")
            lo, hi = point(f"A{number} in end"), point(f"A{number} out end")
            quality = "unknown" if e is None else e.quality
            mark_quality(cell, quality)  # greyed, with its age, while stale or offline
            mark_quality(bar, quality)
            age.set_text(quality_note(quality, entry_age(e), self.view.lang) if quality in ("stale", "offline") else "")
            good = good and not _aging(quality)
            if e is None:
                text.set_text("-")
                continue
            text.set_text(self.view.lang.numbers_in(e.text or str(e.value)))
            if lo and hi and hi.value != lo.value:
                bar.set_value(max(0.0, min(1.0, (e.value - lo.value) / (hi.value - lo.value))))
        return good


class StatusCard(DrawnCard):
    """Status 1 and 2 of each actuator as lamps, its current and speed."""

    def __init__(self, view: ScuView):
        super().__init__(view)
        self.columns: list[tuple[int, LampStrip]] = []
        self.POINTS = tuple(f"A{n} {key}" for n in range(1, len(view.scales) + 1)
                            for key in (*STATUS_BITS, "current", "speed"))

    def build(self) -> None:
        with titled_card(self.view.lang.gettext("Actuator status 1 (0x0171..) and 2 (0x00E1..), current (0x00A1..), speed (0x00F1..)")):
            with ui.row().classes("gap-8 items-start"):
                for n in range(1, len(self.view.scales) + 1):
                    with ui.column().classes("gap-0"):
                        ui.label(f"A{n}").classes("text-subtitle2")
                        self.columns.append((n, LampStrip("nicegui-column gap-0")))

    def draw(self, access: Access) -> bool:
        point, good = self.view.live, True
        for n, strip in self.columns:
            parts = []
            for key, words in STATUS_BITS.items():  # each lamp keyed by the point it shows
                entry = point(f"A{n} {key}")
                words = self.view.lang.gettext(words)  # table 6's words, marked in devices/scu/params.py
                parts.append(lamp_html(f"A{n} {key}", words[0].upper() + words[1:], entry, f"A{n} {key}"))
                good = good and (entry is None or not _aging(entry.quality))
            for what, label in (("current", N_("current")), ("speed", N_("speed"))):
                e = point(f"A{n} {what}")
                lang = self.view.lang
                parts.append(value_html(f"A{n} {what}", f"{what}-A{n}",
                                         "-" if e is None else f"{lang.gettext(label)}: {lang.number(e.value)} {lang.unit(e.unit)}".strip(), e))
                good = good and (e is None or not _aging(e.quality))
            strip.show(parts)
        return good


class SupplyCard(DrawnCard):
    """Mains, battery and outputs as lamps; the I/O values, one line per point."""

    POINTS = SUPPLY_LAMPS + tuple(IO_POINTS)
    TIPS = {key: f"{p.item(data_id).key} {p.item(data_id).name}: " for key, data_id in IO_POINTS.items()}

    def build(self) -> None:
        with titled_card(self.view.lang.gettext("Supply and I/O")):
            self.lamps = LampStrip("nicegui-row row gap-6")
            self.lines = LampStrip("nicegui-column gap-0 text-body2")  # one line per point

    def draw(self, access: Access) -> bool:
        point, good, parts = self.view.live, True, []
        lamps = [(key, point(key)) for key in SUPPLY_LAMPS]
        _ = self.view.lang.gettext
        self.lamps.show([lamp_html(key, _(key), entry) for key, entry in lamps])
        for key in IO_POINTS:
            e = point(key)
            if e is None:
                continue  # not read (yet): no line
            words, code = io_text(key, e, self.view.lang)
            quality = e.quality
            marks = f" q-{quality}" if quality in ("stale", "offline", "unknown") else ""
            parts.append(f'<div class="nicegui-row row items-baseline gap-2 no-wrap{marks}" data-io="{html_attr(key)}" '
                         f'data-quality="{quality}"><div>{html.escape(words)}</div>'
                         f'<div class="mono text-caption text-grey-7" data-tip="{html_attr(self.TIPS[key] + _(RAW_NOTE))}">'
                         f'{html.escape(code)}</div></div>')
            good = good and not _aging(quality)
        self.lines.show(parts)
        return good and not any(e is not None and _aging(e.quality) for _key, e in lamps)


class ErrorsCard(DrawnCard):
    """The error code and its history, each set bit with its cause, condition and behaviour."""

    POINTS = tuple(ERROR_POINTS)

    def __init__(self, view: ScuView):
        super().__init__(view)
        self.rows: dict[str, tuple] = {}  # per register: its line, and its bits (rebuilt only when the value changes)
        self.shown: dict[str, int] = {}

    def build(self) -> None:
        _ = self.view.lang.gettext
        with titled_card(_("Error code (0x00D1) and history (0x00D2..0x00D5), bit n = mask 1 << (n-1)")):
            with ui.column().classes("gap-1").props("data-testid=errors"):
                for key, title in ERROR_POINTS.items():
                    with ui.column().classes("gap-1").props(f'data-error="{key}"') as box:
                        with ui.row().classes("items-baseline gap-2") as head:
                            line = ui.label().classes("text-body2 text-weight-medium")
                            raw = ui.label().classes("mono text-caption text-grey-7")
                            raw.tooltip(f"Error_Code {_(RAW_NOTE)}")
                        self.rows[key] = (box, head, line, raw, ui.column().classes("gap-1"), _(title))

    def inputs(self, access: Access) -> tuple:
        state = self.view.state
        return state.status, point_values(state, self.POINTS)

    def draw(self, access: Access) -> bool:
        good = True
        for key, (box, head, line, raw, bits, title) in self.rows.items():
            e = self.view.live(key)
            box.set_visibility(e is not None)
            if e is None:
                continue
            value = int(e.value)
            mark_quality(head, e.quality)
            mark_quality(bits, e.quality)
            good = good and not _aging(e.quality)
            if self.shown.get(key) == value:
                continue
            self.shown[key] = value
            lang = self.view.lang
            _ = lang.gettext
            # in German each cause with its bit, as table 10 and the plant view word it (the catalog's entries)
            words = codec.NO_ERROR if value == 0 else _error_names(value) if lang.code == "en" else codec.error_text(value)
            line.set_text(f"{title}: " + lang.phrase(words, "Error code"))
            raw.set_text(codec.error_hex(value))
            line.classes(replace="text-body2 text-weight-medium" + (" text-negative" if value and key == "Error code" else ""))
            bits.clear()
            with bits:
                for b in codec.error_bits(value):
                    ui.label(lang.phrase(f"bit {b.bit}: {b.cause}", "Error code")
                             + (" — " + _("condition: {text}").format(text=_(b.condition)) if b.condition else "")
                             + " — " + _("behaviour: {text}").format(text=_(b.behaviour))).classes("text-caption text-negative" if key == "Error code" else "text-caption")
                if key == "Error code" and value & codec.CLEARED_BY_NEXT_MOVE:
                    ui.label(_("What clears it: the next movement (table 10). Take control and jog any actuator "
                               "briefly (hold IN or OUT), or run the checkout, which starts with a move.")) \
                        .classes("text-body2 text-weight-medium").props("data-testid=error-clears")
        return good


class DriveCard(DrawnCard):
    """Control, the function and its actuators, remote speed and positions, Go, Stop and jog (hold to run)."""

    POINTS = (facts.P_RUNNING, facts.P_RS_PENDING)

    def __init__(self, view: ScuView):
        super().__init__(view)
        self.edited: list[int] = []  # the actuator whose remote position was set last on this page
        self.jog_held: dict[int, bool] = {}
        self.moves: list[ui.button] = []  # what starts motion or writes: off without control, session or unit

    def build(self) -> None:
        view = self.view
        _ = view.lang.gettext
        with titled_card(_("Drive")):
            with ui.row().classes("items-center gap-4"):
                self.take = ui.button(_("Take control"), icon="sports_esports",
                                      on_click=lambda: view.act("take control", {"user": _client_user()})) \
                    .props("data-testid=take-control")
                self.release = ui.button(_("Release control"), icon="logout",
                                         on_click=lambda: view.act("release control")).props("outline")
                self.holder = ui.label().classes("text-body2")
            self._selects()
            self.drives = ui.label().classes("text-body2").props("data-testid=function-actuators")
            self.target_warning = ui.label().classes("text-warning text-body2").props("data-testid=target-warning")
            with ui.row().classes("items-end gap-4"):
                for s in view.scales:
                    self._position_entry(s)
            self._motion_buttons()
            with ui.row().classes("items-start no-wrap gap-1 bg-blue-grey-1 q-pa-xs rounded-borders"):
                ui.icon("timer_off", size="xs").classes("q-mt-xs")
                ui.label(_stop_rule(view.lang)).classes("text-caption").props("data-testid=stop-rule")
            self.running = ui.label().classes("text-caption mono")
            self.drive_off = ui.label().classes("text-negative text-body2").props("data-testid=drive-off")
        self.function.on_value_change(lambda _: self.show_targets())
        self.motion.on_value_change(lambda _: self.show_targets())

    def _selects(self) -> None:
        functions, speed = self.view.functions, self.view.fact(facts.P_SPEED)
        lang = self.view.lang
        _ = lang.gettext
        with ui.row().classes("items-end gap-4"):
            self.function = ui.select({int(f): f"{codec.FUNCTIONS[f].label} → "
                                       + (", ".join(f"A{a}" for a in functions.actuators_of(f)) or _("none"))
                                       for f in codec.MOTION_FUNCTIONS}, value=0,
                                      label=_("Function → actuators")).classes("w-40").props("data-testid=function")
            # the options without their detail (data IDs), which is in the tooltip: the whole text fits the field
            self.motion = ui.select({int(m): _(codec.MOTION_LABELS[m].split(" (", 1)[0]) for m in codec.Motion},
                                    value=int(codec.Motion.REMOTE_POSITION), label=_("Motion (para_ID[0])")) \
                .classes("w-72").props("data-testid=motion")
            self.motion.tooltip(" · ".join(_(label) for label in codec.MOTION_LABELS.values() if " (" in label))
            self.ramp = ui.select({1: _("soft start/stop"), 0: _("fast start/stop"), 255: _("as configured (-1)")}, value=1,
                                  label=_("Ramp (para_ID[1])")).classes("w-48")
            # table 7: relative 0 .. 100 %, absolute 0 .. 1000 counts/s, as the unit is parametrised (plant file)
            self.speed = range_number(_("Remote speed [{unit}]").format(unit=lang.unit(speed.unit)), 0, speed.high, integer=True,
                                      value=50, step=1, lang=lang) \
                .classes("w-56").props("data-testid=remote-speed")
            self.moves.append(ui.button(_("Set speed (RT)"), on_click=self.write_speed).props("outline data-testid=set-speed"))

    async def write_speed(self) -> None:
        function = self.function.value + 1
        value = await checked_value(self.speed, self.view.name, f"set remote speed F{function}",
                                    parameter=f"Remote Speed F{function}")
        if value is not None:
            await self.view.act("set remote speed", {"function": function, "speed": int(value)},
                                success=self.view.lang.gettext("remote speed written and read back"))

    def _position_entry(self, s: facts.ActuatorScale) -> None:
        unit = "mm" if s.counts_per_mm or s.stroke_mm else "counts"
        low, high = _position_range(s)
        # without a stroke the entry accepts what INT32 counts can say: shown as "any", not as 2.1e+09
        any_beyond = INT32_LIMIT if s.stroke_mm else min(abs(low), abs(high))
        _ = self.view.lang.gettext
        field = range_number(_("A{n} remote position [{unit}]").format(n=s.number, unit=self.view.lang.unit(unit)), low, high, unit=unit, value=0,
                             integer=unit == "counts", any_beyond=any_beyond, lang=self.view.lang).classes("w-56").props(f"data-testid=remote-pos-A{s.number}")

        async def write_position() -> None:
            view = self.view
            value = await checked_value(field, view.name, f"set remote position A{s.number}",
                                        parameter=f"Remote Position A{s.number}")
            if value is None:
                return
            ok, _result = await view.act("set remote position", {"actuator": s.number, "value": float(value), "mm": unit == "mm"},
                                         success=view.lang.gettext("remote position written and read back"))
            if ok:
                self.edited[:] = [s.number]
                self.show_targets()

        self.moves.append(ui.button(_("Set (RT)"), on_click=write_position).props(f"outline data-testid=set-pos-A{s.number}"))

    def _motion_buttons(self) -> None:
        _ = self.view.lang.gettext
        with ui.row().classes("items-center gap-4"):
            self.moves.append(ui.button(_("Go (RE)"), icon="play_arrow", color="positive", on_click=self.go_pressed)
                              .props("data-testid=go"))
            ui.button(_("Stop (RS)"), icon="stop", color="negative",
                      on_click=lambda: self.view.act("stop (RS)")).props("data-testid=stop")
            ui.label(_("Jog (hold to run):")).classes("text-caption")
            jog_in = ui.button(_("In"), icon="keyboard_double_arrow_left").props("outline data-testid=jog-in")
            jog_out = ui.button(_("Out"), icon="keyboard_double_arrow_right").props("outline data-testid=jog-out")
        self.moves += [jog_in, jog_out]
        for button, direction in ((jog_in, -1), (jog_out, 1)):
            for event in ("mousedown", "touchstart"):
                button.on(event, self.jog(direction))
            for event in ("mouseup", "mouseleave", "touchend", "touchcancel"):
                button.on(event, self.jog_release)

    def ramp_value(self) -> int:
        return self.ramp.value if self.ramp.value != 255 else -1

    async def go_pressed(self) -> None:
        pressed = time.monotonic()  # a Stop after this moment cancels the RE, or follows it at once
        fn = self.function.value
        acts = self.view.functions.actuators_of(fn)
        warning = self.target_mismatch()
        _ = self.view.lang.gettext
        if not await confirm(
                _("Start the motion"),
                _("{function} drives {actuators}: {motion}. Check that the area is clear: nobody and nothing in the stroke "
                  "of {list}.").format(function=codec.FUNCTIONS[fn].label, actuators=functions_text(self.view, fn),
                                       motion=_(codec.MOTION_LABELS[self.motion.value]),
                                       list=", ".join(f"A{a}" for a in acts) or _("its actuators"))
                + (f" {warning}" if warning else ""), ok=_("The area is clear: Go"), lang=self.view.lang):
            return
        # the question above names the declared risk (the area is clear), with the actuators it drives
        await self.view.act("go (RE)", {"function": fn, "motion": self.motion.value, "ramp": self.ramp_value(),
                                        "requested_at": pressed}, confirmed=True)

    def jog(self, direction: int):
        def press():
            pressed = time.monotonic()  # before any await: a release after it cancels or follows the RE
            fn = self.function.value
            self.jog_held[fn] = True
            return self.view.act("jog (RE)", {"function": fn, "direction": direction, "ramp": self.ramp_value(),
                                              "requested_at": pressed})
        return press

    def jog_release(self):
        held = [fn for fn, on in self.jog_held.items() if on]
        self.jog_held.clear()
        if not held:
            return None  # a mouse passing over the button: nothing was pressed
        return self._release_all(held)

    async def _release_all(self, held: list[int]) -> None:
        for fn in held:
            await self.view.act("jog stop (RS)", {"function": fn})

    def target_mismatch(self) -> str:
        fn = self.function.value
        acts = self.view.functions.actuators_of(fn)
        if self.motion.value == int(codec.Motion.REMOTE_POSITION) and self.edited and self.edited[0] not in acts:
            _ = self.view.lang.gettext
            return _("The remote position you set last is A{n}'s, but {function} drives {list}: A{n} will not move.").format(
                n=self.edited[0], function=codec.FUNCTIONS[fn].label, list=", ".join(f"A{a}" for a in acts) or _("no actuator"))
        return ""

    def show_targets(self) -> None:
        fn = self.function.value
        self.drives.set_text(self.view.lang.gettext("{function} drives {actuators}").format(
            function=codec.FUNCTIONS[fn].label, actuators=functions_text(self.view, fn)))
        self.target_warning.set_text(self.target_mismatch())

    def inputs(self, access: Access) -> tuple:
        return (access, point_values(self.view.state, self.POINTS), self.function.value, self.motion.value,
                tuple(self.edited))

    def draw(self, access: Access) -> None:
        holder, mine = access.holder, access.mine
        _ = self.view.lang.gettext
        if holder is None:
            self.holder.set_text(_("nobody holds control"))
        elif mine:
            self.holder.set_text(_("you hold control since {time}").format(time=f"{datetime.fromtimestamp(holder.since):%H:%M:%S}"))
        else:
            self.holder.set_text(_("{user} holds control (another browser) since {time}").format(
                user=holder.user, time=f"{datetime.fromtimestamp(holder.since):%H:%M:%S}"))
        run, failed = _labels(self.view.fact(facts.P_RUNNING, ())), _labels(self.view.fact(facts.P_RS_PENDING, ()))
        self.running.set_text(_("RE sent, RS pending: {list}").format(list=", ".join(run) if run else _("none"))
                              + (_(" · STOP FAILED, RS not acknowledged (sent again every poll): {list}").format(
                                  list=", ".join(failed)) if failed else ""))
        off = access.lost or access.offline or access.estop
        self.drive_off.set_text(_("Drive off: {reason}").format(reason=off) if off and mine else "")
        self.show_targets()
        enable_unless(self.take, access.role or access.offline or (
            "" if holder is None else _("you hold control") if mine else _("another browser holds control")))
        enable_unless(self.release, access.role or ("" if mine else _("you do not hold control")))
        for element in self.moves:
            enable_unless(element, access.role or off or ("" if mine else _("take control first")))


class FunctionsCard(DrawnCard):
    """Buzzer, outputs and LEDs on and off; the emergency stop and its release."""

    def __init__(self, view: ScuView):
        super().__init__(view)
        self.on: list[ui.button] = []
        self.off: list[ui.button] = []

    def build(self) -> None:
        view = self.view
        _ = view.lang.gettext
        with titled_card(_("Functions (firmware V2B1 and later)")):
            with ui.row().classes("items-center gap-4"):
                for fn, label in SWITCHES:
                    with ui.button_group():
                        self.on.append(ui.button(_("{name} on").format(name=_(label)), on_click=lambda fn=fn: view.act(
                            "function on (RE)", {"function": int(fn)})).props("outline"))
                        self.off.append(ui.button(_("off"), on_click=lambda fn=fn: view.act(
                            "function off (RS)", {"function": int(fn)})).props("outline"))
            with ui.row().classes("items-center gap-4"):
                ui.button(_("Emergency stop (F20, function 19)"), icon="emergency", color="negative",
                          on_click=lambda: view.act("emergency stop (RE 19)")).props("data-testid=emergency-stop")
                self.release_estop = ui.button(_("Release emergency stop (RS 19, F20)"), on_click=lambda: view.act(
                    "release emergency stop (RS 19)", title=_("Release the emergency stop?"), ok=_("Release it"))).props("outline")
                ui.label(_("Emergency stop acts at once, without confirmation, for anyone, in any state of the session; "
                           "only its release needs control.")).classes("text-caption")

    def inputs(self, access: Access) -> Access:
        return access

    def draw(self, access: Access) -> None:
        control = "" if access.mine else self.view.lang.gettext("take control first")
        for element in self.on:
            enable_unless(element, access.role or access.lost or access.offline or access.estop or control)
        enable_unless(self.release_estop, access.role or access.lost or access.offline or control)
        for element in self.off:
            enable_unless(element, access.role or control)


def content(name: str) -> None:
    view = ScuView(name)
    _ = view.lang.gettext
    with motion_page(view, _("Ewellix SCU {name}").format(name=name),
                     _("RS to every running function; anyone may stop, also without control."), "stop (RS)"):
        for card in (EstopCard(view), SessionCard(view), PositionsCard(view), StatusCard(view), SupplyCard(view), ErrorsCard(view),
                     DriveCard(view), FunctionsCard(view), SettingsCard(view), DirectoryCard(view), ServiceCard(view)):
            view.add(card)
        sim_card(name)  # the twin's declared controls, in simulation only


# the motions of para_ID[0] (devices/scu/codec.py MOTION_LABELS, table 7) as the select and the question show them
MOTION_WORDS = (
    N_('undefined direction'),
    N_('undefined direction (no motion)'),
    N_('Move to position In'),
    N_('Move to position Out'),
    N_('Move to position Mem1'),
    N_('Move to position Mem2'),
    N_('Move to position Mem3'),
    N_('Move to position Mem4'),
    N_('Move to position Intermediate In'),
    N_('Move to position Intermediate Out'),
    N_('Move to remote position'),
    N_('Move to remote position (data IDs 0x3021..0x3026)'),
)


def functions_text(view: ScuView, function: int) -> str:
    """:meth:`devices.scu.facts.FunctionMap.text` in the page's language: the actuators a function drives."""
    _ = view.lang.gettext
    acts = view.functions.actuators_of(function)
    return (", ".join(f"A{a}" for a in acts) if acts else _("no actuator")) + (
        " " + _("(assumed: SCP11, section 5; set functions in the plant file)") if view.functions.assumed else "")


def _client_user() -> str:
    from pages.session import current_user

    return current_user()[0] or "anonymous"


def _position_range(scale) -> tuple[float, float]:
    """What a remote position entry accepts: INT32 counts (table 7), in mm through the actuator's conversion
    (0 .. stroke when the stroke is known)."""
    low, high = -(2 ** 31), 2 ** 31 - 1
    if scale.stroke_mm:
        return 0.0, float(scale.stroke_mm)
    if scale.counts_per_mm:
        return round(low / scale.counts_per_mm, 1), round(high / scale.counts_per_mm, 1)
    return low, high


__all__ = ["content"]
