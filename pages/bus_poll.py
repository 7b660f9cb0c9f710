"""A generic Modbus poll on an RTU line (/monitor/<bus>/poll), in the manner of Modbus Poll.

Reads change nothing and are open to every role; writes are engineer only and go through
:class:`app.modbus_poll.ModbusPoll.write` (checked against the known devices' parameter models,
confirmed, audited). Requests share the line with the devices' polls.
"""

from __future__ import annotations

from nicegui import ui

from app import modbus_poll as mp
from app import runtime as rt
from app.modbus_line import ModbusLine
from app.worker import AuditUnavailable, PermissionDenied
from pages.frame import fmt_time, frame, notify_error
from pages.session import current_user
from pages.widgets import all_valid, checked_value, range_number, range_text

REFRESH_S = 0.25
WIDE_KINDS = {"u32": "uint32", "i32": "int32", "f32": "float32"}
PAIR_COLUMNS = [f"{kind} {order}" for kind in WIDE_KINDS for order in mp.WORD_ORDERS]
# which 32-bit columns are shown (a display choice, as Modbus Poll's format): all three need about 1250 px,
# one kind fits a 1024 px window
WIDE_CHOICES = {"all": "uint32, int32, float32", **WIDE_KINDS, "none": "none"}


def _columns(base: int, function: int, wide: str = "all") -> list[dict]:
    cols = [
        {"name": "address", "label": f"Address ({base}-based)", "field": "address", "align": "right"},
        {"name": "name", "label": "Known register", "field": "name", "align": "left"},
    ]
    if function in (1, 2):
        return cols + [{"name": "unsigned", "label": "Value", "field": "unsigned", "align": "right"}]
    cols += [{"name": f, "label": f.capitalize(), "field": f, "align": "right", "classes": "mono"} for f in mp.FORMATS]
    cols += [{"name": c, "label": f"{WIDE_KINDS[kind]} {order}", "field": c, "align": "right", "classes": "mono"}
             for c in PAIR_COLUMNS for kind, order in [c.split()] if wide in ("all", kind)]
    return cols


def content(bus: str) -> None:
    runtime = rt.current()
    with frame(f"Modbus poll · {bus}"):
        ui.link(f"← bus monitor {bus}", f"/monitor/{bus}")
        if not isinstance(runtime.worker.lines.get(bus), ModbusLine):
            ui.label(f"{bus} is not a Modbus RTU line: the poll is for Modbus lines.")
            return
        _view(runtime, bus)


def _view(runtime, bus: str) -> None:
    poll = mp.ModbusPoll(runtime.worker, bus)
    client = ui.context.client
    client.on_disconnect(poll.stop)
    role = current_user()[1]  # what the page shows; every write asks again (the gate decides)
    known = {d.options.get("address"): d.name for d in runtime.plant.devices_on(bus)}
    line = runtime.worker.lines[bus]

    ui.label(
        "Requests share the line with the devices' polls (one request of this window between theirs). "
        f"Addresses are protocol addresses; choose how they are counted. Devices on this line: "
        + (", ".join(f"{name} at {a}" for a, name in sorted(known.items())) or "none")
        + (f". Line cycle {line.cycle_s:.2f} s." if line.cycle_s else ".")
    ).classes("text-caption text-grey-8")

    with ui.card().classes("w-full"):
        with ui.row().classes("items-end gap-3 flex-wrap"):
            unit = range_number("Unit", 0, 254, integer=True, value=min(known) if known else 1).classes("w-24")
            function = ui.select({k: v for k, v in mp.FUNCTIONS.items()}, value=3, label="Function").props(
                "dense outlined").classes("w-60")
            base = ui.select({0: "0-based (protocol)", 1: "1-based (register 1 = address 0)"}, value=0,
                             label="Addresses").props("dense outlined").classes("w-64")
            start = _address_field("Start address", 1000, base).classes("w-36")
            count = range_number("Count", 1, 2000, integer=True, value=10).classes("w-32")
            period = range_number("Period s", mp.PERIOD_MIN_S, mp.PERIOD_MAX_S, unit="s", value=1.0, step=0.1).classes("w-32")
            run_button = ui.button("Poll", icon="play_arrow").props("data-testid=poll-start")
            ui.button("Stop", icon="stop", on_click=lambda: (poll.stop(), status.refresh())).props("flat")

    def current_spec() -> mp.PollSpec:
        shown_start = int(start.value or 0)
        protocol = shown_start - int(base.value or 0)
        return mp.PollSpec(int(unit.value or 0), int(function.value), protocol, int(count.value or 1),
                           float(period.value or 1.0)).check()

    def run() -> None:
        if not all_valid(unit, start, count, period):  # each field says what it allows; nothing is polled
            return
        try:
            poll.start(current_spec())
        except mp.PollError as exc:
            notify_error(str(exc))
            return
        shown["polls"] = -1

    run_button.on_click(run)

    shown: dict = {"polls": -1, "columns": None}

    @ui.refreshable
    def status() -> None:
        last = poll.last
        text = "stopped" if not poll.running else "polling"
        if poll.spec is not None:
            text += f" · unit {poll.spec.unit} · {mp.FUNCTIONS[poll.spec.function]} · {poll.polls} polls, {poll.errors} errors"
        if last is not None:
            text += f" · last {fmt_time(last.time)}" + (f" · {last.rtt_ms} ms" if last.rtt_ms is not None else "")
        ui.label(text).props("data-testid=poll-status")
        if last is not None and last.error:
            ui.label(last.error).classes("text-negative").props("data-testid=poll-error")
        if line.cycle_s:
            ui.label(f"line cycle {line.cycle_s:.2f} s · devices stale after "
                     f"{max((s.stale_after for s in runtime.store.devices.values() if s.bus == bus), default=0):.1f} s").classes(
                "text-caption text-grey-7")

    with ui.row().classes("w-full items-start no-wrap"):
        with ui.column().classes("col gap-1"):
            status()
        wide = ui.select(WIDE_CHOICES, value="all", label="32-bit values", on_change=lambda: update_table()).props(
            "dense outlined data-testid=poll-wide").classes("w-56")
    # one table, its rows and columns changed in place on every poll (not a new table each time)
    hint = ui.label("Set unit, function, start and count, then Poll.").classes("text-grey-7")
    grid = ui.table(columns=_columns(0, 3), rows=[], row_key="address").props(
        "dense flat bordered data-testid=poll-table").classes("w-full reg-table")
    pairs = ui.label("32-bit columns: the register with the next one; ABCD = high word first, CDAB = low word first.").classes(
        "text-caption text-grey-7")

    def update_table() -> None:
        spec = poll.spec
        hint.set_visibility(spec is None)
        grid.set_visibility(spec is not None)
        pairs.set_visibility(spec is not None and spec.function not in (1, 2) and wide.value != "none")
        if spec is None:
            return
        offset = int(base.value or 0)
        rows = []
        for r in poll.rows():
            row = {"address": r.address + offset, "name": r.name, **{c: "" for c in (*mp.FORMATS, *PAIR_COLUMNS)}}
            row.update(r.cells)
            rows.append(row)
        columns = _columns(offset, spec.function, wide.value)
        if columns != shown["columns"]:
            grid.columns = shown["columns"] = columns
        elif rows == grid.rows:
            return
        grid.rows = rows
        grid.update()

    update_table()

    def tick() -> None:
        if poll.polls != shown["polls"]:
            shown["polls"] = poll.polls
            status.refresh()
            update_table()

    ui.timer(REFRESH_S, tick)

    # -- writes (engineer only) ---------------------------------------------------------
    with ui.card().classes("w-full"):
        ui.label("Write holding registers or coils").classes("text-subtitle1")
        if role != "engineer":
            ui.label("Writes are for engineers (this session may read only).").classes("text-grey-7").props(
                "data-testid=poll-write-note")
            return
        with ui.row().classes("items-end gap-3 flex-wrap"):
            w_unit = range_number("Unit", 1, 254, integer=True, value=min(known) if known else 1).classes("w-24")
            w_kind = ui.select({"register": "holding register(s), 06/16", "coil": "coil(s), 05/15"}, value="register",
                               label="Write").props("dense outlined data-testid=poll-write-kind").classes("w-56")
            w_address = _address_field("Address", 3000, base).classes("w-32")
            w_values = ui.input("Value(s)", value="200", placeholder="e.g. 200 or 1, 2, -30 (coils: 1 0 1)").props(
                "dense outlined").classes("w-56")
            w_multi = ui.checkbox("function 16 (multiple)")
            w_multi.bind_visibility_from(w_kind, "value", value="register")
            w_button = ui.button("Write", icon="edit")
        ui.label("Addresses as chosen above. Every write goes through the send policy of the unit's device type (by the "
                 "line's type for a unit not in the plant): a known device's register asks for a confirmation; its "
                 "read-only, MFR and never-written registers, and coils of a device without coils, are refused.").classes(
            "text-caption text-grey-7")

    async def write(confirmed: bool = False) -> None:
        target = await checked_value(w_unit, "", f"Modbus poll write on {bus}", parameter="unit")
        where = await checked_value(w_address, "", f"Modbus poll write on {bus}", parameter="address")
        if target is None or where is None:
            return  # the field says what it allows; the refusal is in the audit log
        try:
            values = [int(v, 0) for v in str(w_values.value or "").replace(",", " ").split()]
        except ValueError:
            notify_error(f"'{w_values.value}' is not a list of whole numbers")
            return
        if not values:
            notify_error("enter at least one value")
            return
        coils = w_kind.value == "coil"
        if coils and any(v not in (0, 1) for v in values):
            notify_error(f"'{w_values.value}': a coil is 0 or 1")
            return
        address = int(w_address.value or 0) - int(base.value or 0)
        user, role = current_user()  # the account store's answer now, not the page's when it was built
        try:
            if coils:
                await poll.write_coils(int(w_unit.value or 0), address, [bool(v) for v in values], user=user or "anonymous",
                                       role=role, confirmed=confirmed)
            else:
                await poll.write(int(w_unit.value or 0), address, values, user=user or "anonymous", role=role,
                                 confirmed=confirmed, multiple=bool(w_multi.value) or len(values) > 1)
        except mp.NeedsConfirmation as exc:
            with ui.dialog() as dialog, ui.card().classes("w-[32rem]"):
                ui.label(str(exc)).classes("text-body1")
                with ui.row().classes("justify-end w-full"):
                    ui.button("Cancel", on_click=dialog.close).props("flat")

                    async def go() -> None:
                        dialog.close()
                        await write(confirmed=True)

                    ui.button("Write", color="warning", on_click=go).props("data-testid=poll-confirm")
            dialog.open()
            return
        except (mp.PollError, PermissionDenied, AuditUnavailable) as exc:
            notify_error(str(exc))
            return
        except Exception as exc:  # noqa: BLE001 - the line's error, shown
            notify_error(f"write failed: {exc}")
            return
        ui.notify("written", type="positive")

    w_button.on_click(lambda: write())


def _address_field(label: str, value: int, base) -> ui.number:
    """An address entry whose range follows how addresses are counted: 0 .. 65535 (0-based) or 1 .. 65536
    (1-based, register 1 = address 0); a wrong entry stays as typed, marked with the range."""

    def limits() -> tuple[int, int]:
        first = int(base.value or 0)
        return first, mp.ADDRESS_MAX + first

    def check(v) -> str | None:
        if v is None:
            return None
        low, high = limits()
        if float(v) != int(float(v)):
            return f"whole numbers only, {range_text(low, high)}"
        return None if low <= float(v) <= high else f"out of range: {range_text(low, high)}"

    field = ui.number(label, value=value, validation=check).props("dense outlined")

    def show_range() -> None:
        field.rule = range_text(*limits())  # type: ignore[attr-defined]
        field.props(f'hint="{field.rule}"')
        if field.value is not None:
            field.validate()

    show_range()
    base.on_value_change(lambda _: show_range())
    return field
