"""Electrak HD network page: live charts, flags, control with keep-alive, service parameters."""

from __future__ import annotations

import csv
import inspect
import io
import time
from datetime import datetime

from nicegui import ui

from app import runtime as rt
from app import worker as worker_module
from devices.electrak import codec
from devices.electrak.adapter import FOREIGN_SENDER, SERIES
from devices.electrak.params import BITRATE_AT_POWER_UP, BITRATE_NAMES, BITRATE_SPECIFIER, PARAMS, password_of, refusal
from pages.frame import fmt_age, fmt_time, frame, set_status_badge
from pages.widgets import (
    sim_card_allowed,
    HistoryChart,
    Lamp,
    LiveValue,
    WriteGuard,
    checked_value,
    counter_line,
    event_log,
    follow,
    mark_quality,
    quality_note,
    range_number,
    refuse,
    run_command,
    stop_bar,
    write_from_page,
)

WINDOW_S = 60


TIMEOUT_BIT = 5  # error flags bit 5: Message timeout ("Fehler-Flags")


def content(name: str) -> None:
    runtime = rt.current()
    state = runtime.store.devices[name]
    adapter = runtime.worker.adapters[name]
    twin = runtime.twins.get(name)
    client = ui.context.client
    session = client.id

    async def act(describe: str, fn, success: str = "", write: bool = True):
        async def action(a):
            result = fn(a)
            return await result if inspect.isawaitable(result) else result

        result = await run_command(name, action, describe, success=success, write=write)
        refresh_now()  # what the command changed (control, enable) is shown at once, not at the next push
        return result

    def refresh_now() -> None:
        if updater:
            updater[0]()

    updater: list = []

    def release_on_disconnect() -> None:  # second line of defence; the worker's dead-man rule is the first
        adapter.session_lost(session, "the controlling browser disconnected")

    client.on_disconnect(release_on_disconnect)
    client.on_delete(release_on_disconnect)

    with frame(f"Electrak HD network {name}"):
        guard = WriteGuard(state)  # write and motion-start controls, disabled with the reason while the network is silent
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-6 w-full"):
                badge = ui.badge("waiting", color="grey").classes("text-body2")
                heard = ui.label().classes("text-body2")
                seen = ui.label().classes("text-body2")
                counter_line(state, lambda c: f"status frames {c.responses} · service requests {c.requests} · timeouts {c.timeouts} · "
                             f"error answers {c.exceptions} · malformed {c.malformed}")
            _numbers_grid(state, len(adapter.actuators))
            heard_warning = ui.label().classes("text-warning text-body2")
            saturated_warning = ui.label().classes("text-warning text-body2").props("data-testid=saturated-warning")
            limits = adapter.limits
            ui.label(
                "actuators: " + "; ".join(f"{a.model} {a.gearing} {a.stroke_mm:g} mm stroke" for a in adapter.actuators)
                + f" · accepted: 0..{limits.stroke_mm:g} mm, {limits.speed_min:g}..{limits.speed_max:g} mm/s, "
                f"0..{limits.current_a:g} A (0 = calibrated limit)"
            ).classes("text-caption text-grey-8")

        with ui.card().classes("w-full"):
            with ui.row().classes("gap-10 items-start"):
                with ui.column():
                    ui.label("Motion").classes("text-subtitle2")
                    motion_lamps = {bit: Lamp(n, "ok", text) for bit, (n, text) in codec.MOTION_FLAGS.items()}
                with ui.column():
                    ui.label("Faults").classes("text-subtitle2")
                    with ui.grid(columns=4).classes("gap-x-6 gap-y-1"):
                        error_lamps = {
                            bit: Lamp(n, "alarm", f"{text}. Clears: {clears}.") for bit, (n, text, clears) in codec.ERROR_FLAGS.items()
                        }
            fault_text = ui.column().classes("gap-0")
            idle_note = ui.label().classes("text-caption text-grey-8").props("data-testid=idle-note")

        with ui.row().classes("w-full no-wrap items-start gap-4"):
            with ui.card().classes("col-8"):
                with ui.row().classes("items-center w-full"):
                    ui.label(f"Position, current and speed (last {WINDOW_S} s, 100 ms frames)").classes("text-subtitle1")
                    ui.space()
                    ui.button("CSV", icon="download", on_click=lambda: _export_csv(state, name)).props("flat dense")
                    ui.button("PNG", icon="image", on_click=lambda: _export_png(chart, name)).props("flat dense")
                # one figure, three rows over one time axis: one drawing a second for all of them
                chart = HistoryChart(state, rows=[["Position [mm]", "Target [mm]"], ["Current [A]"], ["Speed [mm/s]"]],
                                     row_heights=(1.6, 1, 1), window_s=WINDOW_S, height=520)
                target_trace = chart.figure["data"][1]
                target_trace["line"] = {"dash": "dash", "color": "#c10015"}
                target_trace["mode"] = "lines"
                chart.figure["data"][3]["line"] = {"color": "#6a1b9a"}  # speed: not a second red beside the target
                chart.figure["layout"]["margin"]["b"] = 48  # room under the time axis for its date line, never clipped
                chart.plot.update()
            with ui.column().classes("col gap-4"):
                controls = _control_card(name, adapter, session, act, guard)
                if twin is not None:
                    _sim_card(twin)

        service_refresh = _service_card(name, state, adapter, guard)
        bitrate_refresh = _bitrate_card(name, state, adapter, runtime, guard)

        with ui.expansion("Events", icon="list", value=True).classes("w-full"):
            event_log(state)  # state changes, faults rising and clearing, offline and back, commands; newest first

    stop_bar("Clears enable at once; anyone may stop, also without control.", "STOP", "stop_circle",
             lambda: act("stop", lambda a: a.stop(session), write=False), "stop-bar", "big-stop").classes("text-h6")

    def online_now() -> bool:
        return state.status == "online"

    def update() -> None:
        set_status_badge(badge, state.status, state.age)
        info = state.info
        heard.set_text(f"actuators heard per 100 ms: {info.get('heard', 0)} of {info.get('configured')} configured")
        differs = state.status == "online" and info.get("heard") != info.get("configured")
        heard_warning.set_text(
            f"The network answers with {info.get('heard')} status telegrams per 100 ms, but {info.get('configured')} actuators are configured: "
            "check wiring and power, or the plant file." if differs else ""
        )
        saturated_warning.set_text(info.get("saturated_warning", "") if online_now() else "")
        seen.set_text(f"last status {fmt_age(state.age)}")
        online = state.status == "online"
        for bit, lamp in motion_lamps.items():
            lamp.show(state.point(codec.MOTION_FLAGS[bit][0]))
        for bit, lamp in error_lamps.items():
            lamp.show(state.point(codec.ERROR_FLAGS[bit][0]))
        # Message timeout while nobody sends 0x06 is the network's idle state: grey and explained, not a red fault
        idle = adapter.idle()
        if idle != idle_shown[0]:
            idle_shown[0] = idle
            timeout_lamp = error_lamps[TIMEOUT_BIT]
            if idle:
                timeout_lamp.dot.classes(remove="alarm").style("background: #9e9e9e; box-shadow: none")
            else:
                timeout_lamp.dot.classes(add="alarm").style(remove="background: #9e9e9e; box-shadow: none")
            timeout_lamp.row.props(f'data-idle="{int(idle)}"')
        idle_note.set_text("Message timeout is expected while idle: nobody sends the control telegram 0x06. "
                           "It clears with the first telegrams when you take control."
                           if idle and online and info.get("errors", 0) >> TIMEOUT_BIT & 1 else "")
        faults = tuple(bit for bit in codec.ERROR_FLAGS if online and info.get("errors", 0) >> bit & 1
                       and not (idle and bit == TIMEOUT_BIT))
        if faults != shown_faults[0]:  # rebuilt only when the faults change
            shown_faults[0] = faults
            fault_text.clear()
            with fault_text:
                for bit in faults:
                    fault, _text, clears = codec.ERROR_FLAGS[bit]
                    ui.label(f"{fault}: clears: {clears}").classes("text-negative text-body2")
        guard.update()
        controls()
        service_refresh()
        bitrate_refresh()

    shown_faults: list = [None]
    idle_shown: list = [None]
    updater.append(update)
    update()
    follow(state, update)  # on every change the store pushes (at most 10/s) and once a second for the ages


def _stop_rule() -> str:
    return (
        f"Stop rule: motion stops when a jog button is released, on Stop, and within {worker_module.DEADMAN_BOUND_S:g} s of this browser going away "
        "(closed, disconnected or frozen): enable is cleared and sent at once. Without control telegrams the actuators "
        "stop by themselves after their Timeout (250 ms by default)."
    )


def _control_card(name: str, adapter, session: str, act, guard: WriteGuard):
    limits = adapter.limits
    with ui.card().classes("w-full"):
        ui.label("Drive the network").classes("text-subtitle1")
        holder = ui.label().classes("text-body2")
        foreign = ui.label().classes("text-negative text-body2").props("data-testid=foreign-control")
        with ui.row():
            take = ui.button("Take control", icon="sports_esports",
                             on_click=lambda: act("take control", lambda a: a.take_control(session, "local engineer"))).props("data-testid=take-control")
            take.tooltip(f"Listens {codec.LISTEN_S:g} s for another sender of 0x06 first ({FOREIGN_SENDER}); refused if there is one")
            release = ui.button("Release", icon="logout",
                                on_click=lambda: act("release control", lambda a: a.release_control(session), write=False)).props("outline")
        # the ranges every actuator of the network accepts (codec.Limits: model, gearing, stroke): kept as typed, never clamped
        position = range_number("Target position [mm]", 0, limits.stroke_mm, unit="mm", value=0.0, step=0.1, fmt="%.1f") \
            .props("data-testid=target").classes("w-full")
        speed = range_number("Speed [mm/s]", limits.speed_min, limits.speed_max, unit="mm/s", value=limits.speed_max, step=0.1,
                             fmt="%.1f").props("data-testid=speed").classes("w-full")
        current = range_number("Current limit [A] (0 = calibrated)", 0, limits.current_a, unit="A", value=0.0, step=0.1,
                               fmt="%.1f").props("data-testid=current-limit").classes("w-full")

        async def entries(describe: str) -> tuple[float, float, float] | None:
            """Target, speed and limit as typed, or None: each bad one marked with its range, refused in the audit log."""
            values = [await checked_value(field, name, describe, parameter=parameter) for field, parameter in
                      ((position, "Target position"), (speed, "Target speed"), (current, "Current limit"))]
            return None if None in values else (float(values[0]), float(values[1]), float(values[2]))

        async def apply() -> bool:
            values = await entries("set target")
            if values is None:
                return False
            ok, _ = await act(f"set target: position {values[0]:g} mm, speed {values[1]:g} mm/s, current limit {values[2]:g} A"
                              + (" (calibrated)" if not values[2] else ""), lambda a: a.set_command(session, *values))
            return ok

        async def go() -> None:
            if await apply():
                await act(f"go: target {adapter.command.position_mm:g} mm, speed {adapter.command.speed_mm_s:g} mm/s, "
                          f"current limit {adapter.command.current_a:g} A", lambda a: a.go(session))

        with ui.row():
            apply_button = ui.button("Apply", on_click=apply).props("outline data-testid=apply")
            go_button = ui.button("Go", icon="play_arrow", color="positive", on_click=go).props("data-testid=go")
            ui.button("Stop", icon="stop", color="negative", on_click=lambda: act("stop", lambda a: a.stop(session), write=False)) \
                .props("data-testid=stop")
        ui.label("Jog (hold to run, stops when released)").classes("text-caption text-grey-8")
        with ui.row():
            jog_in = ui.button("In", icon="keyboard_double_arrow_left").props("outline data-testid=jog-in")
            jog_out = ui.button("Out", icon="keyboard_double_arrow_right").props("outline data-testid=jog-out")
            reset = ui.button("Override/reset").props("flat")

        def jog_start(direction: int):
            async def start() -> None:
                describe = f"jog {'out' if direction > 0 else 'in'}"
                value = await checked_value(speed, name, describe, parameter="Target speed")
                if value is None:
                    return
                await act(f"{describe}: speed {value:g} mm/s, current limit {adapter.command.current_a:g} A",
                          lambda a: a.jog(session, direction, float(value)))
            return start

        def jog_stop(a) -> None:
            if a.controller is not None and a.controller.session == session and a.command.enable:
                a.jog(session, 0)

        for button, direction in ((jog_in, -1), (jog_out, 1)):
            for event in ("mousedown", "touchstart"):
                button.on(event, jog_start(direction))
            for event in ("mouseup", "mouseleave", "touchend", "touchcancel"):
                button.on(event, lambda: act("jog stop", jog_stop, write=False))
        reset.on("mousedown", lambda: act("override", lambda a: a.override(session, True)))
        reset.on("mouseup", lambda: act("override", lambda a: a.override(session, False)))
        with ui.row().classes("items-start no-wrap gap-1 bg-blue-grey-1 q-pa-xs rounded-borders"):
            ui.icon("timer_off", size="xs").classes("q-mt-xs")
            ui.label(_stop_rule()).classes("text-caption").props("data-testid=stop-rule")
        sent = ui.label().classes("text-caption mono text-grey-8")

    def refresh() -> None:
        c = adapter.controller
        mine = c is not None and c.session == session
        if c is None:
            holder.set_text("nobody controls the network: control telegrams are off")
        elif mine:
            holder.set_text(f"you hold control since {datetime.fromtimestamp(c.since):%H:%M:%S}; control telegram every 100 ms")
        else:
            holder.set_text(f"{c.user} holds control (another browser) since {datetime.fromtimestamp(c.since):%H:%M:%S}")
        other = adapter.state.info.get("foreign_control")
        if other and adapter.foreign_sender(time.monotonic() - 2.0 + codec.LISTEN_S):  # shown for 2 s after the last one
            foreign.set_text(f"Another sender of the control telegram 0x06 is on the bus ({FOREIGN_SENDER}): "
                             f"{other['text']} · {other['frames']} frames. Take control is refused while it sends.")
        else:
            foreign.set_text("")
        offline = guard.reason  # motion and writes wait for a network that answers; the stops never do
        gate(take, offline or ("" if c is None else "you hold control" if mine else "another browser holds control"))
        gate(release, "" if mine else "you do not hold control")
        for element in (apply_button, go_button, jog_in, jog_out, reset):
            gate(element, offline or ("" if mine else "take control first"))
        cmd = adapter.command
        sent.set_text(f"0x006: {cmd.encode().hex(' ').upper()} (target {cmd.position_mm:g} mm, {cmd.speed_mm_s:g} mm/s, "
                      f"{cmd.current_a:g} A, {'enable' if cmd.enable else 'no enable'}{', override' if cmd.override else ''})")

    return refresh


def gate(control: ui.element, reason: str) -> None:
    """Enable ``control``, or disable it with ``reason`` as its tooltip (changed only when the reason changes)."""
    if getattr(control, "gate_reason", None) == reason:
        return
    control.gate_reason = reason  # type: ignore[attr-defined]
    control.set_enabled(not reason)
    if reason:
        text = reason.replace('"', "'")
        control.props(f'title="{text}" data-disabled-reason="{text}"')
    else:
        control.props(remove="title data-disabled-reason")


def _numbers_grid(state, configured: int) -> None:
    """Position, current and speed as numbers: the network's (mean, highest, mean) and each status telegram's."""

    def word(i: int, scale: float, unit: str):
        def fmt(entry: dict) -> str:
            raw = entry.get("raw") or []
            return f"{raw[i] * scale:.1f} {unit}" if i < len(raw) else "not heard"
        return fmt

    with ui.grid(columns=configured + 2).classes("items-baseline gap-x-6 gap-y-0").props("data-testid=numbers"):
        ui.label("")
        ui.label("network").classes("text-caption text-grey-8")
        for i in range(configured):
            ui.label(f"actuator {i + 1}").classes("text-caption text-grey-8").tooltip(
                "The n-th status telegram 0x07 of each 100 ms: the telegrams carry no actuator number (document, "
                "status telegram), so the columns follow the order heard.")
        for point, unit in (("Position", "mm"), ("Current", "A"), ("Speed", "mm/s")):
            ui.label(point).classes("text-body2 text-weight-medium")
            LiveValue(state, point, lambda e: f"{e['value']:.1f} {e['unit']} ({(e['text'] or '').split(' of ')[0]})",
                      classes="text-body1 mono").row.props(f"data-testid=network-{point.lower()}")
            for i in range(configured):
                LiveValue(state, point, word(i, 0.1, unit), classes="text-body1 mono") \
                    .row.props(f"data-testid=actuator-{i + 1}-{point.lower()}")  # words in 0.1 mm, 0.1 A, 0.1 mm/s


def _sim_card(twin) -> None:
    with ui.card().classes("w-full bg-purple-1"):
        ui.label("Simulated actuators (demo)").classes("text-subtitle1")
        if not sim_card_allowed():  # a viewer changes nothing, the simulated plant included
            return
        ui.label("Extra load current [A]").classes("text-caption")
        ui.slider(min=0, max=25, step=0.5, value=0, on_change=lambda e: twin.set_load(e.value)).props("label-always") \
            .classes("q-mt-lg")  # the value bubble stands above the track: room so it does not cover the label
        ui.label("Static load on a standing rod [mm/s, - pushes in]").classes("text-caption")
        ui.slider(min=-5, max=5, step=0.5, value=0, on_change=lambda e: twin.set_backdrive(e.value)).props("label-always") \
            .classes("q-mt-lg")
        with ui.row():
            for i in range(len(twin.actuators)):
                ui.switch(f"actuator {i + 1} connected", value=True,
                          on_change=lambda e, i=i: twin.restore(i) if e.value else twin.remove(i))
        with ui.row():
            ui.switch("Supply voltage fault", on_change=lambda e: [setattr(a, "voltage_fault", e.value) for a in twin.actuators])
            ui.switch("Temperature fault", on_change=lambda e: [setattr(a, "temperature_fault", e.value) for a in twin.actuators[:1]])
        with ui.row().classes("items-center"):
            ui.select({0: "off", 1: "out", -1: "in"}, value=0, label="Manual control line",
                      on_change=lambda e: twin.set_manual_line(e.value)).props("dense outlined options-dense").classes("w-40")
            if len(twin.actuators) > 1:
                ui.switch("last actuator disagrees", on_change=lambda e: _disagree(twin, e.value)).tooltip(
                    "its soft start time differs: reads of it fail, as they should")
        ui.button("Power-cycle actuators", icon="power_settings_new", on_click=twin.power_cycle).props("outline dense")


def _disagree(twin, on: bool) -> None:
    values = twin.actuators[-1].service.values
    values[0x01] = twin.actuators[0].service.values[0x01] + (100 if on else 0)


def _answers_text(report: dict | None) -> tuple[str, str]:
    """Short text and tooltip of the last exchange of one parameter with every actuator."""
    if not report:
        return "", ""
    answers = report["answers"]
    tip = "; ".join(f"answer {n}: {a}" for n, a in enumerate(answers, 1)) or "no answer"
    if report["ok"]:
        return f"{len(answers)} of {report['expected']} agree", tip
    return "; ".join(report["problems"]), tip


def _service_card(name: str, state, adapter, guard: WriteGuard):
    rows = {}
    with ui.card().classes("w-full"):
        with ui.row().classes("items-center w-full"):
            ui.label("Service parameters (0x0A / 0x0B)").classes("text-subtitle1")
            unsaved = ui.badge("", color="orange")
            ui.space()
            guard.add(
                ui.button("Read all", icon="refresh", on_click=lambda: run_command(name, lambda a: a.read_all(), "read service parameters", write=False)).props("outline"),
                ui.button("Save parameters (0xF0)", icon="save", on_click=lambda: _save(name)).props("data-testid=save-params"),
            )
        ui.label(f"The right password is written to 0xFF before each read or write. Each of the {len(adapter.actuators)} actuators answers "
                 "for itself: a read or write fails unless every one answers alike. Changes hold until power-off unless saved.").classes("text-caption text-grey-8")
        with ui.grid(columns=5).classes("w-full items-center gap-x-4 gap-y-1"):
            for h in ("Specifier", "Parameter", "Value (every actuator)", "New value", ""):
                ui.label(h).classes("text-caption text-grey-8")
            for p in PARAMS:
                ui.label(f"0x{p.address:02X} (password 0x{password_of(p):08X})").classes("mono text-caption")
                with ui.row().classes("items-center gap-1"):
                    ui.label(p.name).tooltip(p.description)
                    mark = ui.badge("unsaved", color="orange")
                with ui.column().classes("gap-0") as cell:
                    with ui.row().classes("items-baseline gap-0 no-wrap"):
                        value = ui.label("not read").classes("mono")
                        age = ui.label().classes("q-age").props(f"data-testid=age-{p.address:02X}")
                    with ui.label().classes("text-caption") as answers:
                        answers_tip = ui.tooltip("")
                if p.address == BITRATE_SPECIFIER:
                    ui.label("change it step by step below").classes("text-caption text-grey-8")
                    ui.element("span")
                else:
                    low, high = p.limits()
                    entry = range_number("", low, high, unit=p.unit, integer=p.scale == 1).classes("w-48") \
                        .props(f"data-testid=entry-{p.address:02X}")
                    guard.add(ui.button("Write", on_click=lambda p=p, entry=entry: _write_service(name, p, entry))
                              .props(f"dense data-testid=write-{p.address:02X}"))
                rows[p.key] = (p, value, mark, answers, answers_tip, cell, age)
        last = ui.label().classes("text-caption mono text-grey-8")
        form = ui.label().classes("text-caption text-grey-8")

    def refresh() -> None:
        reports = state.info.get("service_reports", {})
        now = time.time()
        for key, (p, value, mark, answers, answers_tip, cell, age) in rows.items():
            raw = state.raw(p)
            report = reports.get(key)
            value.set_text(("not read" if not report or report["ok"] else "no common value") if raw is None else p.display(raw))
            read = state.read_time(p)
            quality = state.quality(read, False, now)  # read on demand: good while the network answers
            mark_quality(cell, quality if raw is not None else "unknown")
            note = quality_note(quality, None if read is None else now - read) if quality in ("stale", "offline") else ""
            age.set_text(note or (f"read {fmt_time(read)}" if read is not None and raw is not None else ""))
            text, tip = _answers_text(report)
            answers.set_text(text)
            answers.classes(replace="text-caption " + ("text-grey-8" if not report or report["ok"] else "text-negative"))
            answers_tip.set_text(tip)
            mark.set_visibility(key in state.unsaved)
        unsaved.set_text(f"{len(state.unsaved)} unsaved")
        unsaved.set_visibility(bool(state.unsaved))
        report = state.info.get("service_last")
        last.set_text("" if not report else f"last service telegram: {report['what']} at {fmt_time(report['time'])}: "
                      + ("; ".join(f"answer {n}: {a}" for n, a in enumerate(report["answers"], 1)) or "no answer")
                      + ("" if report["ok"] else " - " + "; ".join(report["problems"])))
        form.set_text(f"last save: the network accepted the {state.info['save_form']}" if state.info.get("save_form") else
                      f"Save sends the {codec.SAVE_FORMS[codec.SAVE_LENGTHS[0]]} and, on WRONG_SIZE, once the {codec.SAVE_FORMS[codec.SAVE_LENGTHS[1]]}.")

    return refresh


async def _save(name: str) -> None:
    ok, form = await run_command(name, lambda a: a.save_parameters(), "save parameters")
    if ok:
        ui.notify(f"parameters saved: the network accepted the {form}", type="positive")


async def _write_service(name: str, param, entry) -> None:
    value = await checked_value(entry, name, f"write {param.name}", parameter=param.name)
    if value is None:
        return
    reason = refusal(param, value)  # beyond the range: the document's own refusals (params.refusal)
    if reason:
        entry.error = reason
        await refuse(name, f"write {param.name}", reason, parameter=param.name, new=value)
        return
    await write_from_page(name, param, value, success="{name} = {value} written and read back from every actuator",
                          title="Set {name} to {value}?", ok="Change bit rate", field=entry)


def _bitrate_card(name: str, state, adapter, runtime, guard: WriteGuard):
    """Write, save, switch the bus, restart: the bit rate changes only when all four are done."""
    param = PARAMS.get("service", BITRATE_SPECIFIER)
    bus = adapter.bus
    bus_rate = bus.options.get("bitrate", codec.DEFAULT_BITRATE)
    others = [d.name for d in runtime.plant.devices_on(state.bus) if d.name != name]
    with ui.card().classes("w-full").props("data-testid=bitrate-card"):
        ui.label("Change the bit rate").classes("text-subtitle1")
        ui.label(f"Bus {state.bus} runs at {bus_rate // 1000} kbit/s"
                 + (f"; on it also: {', '.join(others)} (switch them alike, or they leave the bus)." if others else ".")
                 + (" Assumption (the document does not say): the actuators take a new bit rate when powered up again."
                    if BITRATE_AT_POWER_UP else "")).classes("text-caption text-grey-8")
        steps = []
        with ui.column().classes("gap-1 w-full"):
            with ui.row().classes("items-center gap-2") as row:
                icon = ui.icon("radio_button_unchecked")
                ui.label("1. Write the new bit rate and read it back from every actuator").classes("text-body2")
                choice = ui.select({k: v for k, v in BITRATE_NAMES.items() if codec.BITRATES[k] != bus_rate}, value=None,
                                   label="new bit rate").props("dense outlined options-dense data-testid=new-bitrate").classes("w-36")
                guard.add(ui.button("Write", on_click=lambda: _write_bitrate(name, param, choice.value)).props("dense"))
            steps.append((icon, row))
            with ui.row().classes("items-center gap-2") as row:
                icon = ui.icon("radio_button_unchecked")
                ui.label("2. Save it (0xF0) on every actuator, or it is lost at power-off").classes("text-body2")
                guard.add(ui.button("Save", icon="save", on_click=lambda: _save(name)).props("dense outline"))
            steps.append((icon, row))
            with ui.row().classes("items-center gap-2") as row:
                icon = ui.icon("radio_button_unchecked")
                switch_text = ui.label().classes("text-body2")
            steps.append((icon, row))
            with ui.row().classes("items-center gap-2") as row:
                icon = ui.icon("radio_button_unchecked")
                ui.label("4. Restart commission with the changed plant file, then power-cycle the actuators; they come back "
                         "at the new bit rate").classes("text-body2")
            steps.append((icon, row))
        status = ui.label().classes("text-body2").props("data-testid=bitrate-status")

    def refresh() -> None:
        raw = state.raw(param)
        change = state.info.get("bitrate_change")
        pending = raw if raw is not None and codec.BITRATES.get(raw) != bus_rate else (change or {}).get("raw")
        target = codec.BITRATES.get(pending) if pending is not None else None
        heard_all = state.status == "online" and state.info.get("heard") == state.info.get("configured")
        written = target is not None
        saved = written and param.key not in state.unsaved and bool(change is None or change.get("saved"))
        done = [written, saved, False, False]
        switch_text.set_text("3. Switch the bus: in the plant file set bitrate = "
                             + (f"{target}" if target else "<new rate>") + f" for [[bus]] name = \"{state.bus}\"")
        for (icon, _row), ok in zip(steps, done):
            color = "positive" if ok else "grey"
            if icon.props.get("color") != color:  # runs on every push: nothing to send when unchanged
                icon.name = "check_circle" if ok else "radio_button_unchecked"
                icon.props(f"color={color}")
                icon.update()
        if not written:
            status.set_text(f"The actuators run at the bus's {bus_rate // 1000} kbit/s." if raw is not None and heard_all
                            else "Read the bit rate (Read all) to see what the actuators hold.")
        elif not saved:
            status.set_text(f"{BITRATE_NAMES.get(pending)} written and read back, NOT saved: save it (step 2), or power-cycling "
                            "the actuators brings back the old bit rate.")
        else:
            status.set_text(f"{BITRATE_NAMES.get(pending)} saved. The actuators switch at their next power-up: do steps 3 and 4 "
                            "now, or they are lost to this bus after a power cut.")
        status.classes(replace="text-body2 " + ("text-warning" if written else "text-grey-8"))

    return refresh


async def _write_bitrate(name: str, param, code) -> None:
    if code is None:
        ui.notify("Choose the new bit rate first", type="warning")
        return
    await write_from_page(name, param, int(code), success="{name} {value} written and read back from every actuator: now save it",
                          title="Set the actuators' bit rate to {value}?", ok="Write bit rate")


def _export_csv(state, name: str) -> None:
    out = io.StringIO()
    writer = csv.writer(out)
    writer.writerow(["time", *SERIES])
    for t, sample in state.history:
        writer.writerow([datetime.fromtimestamp(t).isoformat(timespec="milliseconds"), *(sample.get(s) for s in SERIES)])
    ui.download(out.getvalue().encode(), f"{name}-{datetime.now():%Y%m%d-%H%M%S}.csv", "text/csv")


def _export_png(chart, name: str) -> None:
    """The chart as drawn (position, current and speed), 1200x800 px."""
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    ui.run_javascript(
        f"Plotly.downloadImage(getElement({chart.plot.id}).$el,"
        f" {{format: 'png', filename: '{name}-{stamp}', width: 1200, height: 800}})"
    )
