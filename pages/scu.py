"""Ewellix SCU page: live positions and status, remote session, drive by function, data directory, service table."""

from __future__ import annotations

import time
from datetime import datetime

from nicegui import ui

from app import runtime as rt
from app import worker as worker_module
from devices.scu import codec
from devices.scu import params as p
from devices.scu.adapter import SERVICE_IDS
from pages.electrak import gate
from pages.frame import fmt_age, fmt_time, frame, set_status_badge
from pages.widgets import (
    HistoryChart,
    Lamp,
    LiveValue,
    WriteGuard,
    checked_value,
    counter_line,
    entry_age,
    event_log,
    follow,
    mark_quality,
    quality_note,
    range_number,
    confirm,
    run_command,
    session_role,
    stop_bar,
)

STATUS_1 = ("present", "limit_in_out", "switch_1", "switch_2", "motion", "in_position", "out_position", "stroke_recorded")
STATUS_2 = ("initialised", "enable_in", "enable_out")
SWITCHES = ((codec.Function.BUZZER, "Buzzer"), (codec.Function.BINARY_OUTPUT_1, "Binary output 1"),
            (codec.Function.BINARY_OUTPUT_2, "Binary output 2"), (codec.Function.LED_1, "Operating unit LED1"),
            (codec.Function.LED_2, "Operating unit LED2"))


def _stop_rule() -> str:
    return (f"Every RE (Go, jog, function on) is followed by its RS: on Stop, on release of a jog button, on release "
            f"of control, and within {worker_module.DEADMAN_BOUND_S:g} s when this browser closes, disconnects or "
            "freezes (dead-man rule), and after a lost session, even when the actuator stopped at its end position "
            "(section 4.6). Without RC for 500 ms the unit itself stops and leaves remote mode.")


def content(name: str) -> None:
    runtime = rt.current()
    state = runtime.store.devices[name]
    adapter = runtime.worker.adapters[name]
    client = ui.context.client
    session = client.id
    viewer = session_role() == "viewer"
    n_act = len(adapter.scales)

    async def act(command: str, args: dict | None = None, success: str = "", confirmed: bool = False, title: str = "",
                  ok: str = "Send"):
        """Invoke the SCU's declared command ``command`` (devices/scu/policy.py) through the worker's gate."""
        result = await run_command(name, command, args=args, session=session, success=success, confirmed=confirmed,
                                   title=title, ok=ok)
        if updater:
            updater[0]()  # what the command changed (control, RE/RS pending) is shown at once
        return result

    updater: list = []

    def on_gone() -> None:  # second line of defence; the worker's dead-man rule is the first
        adapter.session_lost(session, "the controlling browser disconnected")

    client.on_disconnect(on_gone)
    client.on_delete(on_gone)

    with frame(f"Ewellix SCU {name}"):
        guard = WriteGuard(state)  # the reason write and motion-start controls are off while the unit does not answer
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-6 w-full"):
                badge = ui.badge("waiting", color="grey").classes("text-body2")
                session_label = ui.label().classes("text-body1").props("data-testid=session")
                period = ui.label().classes("text-body2").props("data-testid=rc-period")
                counter_line(state, lambda c: f"requests {c.requests} · answers {c.responses} · timeouts {c.timeouts} · bad CRC "
                             f"{c.crc_errors} (retried) · error answers {c.exceptions} · seen {fmt_age(state.age)}")
            cyclic = ui.label().classes("text-caption")
            refusal = ui.label().classes("text-warning text-body2").props("data-testid=refusal")
            error_line = ui.label().classes("text-negative text-body2")
            ui.label(f"Line {adapter.port} at {adapter.baudrate} baud 8N1. DTR and RTS are switched on when the port "
                     "opens and kept on: they power the unit's RS232 converter (section 3).").classes("text-caption text-grey-8")
            with ui.expansion(f"Safety_ID {int(adapter.safety_id)} (RO): what the unit does on a communication timeout") \
                    .classes("w-full text-caption"):
                for sid, text in codec.SAFETY_MODES.items():
                    ui.label(f"{int(sid)}: {text}" + ("  ← this plant" if sid == adapter.safety_id else "")) \
                        .classes("text-caption" + (" text-weight-bold" if sid == adapter.safety_id else ""))
            with ui.row():
                release_scu = ui.button("Release the SCU (RA)", icon="pan_tool",
                                        on_click=lambda: act("release the SCU (RA)", success="released: the hand switch has the unit")) \
                    .props("outline data-testid=release-scu")
                reopen = ui.button("Open the remote session", icon="link",
                                   on_click=lambda: act("open remote session")).props("outline")

        # -- positions --------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            ui.label("Positions").classes("text-subtitle1")
            pos_rows = []
            with ui.grid(columns=3).classes("w-full gap-x-4 gap-y-1 items-center").style("grid-template-columns: 60px 1fr 280px"):
                for s in adapter.scales:
                    ui.label(f"A{s.number}").classes("text-body1")
                    bar = ui.linear_progress(value=0, show_value=False).props("size=14px rounded")
                    with ui.row().classes("items-baseline gap-0 no-wrap") as cell:
                        text = ui.label("-").classes("mono").props(f"data-testid=pos-A{s.number}")
                        age = ui.label().classes("q-age")
                    pos_rows.append((s.number, bar, text, cell, age))
            chart = HistoryChart(state, adapter.series, window_s=60, height=260)

        # -- status per actuator ------------------------------------------------------------------
        with ui.card().classes("w-full"):
            ui.label("Actuator status 1 (0x0171..) and 2 (0x00E1..), current (0x00A1..), speed (0x00F1..)").classes("text-subtitle1")
            lamps: dict[str, Lamp] = {}
            with ui.row().classes("gap-8 items-start"):
                for n in range(1, n_act + 1):
                    with ui.column().classes("gap-0"):
                        ui.label(f"A{n}").classes("text-subtitle2")
                        for key in STATUS_1 + STATUS_2:
                            lamps[f"A{n} {key}"] = Lamp(f"A{n} {key}", "ok")
                        for what in ("current", "speed"):
                            LiveValue(state, f"A{n} {what}", lambda e, what=what: f"{what}: {e['value']:g} {e['unit']}".strip(),
                                      classes="mono text-body2").row.props(f"data-testid={what}-A{n}")

        # -- supply, I/O -----------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            ui.label("Supply and I/O").classes("text-subtitle1")
            with ui.row().classes("gap-6"):
                for key in ("Mains", "Battery", "Charger on", "Charging", "Output 1", "Output 2", "Buzzer", "Sensor supply"):
                    lamps[key] = Lamp(key, "ok")
            with ui.column().classes("gap-0 mono text-body2"):  # one line per point, changed in place
                io_lines = {key: ui.label() for key in IO_POINTS}

        # -- errors -----------------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            ui.label("Error code (0x00D1) and history (0x00D2..0x00D5), bit n = mask 1 << (n-1)").classes("text-subtitle1")
            error_rows = {}  # per register: its line, and its bits (rebuilt only when the value changes)
            with ui.column().classes("gap-1").props("data-testid=errors"):
                for key in ERROR_POINTS:
                    with ui.column().classes("gap-1") as box:
                        error_rows[key] = (box, ui.label().classes("text-body2 text-weight-medium"), ui.column().classes("gap-1"))

        # -- drive --------------------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            ui.label("Drive").classes("text-subtitle1")
            with ui.row().classes("items-center gap-4"):
                take = ui.button("Take control", icon="sports_esports",
                                 on_click=lambda: act("take control", {"user": client_user()})) \
                    .props("data-testid=take-control")
                release = ui.button("Release control", icon="logout",
                                    on_click=lambda: act("release control")) \
                    .props("outline")
                holder = ui.label().classes("text-body2")
            with ui.row().classes("items-end gap-4"):
                fn_select = ui.select({int(f): f"{codec.FUNCTIONS[f].label} → "
                                       + (", ".join(f"A{a}" for a in adapter.actuators_of(f)) or "none")
                                       for f in codec.MOTION_FUNCTIONS}, value=0,
                                      label="Function → actuators").classes("w-40").props("data-testid=function")
                motion = ui.select({int(m): codec.MOTION_LABELS[m] for m in codec.Motion}, value=int(codec.Motion.REMOTE_POSITION),
                                   label="Motion (para_ID[0])").classes("w-72")
                ramp = ui.select({1: "soft start/stop", 0: "fast start/stop", 255: "as configured (-1)"}, value=1,
                                 label="Ramp (para_ID[1])").classes("w-48")
                # table 7: relative 0 .. 100 %, absolute 0 .. 1000 counts/s, as the unit is parametrised (plant file)
                speed = range_number(f"Remote speed [{adapter.speed_unit}]", 0, adapter.speed_max, integer=True,
                                     value=50, step=1) \
                    .classes("w-56").props("data-testid=remote-speed")

                async def write_speed() -> None:
                    function = fn_select.value + 1
                    value = await checked_value(speed, name, f"set remote speed F{function}", parameter=f"Remote Speed F{function}")
                    if value is not None:
                        await act("set remote speed", {"function": function, "speed": int(value)},
                                  success="remote speed written and read back")

                set_speed = ui.button("Set speed (RT)", on_click=write_speed).props("outline data-testid=set-speed")
            drives = ui.label().classes("text-body2").props("data-testid=function-actuators")
            target_warning = ui.label().classes("text-warning text-body2").props("data-testid=target-warning")
            edited: list[int] = []  # the actuator whose remote position was set last on this page
            pos_inputs = []
            with ui.row().classes("items-end gap-4"):
                for s in adapter.scales:
                    unit = "mm" if s.counts_per_mm or s.stroke_mm else "counts"
                    low, high = _position_range(s)
                    field = range_number(f"A{s.number} remote position [{unit}]", low, high, unit=unit, value=0,
                                         integer=unit == "counts").classes("w-56").props(f"data-testid=remote-pos-A{s.number}")

                    async def write_position(s=s, field=field, unit=unit) -> None:
                        value = await checked_value(field, name, f"set remote position A{s.number}",
                                                    parameter=f"Remote Position A{s.number}")
                        if value is None:
                            return
                        ok, _ = await act("set remote position", {"actuator": s.number, "value": float(value),
                                                                  "mm": unit == "mm"},
                                          success="remote position written and read back")
                        if ok:
                            edited[:] = [s.number]
                            show_targets()

                    btn = ui.button("Set (RT)", on_click=write_position).props(f"outline data-testid=set-pos-A{s.number}")
                    pos_inputs.append(btn)
            with ui.row().classes("items-center gap-4"):
                go = ui.button("Go (RE)", icon="play_arrow", color="positive", on_click=lambda: go_pressed()) \
                    .props("data-testid=go")
                ui.button("Stop (RS)", icon="stop", color="negative",
                          on_click=lambda: act("stop (RS)")).props("data-testid=stop")
                ui.label("Jog (hold to run):").classes("text-caption")
                jog_in = ui.button("In", icon="keyboard_double_arrow_left").props("outline data-testid=jog-in")
                jog_out = ui.button("Out", icon="keyboard_double_arrow_right").props("outline data-testid=jog-out")

            def ramp_value() -> int:
                return ramp.value if ramp.value != 255 else -1

            async def go_pressed() -> None:
                pressed = time.monotonic()  # a Stop after this moment cancels the RE, or follows it at once
                fn = fn_select.value
                acts = adapter.actuators_of(fn)
                warning = target_mismatch()
                if not await confirm(
                        "Start the motion",
                        f"{codec.FUNCTIONS[fn].label} drives {adapter.functions_text(fn)}: "
                        f"{codec.MOTION_LABELS[motion.value]}. Check that the area is clear: nobody and nothing in "
                        "the stroke of " + (", ".join(f"A{a}" for a in acts) or "its actuators") + "."
                        + (f" {warning}" if warning else ""), ok="The area is clear: Go"):
                    return
                # the question above names the declared risk (the area is clear), with the actuators it drives
                await act("go (RE)", {"function": fn, "motion": motion.value, "ramp": ramp_value(),
                                      "requested_at": pressed}, confirmed=True)

            jog_held: dict[int, bool] = {}

            def jog(direction: int):
                def press():
                    pressed = time.monotonic()  # before any await: a release after it cancels or follows the RE
                    fn = fn_select.value
                    jog_held[fn] = True
                    return act("jog (RE)", {"function": fn, "direction": direction, "ramp": ramp_value(),
                                            "requested_at": pressed})
                return press

            def jog_release():
                held = [fn for fn, on in jog_held.items() if on]
                jog_held.clear()
                if not held:
                    return None  # a mouse passing over the button: nothing was pressed
                return _release_all(held)

            async def _release_all(held):
                for fn in held:
                    await act("jog stop (RS)", {"function": fn})

            for button, direction in ((jog_in, -1), (jog_out, 1)):
                for event in ("mousedown", "touchstart"):
                    button.on(event, jog(direction))
                for event in ("mouseup", "mouseleave", "touchend", "touchcancel"):
                    button.on(event, jog_release)
            with ui.row().classes("items-start no-wrap gap-1 bg-blue-grey-1 q-pa-xs rounded-borders"):
                ui.icon("timer_off", size="xs").classes("q-mt-xs")
                ui.label(_stop_rule()).classes("text-caption").props("data-testid=stop-rule")
            running = ui.label().classes("text-caption mono")
            drive_off = ui.label().classes("text-negative text-body2").props("data-testid=drive-off")

        # -- functions ----------------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            ui.label("Functions (firmware V2B1 and later)").classes("text-subtitle1")
            switches, switches_off = [], []
            with ui.row().classes("items-center gap-4"):
                for fn, label in SWITCHES:
                    with ui.button_group():
                        b_on = ui.button(f"{label} on", on_click=lambda fn=fn: act(
                            "function on (RE)", {"function": int(fn)})).props("outline")
                        b_off = ui.button("off", on_click=lambda fn=fn: act(
                            "function off (RS)", {"function": int(fn)})).props("outline")
                    switches.append(b_on)
                    switches_off.append(b_off)
            with ui.row().classes("items-center gap-4"):
                ui.button("Emergency stop (function 19)", icon="emergency", color="negative",
                          on_click=lambda: act("emergency stop (RE 19)")) \
                    .props("data-testid=emergency-stop")
                release_estop = ui.button("Release emergency stop (RS 19)", on_click=lambda: act(
                    "release emergency stop (RS 19)", title="Release the emergency stop?", ok="Release it")).props("outline")
                ui.label("Emergency stop acts at once, without confirmation.").classes("text-caption")

        # -- data directory -----------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            ui.label("Data directory (section 4.3): read any data ID or group ID").classes("text-subtitle1")
            rows = [{"id": e.key, "name": e.name, "type": e.type_name, "unit": e.unit, "access": e.access.value,
                     "comment": e.comment} for e in p.DIRECTORY.values()]
            table = ui.table(columns=[{"name": k, "label": k.capitalize(), "field": k, "align": "left"}
                                      for k in ("id", "name", "type", "unit", "access", "comment")],
                             rows=rows, row_key="id", selection="single", pagination=10).classes("w-full text-caption")
            table.props("dense wrap-cells")
            with ui.row().classes("items-center gap-4"):
                pick = ui.select({e.data_id: f"{e.key} {e.name}" for e in p.DIRECTORY.values()}, value=0x0010,
                                 label="Data ID", with_input=True).classes("w-96").props("data-testid=data-id")
                table.on("selection", lambda e: pick.set_value(int(e.args["rows"][0]["id"], 16)) if e.args.get("rows") else None)

                async def read_one() -> None:
                    ok, result = await act("read data", {"data_id": pick.value})
                    if ok:
                        shown.set_text(f"{result['key']} {result['name']} ({result['type']}): "
                                       f"{result['text'] or result['error']}")
                        raw.set_text(f"raw: {result['raw'] or '(no data)'}")

                read_button = ui.button("Read (RG)", on_click=read_one).props("data-testid=read-data")
            shown = ui.label().classes("mono text-body2").props("data-testid=data-value")
            raw = ui.label().classes("mono text-caption text-grey-8").props("data-testid=data-raw")

        # -- service table -----------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            ui.label("Service table").classes("text-subtitle1")
            service = ui.table(columns=[{"name": k, "label": k.capitalize(), "field": k, "align": "left"}
                                        for k in ("id", "name", "value", "read")], rows=[], row_key="id").classes("w-full text-caption")
            service.props('dense wrap-cells data-testid=service-table :table-row-class-fn="row => row.quality_class"')

            async def read_service() -> None:
                ids = list(SERVICE_IDS) + [0x2000 + s.number for s in adapter.scales]
                out = []
                for data_id in ids:
                    ok, result = await act("read data", {"data_id": data_id})
                    if not ok:
                        break
                    out.append({"id": result["key"], "name": result["name"], "value": result["text"] or result["error"],
                                "time": time.time(), "read": "", "quality_class": ""})
                service.rows = out
                service_ages()

            read_service_button = ui.button("Read service data (RG)", on_click=read_service) \
                .props("outline data-testid=read-service")
            ui.label("Backup: the Backup page writes a snapshot of identity, counters, conversion factors and user "
                     f"position data. There is no restore: {adapter.restore_refused}.").classes("text-caption text-grey-8")

        with ui.expansion("Events", icon="list", value=True).classes("w-full"):
            event_log(state)  # session changes, error answers, offline and back, commands; newest first

    stop_bar("RS to every running function; anyone may stop, also without control.", "STOP", "stop_circle",
             lambda: act("stop (RS)"), "stop-bar", "big-stop").classes("text-h6")

    def client_user() -> str:
        from pages.session import current_user

        return current_user()[0] or "anonymous"

    def point(key: str):
        return state.point(key)

    def service_ages() -> None:
        """The service table's rows with the time of their reading; greyed with their age while the unit does not answer."""
        quality = "offline" if state.status == "offline" else "good"
        now = time.time()
        rows = [{**row, "read": quality_note(quality, now - row["time"]) if quality == "offline" else fmt_time(row["time"]),
                 "quality_class": "q-offline" if quality == "offline" else ""} for row in service.rows]
        if rows != service.rows:
            service.rows = rows
            service.update()

    last_view: dict = {}

    def changed(key: str, value) -> bool:
        if last_view.get(key) == value:
            return False
        last_view[key] = value
        return True

    def refresh() -> None:
        info = state.info
        set_status_badge(badge, state.status, state.age)
        sess = info.get("session", "closed")
        session_label.set_text(f"remote session: {sess}" + (f" ({info['session_reason']})" if info.get("session_reason") else ""))
        cyclic.set_text(" · ".join(x for x in (info.get("watch") or "", info.get("cyclic") or "") if x))
        r = info.get("last_refusal")
        refusal.set_text(f"last error answer: {r['name']} ({r['title']}) to {r['command']}: {r['meaning']}. What to do: {r['remedy']}"
                         if r else "")
        error_line.set_text(state.last_error if state.online is False else "")
        for number, bar, text, cell, age in pos_rows:
            e = point(f"A{number} position")
            lo, hi = point(f"A{number} in end"), point(f"A{number} out end")
            quality = "unknown" if e is None else e["quality"]
            mark_quality(cell, quality)  # greyed, with its age, while stale or offline
            mark_quality(bar, quality)
            age.set_text(quality_note(quality, entry_age(e)) if quality in ("stale", "offline") else "")
            if e is None:
                text.set_text("-")
                continue
            text.set_text(e["text"] or str(e["value"]))
            if lo and hi and hi["value"] != lo["value"]:
                bar.set_value(max(0.0, min(1.0, (e["value"] - lo["value"]) / (hi["value"] - lo["value"]))))
        for key, lamp in lamps.items():
            lamp.show(point(key))
        for key, line in io_lines.items():
            e = point(key)
            line.set_visibility(e is not None)
            if e is not None:
                line.set_text(f"{key}: {e['text'] or e['value']} {e['unit']}".strip())
                mark_quality(line, e["quality"])
        for key, (box, line, bits) in error_rows.items():
            e = point(key)
            box.set_visibility(e is not None)
            if e is None:
                continue
            value = int(e["value"])
            line.set_text(f"{key}: 0x{value:08X}")
            mark_quality(line, e["quality"])
            mark_quality(bits, e["quality"])
            if changed(key, value):
                bits.clear()
                with bits:
                    for b in codec.error_bits(value):
                        ui.label(f"bit {b.bit}: {b.cause}" + (f" — condition: {b.condition}" if b.condition else "")
                                 + f" — behaviour: {b.behaviour}").classes("text-caption text-negative" if key == "Error code" else "text-caption")
        ctrl = adapter.controller
        mine = ctrl is not None and ctrl.session == session
        if ctrl is None:
            holder.set_text("nobody holds control")
        elif mine:
            holder.set_text(f"you hold control since {datetime.fromtimestamp(ctrl.since):%H:%M:%S}")
        else:
            holder.set_text(f"{ctrl.user} holds control (another browser) since {datetime.fromtimestamp(ctrl.since):%H:%M:%S}")
        run = [codec.FUNCTIONS[codec.Function(f)].label for f in sorted(adapter.running)]
        failed = [codec.FUNCTIONS[codec.Function(f)].label for f in sorted(adapter.rs_pending)]
        running.set_text("RE sent, RS pending: " + (", ".join(run) if run else "none")
                         + (f" · STOP FAILED, RS not acknowledged (sent again every poll): {', '.join(failed)}" if failed else ""))
        guard.update()
        offline = guard.reason  # writes and motion wait for a unit that answers; the stops never do
        lost = ""  # a lost or released session: nothing reaches the unit until it is open again
        if sess in ("lost", "released"):
            lost = (f"the remote session is {sess}" + (f" ({info['session_reason']})" if info.get("session_reason") else "")
                    + ("; it is reopened with backoff, or press \"Open the remote session\"" if sess == "lost"
                       else "; press \"Open the remote session\" to drive again"))
        estop = "the emergency stop (function 19) is on: release it first" if info.get("emergency_stop") else ""
        drive_off.set_text(f"Drive off: {lost or offline or estop}" if (offline or lost or estop) and mine else "")
        show_targets()
        role = "a viewer cannot change anything" if viewer else ""
        gate(take, role or offline or ("" if ctrl is None else "you hold control" if mine else "another browser holds control"))
        gate(release, role or ("" if mine else "you do not hold control"))
        for element in (set_speed, go, jog_in, jog_out, *pos_inputs, *switches):
            gate(element, role or lost or offline or estop or ("" if mine else "take control first"))
        gate(release_estop, role or lost or offline or ("" if mine else "take control first"))
        for element in switches_off:
            gate(element, role or ("" if mine else "take control first"))
        for element in (read_button, read_service_button):
            gate(element, role or offline or (lost if adapter.watch != "rg" else ""))
        for element in (reopen, release_scu):  # opening again is how a session recovers; RA hands the unit back
            gate(element, role)
        service_ages()

    def show_period() -> None:  # a statistic of every RC: once a second
        info = state.info
        period.set_text(f"RC period {info['rc_period_ms']:g} ms, longest gap {info['rc_max_gap_ms']:g} ms"
                        if info.get("rc_period_ms") is not None else "RC period: -")

    def target_mismatch() -> str:
        fn = fn_select.value
        acts = adapter.actuators_of(fn)
        if motion.value == int(codec.Motion.REMOTE_POSITION) and edited and edited[0] not in acts:
            return (f"The remote position you set last is A{edited[0]}'s, but {codec.FUNCTIONS[fn].label} drives "
                    + (", ".join(f"A{a}" for a in acts) or "no actuator") + f": A{edited[0]} will not move.")
        return ""

    def show_targets() -> None:
        fn = fn_select.value
        drives.set_text(f"{codec.FUNCTIONS[fn].label} drives {adapter.functions_text(fn)}")
        target_warning.set_text(target_mismatch())

    fn_select.on_value_change(lambda _: show_targets())
    motion.on_value_change(lambda _: show_targets())
    updater.append(refresh)
    refresh()
    show_period()
    follow(state, refresh)  # on every change the store pushes (at most 10/s) and once a second for the ages
    follow(state, show_period, slow=True)


IO_POINTS = ("Battery voltage", "Actual_State_Binary Inputs 1 ... 4", "Analogue input 1", "Analogue input 2",
             "Analogue input 3", "Analogue input 4", "Binary Output Status", "LED HS", "LED LB",
             "Lock Status", "Locking Box detected", "Benutzer")
ERROR_POINTS = ("Error code", "Error history 1", "Error history 2", "Error history 3", "Error history 4")


def _position_range(scale) -> tuple[float, float]:
    """What a remote position entry accepts: INT32 counts (table 7), in mm through the actuator's conversion
    (0 .. stroke when the stroke is known)."""
    low, high = -(2 ** 31), 2 ** 31 - 1
    if scale.stroke_mm:
        return 0.0, float(scale.stroke_mm)
    if scale.counts_per_mm:
        return round(low / scale.counts_per_mm, 1), round(high / scale.counts_per_mm, 1)
    return low, high
