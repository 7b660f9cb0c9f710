"""Bauer MO 64 page: gate state with a picture of the boom, position, the 40 status bits, identity,
counters, error memory, modes; commands, settings, change monitoring and the TCP connection."""

from __future__ import annotations

from nicegui import ui

from app import runtime as rt
from devices.mo64 import codec
from devices.mo64.adapter import COMMAND_NAMES, HELD_LEVELS
from devices.mo64.policy import EEPROM_RISK, operation_name, setting_name
from pages.electrak import gate
from pages.frame import frame, set_status_badge
from pages.widgets import (
    Lamp,
    WriteGuard,
    checked_value,
    counter_line,
    entry_age,
    event_log,
    follow,
    mark_quality,
    quality_note,
    range_number,
    refuse,
    run_command,
)

MOTION_WARNING = "the boom moves: check that nobody stands under it"
EEPROM_WARNING = EEPROM_RISK  # the declared risk of every setting write (devices/mo64/policy.py)
ALARM_BITS = {"LS", "Baum ab", "F_ereignis"}
# what the status bits mean (chapter 5.1.7, pages 16-17; SPEC-NOTES "Barrier status"); a bit the summary
# names without its function says so
BIT_MEANINGS = {
    "Funk": "radio (Funk): the learned radio code is being received (page 16)",
    "BT": "BT: the open command input (BT = open, BZ = close, chapter 5.2.1)",
    "BTS": "BTS: command input named in chapter 5.1.7; its function is not in the summary",
    "SLZ": "SLZ: input named in chapter 5.1.7; its function is not in the summary",
    "LS": "LS: the light barrier is interrupted (safety: a closing boom reverses)",
    "Baum ab": "Baum ab: boom off - the boom is broken away or removed (safety)",
    "F_ereignis": "F_ereignis: fault event - an error flag is set; see the error memory (safety)",
    "SERVICE": "SERVICE: maintenance is due (maintenance counter reached the interval)",
    "mains monitoring": "mains monitoring: the mains supply monitor reports",
}
for _name in ("BTA1", "BTA2", "BTA3", "BTZ1A", "BTZ1B", "BTZ2"):
    BIT_MEANINGS[_name] = f"{_name}: command input named in chapter 5.1.7; its function is not in the summary"
for _loop in "ABC":
    BIT_MEANINGS[f"adjusting loop {_loop}"] = f"loop {_loop} is being adjusted (Abgleich Schleife {_loop}, page 17)"
    BIT_MEANINGS[f"loop {_loop} occupied"] = f"a vehicle is on loop {_loop}"
BIT_MEANINGS["loop EXT"] = "the external loop detector reports"
for _n in range(1, 7):
    BIT_MEANINGS[f"multi relay {_n}"] = f"multi relay {_n} is switched on (Multi{_n}, page 17)"
LEGEND = ("Funk = radio code received; BT = open input; LS = light barrier interrupted; Baum ab = boom off "
          "(broken away or removed); F_ereignis = fault event (see the error memory); SERVICE = maintenance due. "
          "Hover a lamp for its meaning.")
TIME_KEYS = ("t_open", "t_prewarn_open", "t_prewarn_close")
INT_KEYS = ("maintenance_interval", "vehicle_counter")
SETTING_POINTS = {"t_open": "Open time", "t_prewarn_open": "Pre-warning before opening",
                  "t_prewarn_close": "Pre-warning before closing", "change_monitoring": "Change monitoring",
                  "status_mask": "Status mask", "multi_relays": "Multi-relay modes",
                  "config_flags": "Configuration flags", "maintenance_interval": "Maintenance interval",
                  "vehicle_counter": "Vehicle counter"}
IDENTITY_POINTS = ("Device code", "Program version", "Serial number", "MAC address", "Operating hours")
COUNTER_POINTS = ("Service counter", "Maintenance counter", "Maintenance interval", "Vehicle counter",
                  "Loop-adjust counter A", "Loop-adjust counter B", "Loop-adjust counter C")
MODE_POINTS = ("Induction-loop modes", "Direction logics", "Configuration flags", "Multi-relay modes",
               "Status mask", "Counting function", "Radio code (dec_bt)", "Loop periods")
HIDDEN_BITS = frozenset(f"multi relay {n}" for n in range(7, 15))  # an MO 64 has six (5.1.25): SPEC-NOTES


def boom_svg(position: int | None) -> str:
    """A barrier post with its boom raised by ``position`` % (0 closed, horizontal; 100 open, upright)."""
    angle = 0 if position is None else -90 * max(0, min(100, position)) / 100
    colour = "#9e9e9e" if position is None else "#c62828"
    return (f'<svg width="220" height="130" viewBox="0 0 220 130" role="img" aria-label="boom">'
            f'<rect x="10" y="60" width="26" height="66" fill="#455a64"/>'
            f'<g transform="rotate({angle:.1f} 23 64)">'
            f'<rect x="23" y="58" width="190" height="12" rx="3" fill="#fff" stroke="{colour}" stroke-width="3"/>'
            + "".join(f'<rect x="{40 + 40 * i}" y="59" width="18" height="10" fill="{colour}"/>' for i in range(4))
            + '</g><circle cx="23" cy="64" r="6" fill="#263238"/></svg>')


def content(name: str) -> None:
    runtime = rt.current()
    state = runtime.store.devices[name]
    adapter = runtime.worker.adapters[name]
    client = ui.context.client
    session = client.id

    async def act(command: str, args: dict | None = None, success: str = "", confirmed: bool = False):
        """Invoke a declared command of the MO 64 (devices/mo64/policy.py) by name: the gate decides on its
        kind and the role, and asks its declared risk here (run_command) unless ``confirmed``."""
        result = await run_command(name, command, args=args, session=session, success=success, confirmed=confirmed)
        if updater:
            updater[0]()  # the reply and the levels are shown at once
        return result

    updater: list = []

    async def move(cmd: codec.Command, fn: codec.Function) -> None:
        words = operation_name(cmd, fn)
        # the declared risk ("the area is clear") is asked once per session: a session that confirmed it
        # (the adapter keeps that) is not asked again
        await act(words, success=f"{words}: ack", confirmed=session in adapter.motion_confirmed)

    async def clear_levels() -> None:
        if not adapter.levels:
            ui.notify("no level set by this tool is active")
            return
        await act("clear levels", success="levels deactivated")  # the gate asks the declared risk

    async def write(key: str, field) -> None:
        setting = codec.SETTINGS[key]
        value = await _entry_value(name, key, field)
        if value is None:
            return
        args: dict = codec.setting_to_fields(key, value)
        if setting.assumed and key not in adapter.verified_selectors:
            # the engineer states it by confirming the declared risk, which says so
            args["selector_verified"] = True
        await act(setting_name(key), args, success=f"{setting.name} written and read back")

    async def monitoring(on: bool) -> None:
        await act("change monitoring", {"on": int(on)}, success="change monitoring " + ("on" if on else "off"))

    with frame(f"Bauer MO 64 {name}"):
        guard = WriteGuard(state)  # commands and settings, disabled with the reason while the barrier does not answer
        # -- gate ----------------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-6 w-full no-wrap"):
                picture = ui.html(boom_svg(None)).props("data-testid=boom")
                with ui.column().classes("gap-1"):
                    with ui.row().classes("items-center gap-4"):
                        badge = ui.badge("waiting", color="grey").classes("text-body2")
                        gate = ui.label("gate state: -").classes("text-h6").props("data-testid=gate-state")
                    position = ui.label("position: -").classes("text-h6").props("data-testid=position")
                    bar = ui.linear_progress(value=0, show_value=False).props("size=14px rounded").classes("w-72")
                    alarms = ui.label().classes("text-negative text-body1").props("data-testid=alarms")
                    link = ui.label().classes("text-body2").props("data-testid=connection")
                    error_line = ui.label().classes("text-negative text-caption")
                    unavailable = ui.label().classes("text-caption text-grey-8").props("data-testid=unavailable")
                    counter_line(state, lambda c: f"requests {c.requests}  answers {c.responses}  timeouts {c.timeouts}  malformed {c.malformed}")
            if adapter.rs485:
                ui.label(f"RS485 bus address {adapter.address}, this tool is master {adapter.master}.") \
                    .classes("text-caption text-grey-8")
            else:
                with ui.row().classes("items-center gap-2"):
                    ui.label("The MO 64 serves one TCP client at a time (chapter 3).").classes("text-caption text-grey-8")
                    ui.button("Release the connection", icon="link_off", on_click=lambda: act(
                        "release the connection", success="released: another client may connect")) \
                        .props("outline dense data-testid=release")
                    ui.button("Take it back", icon="link", on_click=lambda: act("take the connection back")) \
                        .props("outline dense data-testid=resume")

        # -- commands ------------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            ui.label("Commands (chapter 5.2.1)").classes("text-subtitle1")
            with ui.row().classes("items-center gap-3"):
                ui.label("Pulse:").classes("text-body2")
                for cmd, icon in ((codec.Command.OPEN, "arrow_upward"), (codec.Command.CLOSE, "arrow_downward"),
                                  (codec.Command.REVERSE, "swap_vert")):
                    guard.add(ui.button(COMMAND_NAMES[cmd].capitalize(), icon=icon,
                                        on_click=lambda cmd=cmd: move(cmd, codec.Function.PULSE))
                              .props(f"data-testid=pulse-{COMMAND_NAMES[cmd]}"))
            with ui.row().classes("items-center gap-3"):
                ui.label("Level:").classes("text-body2")
                for cmd in (codec.Command.OPEN, codec.Command.CLOSE, codec.Command.REVERSE):
                    with ui.button_group():
                        guard.add(ui.button(f"{COMMAND_NAMES[cmd]} activate",
                                            on_click=lambda cmd=cmd: move(cmd, codec.Function.ACTIVATE))
                                  .props(f"outline data-testid=activate-{COMMAND_NAMES[cmd]}"))
                        ui.button("deactivate", on_click=lambda cmd=cmd: move(cmd, codec.Function.DEACTIVATE)) \
                            .props(f"outline data-testid=deactivate-{COMMAND_NAMES[cmd]}")
                ui.button("Clear my levels", icon="layers_clear", on_click=clear_levels) \
                    .props("data-testid=clear-levels")
            levels = ui.label().classes("text-body2").props("data-testid=levels")
            reply = ui.label().classes("text-body2 mono").props("data-testid=reply")
            ui.label("A level stays active in the barrier until it is deactivated. Close and reverse levels are "
                     "deactivated when this browser closes or freezes (dead-man rule) and when the tool stops (each "
                     "acknowledged by the barrier); an open level is not, since "
                     "deactivating it would let an unattended boom close. The first motion of a session asks for "
                     f"a confirmation ({MOTION_WARNING}).").classes("text-caption text-grey-8")

        # -- status bits ---------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            ui.label("Barrier status (40 bits, chapter 5.1.7)").classes("text-subtitle1")
            lamps: dict[str, Lamp] = {}
            with ui.row().classes("gap-8 items-start"):
                for group, names in codec.STATUS_GROUPS.items():
                    with ui.column().classes("gap-0"):
                        ui.label(group).classes("text-subtitle2")
                        for bit in names:
                            if bit in HIDDEN_BITS:
                                continue
                            lamps[bit] = Lamp(bit, "alarm" if bit in ALARM_BITS else "ok",
                                              tooltip=BIT_MEANINGS.get(bit, f"{bit}: named in chapter 5.1.7"))
            ui.label(LEGEND).classes("text-caption text-grey-8").props("data-testid=status-legend")

        # -- identity, counters --------------------------------------------------------------------
        with ui.row().classes("w-full gap-4 items-stretch"):
            with ui.card().classes("col"):
                ui.label("Identity").classes("text-subtitle1")
                with ui.column().classes("gap-0 mono text-body2").props("data-testid=identity"):
                    identity = {pt: _value_line() for pt in IDENTITY_POINTS}
            with ui.card().classes("col"):
                ui.label("Counters").classes("text-subtitle1")
                with ui.column().classes("gap-0 mono text-body2").props("data-testid=counters"):
                    counts = {pt: _value_line() for pt in COUNTER_POINTS}
                ui.label("The vehicle counter lives in RAM only: it is 0 after power-up (chapter 5.2.5).") \
                    .classes("text-caption text-grey-8")

        # -- error memory ---------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-4"):
                ui.label("Error memory (10 levels, newest first, chapter 5.1.23)").classes("text-subtitle1")
                guard.add(ui.button("Read again", on_click=lambda: act("read error memory")).props("outline dense"))
                memory_age = ui.label().classes("q-age").props("data-testid=error-memory-age")
            errors = ui.table(columns=[{"name": k, "label": label, "field": k, "align": "left"} for k, label in
                                       (("level", "Level"), ("flags", "Error flags"), ("time", "Operating hours"))],
                              rows=[], row_key="level").classes("w-full text-caption").props("dense flat")

        # -- modes ------------------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            ui.label("Modes (decoded as far as the document names the fields, raw otherwise)").classes("text-subtitle1")
            with ui.column().classes("gap-0 text-body2").props("data-testid=modes"):
                modes = {pt: _value_line() for pt in MODE_POINTS}

        # -- settings ---------------------------------------------------------------------------------
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-4"):
                ui.label("Settings (chapter 5.2.4-5.2.8)").classes("text-subtitle1")
                writes = ui.label().classes("text-body2").props("data-testid=eeprom-writes")
            ui.label(EEPROM_WARNING + " Busy means the motor runs: try again when it stands.").classes("text-caption text-warning")
            with ui.row().classes("items-center gap-2"):
                ui.label("Change monitoring (TCP: changes are sent by the barrier, polling slows down):").classes("text-body2")
                guard.add(ui.button("On", on_click=lambda: monitoring(True)).props("outline dense data-testid=monitoring-on"),
                          ui.button("Off", on_click=lambda: monitoring(False)).props("outline dense data-testid=monitoring-off"))
                mon = ui.label().classes("text-body2").props("data-testid=monitoring")
            setting_values: dict[str, ui.label] = {}
            with ui.grid(columns=3).classes("w-full gap-x-4 items-center") \
                    .style("grid-template-columns: minmax(120px, 220px) minmax(0, 1fr) 300px; row-gap: 28px"):  # room for each entry's range
                for key, setting in codec.SETTINGS.items():
                    if key == "change_monitoring":
                        continue
                    ui.label(setting.name + (" (assumed selector)" if setting.assumed else "")).classes("text-body2")
                    setting_values[key] = _value_line("mono text-body2")
                    with ui.row().classes("items-center gap-1 no-wrap"):
                        if key in TIME_KEYS:
                            low, high = _limits(key)
                            field = range_number("seconds", low * codec.TIME_STEP_S, high * codec.TIME_STEP_S, unit="s",
                                                 step=0.01).classes("w-40")
                        elif key in INT_KEYS:
                            low, high = _limits(key)
                            field = _whole_number("value", low, high).classes("w-48")
                        else:
                            field = ui.input("raw (as shown, e.g. 0x0 or 1,0,0,0,0,0)",
                                             validation=lambda text, k=key: _raw_problem(k, text)).classes("w-48") \
                                .props("dense outlined")
                        field.props(f"data-testid=entry-{key}")
                        guard.add(ui.button("Write", on_click=lambda k=key, f=field: write(k, f))
                                  .props(f"outline dense data-testid=write-{key}"))

        with ui.expansion("Assumptions beyond the manual (shown as such)").classes("w-full") \
                .props("data-testid=assumptions"):
            for text in codec.ASSUMPTIONS:
                ui.label(f"Assumption: {text}").classes("text-caption")

        with ui.expansion("Events", icon="list", value=True).classes("w-full"):
            event_log(state)  # gate and status changes, faults rising and clearing, offline and back, commands; newest first

    def point_text(point: str, missing: str = "-") -> str:
        entry = state.point(point)
        if entry is None:
            return missing
        return entry["text"] if entry["text"] is not None else f"{entry['value']} {entry['unit']}".strip()

    last_position: list = [object()]

    def refresh() -> None:
        set_status_badge(badge, state.status, state.age)
        gate.set_text(f"gate state: {point_text('Gate state')}")
        pos = state.point("Position")
        value = None if pos is None else pos["value"]
        position.set_text(f"position: {point_text('Position')}")
        bar.set_value(0 if value is None else value / 100)
        if value != last_position[0]:
            last_position[0] = value
            picture.set_content(boom_svg(value))
        on = [b for b in ALARM_BITS if (state.point(b) or {}).get("value")]
        alarms.set_text(", ".join({"LS": "light barrier interrupted", "Baum ab": "boom off",
                                   "F_ereignis": "fault event"}[b] for b in sorted(on)))
        info = state.info
        bus = runtime.store.buses.get(state.bus)
        conn = info.get("connection", "-")
        link.set_text(f"connection: {conn}" + (f" ({bus.last_error})" if bus is not None and bus.last_error else "")
                      + f"; polling {info.get('polling', '-')}; query form: {_form_words(info.get('query_form'))}"
                      + (f"; late answers {info['late_answers']}" if info.get("late_answers") else ""))
        missing = info.get("unavailable") or []
        levels_missing = info.get("error_memory_unavailable") or []
        unavailable.set_text(("not available on this unit: " + ", ".join(missing) if missing else "")
                             + ("; " if missing and levels_missing else "")
                             + (f"error memory levels {', '.join(map(str, levels_missing))} not available on this unit"
                                if levels_missing else ""))
        error_line.set_text(state.last_error)
        for bit, lamp in lamps.items():
            lamp.show(state.point(bit))
        mine = sorted(COMMAND_NAMES[cmd] + (" (dead-man)" if cmd in HELD_LEVELS else "")
                      for cmd in adapter.levels)
        levels.set_text("levels this tool set: " + (", ".join(mine) if mine else "none"))
        reply.set_text(f"last answer: {info.get('last_reply') or '-'}")
        for labels in (identity, counts, modes):
            for point, line in labels.items():
                _show_line(line, f"{point}: {point_text(point)}", state.point(point))
        rows = [{"level": e["level"], "flags": f"0x{e['flags']:08X}", "time": f"{e['timestamp_h']} h"}
                for e in info.get("error_memory", [])]
        if rows != errors.rows:
            errors.rows = rows
            errors.update()
        status = state.status
        mark_quality(errors, "offline" if status == "offline" and rows else "good")
        memory_age.set_text(quality_note("offline", state.age) if status == "offline" and rows else "")
        for key, line in setting_values.items():
            _show_line(line, point_text(SETTING_POINTS[key]), state.point(SETTING_POINTS[key]))
        writes.set_text(f"EEPROM writes this session: {adapter.eeprom_writes.get(session, 0)} "
                        f"(all sessions: {adapter.eeprom_writes_total})")
        mon.set_text(f"{point_text('Change monitoring')}; {info.get('monitoring', '-')}")

    updater.append(refresh)
    refresh()
    follow(state, refresh)  # on every change the store pushes (at most 10/s) and once a second for the ages


def _value_line(classes: str = "") -> tuple[ui.row, ui.label, ui.label]:
    """A value with its age next to it (shown while the value is stale or offline)."""
    with ui.row().classes("items-baseline gap-0 no-wrap") as row:
        text = ui.label("-").classes(classes)
        age = ui.label().classes("q-age")
    return row, text, age


def _show_line(line: tuple, text: str, entry: dict | None) -> None:
    row, label, age = line
    quality = "unknown" if entry is None else entry["quality"]
    label.set_text(text)
    mark_quality(row, quality)  # greyed while stale or offline
    age.set_text(quality_note(quality, entry_age(entry)) if quality in ("stale", "offline") else "")


def _form_words(form: str | None) -> str:
    return {"document": "02 Auswahl index (the document's, page 33)",
            "short": "02 Auswahl (the document's form refused)"}.get(form or "", "not known yet")


def _whole_number(label: str, low: int, high: int) -> ui.number:
    """A whole-number entry whose range reads as whole numbers (not 2.14748e+09)."""
    rule = f"allowed {low:,} .. {high:,}".replace(",", "\u2009")

    def check(v) -> str | None:
        if v is None:
            return None
        if float(v) != int(float(v)):
            return f"whole numbers only, {rule}"
        if not low <= float(v) <= high:
            return f"out of range: {rule}"
        return None

    field = ui.number(label, step=1, format="%d", validation=check)
    field.props(f'hint="{rule}" dense outlined')
    field.rule = rule  # type: ignore[attr-defined]
    return field


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
    text = field.value
    problem = "enter a value first" if not (text or "").strip() else _raw_problem(key, text)
    if problem:
        field.error = problem
        await refuse(device, f"set {setting.name}", f"{text!r}: {problem}", parameter=setting.name, new=text or "")
        return None
    field.error = None
    return _parse(key, text)


def _parse(key: str, text: str | None):
    """A raw entry: a number (0x.. allowed) or a comma-separated list for relay modes and configuration flags."""
    text = (text or "").strip()
    if key in ("multi_relays", "config_flags"):
        numbers = [int(x.strip(), 0) for x in text.split(",") if x.strip()]
        if key == "config_flags":
            return dict(zip(("konfig0", "konfig1", "konfig2", "konfig3"), numbers))
        return numbers
    return int(text, 0) if text else 0


__all__ = ["content", "boom_svg"]
