"""HD-Lock page: status lamps, live chart, parameters, system commands, register tables."""

from __future__ import annotations

from nicegui import ui

from app import runtime as rt
from devices.hdlock import codec
from devices.hdlock.adapter import CHART_SERIES
from devices.hdlock.params import HOLDING, INPUT, LOCK_STATUS_BITS, PARAMS
from devices.params import Param, ParamError
from pages.frame import fmt_age, fmt_time, frame, set_status_badge
from pages.widgets import HistoryChart, Lamp, RegisterTable, confirm, run_command

DEVICE_TYPE = "hdlock"

ENUM_VALUES = ("DoorState", "StateMachineState", "MotorState", "MotorState (IR53)", "MotorResult", "LockRequestSource")
LAMP_KIND = {"ProximityOverrange": "warn", "ForceActive": "warn"}


def content(name: str) -> None:
    runtime = rt.current()
    state = runtime.store.devices[name]
    twin = runtime.twins.get(name)
    with frame(f"HD-Lock {name}"):
        # -- identity and health --------------------------------------------------------
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-6 w-full"):
                badge = ui.badge("waiting", color="grey").classes("text-body2")
                ident = ui.label().classes("text-body2")
                seen = ui.label().classes("text-body2")
                counters = ui.label().classes("text-caption mono text-grey-8")
            error = ui.label().classes("text-negative text-body2")

        # -- status lamps ---------------------------------------------------------------
        with ui.card().classes("w-full"):
            ui.label("LockStatus (holding 1000)").classes("text-subtitle1")
            with ui.row().classes("gap-5"):
                lamps = {f.name: Lamp(f.name, LAMP_KIND.get(f.name, "ok"), f.description) for f in LOCK_STATUS_BITS}
            with ui.row().classes("gap-8 q-mt-sm"):
                enum_labels = {}
                for key in ENUM_VALUES:
                    with ui.column().classes("gap-0"):
                        ui.label(key).classes("text-caption text-grey-8")
                        enum_labels[key] = ui.label("-").classes("text-body1 text-weight-medium")
                        enum_labels[key].props(f'data-value="{key}"')

        with ui.row().classes("w-full no-wrap items-start gap-4"):
            with ui.card().classes("col-7"):
                ui.label("Bolt, motor current and proximity (last 5 minutes)").classes("text-subtitle1")
                chart = HistoryChart(state, list(CHART_SERIES))
            with ui.column().classes("col gap-4"):
                if twin is not None:
                    _sim_controls(twin)
                _set_address_card(name, state)

        # -- writable parameters -----------------------------------------------------------
        param_rows = _parameter_card(name, state)

        with ui.card().classes("w-full"):
            with ui.tabs() as tabs:
                t_in = ui.tab("Input registers")
                t_hold = ui.tab("Holding registers")
            with ui.tab_panels(tabs, value=t_in).classes("w-full"):
                with ui.tab_panel(t_in):
                    input_table = RegisterTable(state, PARAMS.space(INPUT))
                with ui.tab_panel(t_hold):
                    holding_table = RegisterTable(state, PARAMS.space(HOLDING))

        with ui.expansion("Events", icon="list").classes("w-full"):
            events = ui.log(max_lines=200).classes("w-full h-40")
        shown_events = [0]

        def update() -> None:
            set_status_badge(badge, state.status, state.age)
            values = state.values()
            serial = values.get("SerialNumber", {}).get("value")
            fw = values.get("FirmwareVersion", {}).get("value")
            ident.set_text(
                f"Modbus address {state.info.get('address')} · serial {serial if serial is not None else '-'}"
                f" · firmware V{fw if fw is not None else '-'}"
            )
            seen.set_text(f"last seen {fmt_age(state.age)}")
            c = state.counters
            counters.set_text(
                f"requests {c.requests} · timeouts {c.timeouts} · CRC {c.crc_errors} · exceptions {c.exceptions} · write errors {c.write_errors}"
            )
            error.set_text(state.last_error if state.status != "online" else "")
            status = values.get("LockStatus")
            for field_name, lamp in lamps.items():
                lamp.set(None if status is None else bool(status["fields"][field_name]))
            for key, label in enum_labels.items():
                entry = values.get(key)
                label.set_text(entry["name"] or f"undefined ({entry['value']})" if entry else "-")
            param_rows()
            input_table.update()
            holding_table.update()
            for event in state.events:
                if event.time > shown_events[0]:
                    events.push(f"{fmt_time(event.time)} {event.level.upper()}: {event.text}")
                    shown_events[0] = event.time

        update()
        ui.timer(0.5, update)
        ui.timer(1.0, chart.update)


def _sim_controls(twin) -> None:
    with ui.card().classes("w-full bg-purple-1"):
        ui.label("Simulated lock (demo)").classes("text-subtitle1")
        with ui.row():
            ui.button("Close door", icon="door_front", on_click=twin.close_door).props("data-testid=sim-close")
            ui.button("Open door", icon="meeting_room", on_click=twin.open_door).props("outline data-testid=sim-open")
        with ui.row():
            ui.switch("LOCK-REQUEST input active", value=twin.line_input, on_change=lambda e: twin.set_line_input(e.value))
            ui.switch("Strong magnet", value=twin.strong_magnet, on_change=lambda e: setattr(twin, "strong_magnet", e.value))
            ui.switch("Stop answering", value=twin.silent, on_change=lambda e: setattr(twin, "silent", e.value))


def _parameter_card(name: str, state):
    """Editable RW holding registers with validation, unsaved marks, Save/Restore-Settings."""
    writable = [p for p in PARAMS.space(HOLDING) if p.writable]
    rows: dict[str, tuple] = {}
    with ui.card().classes("w-full"):
        with ui.row().classes("items-center w-full"):
            ui.label("Parameters (RW holding registers)").classes("text-subtitle1")
            unsaved_label = ui.badge("", color="orange")
            ui.space()
            save = ui.button("Save-Settings", icon="save", on_click=lambda: _save(name)).props("data-testid=save-settings")
            ui.button("Restore-Settings", icon="restore", on_click=lambda: _restore(name)).props("outline")
        ui.label(
            "Writes are volatile until Save-Settings; Restore-Settings reloads the saved values and discards unsaved changes."
        ).classes("text-caption text-grey-8")
        with ui.grid(columns=5).classes("w-full items-center gap-x-4 gap-y-1"):
            for h in ("Register", "Name", "Current", "New value", ""):
                ui.label(h).classes("text-caption text-grey-8")
            for p in writable:
                ui.label(str(p.address)).classes("mono")
                with ui.row().classes("items-center gap-1"):
                    ui.label(p.label or p.name).tooltip(p.description)
                    mark = ui.badge("unsaved", color="orange")
                current = ui.label("-").classes("mono")
                if p.enum is not None:
                    entry = ui.select({k: f"{v} ({k})" for k, v in p.enum.items()}, value=None).props("dense outlined options-dense").classes("w-64")
                else:
                    low, high = p.limits()
                    entry = ui.number(placeholder=f"{low:g} .. {high:g} {p.unit}".strip(), format="%d").props("dense outlined").classes("w-48")
                entry.props(f'data-param="{p.name}"')
                ui.button("Write", on_click=lambda p=p, entry=entry: _write(name, p, entry.value)).props(f'dense data-write="{p.name}"')
                rows[p.key] = (p, current, mark)

    def refresh() -> None:
        for key, (p, current, mark) in rows.items():
            raw = state.raw(p)
            current.set_text("-" if raw is None else p.display(raw))
            mark.set_visibility(key in state.unsaved)
        count = len(state.unsaved)
        unsaved_label.set_text(f"{count} unsaved change{'s' if count != 1 else ''}")
        unsaved_label.set_visibility(count > 0)
        save.props(f"color={'orange' if count else 'primary'}")

    return refresh


async def _write(name: str, param: Param, value) -> None:
    if value is None or value == "":
        ui.notify(f"{param.name}: enter a value first", type="warning")
        return
    try:
        raw = param.validate(value)
    except ParamError as exc:
        ui.notify(str(exc), type="negative")
        return
    warning = param.needs_confirmation(raw)
    if warning and not await confirm(f"Write {param.name} = {param.display(raw)}?", warning, ok="Write anyway"):
        return
    await run_command(
        name,
        lambda a: a.write_param(param, param.decode(raw), confirmed=bool(warning)),
        f"write {param.name}",
        success=f"{param.name} = {param.display(raw)} written and read back (not yet saved)",
    )


async def _save(name: str) -> None:
    await run_command(name, lambda a: a.save_settings(), "Save-Settings", success="Settings saved to the lock's flash")


async def _restore(name: str) -> None:
    if await confirm("Restore-Settings?", "All changes not yet saved are discarded and the saved values reloaded.", ok="Restore"):
        await run_command(name, lambda a: a.restore_settings(), "Restore-Settings", success="Saved settings restored")


def _set_address_card(name: str, state) -> None:
    """Set Modbus Address (command 3) with its two condition masks and a live preview."""
    with ui.card().classes("w-full"):
        ui.label("Set Modbus Address (command 3)").classes("text-subtitle1")
        ui.label("Taken only if (P1 & LockStatus) ^ P2 == 0 (section 4.3).").classes("text-caption text-grey-8")
        with ui.row().classes("items-center"):
            new = ui.number("New address", value=None, min=1, max=254, format="%d").props("dense outlined").classes("w-32")
            p1 = ui.input("P1 mask (hex)", value="0x0000").props("dense outlined").classes("w-32 mono")
            p2 = ui.input("P2 expected (hex)", value="0x0000").props("dense outlined").classes("w-32 mono")
        bits = ui.label().classes("text-caption")
        preview = ui.label().classes("text-body2")
        button = ui.button("Send Set Modbus Address", icon="pin")

    def parse(text: str) -> int | None:
        try:
            value = int(str(text).strip(), 0)
        except ValueError:
            return None
        return value if 0 <= value <= 0xFFFF else None

    def names(mask: int) -> str:
        return ", ".join(f.name for f in LOCK_STATUS_BITS if mask >> f.shift & 1) or "no bits"

    def update_preview() -> None:
        m, e = parse(p1.value), parse(p2.value)
        if m is None or e is None:
            preview.set_text("P1 and P2 must be 16-bit numbers, e.g. 0x010C")
            preview.classes(replace="text-body2 text-negative")
            return
        bits.set_text(f"checks: {names(m)}; must be set: {names(e & m) if e & m else 'none'}")
        status = state.value("LockStatus")
        if status is None:
            preview.set_text("LockStatus not read yet")
            return
        result = codec.set_address_condition(m, e, int(status))
        ok = result == 0
        preview.set_text(
            f"now: (0x{m:04X} & 0x{int(status):04X}) ^ 0x{e:04X} = 0x{result:04X} -> "
            + ("condition holds, the lock would take the address" if ok else "condition fails, the lock would refuse")
        )
        preview.classes(replace="text-body2 " + ("text-positive" if ok else "text-negative"))

    async def send() -> None:
        m, e = parse(p1.value), parse(p2.value)
        if new.value is None or not 1 <= int(new.value) <= 254:
            ui.notify("Enter a new address 1..254", type="warning")
            return
        if m is None or e is None:
            ui.notify("P1 and P2 must be 16-bit numbers", type="warning")
            return
        target = int(new.value)
        if not await confirm(
            f"Change the Modbus address to {target}?",
            "If the condition holds the lock answers only at the new address from now on. "
            "Send Save-Settings afterwards to keep it, and change the address in the plant file.",
            ok="Send",
        ):
            return
        ok, accepted = await run_command(name, lambda a: a.set_address(target, m, e), "Set Modbus Address")
        if ok:
            if accepted:
                ui.notify(f"The lock answers at address {target} now. Save-Settings keeps it.", type="positive")
            else:
                ui.notify("The lock refused the new address: the condition did not hold", type="warning")

    for element in (p1, p2):
        element.on_value_change(update_preview)
    button.on_click(send)
    update_preview()
    ui.timer(1.0, update_preview)
