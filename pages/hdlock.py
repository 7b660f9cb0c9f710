"""HD-Lock page: status lamps, live chart, parameters, system commands, register tables."""

from __future__ import annotations

import time

from nicegui import ui

from app import runtime as rt
from devices.hdlock import codec
from devices.hdlock.adapter import CHART_SERIES
from devices.hdlock.params import HOLDING, INPUT, LOCK_STATUS_BITS, PARAMS
from devices.hdlock.policy import unsaved_changes
from devices.params import Param
from pages.frame import fmt_age, frame, set_status_badge
from pages.widgets import (
    HistoryChart,
    Lamp,
    RegisterTable,
    WriteGuard,
    checked_value,
    confirm,
    counter_line,
    entry_age,
    event_log,
    follow,
    mark_quality,
    quality_note,
    range_number,
    refuse,
    run_command,
    sim_action,
    sim_card_allowed,
    write_from_page,
)

DEVICE_TYPE = "hdlock"

# the LockRequestSource shown is holding 4, the one the lock uses (section 6.5.1)
ENUM_VALUES = ("DoorState", "StateMachineState", "MotorState", "MotorState (IR53)", "MotorResult", "LockRequestSource (HR4)")
LAMP_KIND = {"ProximityOverrange": "warn", "ForceActive": "warn"}
CHART_AXES = {"MotorCurrent [mA]": "y2"}  # increments on the left axis, mA on the right
CHART_WINDOWS = (30, 300)  # the bolt moves in about half a second: 30 s by default, 5 min on demand
# cards beside each other as the width allows, each as tall as its row (no blank area under a short one)
CARD_GRID = "display: grid; grid-template-columns: repeat(auto-fit, minmax(420px, 1fr)); gap: 16px; width: 100%"


def content(name: str) -> None:
    runtime = rt.current()
    state = runtime.store.devices[name]
    twin = runtime.twins.get(name)
    is_can = getattr(runtime.worker.adapters[name], "transport", "") == "can"
    with frame(f"HD-Lock {name}"):
        guard = WriteGuard(state)  # every write and command button of the page, disabled with the reason while silent
        # -- identity and health --------------------------------------------------------
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-6 w-full"):
                badge = ui.badge("waiting", color="grey").classes("text-body2")
                ident = ui.label().classes("text-body2")
                seen = ui.label().classes("text-body2")
                counter_line(state, lambda c: f"requests {c.requests} · timeouts {c.timeouts} · CRC {c.crc_errors} · "
                             f"exceptions {c.exceptions} · write errors {c.write_errors}")
            error = ui.label().classes("text-negative text-body2")

        # -- status lamps ---------------------------------------------------------------
        with ui.card().classes("w-full"):
            with ui.row().classes("items-baseline gap-2"):
                ui.label("LockStatus (holding 1000)").classes("text-subtitle1")
                lamps_note = ui.label().classes("q-age").props("data-testid=lockstatus-quality")
            with ui.row().classes("gap-5"):
                lamps = {f.name: Lamp(f.name, LAMP_KIND.get(f.name, "ok"), f.description) for f in LOCK_STATUS_BITS}
            with ui.row().classes("gap-8 q-mt-sm"):
                enum_labels, enum_notes = {}, {}
                for key in ENUM_VALUES:
                    with ui.column().classes("gap-0"):
                        ui.label(key).classes("text-caption text-grey-8")
                        enum_labels[key] = ui.label("-").classes("text-body1 text-weight-medium")
                        enum_labels[key].props(f'data-value="{key}"')
                        enum_notes[key] = ui.label().classes("q-age q-ml-none")

        with ui.card().classes("w-full gap-1"):
            ui.label("Bolt, motor current and proximity").classes("text-subtitle1")
            HistoryChart(state, list(CHART_SERIES), window_s=CHART_WINDOWS[0], axes=CHART_AXES, windows=CHART_WINDOWS)
        with ui.element("div").style(CARD_GRID).props("data-testid=hdlock-cards"):
            if twin is not None:
                _sim_controls(state, twin, is_can)
            if is_can:
                can_status = _can_status_card(state)
                _can_commands_card(name, state, guard)
            else:
                can_status = None
                _set_address_card(name, state, guard)
                _broadcast_address_card(name, state, guard)

        # -- writable parameters -----------------------------------------------------------
        param_rows = _parameter_card(name, state, guard)

        with ui.card().classes("w-full"):
            with ui.tabs() as tabs:
                t_in = ui.tab("Input registers")
                t_hold = ui.tab("Holding registers")
            with ui.tab_panels(tabs, value=t_in).classes("w-full"):
                with ui.tab_panel(t_in):
                    RegisterTable(state, PARAMS.space(INPUT))  # follows the store itself: values, ages, greyed rows
                with ui.tab_panel(t_hold):
                    RegisterTable(state, PARAMS.space(HOLDING))

        with ui.expansion("Events", icon="list", value=True).classes("w-full"):
            event_log(state)

        def update() -> None:
            set_status_badge(badge, state.status, state.age)
            serial, fw = state.value("SerialNumber"), state.value("FirmwareVersion")
            where = f"CAN device ID {state.info.get('device_id')}" if is_can else f"Modbus address {state.info.get('address')}"
            ident.set_text(
                f"{where} · serial {serial if serial is not None else '-'} · firmware V{fw if fw is not None else '-'}"
            )
            if can_status is not None:
                can_status()
            seen.set_text(f"last seen {fmt_age(state.age)}")
            error.set_text(state.last_error if state.status != "online" else "")
            status = state.entry("LockStatus")
            for field_name, lamp in lamps.items():
                lamp.show(status, None if status is None else status["fields"][field_name])
            lamps_note.set_text(_note(status))
            for key, label in enum_labels.items():
                entry = state.entry(key)
                label.set_text(entry["name"] or f"undefined ({entry['value']})" if entry else "-")
                mark_quality(label, entry["quality"] if entry else "unknown")
                enum_notes[key].set_text(_note(entry))
            param_rows()

        update()
        follow(state, update)  # on every change the store pushes (at most 10/s) and once a second for the ages


def _note(entry: dict | None) -> str:
    """``stale 4 s`` / ``offline, last 1 min`` under a value that is not good."""
    if entry is None or entry["quality"] not in ("stale", "offline"):
        return ""
    return quality_note(entry["quality"], entry_age(entry))


def _sim_controls(state, twin, is_can: bool) -> None:
    """The twin's controls: engineers only, each action through the worker's gate and in the audit log."""
    name = state.name

    def toggled(describe: str, apply):
        return lambda e: sim_action(name, f"{describe} {'on' if e.value else 'off'}", lambda: apply(e.value))()

    with ui.card().classes("w-full bg-purple-1"):
        ui.label("Simulated lock (demo)").classes("text-subtitle1")
        if not sim_card_allowed():
            return
        if is_can:
            rate = ui.label().classes("text-caption")

            def show_rate() -> None:
                rate.set_text(f"simulated lock runs at {twin.can_bitrate} bit/s, device ID {twin.device_id}")

            show_rate()
            follow(state, show_rate)
        with ui.row():
            ui.button("Close door", icon="door_front", on_click=sim_action(name, "close door", twin.close_door)).props(
                "data-testid=sim-close")
            ui.button("Open door", icon="meeting_room", on_click=sim_action(name, "open door", twin.open_door)).props(
                "outline data-testid=sim-open")
        with ui.row():
            ui.switch("LOCK-REQUEST input active", value=twin.line_input,
                      on_change=toggled("LOCK-REQUEST input", twin.set_line_input))
            ui.switch("Strong magnet", value=twin.strong_magnet,
                      on_change=toggled("strong magnet", lambda v: setattr(twin, "strong_magnet", v)))
            ui.switch("Stop answering", value=twin.silent,
                      on_change=toggled("stop answering", lambda v: setattr(twin, "silent", v))).props("data-testid=sim-silent")
            if not is_can:
                ui.switch(
                    "Answer Set Modbus Address at the old address", value=twin.answers_address_command,
                    on_change=toggled("answer Set Modbus Address", lambda v: setattr(twin, "answers_address_command", v)),
                ).tooltip("Section 4.3 does not say whether the lock answers the command write; off = it stays silent")
            if is_can:
                ui.switch("Firmware-update mode", value=twin.fwu_mode,
                          on_change=toggled("firmware-update mode", lambda v: setattr(twin, "fwu_mode", v)))
                ui.button("Back to the bus bit rate", on_click=sim_action(
                    name, "back to the bus bit rate", lambda: setattr(twin, "can_bitrate", _bus_bitrate(twin)))).props("flat dense")


def _parameter_card(name: str, state, guard: WriteGuard):
    """Editable RW holding registers with validation, unsaved marks, Save/Restore-Settings."""
    writable = [p for p in PARAMS.space(HOLDING) if p.writable]
    rows: dict[str, tuple] = {}
    entries: dict[str, ui.element] = {}
    with ui.card().classes("w-full"):
        with ui.row().classes("items-center w-full"):
            ui.label("Parameters (RW holding registers)").classes("text-subtitle1")
            unsaved_label = ui.badge("", color="orange")
            ui.space()
            save = ui.button("Save-Settings", icon="save", on_click=lambda: _save(name, state)).props("data-testid=save-settings")
            restore = ui.button("Restore-Settings", icon="restore", on_click=lambda: _restore(name)).props(
                "outline data-testid=restore-settings")
            guard.add(save, restore)
        ui.label(
            "Writes are volatile until Save-Settings; Restore-Settings reloads the saved values and discards unsaved changes."
        ).classes("text-caption text-grey-8")
        # register, name, current, entry, button: the name column gives way on narrow screens
        with ui.grid(columns="auto minmax(8rem, 1fr) minmax(6rem, 1fr) auto auto").classes("w-full items-center gap-x-4 gap-y-1"):
            for h in ("Register", "Name", "Current", "New value", ""):
                ui.label(h).classes("text-caption text-grey-8")
            for p in writable:
                ui.label(str(p.address)).classes("mono")
                with ui.row().classes("items-center gap-1"):
                    ui.label(p.label or p.name).tooltip(p.description)
                    mark = ui.badge("unsaved", color="orange")
                with ui.row().classes("items-baseline gap-0 no-wrap") as cell:
                    current = ui.label("-").classes("mono")
                    age = ui.label().classes("q-age")
                if p.enum is not None:
                    entry = ui.select({k: f"{v} ({k})" for k, v in p.enum.items()}, value=None).props("dense outlined options-dense").classes("w-64")
                else:
                    low, high = p.limits()
                    entry = range_number("", low, high, unit=p.unit, integer=p.scale == 1).classes("w-48")
                entry.props(f'data-param="{p.name}"')
                entry.on("keydown.enter", lambda p=p, entry=entry: _write(name, p, entry))  # Enter writes, as the button does
                button = ui.button("Write", on_click=lambda p=p, entry=entry: _write(name, p, entry)).props(f'dense data-write="{p.name}"')
                guard.add(button)
                rows[p.key] = (p, cell, current, age, mark)
                entries[p.key] = entry
    shown: dict[str, object] = {}  # the device value each field was last given

    def follow_entry(key: str, p: Param, raw: int | None) -> None:
        """A field shows the device's value until the engineer types; after a write, the value read back."""
        if raw is None:
            return
        value = p.decode(raw)
        entry = entries[key]
        if (entry.value is None and key not in shown) or entry.value in (shown.get(key), value):  # untouched
            if entry.value != value:
                entry.value = value
            shown[key] = value

    def refresh() -> None:
        now = time.time()
        for key, (p, cell, current, age, mark) in rows.items():
            raw = state.raw(p)
            current.set_text("-" if raw is None else p.display(raw))
            follow_entry(key, p, raw)
            read = state.read_time(p)
            quality = state.quality(read, state.registers_periodic, now)
            mark_quality(cell, quality)  # greyed with the age of its value while stale or offline
            age.set_text(quality_note(quality, None if read is None else now - read) if quality in ("stale", "offline") else "")
            mark.set_visibility(key in state.unsaved)
        count = len(state.unsaved)
        unsaved_label.set_text(f"{count} unsaved change{'s' if count != 1 else ''}")
        unsaved_label.set_visibility(count > 0)
        if save.props.get("color") != ("orange" if count else "primary"):
            save.props(f"color={'orange' if count else 'primary'}")

    return refresh


async def _write(name: str, param: Param, entry) -> None:
    await write_from_page(name, param, entry.value, success="{name} = {value} written and read back (not yet saved)",
                          field=entry)


async def _save(name: str, state) -> None:
    """Save-Settings writes the lock's flash (section 4.1): ask first, naming what becomes permanent."""
    changes = unsaved_changes(state)
    with ui.dialog() as dialog, ui.card().classes("max-w-lg").props("data-testid=save-dialog"):
        ui.label("Save-Settings: write the settings to the lock's flash?").classes("text-h6")
        if changes:
            ui.label(f"{len(changes)} unsaved change{'s' if len(changes) != 1 else ''} become{'s' if len(changes) == 1 else ''} "
                     "permanent (kept after a reset):").classes("text-body1")
            with ui.column().classes("gap-0 q-pl-md").props("data-testid=save-changes"):
                for line in changes:
                    ui.label(line).classes("text-body2 mono")
        else:
            ui.label("No unsaved changes are known here: the lock's current settings are written to its flash again.").classes(
                "text-body1")
        ui.label("Each save is counted in SavedSettings (input 101).").classes("text-caption text-grey-8")
        with ui.row().classes("justify-end w-full"):
            ui.button("Cancel", on_click=lambda: dialog.submit(False)).props("flat")
            ui.button("Save to flash", icon="save", on_click=lambda: dialog.submit(True)).props("data-testid=save-confirm")
    confirmed = await dialog
    dialog.delete()
    if not confirmed:
        await refuse(name, "Save-Settings", "not confirmed", parameter="Save-Settings", new="; ".join(changes))
        return
    # the declaration's audit row lists what became permanent, as read when the command runs
    await run_command(name, "Save-Settings", success="Settings saved to the lock's flash")


async def _restore(name: str) -> None:
    # the declared command names its risk (all unsaved changes are lost): run_command asks it
    await run_command(name, "Restore-Settings", success="Saved settings restored")


def _parse_word(text) -> int | None:
    """A 16-bit mask typed as decimal or 0x hex, else None."""
    try:
        value = int(str(text).strip(), 0)
    except ValueError:
        return None
    return value if 0 <= value <= 0xFFFF else None


def _bit_names(mask: int) -> str:
    return ", ".join(f.name for f in LOCK_STATUS_BITS if mask >> f.shift & 1) or "no bits"


def _condition_text(m: int, e: int) -> str:
    return f"checks: {_bit_names(m)}; must be set: {_bit_names(e & m) if e & m else 'none'}"


MASK_RULE = "16-bit number, e.g. 0x010C"


def _mask_check(text) -> str | None:
    return None if _parse_word(text) is not None else MASK_RULE


def _mask_inputs(prefix: str):
    """P1 and P2 of section 4.3; a wrong entry stays as typed, marked with what is allowed."""
    p1 = ui.input("P1 mask (hex)", value="0x0000", validation=_mask_check).props(
        f"dense outlined data-testid={prefix}-p1").classes("w-44 mono")
    p2 = ui.input("P2 expected (hex)", value="0x0000", validation=_mask_check).props(
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


def _set_address_card(name: str, state, guard: WriteGuard) -> None:
    """Set Modbus Address (command 3) with its two condition masks and a live preview."""
    with ui.card().classes("w-full"):
        ui.label("Set Modbus Address (command 3)").classes("text-subtitle1")
        ui.label("Taken only if (P1 & LockStatus) ^ P2 == 0 (section 4.3).").classes("text-caption text-grey-8")
        with ui.row().classes("items-center"):
            new = range_number("New address", 1, 254, integer=True).classes("w-56")
            p1, p2 = _mask_inputs("sa")
        bits = ui.label().classes("text-caption")
        preview = ui.label().classes("text-body2")
        button = ui.button("Send Set Modbus Address", icon="pin").props("data-testid=sa-send")
        guard.add(button)

    def update_preview() -> None:
        m, e = _parse_word(p1.value), _parse_word(p2.value)
        if m is None or e is None:
            preview.set_text("P1 and P2 must be 16-bit numbers, e.g. 0x010C")
            preview.classes(replace="text-body2 text-negative")
            return
        bits.set_text(_condition_text(m, e))
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
        value = await checked_value(new, name, "Set Modbus Address", parameter="DeviceAddress")
        masks = await _checked_masks(name, "Set Modbus Address", p1, p2)
        if value is None or masks is None:
            return
        m, e = masks
        target = int(value)
        # the declared risk (the lock answers only at the new address) is asked by run_command
        ok, outcome = await run_command(name, "Set Modbus Address", args={"new_address": target, "mask": m, "expected": e},
                                        title=f"Change the Modbus address to {target}?")
        if ok:
            ui.notify(outcome.text, type="positive" if outcome.taken else "warning", multi_line=True, close_button="OK", timeout=15000)

    for element in (p1, p2):
        element.on_value_change(update_preview)
    button.on_click(send)
    update_preview()
    follow(state, update_preview)


def _line_locks(name: str, state) -> tuple[dict[int, str], dict[str, int | None], int, int]:
    """Locks known on this lock's line: address -> name, name -> last LockStatus, and how many
    are in the plant file and how many only in scans of the line."""
    runtime = rt.current()
    known: dict[int, str] = {}
    statuses: dict[str, int | None] = {}
    for dev in runtime.plant.devices_on(state.bus):
        if dev.type != DEVICE_TYPE:
            continue
        address = runtime.store.devices[dev.name].info.get("address", dev.options.get("address"))
        known[address] = dev.name
        status = runtime.store.devices[dev.name].value("LockStatus")
        statuses[dev.name] = None if status is None else int(status)
    in_plant = len(known)
    for entry in state.info.get("line_discovered", []):
        if entry["address"] not in known:
            label = f"address {entry['address']}" + (f" (serial {entry['serial']})" if entry.get("serial") is not None else "")
            known[entry["address"]] = label
            statuses[label] = None
    return known, statuses, in_plant, len(known) - in_plant


def _broadcast_address_card(name: str, state, guard: WriteGuard) -> None:
    """Set Modbus Address to broadcast address 255 (section 4.3): every lock on the line at once."""
    with ui.card().classes("w-full"):
        ui.label(f"Set Modbus Address on every lock of {state.bus} (broadcast 255)").classes("text-subtitle1")
        ui.label(
            "Every lock on the line gets the command and none answers; each lock whose LockStatus meets "
            "(P1 & LockStatus) ^ P2 == 0 takes the new address (section 4.3)."
        ).classes("text-caption text-grey-8")
        with ui.row().classes("items-center"):
            new = range_number("New address", 1, 254, integer=True).props("data-testid=bc-address").classes("w-56")
            p1, p2 = _mask_inputs("bc")
        bits = ui.label().classes("text-caption")
        known_label = ui.label().classes("text-body2").props("data-testid=bc-known")
        button = ui.button("Send to all locks (255)", icon="campaign").props("color=negative data-testid=bc-send")
        guard.add(button)

    def update_preview() -> None:
        m, e = _parse_word(p1.value), _parse_word(p2.value)
        known, statuses, in_plant, scanned = _line_locks(name, state)
        listed = ", ".join(f"{label} @{address}" if not label.startswith("address") else label for address, label in sorted(known.items()))
        text = f"{len(known)} lock{'s' if len(known) != 1 else ''} known on {state.bus} ({in_plant} in the plant, {scanned} found by a scan): {listed}"
        if m is None or e is None:
            bits.set_text("P1 and P2 must be 16-bit numbers, e.g. 0x010C")
        else:
            bits.set_text(_condition_text(m, e))
            takers, unknown = codec.broadcast_takers(m, e, statuses)
            text += f". By the last LockStatus read: {', '.join(takers) or 'none'} would take it"
            if unknown:
                text += f"; unknown for {', '.join(unknown)}"
        known_label.set_text(text)

    async def send() -> None:
        describe = "Broadcast Set Modbus Address (255)"
        value = await checked_value(new, name, describe, parameter="DeviceAddress")
        masks = await _checked_masks(name, describe, p1, p2)
        if value is None or masks is None:
            return
        m, e = masks
        target = int(value)
        known, statuses, in_plant, scanned = _line_locks(name, state)
        if target in known:
            new.error = f"address {target} is {known[target]}: choose an address no lock uses"
            await refuse(name, describe, new.error, parameter="DeviceAddress", new=target)
            return
        takers, unknown = codec.broadcast_takers(m, e, statuses)
        if len(takers) > 1:
            ui.notify(
                f"{' and '.join(takers)} would all take address {target} and then answer together: "
                "narrow the condition (P1/P2) so that only one lock meets it", type="warning", multi_line=True,
            )
            return
        count = len(known)
        if not await confirm(
            f"Up to {count} lock{'s' if count != 1 else ''} on {state.bus} may take address {target}",
            f"{count} lock{'s' if count != 1 else ''} known on {state.bus} may be affected ({in_plant} in the plant, "
            f"{scanned} found by a scan): {', '.join(sorted(known.values()))}. Every lock whose LockStatus meets the "
            f"condition ({_condition_text(m, e)}) takes address {target} at once; by the last status read "
            f"{', '.join(takers) or 'none of them'} would"
            + (f", unknown for {', '.join(unknown)}" if unknown else "")
            + ". Locks on the line that are not known here take it too if they meet the condition. "
            f"Afterwards send Save-Settings at address {target} and change the plant file.",
            ok=f"Send to all ({count})",
        ):
            return
        # the question above names the declared risk, with the locks known here
        ok, outcome = await run_command(name, "Broadcast Set Modbus Address (255)", confirmed=True,
                                        args={"new_address": target, "mask": m, "expected": e, "known": known})
        if ok:
            ui.notify(outcome.text, type="positive" if outcome.taken else "warning", multi_line=True, close_button="OK", timeout=20000)
        update_preview()

    for element in (p1, p2):
        element.on_value_change(update_preview)
    button.on_click(send)
    update_preview()
    follow(state, update_preview)


def _bus_bitrate(twin) -> int:
    runtime = rt.current()
    for server in runtime.sim.servers if runtime.sim else []:
        if twin in getattr(server, "twins", {}).values() and hasattr(server, "bitrate"):
            return server.bitrate
    return codec.CAN_DEFAULT_BITRATE


def _can_status_card(state):
    """What the periodic status frame (section 6.5.1) and FWU status (6.5.2) say."""
    with ui.card().classes("w-full"):
        ui.label("CAN status frame (every 1000 ms)").classes("text-subtitle1")
        text = ui.label("no status frame yet").classes("text-body2 mono")
        fwu = ui.label().classes("text-body2 text-warning")

    def refresh() -> None:
        frame = state.info.get("can_status")
        if frame is not None:
            source = PARAMS.by_name["LockRequestSource"].enum.get(frame.lock_request_source, "?")
            text.set_text(
                f"Status 0x{frame.status:04X} · motorPos {frame.motor_pos} Inc · proximity {frame.proximity} Inc"
                f" · LockRequestSource 0x{frame.lock_request_source:02X} {source}"
            )
        f = state.info.get("fwu")
        fwu.set_text(
            "" if f is None else f"FWU status: firmware-update mode, {'flashing' if f.flashing else 'not flashing'}, "
            f"{'application' if f.application else 'boot loader'} (no status frames meanwhile)"
        )

    return refresh


def _can_commands_card(name: str, state, guard: WriteGuard) -> None:
    """Commands through 0x700 and Set Device Address through 0x701 (section 6.6)."""
    sources = PARAMS.by_name["LockRequestSource"].enum
    with ui.card().classes("w-full"):
        ui.label("CAN commands (0x700, 0x701)").classes("text-subtitle1")
        broadcast = ui.checkbox("Send to all locks on this bus (broadcast, device ID 0)")
        with ui.row().classes("items-center"):
            source = ui.select({k: f"{v} (0x{k:02X})" for k, v in sources.items()}, label="LockRequestSource").props("dense outlined options-dense").classes("w-72")
            guard.add(ui.button("Set", on_click=lambda: _send_source(name, source, broadcast.value)).props("dense"))
        with ui.row().classes("items-center"):
            rate = ui.select(
                {k: f"{r // 1000 if r % 1000 == 0 else r / 1000:g} kbit/s" + (f" ({length})" if length else "") for k, (r, length) in codec.CAN_BITRATES.items()},
                label="CAN bit rate",
            ).props("dense outlined options-dense").classes("w-72")
            guard.add(ui.button("Set", on_click=lambda: _send_bitrate(name, rate, broadcast.value)).props("dense color=negative"))
        ui.separator()
        ui.label("Set Device Address (0x701)").classes("text-body2 text-weight-medium")
        ui.label(
            "IDs above 0x7FF are extended (29-bit) automatically; tick Extended to use an extended ID up to 0x7FF "
            "(the request then carries 0x80000000)."
        ).classes("text-caption text-grey-8")
        with ui.row().classes("items-center"):
            new_id = ui.input("New device ID (dec or 0x hex)").props("dense outlined").classes("w-56")
            extended = ui.checkbox("Extended")
            guard.add(ui.button("Send", on_click=lambda: _send_device_id(name, new_id, extended.value)).props("dense"))


async def _send_source(name: str, field, broadcast: bool) -> None:
    value = field.value
    if value is None:
        field.error = "choose a LockRequestSource first"
        return
    field.error = None
    label = PARAMS.by_name["LockRequestSource"].enum[value]
    # 0x80-0x87 (the door ignored) and a broadcast are risks the HD-Lock policy names: the gate asks them
    await run_command(name, "cmdSetLockRequestSource", args={"value": value, "broadcast": broadcast},
                      success=f"LockRequestSource {label} sent" + (" to all locks" if broadcast else " and read back from holding 4"))


async def _send_bitrate(name: str, field, broadcast: bool) -> None:
    code = field.value
    if code is None:
        field.error = "choose a bit rate first"
        return
    field.error = None
    rate = codec.CAN_BITRATES[code][0]
    who = "Every lock on this bus" if broadcast else "The lock"
    if not await confirm(
        f"Switch to {rate} bit/s?",
        f"{who} leaves this bus at once and is unreachable until the bus itself is switched to {rate} bit/s "
        "(change bitrate in the plant file and restart). Send Save-Settings first if other changes should be kept.",
        ok="Switch bit rate",
    ):
        return
    await run_command(name, "cmdSetCANbaudrate", args={"code": code, "broadcast": broadcast}, confirmed=True,
                      success=f"bit rate {rate} bit/s sent")  # the question above names the risk


async def _send_device_id(name: str, field, extended: bool) -> None:
    """Set Device Address (section 6.6): a wrong entry stays in the field, marked, and is audited; nothing is sent."""
    text = field.value
    try:
        value = int(str(text).strip(), 0)
        new = codec.DeviceId.make(value, extended or None)
        reason = "0 is the broadcast address" if value == 0 else None
    except (ValueError, codec.CodecError) as exc:
        reason = str(exc) if isinstance(exc, codec.CodecError) else "a number, e.g. 11 or 0x1A2B"
    field.error = reason
    if reason is not None:
        await refuse(name, "Set Device Address", f"{text!r}: {reason}", parameter="DeviceId", new=text)
        return
    # refused when another participant uses the ID (section 6.2 b), asked first otherwise: the HD-Lock policy
    ok, heard = await run_command(name, "Set Device Address", args={"new_value": new.value, "extended": new.extended})
    if ok:
        if heard:
            ui.notify(f"The lock answers under {new} now", type="positive")
        else:
            ui.notify("No frame under the new ID: the lock may have kept its old ID", type="warning")
