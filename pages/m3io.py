"""CAN-M3IO page: inputs, SSR channels with fuse/triac/load, temperatures, watchdog, addressed data."""

from __future__ import annotations

import inspect
from datetime import datetime

from nicegui import ui

from app import runtime as rt
from app.worker import DEADMAN_BOUND_S
from devices.m3io import codec
from devices.m3io.codec import Variant
from pages.frame import fmt_age, frame, set_status_badge
from pages.session import current_user
from pages.widgets import (
    sim_card_allowed,
    HistoryChart,
    Lamp,
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
    stop_bar,
)

STATE_COLOR = {"ok": "positive", "present": "positive", "blown": "negative", "defective": "negative"}
VARIANT_COLOR = {"ok": "text-positive", "mismatch": "text-negative text-weight-medium", "unchecked": "text-grey-8", "not possible": "text-warning"}
STOP_RULE = (
    "Outputs belong to the page that switched them on: they go off at once when that page is closed or reloaded, "
    f"or within {DEADMAN_BOUND_S:g} s when it stops confirming that it is alive (frozen tab, sleeping laptop, lost network). "
    "Another open tab does not keep them on. While you control the module this tool serves its 2 s watchdog, "
    "and it switches the outputs off by itself if the program stalls."
)


def temp_text(variant: Variant, channel: int, word: codec.TempWord) -> str:
    """``21.5 °C`` or ``out of range (-5.0 °C)``: the reading in the bus monitor's words (codec.describe_temp, 7.2.2)."""
    return codec.describe_temp(variant, channel, word).split(" · ", 1)[0].split(" ", 1)[1]


def content(name: str) -> None:
    runtime = rt.current()
    state = runtime.store.devices[name]
    adapter = runtime.worker.adapters[name]
    twin = runtime.twins.get(name)
    ids = adapter.ids
    session = ui.context.client.id  # outputs switched on here belong to this page session

    async def act(describe: str, fn, success: str = "", write: bool = True):
        async def action(a):
            result = fn(a)
            return await result if inspect.isawaitable(result) else result

        return await run_command(name, action, describe, success=success, write=write)

    with frame(f"CAN-M3IO {name} ({adapter.variant.value})"):
        guard = WriteGuard(state)  # switches and commands, disabled with the reason while the module does not answer
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-6 w-full"):
                badge = ui.badge("waiting", color="grey").classes("text-body2")
                watchdog = ui.label().classes("text-body2")
                counter_line(state, lambda c: f"frames in {c.responses} · requests {c.requests} · timeouts {c.timeouts} · "
                             f"malformed {c.malformed} · write errors {c.write_errors}")
            ui.label(
                f"SW1 0x{adapter.sw1:02X} ({adapter.sw1:08b}): "
                + ("addressed mode (S8 on), " if ids.addressed else "S8 off, ")
                + f"{ids.bitrate // 1000} kbit/s · "
                + " · ".join(f"{k} 0x{v:03X}" for k, v in ids.by_name().items())
            ).classes("text-body2 mono")
            variant_line = ui.label().classes("text-body2").props("data-testid=variant-check")
            # the module is a slave: this tool serves its watchdog (DigOut) only while an engineer controls it
            with ui.row().classes("items-center gap-3"):
                take = ui.button("Take control", icon="sports_esports", on_click=lambda: act(
                    "take control", lambda a: a.take_control(session, current_user()[0] or "local engineer"),
                    success="you control the module: DigOut serves its watchdog")).props("data-testid=take-control")
                take.tooltip(f"Listens for another master (a PLC sending DigOut 0x{ids.dig_out:03X}) first; refused if there is one")
                ui.button("Release", icon="logout", on_click=lambda: act(
                    "release control", lambda a: a.release_control(session), write=False)).props("outline data-testid=release-control")
                holder = ui.label().classes("text-body2").props("data-testid=controller")
            if state.info.get("bitrate_mismatch"):
                ui.label(
                    f"SW1 sets {ids.bitrate // 1000} kbit/s, but the bus runs at {state.info['bus_bitrate'] // 1000} kbit/s: "
                    "the module cannot be reached. Fix SW1 or the bus bit rate in the plant file."
                ).classes("text-negative text-body1")

        # side by side from 1024 px; one above the other on a tablet, where the chart would get a third of the width
        with ui.row().classes("w-full items-start gap-4"):
            with ui.card().classes("col-xs-12 col-md"):
                ui.label("Digital inputs").classes("text-subtitle1")
                with ui.row().classes("gap-5"):
                    input_lamps = {f"E{i}": Lamp(f"E{i}") for i in range(1, 7)}
                ui.separator()
                with ui.row().classes("items-center w-full"):
                    ui.label("Outputs").classes("text-subtitle1")
                    ui.space()
                    ui.label("All off: in the bar at the bottom, always in sight").classes("text-caption text-grey-8")
                with ui.row().classes("items-start gap-1 no-wrap").props("data-testid=stop-rule"):
                    ui.icon("front_hand", size="xs").classes("text-grey-8 q-mt-xs")
                    ui.label(STOP_RULE).classes("text-caption text-grey-8")
                refused = ui.label().classes("text-negative text-body2")
                led = ui.switch("LED (Bereit)", on_change=lambda e: _switch(act, adapter, session, "LED", e, mains=False))
                led.props("data-output=LED")
                guard.add(led)
                channel_rows = _channels(adapter, act, session, guard) if adapter.variant is not Variant.KM else {}
                if adapter.variant is Variant.HMR:
                    with ui.row().classes("items-center"):
                        p2 = ui.switch("Three-phase output loaded on two phases only (P2)",
                                       on_change=lambda e: act("P2", lambda a: a.set_two_phase(e.value)))
                        guard.add(p2)
                        ui.label("not stored in the module: sent with every DigOut, so a reset cannot lose it").classes(
                            "text-caption text-grey-8"
                        )
            if adapter.variant is not Variant.KM:
                with ui.card().classes("col-xs-12 col-md"):
                    ui.label("Pt100 temperatures (0.1 °C)").classes("text-subtitle1")
                    temp_labels, temp_notes = {}, {}
                    with ui.row().classes("gap-6"):
                        for channel in adapter.temp_channels():
                            with ui.column().classes("gap-0"):
                                ui.label(f"TEMP{channel}" + (" (SSR1-3)" if adapter.variant is Variant.HMR and channel == 1 else "")).classes(
                                    "text-caption text-grey-8"
                                )
                                temp_labels[channel] = ui.label("-").classes("text-h6").props(f'data-temp="{channel}"')
                                temp_notes[channel] = ui.label().classes("q-age q-ml-none")
                    chart = HistoryChart(state, [adapter.temp_label(c) for c in adapter.temp_channels()], window_s=600, height=260)
            else:
                temp_labels, chart = {}, None

        if twin is not None:
            _sim_card(twin, adapter)
        if ids.addressed:
            _addressed_card(name, state, adapter, guard)

        with ui.expansion("Events", icon="list", value=True).classes("w-full"):
            event_log(state)

    stop_bar("Switches every output off at once; anyone may, also without writing rights.", "All off", "power_off",
             lambda: act("all off", lambda a: a.all_off("all off pressed"), write=False), "off-bar", "all-off")

    def update() -> None:
        set_status_badge(badge, state.status, state.age)
        served = adapter.bus.cyclic_running(adapter.key)
        last = adapter.last_answer
        foreign = adapter.foreign_master()
        watchdog.set_text(
            (f"watchdog served: DigOut every {codec.DIGOUT_PERIOD_S * 1000:.0f} ms"
             + (" (every output off: nobody controls the module)" if adapter.controller is None else "") if served
             else "watchdog served by another master (a PLC): this tool only listens" if foreign
             else "watchdog not served: outputs are off in the module; take control to serve it")
            + f" · last answer {fmt_age(None if last is None else datetime.now().timestamp() - last)}"
        )
        watchdog.classes(replace="text-body2 " + ("text-positive" if served else "text-warning" if foreign else "text-grey-8"))
        controller = adapter.controller
        holder.set_text(("you control the module" if controller.session == session else f"{controller.user} controls the module")
                        if controller else "nobody controls the module")
        check = adapter.variant_check
        variant_line.set_text(f"Variant {adapter.variant.value}: {check.text}")
        variant_line.classes(replace="text-body2 " + VARIANT_COLOR[check.state])
        refused.set_text("" if check.may_switch else f"Switching on is refused: {check.text}")
        refused.set_visibility(not check.may_switch)
        for key, lamp in input_lamps.items():
            lamp.show(state.point(key))
        led.set_value(adapter.outputs["LED"])
        for refresh in channel_rows.values():
            refresh()
        if adapter.variant is Variant.HMR:
            p2.set_value(adapter.two_phase)
        for channel, label in temp_labels.items():
            word = adapter.temps.get(channel)
            label.set_text("-" if word is None else temp_text(adapter.variant, channel, word))
            label.classes(replace="text-h6 " + ("" if word is None or word.in_range else "text-warning"))
            entry = state.point(f"TEMP{channel}")
            quality = "unknown" if entry is None else entry["quality"]
            mark_quality(label, quality)
            temp_notes[channel].set_text(quality_note(quality, entry_age(entry)) if quality in ("stale", "offline") else "")

    update()
    follow(state, update)  # on every change the store pushes (at most 10/s) and once a second for the ages


async def _switch(act, adapter, session: str, output: str, event, mains: bool = True) -> None:
    value = event.value
    if value == adapter.outputs[output]:
        return
    if value and mains:
        three = output == "SSR1-3"
        ok = await confirm(
            f"Switch {output} on?",
            ("The three-phase output (400 V) " if three else "This output switches mains voltage (230/400 V) ")
            + "to the connected load. Make sure nobody works on it.",
            ok="Switch on",
        )
        if not ok:
            event.sender.set_value(False)
            return
    ok, _ = await act(f"{output} {'on' if value else 'off'}", lambda a: a.set_output(session, output, value), write=value)
    if not ok:
        event.sender.set_value(adapter.outputs[output])


def _channels(adapter, act, session: str, guard: WriteGuard) -> dict:
    """One row per SSR channel (HMR: SSR1-3 as one three-phase channel)."""
    rows = {}
    groups = [("SSR1-3", [1, 2, 3])] + [(f"SSR{i}", [i]) for i in (4, 5, 6)] if adapter.variant is Variant.HMR else [
        (f"SSR{i}", [i]) for i in range(1, 7)
    ]
    with ui.column().classes("w-full gap-1"):
        for output, channels in groups:
            with ui.row().classes("items-center w-full gap-3 no-wrap") as row:
                row.props(f'data-channel="{output}"')
                switch = ui.switch(output, on_change=lambda e, o=output: _switch(act, adapter, session, o, e)).classes("w-32")
                switch.props(f'data-output="{output}"')
                guard.add(switch)
                details = ui.column().classes("gap-1 col")
                age = ui.label().classes("q-age")
            if output == "SSR1-3":
                ui.label("Three-phase output: a fault on one of SSR1, SSR2, SSR3 switches all three off.").classes("text-caption text-grey-8")

            shown: list = [None]

            def refresh(switch=switch, details=details, age=age, output=output, channels=channels, shown=shown) -> None:
                switch.set_value(adapter.outputs[output])
                owner = adapter.owners.get(output)
                foreign = adapter.outputs[output] and owner is not None and owner != session
                group_fault = adapter.group_load_fault() if output == "SSR1-3" else None
                view = (foreign, group_fault, tuple(
                    (adapter.channels[c].load, adapter.channels[c].fuse, adapter.channels[c].triac, c in adapter.temps) for c in channels
                ))
                entry = adapter.state.point(f"SSR{channels[0]} Last")
                quality = "unknown" if entry is None else entry["quality"]
                mark_quality(details, quality)  # greyed, with the age of its status, while stale or offline
                age.set_text(quality_note(quality, entry_age(entry)) if quality in ("stale", "offline") else "")
                if view == shown[0]:
                    return  # rebuild only what changed
                shown[0] = view
                details.clear()
                with details:
                    if foreign:
                        ui.label("switched on from another page: it goes off when that page goes away").classes("text-caption text-warning")
                    if group_fault:
                        ui.label(group_fault).classes("text-negative text-body2")
                    for channel in channels:
                        m = adapter.channels[channel]
                        with ui.row().classes("items-center gap-2"):
                            if len(channels) > 1:
                                ui.label(f"SSR{channel}").classes("text-caption mono")
                            for title, value in (("load", m.load), ("fuse", m.fuse), ("triac", m.triac)):
                                color = STATE_COLOR.get(value, "grey")
                                ui.badge(f"{title}: {value}", color=color).props(f'data-{title}="{value}" outline={color == "grey"} multi-line')
                            if channel not in adapter.temps:
                                ui.label("no status yet").classes("text-caption text-grey-8")
                        if m.fuse == "blown":
                            ui.label(codec.fuse_advice(adapter.variant, channel)).classes("text-negative text-body2")
                        if m.triac == "defective":
                            ui.label("triac defective: it does not conduct while switched on").classes("text-negative text-body2")

            rows[output] = refresh
    return rows


def _sim_card(twin, adapter) -> None:
    with ui.card().classes("w-full bg-purple-1"):
        ui.label("Simulated module (demo)").classes("text-subtitle1")
        if not sim_card_allowed():  # a viewer changes nothing, the simulated plant included
            return
        with ui.row().classes("items-center"):
            for i in range(1, 7):
                ui.button(f"E{i}", on_click=lambda i=i: twin.toggle_input(f"E{i}")).props("outline dense")
            ui.label("toggle inputs").classes("text-caption")
        if adapter.variant is not Variant.KM:
            with ui.row().classes("items-center gap-2"):
                channel = ui.select({i: f"SSR{i}" for i in range(1, 7)}, value=1, label="Channel").props("dense outlined").classes("w-28")
                ui.button("Remove load", on_click=lambda: setattr(twin.ssr[channel.value], "load", False)).props("outline dense")
                ui.button("Connect load", on_click=lambda: setattr(twin.ssr[channel.value], "load", True)).props("outline dense")
                ui.button("Blow fuse", on_click=lambda: setattr(twin.ssr[channel.value], "fuse_ok", False)).props(
                    "outline dense color=negative data-testid=sim-blow-fuse"
                )
                ui.button("Break triac", on_click=lambda: setattr(twin.ssr[channel.value], "triac_ok", False)).props("outline dense color=negative")
                ui.button("Short triac", on_click=lambda: setattr(twin.ssr[channel.value], "triac_shorted", True)).props("outline dense color=negative")
                ui.button("Repair", on_click=lambda: _repair(twin.ssr[channel.value])).props("outline dense")
            with ui.row().classes("items-center gap-2"):
                temp = ui.number("Temperature °C", value=25.0, step=0.5).props("dense outlined").classes("w-40")
                ui.button("Set", on_click=lambda: twin.set_temperature(channel.value, float(temp.value or 0))).props("outline dense")
                ui.button("Cut 24 V (reset)", on_click=twin.power_cycle).props("outline dense data-testid=sim-power-cycle")
                ui.label("The module reports a blown fuse until its 24 V are cut, even after repair.").classes("text-caption")


def _repair(ssr) -> None:
    ssr.fuse_ok = ssr.triac_ok = True
    ssr.triac_shorted = False


def _addressed_card(name: str, state, adapter, guard: WriteGuard) -> None:
    with ui.card().classes("w-full"):
        ui.label("Addressed data (SW1 switch 8 on)").classes("text-subtitle1")
        identity = ui.label("not read").classes("text-body2")

        async def read_identity() -> None:
            ok, info = await run_command(name, lambda a: a.read_identity(), "read identity", write=False)
            if ok:
                identity.set_text(
                    f"serial {info['serial']} · product 0x{info['product_code']:04X} {info['product']} · "
                    f"software {info['version']} · configuration 0x{info['config']:02X}"
                )

        guard.add(ui.button("Read identity", icon="badge", on_click=read_identity).props("outline dense"))
        ui.separator()
        ui.label("Customer data (15 records of 6 bytes)").classes("text-body2 text-weight-medium")
        with ui.row().classes("items-center"):
            # records 1-15 of 6 bytes (section 7.2.4.2, areas 3 and 4)
            index = range_number("Record", 1, 15, integer=True, value=1).classes("w-32").props("data-testid=record")
            data = ui.input("Bytes (hex, up to 6)", placeholder="01 02 03", validation=_bytes_check).props(
                "dense outlined data-testid=record-bytes").classes("w-56 mono")
            record = ui.label().classes("mono")

            async def read_record() -> None:
                number = await checked_value(index, name, "read customer data", parameter="Customer data")
                if number is None:
                    return
                ok, payload = await run_command(name, lambda a: a.read_customer(int(number)), "read customer data", write=False)
                if ok:
                    record.set_text(f"record {int(number)}: {payload.hex(' ')}")

            async def write_record() -> None:
                number = await checked_value(index, name, "write customer data", parameter="Customer data")
                reason = _bytes_check(data.value)
                if reason is not None:
                    data.validate()
                    await refuse(name, "write customer data", f"{data.value!r}: {reason}", parameter="Customer data", new=data.value)
                if number is None or reason is not None:
                    return
                payload = bytes.fromhex(data.value or "")
                ok, stored = await run_command(name, lambda a: a.write_customer(int(number), payload), "write customer data",
                                               success="written and verified", parameter=f"Customer data {int(number)}",
                                               new=payload.hex(" "))
                if ok:
                    record.set_text(f"record {int(number)}: {stored.hex(' ')} (verified)")

            guard.add(ui.button("Read", on_click=read_record).props("outline dense"),
                      ui.button("Write", on_click=write_record).props("dense data-testid=record-write"))
        ui.separator()
        loads = ui.label().classes("text-body2 mono")

        async def read_loads() -> None:
            ok, result = await run_command(name, lambda a: a.read_load_data(), "read load data", write=False)
            if ok:
                loads.set_text(" · ".join(
                    f"SSR{i}: {w.text()} load {int(w.load)} triac {int(w.triac)} fuse {int(w.fuse)}" for i, w in result.items()
                ))

        guard.add(ui.button("Read actual load data SSR1-6", on_click=read_loads).props("outline dense"))


def _bytes_check(text) -> str | None:
    """Customer data: up to 6 bytes as hex (section 7.2.4.2: 6 data bytes per record)."""
    try:
        payload = bytes.fromhex(text or "")
    except ValueError:
        return "bytes as hex, e.g. 01 02 0A"
    return None if len(payload) <= 6 else f"at most 6 bytes ({len(payload)} entered)"
