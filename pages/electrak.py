"""Electrak HD network page: live charts, flags, control with keep-alive, service parameters
(:mod:`pages.electrak_service`), bit rate.

Reads only the live store (the points and records :mod:`devices.electrak.adapter` publishes) and invokes
the declared commands (devices/electrak/policy.py) through the worker's gate. Each card is a
:class:`pages.cards.DeviceCard` with ``build()`` (in the page's layout) and ``refresh()`` (on every
change the store pushes); :func:`pages.device_page.device_page` puts the frame, events and STOP bar around them."""

from __future__ import annotations

import time
from datetime import datetime

from nicegui import ui

from app import i18n
from app import worker as worker_module
from app.csvfile import csv_text
from app.i18n import N_
from app.message import said
from devices.electrak import adapter as facts
from devices.electrak import codec
from devices.electrak.adapter import FOREIGN_SENDER, SERIES
from devices.electrak.params import BITRATE_AT_POWER_UP, BITRATE_NAMES, BITRATE_SPECIFIER, PARAMS
from devices.electrak.policy import AREA_CLEAR_RISK
from pages.cards import DeviceCard, DrawnCard, point_values, titled_card
from pages.charts import HistoryChart
from pages.command_client import checked_value, confirm, enable_unless, refuse, write_from_page
from pages.device_page import DeviceView, StatusRow, motion_page
from pages.electrak_service import ServiceCard, save_parameters
from pages.frame import fmt_age
from pages.session import current_user
from pages.simcontrols import sim_card
from pages.widgets import LampStrip, entry_age, lamp_html, mark_quality, quality_note, range_number

WINDOW_S = 60
TIMEOUT_BIT = 5  # error flags bit 5: Message timeout ("Fehler-Flags")
CHART_ROWS = [[facts.P_POSITION, facts.P_DRIVE_TARGET], [facts.P_CURRENT], [facts.P_SPEED]]
# the points' names and the network's summary of them (devices/electrak/adapter.py), and who else may send 0x06
POINT_WORDS = (N_("Drive target"), N_("Position"), N_("Current"), N_("Speed"), N_("mean"), N_("highest"),
               N_("a PLC, or an actuator whose manual control line is active"))
CHART_UNITS = ("mm", "A", "mm/s")  # the rows' axes


class ElectrakView(DeviceView):
    """What every card of one page shares: the network's live record, its actuators and the ranges they
    accept, and its declared commands (devices/electrak/policy.py)."""

    def __init__(self, name: str):
        super().__init__(name)
        self.actuators: tuple[codec.Actuator, ...] = self.fact(facts.P_ACTUATORS, ())  # as configured
        self.limits: codec.Limits = self.fact(facts.P_LIMITS)

    def online(self) -> bool:
        return self.state.status == "online"

    def refresh(self) -> None:
        if self.guard is not None:
            self.guard.update()  # first: the drive card's gates read its reason
        super().refresh()


class NetworkCard(DrawnCard):
    """Status, actuators heard, the numbers of each status telegram, warnings and the configured ranges."""

    view: ElectrakView
    NUMBERS = (facts.P_POSITION, facts.P_CURRENT, facts.P_SPEED)

    def build(self) -> None:
        view, state = self.view, self.view.state
        _ = view.lang.gettext
        self.status = StatusRow(state, lambda c: _("status frames {responses} · service requests {requests} · timeouts "
                                                   "{timeouts} · error answers {exceptions} · malformed {malformed}").format(
            responses=c.responses, requests=c.requests, timeouts=c.timeouts, exceptions=c.exceptions, malformed=c.malformed),
            view.lang)
        with ui.card().classes("w-full"):
            with self.status.build():
                self.heard = ui.label().classes("text-body2")
                self.seen = ui.label().classes("text-body2")
            self.numbers = NumbersGrid(state, len(view.actuators), view.lang)
            self.heard_warning = ui.label().classes("text-warning text-body2")
            self.saturated = ui.label().classes("text-warning text-body2").props("data-testid=saturated-warning")
            limits, number = view.limits, view.lang.number
            ui.label(
                _("actuators: {list}").format(list="; ".join(_("{model} {gearing} {stroke} mm stroke").format(
                    model=a.model, gearing=a.gearing, stroke=number(a.stroke_mm)) for a in view.actuators))
                + " · " + _("accepted: 0..{stroke} mm, {low}..{high} mm/s, 0..{current} A (0 = calibrated limit)").format(
                    stroke=number(limits.stroke_mm), low=number(limits.speed_min), high=number(limits.speed_max),
                    current=number(limits.current_a))
            ).classes("text-caption text-grey-8")

    def inputs(self) -> tuple:
        state = self.view.state
        return (state.status, point_values(state, self.NUMBERS), point_values(state, (facts.P_HEARD, facts.P_CONFIGURED,
                                                                                     facts.P_SATURATED)))

    def draw(self) -> bool:
        view, state = self.view, self.view.state
        _ = view.lang.gettext
        self.status.refresh()
        heard, configured = view.fact(facts.P_HEARD, 0), view.fact(facts.P_CONFIGURED)
        self.heard.set_text(_("actuators heard per 100 ms: {heard} of {configured} configured").format(
            heard=heard, configured=configured))
        self.heard_warning.set_text(
            _("The network answers with {heard} status telegrams per 100 ms, but {configured} actuators are configured: "
              "check wiring and power, or the plant file.").format(heard=heard, configured=configured)
            if view.online() and heard != configured else "")
        saturated = view.fact(facts.P_SATURATED, "")
        self.saturated.set_text(said(saturated, view.lang) if saturated and view.online() else "")
        self.seen.set_text(_("last status {age}").format(age=fmt_age(state.age, view.lang)))
        return self.numbers.draw()  # False: a stale or offline value, drawn again with the next telegram (it may be good again)


class FlagsCard(DrawnCard):
    """Motion and fault flags as lamps; Message timeout while nobody sends 0x06 is grey and explained."""

    view: ElectrakView
    POINTS = (*(n for n, _text in codec.MOTION_FLAGS.values()), *(n for n, _text, _clears in codec.ERROR_FLAGS.values()),
              facts.P_IDLE, facts.P_ERRORS)

    def __init__(self, view: ElectrakView):
        super().__init__(view)
        self.shown_faults: tuple | None = None

    def build(self) -> None:
        _ = self.view.lang.gettext
        with ui.card().classes("w-full"):
            with ui.row().classes("gap-10 items-start"):
                with ui.column():
                    ui.label(_("Motion")).classes("text-subtitle2")
                    self.motion = LampStrip("nicegui-column")
                with ui.column():
                    ui.label(_("Faults")).classes("text-subtitle2")
                    self.errors = LampStrip("nicegui-grid gap-x-6 gap-y-1")
                    self.errors.element.style("grid-template-columns: repeat(4, minmax(0, 1fr))")
            self.fault_text = ui.column().classes("gap-0")
            self.idle_note = ui.label().classes("text-caption text-grey-8").props("data-testid=idle-note")

    def inputs(self) -> tuple:
        state = self.view.state
        return state.status, point_values(state, self.POINTS)

    def draw(self) -> bool:
        view, state = self.view, self.view.state
        _ = view.lang.gettext
        online = view.online()
        idle = bool(view.fact(facts.P_IDLE, True))  # Message timeout while nobody sends 0x06: the idle state, not a red fault
        motion = [(state.live(n), n, _(text)) for n, text in codec.MOTION_FLAGS.values()]
        errors = [(state.live(n), n, _("{text}. Clears: {clears}.").format(text=_(text), clears=_(clears)), bit)
                  for bit, (n, text, clears) in codec.ERROR_FLAGS.items()]
        self.motion.show([lamp_html(n, _(n), entry, text) for entry, n, text in motion])
        self.errors.show([lamp_html(n, _(n), entry, text, "alarm", idle if bit == TIMEOUT_BIT else None)
                          for entry, n, text, bit in errors])
        # a stale or offline lamp: drawn again with the next telegram, which may bring them back
        good = not any(value is not None and value.quality in ("stale", "offline") for value, *_rest in motion + errors)
        errors = view.fact(facts.P_ERRORS, 0)
        self.idle_note.set_text(_("Message timeout is expected while idle: nobody sends the control telegram 0x06. "
                                  "It clears with the first telegrams when you take control.")
                                if idle and online and errors >> TIMEOUT_BIT & 1 else "")
        faults = tuple(bit for bit in codec.ERROR_FLAGS if online and errors >> bit & 1 and not (idle and bit == TIMEOUT_BIT))
        if faults != self.shown_faults:  # rebuilt only when the faults change
            self.shown_faults = faults
            self.fault_text.clear()
            with self.fault_text:
                for bit in faults:
                    fault, _text, clears = codec.ERROR_FLAGS[bit]
                    ui.label(_("{fault}: clears: {clears}").format(fault=_(fault), clears=_(clears))).classes("text-negative text-body2")
        return good


class ChartCard(DeviceCard):
    """Position (with the target driven to), current and speed over the last minute, one figure in rows (it
    follows the store itself: nothing to refresh)."""

    def build(self) -> None:
        name, state = self.view.name, self.view.state
        with ui.card().classes("col-12 col-md-8"):
            with ui.row().classes("items-center w-full"):
                ui.label(self.view.lang.gettext("Position, current and speed (last {window} s, 100 ms frames)").format(
                    window=WINDOW_S)).classes("text-subtitle1")
                ui.space()
                ui.button("CSV", icon="download", on_click=lambda: _export_csv(state, name, self.view.lang)).props("flat dense")
                ui.button("PNG", icon="image", on_click=lambda: _export_png(chart, name)).props("flat dense")
            # one figure, three rows over one time axis: one drawing a second for all of them
            chart = HistoryChart(state, rows=CHART_ROWS, row_heights=(1.6, 1, 1), window_s=WINDOW_S, height=520,
                                 lang=self.view.lang)
            layout = chart.figure["layout"]
            for axis, unit in zip(("yaxis", "yaxis2", "yaxis3"), CHART_UNITS):
                layout[axis]["title"] = {"text": unit}  # the axes name the units; the legend names the points
                # position, current and speed are unsigned in the status frame: at rest an axis runs from 0, not -1
                layout[axis]["rangemode"] = "nonnegative"
            target_trace = chart.figure["data"][1]
            target_trace["line"] = {"dash": "dash", "color": "#c10015"}
            target_trace["mode"] = "lines"
            chart.figure["data"][3]["line"] = {"color": "#6a1b9a"}  # speed: not a second red beside the target
            layout["margin"]["b"] = 48  # room under the time axis for its date line, never clipped
            chart.plot.update()


def content(name: str) -> None:
    view = ElectrakView(name)
    _ = view.lang.gettext
    with motion_page(view, _("Electrak HD network {name}").format(name=name),
                     _("Clears enable at once; anyone may stop, also without control."), "stop"):
        view.add(NetworkCard(view))
        # chart and drive side by side from 1024 px, right under the network's values, so Go and the jog buttons are
        # in sight at 1440x900; on a tablet the drive card below the chart, each full width
        # (beside it the chart was drawn over the drive card)
        with ui.row().classes("w-full items-start gap-4"):
            view.add(ChartCard(view))
            with ui.column().classes("col-12 col-md gap-4"):
                view.add(DriveCard(view))
        view.add(FlagsCard(view))
        sim_card(name)  # full width: its entries and buttons need a row of their own on a narrow screen
        view.add(ServiceCard(view))
        view.add(BitrateCard(view))


def holder_name() -> str:
    """Who takes control from this page: the logged-in account (the name the other browsers and the audit log show)."""
    return current_user()[0] or "anonymous"


def _stop_rule(lang=None) -> str:
    return (lang or i18n.get("en")).gettext(
        "Stop rule: motion stops when a jog button is released, on Stop, and within {bound} s of this browser going away "
        "(closed, disconnected or frozen): enable is cleared and sent at once. Without control telegrams the actuators "
        "stop by themselves after their Timeout (250 ms by default)."
    ).format(bound=f"{worker_module.DEADMAN_BOUND_S:g}")


class DriveCard(DrawnCard):
    """Take control, target, speed and current limit, Go, Stop, hold-to-run jog, override; the telegram sent."""

    view: ElectrakView

    def __init__(self, view: ElectrakView):
        super().__init__(view)
        self.area_clear_for: float | None = None  # the control (its start) for which the jog was armed

    def build(self) -> None:
        view, limits = self.view, self.view.limits
        lang = view.lang
        _ = lang.gettext
        with titled_card(_("Drive the network")):
            self.holder = ui.label().classes("text-body2")
            self.foreign = ui.label().classes("text-negative text-body2").props("data-testid=foreign-control")
            with ui.row():
                self.take = ui.button(_("Take control"), icon="sports_esports",
                                      on_click=lambda: view.act("take control", {"user": holder_name()})).props("data-testid=take-control")
                self.take.tooltip(_("Listens {seconds} s for another sender of 0x06 first ({sender}); refused if there is "
                                    "one").format(seconds=lang.number(codec.LISTEN_S), sender=_(FOREIGN_SENDER)))
                self.release = ui.button(_("Release"), icon="logout", on_click=lambda: view.act("release control")).props("outline")
            # the ranges every actuator of the network accepts (codec.Limits: model, gearing, stroke): kept as typed, never clamped
            self.position = range_number(_("Target position [mm]"), 0, limits.stroke_mm, unit="mm", value=0.0, step=0.1,
                                         fmt="%.1f", lang=lang).props("data-testid=target").classes("w-full")
            self.speed = range_number(_("Speed [mm/s]"), limits.speed_min, limits.speed_max, unit="mm/s",
                                      value=limits.speed_max, step=0.1, fmt="%.1f", lang=lang).props("data-testid=speed").classes("w-full")
            self.current = range_number(_("Current limit [A] (0 = calibrated)"), 0, limits.current_a, unit="A", value=0.0,
                                        step=0.1, fmt="%.1f", lang=lang).props("data-testid=current-limit").classes("w-full")
            with ui.row():
                self.apply_button = ui.button(_("Apply"), on_click=self.apply).props("outline data-testid=apply")
                self.go_button = ui.button(_("Go"), icon="play_arrow", color="positive", on_click=self.go).props("data-testid=go")
                ui.button(_("Stop"), icon="stop", color="negative", on_click=lambda: view.act("stop")).props("data-testid=stop")
            ui.label(_("Jog (hold to run, stops when released)")).classes("text-caption text-grey-8")
            with ui.row():
                self.jog_in = ui.button(_("In"), icon="keyboard_double_arrow_left").props("outline data-testid=jog-in")
                self.jog_out = ui.button(_("Out"), icon="keyboard_double_arrow_right").props("outline data-testid=jog-out")
                self.reset = ui.button(_("Override/reset"), on_click=self.override).props("flat data-testid=override")
                self.reset.tooltip(_("Resets the number of actuators the network expects (asks first); held for three "
                                     "control periods, then cleared by itself"))
            self.armed = ui.label().classes("text-caption text-grey-8").props("data-testid=jog-armed")
            for button, direction in ((self.jog_in, -1), (self.jog_out, 1)):
                for event in ("mousedown", "touchstart"):
                    button.on(event, self.jog(direction))
                for event in ("mouseup", "mouseleave", "touchend", "touchcancel"):
                    button.on(event, lambda: view.act("jog stop"))
            with ui.row().classes("items-start no-wrap gap-1 bg-blue-grey-1 q-pa-xs rounded-borders"):
                ui.icon("timer_off", size="xs").classes("q-mt-xs")
                ui.label(_stop_rule(lang)).classes("text-caption").props("data-testid=stop-rule")
            self.sent = ui.label().classes("text-caption mono text-grey-8")

    async def entries(self, describe: str) -> tuple[float, float, float] | None:
        """Target, speed and limit as typed, or None: each bad one marked with its range, refused in the audit log."""
        values = [await checked_value(field, self.view.name, describe, parameter=parameter) for field, parameter in
                  ((self.position, "Target position"), (self.speed, "Target speed"), (self.current, "Current limit"))]
        return None if None in values else (float(values[0]), float(values[1]), float(values[2]))

    async def apply(self) -> bool:
        values = await self.entries("set target")
        if values is None:
            return False
        ok, _ = await self.view.act("set target", dict(zip(("position_mm", "speed_mm_s", "current_a"), values)))
        return ok

    async def go(self) -> None:
        if await self.apply():  # the gate asks the declared risk: the area is clear
            _ = self.view.lang.gettext
            await self.view.act("go", title=_("Go: is the area clear?"), ok=_("The area is clear: Go"))

    async def override(self) -> None:
        _ = self.view.lang.gettext
        await self.view.act("override", {"active": 1}, title=_("Override/reset: the network counts its actuators anew"),
                            ok=_("Override/reset"))

    def _my_control(self):
        c = self.view.fact(facts.P_CONTROL)
        return c if c is not None and c.session == self.view.tag else None

    def jog(self, direction: int):
        """Hold-to-run. The area-clear question of the declared jog is asked at the first press while this page holds
        control (a dialog would end the hold): that press arms the jog, the next ones move while held."""
        async def start() -> None:
            name = f"jog {'out' if direction > 0 else 'in'}"
            mine = self._my_control()
            if mine is not None and self.area_clear_for != mine.since:
                _ = self.view.lang.gettext
                if await confirm(_("Jog: is the area clear?"), _(AREA_CLEAR_RISK) + " " + _(
                        "Jogging is then armed while you hold control: hold In or Out to move, release to stop."),
                        ok=_("The area is clear"), lang=self.view.lang):
                    self.area_clear_for = mine.since
                    self.refresh()
                    ui.notify(_("Jog armed: hold In or Out to move (it stops when released)"), type="info")
                else:
                    await refuse(self.view.name, name, "not confirmed")
                return
            value = await checked_value(self.speed, self.view.name, name, parameter="Target speed")
            if value is not None:
                await self.view.act("jog", {"direction": direction, "speed_mm_s": float(value)},
                                    confirmed=mine is not None)  # the question above named the declared risk
        return start

    def inputs(self) -> tuple:
        other = self.view.fact(facts.P_FOREIGN)
        foreign = other is not None and time.time() - other.time <= 2.0
        return (self.guard.reason, point_values(self.view.state, (facts.P_CONTROL, facts.P_TELEGRAM)),
                other if foreign else None, self.area_clear_for)

    def draw(self) -> None:
        view = self.view
        _ = view.lang.gettext
        c = view.fact(facts.P_CONTROL)
        mine = c is not None and c.session == view.tag
        if c is None:
            self.holder.set_text(_("nobody controls the network: control telegrams are off"))
        elif mine:
            self.holder.set_text(_("you hold control as {user} since {time}; control telegram every 100 ms").format(
                user=c.user, time=f"{datetime.fromtimestamp(c.since):%H:%M:%S}"))
        else:
            self.holder.set_text(_("{user} holds control (another browser) since {time}").format(
                user=c.user, time=f"{datetime.fromtimestamp(c.since):%H:%M:%S}"))
        other = view.fact(facts.P_FOREIGN)
        if other is not None and time.time() - other.time <= 2.0:  # shown for 2 s after the last one
            self.foreign.set_text(_("Another sender of the control telegram 0x06 is on the bus ({sender}): {text} · {frames} "
                                    "frames. Take control is refused while it sends.").format(
                sender=_(FOREIGN_SENDER), text=other.text, frames=other.frames))
        else:
            self.foreign.set_text("")
        offline = self.guard.reason  # motion and writes wait for a network that answers; the stops never do
        enable_unless(self.take, offline or ("" if c is None else _("you hold control") if mine
                                             else _("another browser holds control")))
        enable_unless(self.release, "" if mine else _("you do not hold control"))
        for element in (self.apply_button, self.go_button, self.jog_in, self.jog_out, self.reset):
            enable_unless(element, offline or ("" if mine else _("take control first")))
        armed = mine and self.area_clear_for == c.since
        self.armed.set_text("" if not mine else _("jog armed: the area was confirmed clear; hold In or Out to move") if armed
                            else _("the first press of In or Out asks that the area is clear, then arms the jog"))
        telegram = view.state.live(facts.P_TELEGRAM)
        self.sent.set_text("" if telegram is None else said(telegram.shown, view.lang))


class NumbersGrid:
    """Position, current and speed as numbers: the network's (mean, highest, mean) and each status telegram's, each
    greyed with its age while stale or offline. Drawn by its card (one look at the store for all of them)."""

    def __init__(self, state, configured: int, lang=None):
        self.state, self.configured = state, configured
        self.lang = lang or i18n.get("en")
        _ = self.lang.gettext
        self.cells: list[tuple[str, int | None, ui.row, ui.label, ui.label]] = []  # point, word (None: network), ...
        with ui.grid(columns=configured + 2).classes("items-baseline gap-x-6 gap-y-0").props("data-testid=numbers"):
            ui.label("")
            ui.label(_("network")).classes("text-caption text-grey-8")
            for i in range(configured):
                ui.label(_("actuator {n}").format(n=i + 1)).classes("text-caption text-grey-8").tooltip(
                    _("The n-th status telegram 0x07 of each 100 ms: the telegrams carry no actuator number (document, "
                      "status telegram), so the columns follow the order heard."))
            for point in NetworkCard.NUMBERS:
                ui.label(_(point)).classes("text-body2 text-weight-medium")
                for i, testid in [(None, f"network-{point.lower()}")] + [
                        (i, f"actuator-{i + 1}-{point.lower()}") for i in range(configured)]:  # words in 0.1 mm, 0.1 A, 0.1 mm/s
                    with ui.row().classes("items-baseline gap-0 no-wrap") as row:
                        label = ui.label("-").classes("text-body1 mono")
                        age = ui.label().classes("q-age")
                    row.props(f'data-point="{point}" data-testid={testid}')
                    self.cells.append((point, i, row, label, age))

    def text(self, value, word: int | None) -> str:
        lang = self.lang
        if word is None:
            return f"{lang.number(value.value, 1)} {value.unit} ({lang.gettext((value.text or '').split(' of ')[0])})"
        raw = value.raw or []
        return f"{lang.number(raw[word] * 0.1, 1)} {value.unit}" if word < len(raw) else lang.gettext("not heard")

    def draw(self) -> bool:
        """Every cell as the store has it now; False when a value is stale or offline."""
        values = {point: self.state.live(point) for point in NetworkCard.NUMBERS}
        good = True
        for point, word, row, label, age in self.cells:
            value = values[point]
            quality = "unknown" if value is None else value.quality
            label.set_text("-" if value is None else self.text(value, word))
            mark_quality(row, quality)
            if quality in ("stale", "offline"):
                good = False
                age.set_text(quality_note(quality, entry_age(value), self.lang))
            else:
                age.set_text("")
        return good


class BitrateCard(DrawnCard):
    """Write, save, switch the bus, restart: the bit rate changes only when all four are done."""

    view: ElectrakView

    def __init__(self, view: ElectrakView):
        super().__init__(view)
        self.param = PARAMS.get("service", BITRATE_SPECIFIER)
        self.bus_rate = view.fact(facts.P_BUS_BITRATE, codec.DEFAULT_BITRATE)
        self.steps: list = []

    def _step(self, text: str = ""):
        with ui.row().classes("items-center gap-2") as row:
            icon = ui.icon("radio_button_unchecked")
            label = ui.label(text).classes("text-body2")
        self.steps.append((icon, row))
        return row, label

    def build(self) -> None:
        view, state, bus_rate = self.view, self.view.state, self.bus_rate
        _ = view.lang.gettext
        others = [d.name for d in view.runtime.plant.devices_on(state.bus) if d.name != view.name]
        with titled_card(_("Change the bit rate")) as card:
            card.props("data-testid=bitrate-card")
            ui.label(_("Bus {bus} runs at {rate} kbit/s").format(bus=state.bus, rate=bus_rate // 1000)
                     + (_("; on it also: {list} (switch them alike, or they leave the bus).").format(list=", ".join(others))
                        if others else ".")
                     + (" " + _("Assumption (the document does not say): the actuators take a new bit rate when powered up "
                                "again.") if BITRATE_AT_POWER_UP else "")).classes("text-caption text-grey-8")
            with ui.column().classes("gap-1 w-full"):
                row, _label = self._step(_("1. Write the new bit rate and read it back from every actuator"))
                with row:
                    choice = ui.select({k: v for k, v in BITRATE_NAMES.items() if codec.BITRATES[k] != bus_rate}, value=None,
                                       label=_("new bit rate")).props("dense outlined options-dense data-testid=new-bitrate").classes("w-36")
                    self.guard.add(ui.button(_("Write"), on_click=lambda: _write_bitrate(view.name, self.param, choice.value,
                                                                                        view.lang)).props("dense"))
                row, _label = self._step(_("2. Save it (0xF0) on every actuator, or it is lost at power-off"))
                with row:
                    self.guard.add(ui.button(_("Save"), icon="save", on_click=lambda: save_parameters(view)).props("dense outline"))
                _row, self.switch_text = self._step()
                self._step(_("4. Restart commission with the changed plant file, then power-cycle the actuators; they come "
                             "back at the new bit rate"))
            self.status = ui.label().classes("text-body2").props("data-testid=bitrate-status")

    def inputs(self) -> tuple:
        state = self.view.state
        return (state.status, state.raw(self.param), self.param.key in state.unsaved,
                point_values(state, (facts.P_BITRATE_CHANGE, facts.P_HEARD, facts.P_CONFIGURED)))

    def draw(self) -> None:
        view, state, param, bus_rate = self.view, self.view.state, self.param, self.bus_rate
        _ = view.lang.gettext
        raw = state.raw(param)
        change = view.fact(facts.P_BITRATE_CHANGE)
        pending = raw if raw is not None and codec.BITRATES.get(raw) != bus_rate else (change.raw if change else None)
        target = codec.BITRATES.get(pending) if pending is not None else None
        heard_all = view.online() and view.fact(facts.P_HEARD) == view.fact(facts.P_CONFIGURED)
        written = target is not None
        saved = written and param.key not in state.unsaved and bool(change is None or change.saved)
        self.switch_text.set_text(_("3. Switch the bus: in the plant file set bitrate = {rate} for [[bus]] name = \"{bus}\"").format(
            rate=f"{target}" if target else _("<new rate>"), bus=state.bus))
        for (icon, _row), ok in zip(self.steps, [written, saved, False, False]):
            color = "positive" if ok else "grey"
            if icon.props.get("color") != color:  # runs on every push: nothing to send when unchanged
                icon.name = "check_circle" if ok else "radio_button_unchecked"
                icon.props(f"color={color}")
                icon.update()
        if not written:
            self.status.set_text(_("The actuators run at the bus's {rate} kbit/s.").format(rate=bus_rate // 1000)
                                 if raw is not None and heard_all
                                 else _("Read the bit rate (Read all) to see what the actuators hold."))
        elif not saved:
            self.status.set_text(_("{rate} written and read back, NOT saved: save it (step 2), or power-cycling the actuators "
                                   "brings back the old bit rate.").format(rate=BITRATE_NAMES.get(pending)))
        else:
            self.status.set_text(_("{rate} saved. The actuators switch at their next power-up: do steps 3 and 4 now, or they "
                                   "are lost to this bus after a power cut.").format(rate=BITRATE_NAMES.get(pending)))
        self.status.classes(replace="text-body2 " + ("text-warning" if written else "text-grey-8"))


async def _write_bitrate(name: str, param, code, lang=None) -> None:
    _ = (lang or i18n.get("en")).gettext
    if code is None:
        ui.notify(_("Choose the new bit rate first"), type="warning")
        return
    await write_from_page(name, param, int(code), success=_("{name} {value} written and read back from every actuator: now save it"),
                          title=_("Set the actuators' bit rate to {value}?"), ok=_("Write bit rate"), lang=lang)


def _export_csv(state, name: str, lang=None) -> None:
    """The history (position, current, speed, drive target) as a CSV file in the page's language."""
    units = dict(zip(SERIES, ("mm", "A", "mm/s", "mm")))
    shown = i18n.english(lang)
    head = [N_("time"), *(f"{shown.gettext(s)} [{units[s]}]" for s in SERIES)]
    rows = ([datetime.fromtimestamp(t).isoformat(timespec="milliseconds"), *(sample.get(s) for s in SERIES)]
            for t, sample in state.history)
    ui.download(csv_text(head, rows, lang).encode(), f"{name}-{datetime.now():%Y%m%d-%H%M%S}.csv", "text/csv")


def _export_png(chart, name: str) -> None:
    """The chart as drawn (position, current and speed), 1200x800 px."""
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    ui.run_javascript(
        f"const vm = getElement({chart.plot.id}); vm.Plotly.downloadImage(vm.$el,"
        f" {{format: 'png', filename: '{name}-{stamp}', width: 1200, height: 800}})"
    )
