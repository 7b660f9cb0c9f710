"""Overview: every device of the plant as a tile, grouped by bus."""

from __future__ import annotations

import asyncio
import os
import time

from nicegui import ui

from app import runtime as rt
from app.plant import DEMO_PLANT, DeviceConfig, append_device, can_id_conflict, device_toml
from app.worker import AuditUnavailable, PermissionDenied
from devices.registry import DEVICE_TYPES, format_can_ids
from pages.frame import fmt_age, frame, set_status_badge
from pages.plant_view import evaluate_tile
from pages.widgets import mark_quality, quality_note
from pages.session import current_user


class DeviceTile:
    def __init__(self, name: str):
        runtime = rt.current()
        self.state = runtime.store.devices[name]
        self.device_type = DEVICE_TYPES[self.state.type]
        with ui.card().classes("tile").on("click", lambda: ui.navigate.to(f"/device/{name}")) as self.card:
            self.card.props(f'data-device="{name}"')
            with ui.row().classes("items-center w-full"):
                ui.label(name).classes("text-subtitle1 text-weight-bold")
                ui.space()
                self.badge = ui.badge("waiting", color="grey")
            ui.label(f"{self.device_type.title} on {self.state.bus}").classes("text-caption text-grey-8")
            self.seen = ui.label().classes("text-caption")
            self.values = ui.column().classes("gap-0").props("data-tile-values")
            self.quality_note = ui.label().classes("q-age")
            self.shown: list[str] | None = None
            self.counters = ui.label().classes("text-caption mono text-grey-8")
            self.error = ui.label().classes("text-caption text-negative")
        self.update()

    def update(self) -> None:
        s = self.state
        set_status_badge(self.badge, s.status, s.age)
        self.seen.set_text(f"last seen: {fmt_age(s.age)}")
        tile = evaluate_tile(s)  # the device type's declared tile: the same lines and alarms as the plant view
        quality = tile["quality"]
        lines = list(tile["lines"]) + ([tile["bar"][1]] if tile["bar"] else [])
        alarms = tile["alarms"] if quality in ("good", "unknown") else []
        shown = lines + [f"⚠ {a}" for a in alarms]
        if shown != self.shown:
            self.shown = shown
            self.values.clear()
            with self.values:
                for line in lines:
                    ui.label(line).classes("text-body2")
                for alarm in alarms:
                    ui.label(f"⚠ {alarm}").classes("text-body2 text-negative text-weight-medium")
        mark_quality(self.values, quality if quality in ("stale", "offline") else "good")
        self.quality_note.set_text(quality_note(quality, tile["age"]) if quality in ("stale", "offline") else "")
        c = s.counters.as_dict()
        names = {"requests": "req", "timeouts": "timeouts", "crc_errors": "CRC", "exceptions": "exc",
                 "write_errors": "write err", "malformed": "malformed"}
        self.counters.set_text("  ".join(
            f"{names[k]} {v}" for k, v in c.items() if k in names and (v or k in ("requests", "timeouts"))
        ))
        self.error.set_text(s.last_error if s.status != "online" else "")


def content() -> None:
    runtime = rt.current()
    with frame("Overview"):
        tiles: list[DeviceTile] = []
        for bus in runtime.plant.buses.values():
            bus_state = runtime.store.buses[bus.name]
            with ui.row().classes("items-center gap-2"):
                ui.icon("cable")
                ui.label(f"{bus.name}").classes("text-h6")
                ui.label(f"{bus.type} · {bus.endpoint}").classes("text-caption text-grey-8")
                conn = ui.label().classes("text-caption")
                ui.button("Bus monitor", icon="monitor_heart", on_click=lambda b=bus.name: ui.navigate.to(f"/monitor/{b}")).props("flat dense")
                if bus.type == "modbus-rtu":
                    from pages.discover import open_discover_dialog

                    ui.button("Discover locks", icon="search", on_click=lambda b=bus.name: open_discover_dialog(b)).props("flat dense")

            def show_conn(label=conn, state=bus_state) -> None:
                text = "connected" if state.connected else f"not connected: {state.last_error or 'opening...'}"
                if state.connected and hasattr(state, "bus_state"):
                    text += f" · {state.bus_state} · {state.rx_frames} frames in, {state.error_frames} error frames"
                shed = getattr(state, "shed", 0)
                if shed:  # the program could not keep up with this bus: say so rather than lag
                    text += f" · {shed} frames shed: more traffic than this program can handle"
                label.set_text(text)
                ok = state.connected and getattr(state, "bus_state", "") != "bus-off"
                label.classes(replace="text-caption " + (("text-warning" if shed else "text-positive") if ok else "text-negative"))

            show_conn()
            ui.timer(1.0, show_conn)
            with ui.row().classes("gap-4") as row:
                for dev in runtime.plant.devices_on(bus.name):
                    tiles.append(DeviceTile(dev.name))
            if bus.type == "can":
                _discovered_section(bus.name, row, tiles)
        if not runtime.plant.devices:
            ui.label("This plant file lists no devices.").classes("text-grey-8")

        def update() -> None:
            for tile in tiles:
                tile.update()

        ui.timer(1.0, update)


def _discovered_section(bus: str, tile_row, tiles: list) -> None:
    """Devices heard on a CAN bus that the plant does not list yet, with Adopt.

    Only devices that showed the evidence their type needs are listed; unknown IDs still
    being watched, and what was left out, are counted below the list.
    """
    runtime = rt.current()
    box = ui.column().classes("gap-1").props(f'data-discovered="{bus}"')
    shown: list = [None]

    ages: dict = {}  # key -> the label with evidence and age, updated in place (the Adopt button stays put)

    def age_text(entry: dict) -> str:
        return f"{entry.get('evidence') or ''} · {entry['frames']} frames, last {fmt_age(time.time() - entry['last_seen'])}"

    def refresh() -> None:
        entries = list(runtime.worker.discovered.get(bus, {}).items())
        summary = runtime.worker.discovery_summary(bus)
        watching = summary.get("candidates", 0)
        left_out = summary.get("dropped", 0) + summary.get("listed_dropped", 0)
        signature = ([k for k, _e in entries], watching, left_out)
        if signature == shown[0]:
            for key, entry in entries:  # only the texts change: rows and buttons are not rebuilt under the mouse
                if key in ages:
                    ages[key].set_text(age_text(entry))
            return
        shown[0] = signature
        box.clear()
        ages.clear()
        if not entries and not watching and not left_out:
            return
        with box:
            if entries:
                ui.label(f"Discovered on {bus}, not in the plant file").classes("text-subtitle2")
            for key, entry in entries:
                with ui.row().classes("items-center gap-3"):
                    ui.icon("fiber_new", color="orange")
                    ident = f"{entry['device_id']} ({'ext' if entry['extended'] else 'std'} 0x{entry['device_id']:X})"
                    title = DEVICE_TYPES[entry["type"]].title
                    ui.label(f"{title} with device ID {ident}").classes("text-body2")
                    ages[key] = ui.label(age_text(entry)).classes("text-caption text-grey-8")
                    ui.button("Adopt", icon="add", on_click=lambda e=entry: _adopt_dialog(bus, e, tile_row, tiles)).props("dense outline").props(
                        f'data-adopt="{entry["device_id"]}"'
                    )
            notes = []
            if watching:
                rules = "; ".join(summary.get("rules") or [])
                notes.append(f"watching {watching} unknown ID{'s' if watching != 1 else ''}" + (f" (listed after {rules})" if rules else ""))
            if left_out:
                notes.append(f"{left_out} left out: too many unknown IDs at once")
            if notes:
                ui.label("Discovery on " + bus + ": " + "; ".join(notes)).classes("text-caption text-grey-8").props("data-discovery-note")

    refresh()
    ui.timer(2.0, refresh)


def _adopt_dialog(bus: str, entry: dict, tile_row, tiles: list) -> None:
    runtime = rt.current()
    suggested = f"{entry['type']}-{entry['device_id']}"
    path = runtime.plant.path
    bus_config = runtime.plant.buses[bus]
    device_type = DEVICE_TYPES[entry["type"]]

    def config(name: str) -> DeviceConfig:
        return DeviceConfig(name, entry["type"], bus, {"device_id": entry["device_id"], "extended": entry["extended"]})

    # the same check as the plant loader and the worker: one CAN ID, one sender (HD-Lock document 6.2 b)
    conflict = can_id_conflict(runtime.plant.devices_on(bus) + [config(suggested)], bus_config)

    with ui.dialog() as dialog, ui.card().classes("w-[34rem] max-w-full"):
        ui.label("Adopt a discovered device").classes("text-h6")
        name = ui.input("Name in the plant", value=suggested).props("outlined dense")
        own = [u for u in device_type.can_id_uses(config(suggested).options, "can") if not u.shared]
        if own:
            ui.label("CAN IDs it uses: " + "; ".join(f"{format_can_ids(u.first, u.last, u.extended)} {u.use}" for u in own)).classes(
                "text-caption")
        ui.label("Lines for the plant file:").classes("text-caption text-grey-8")
        lines = ui.code(device_toml(config(suggested)), language="toml").classes("w-full")
        name.on_value_change(lambda e: lines.set_content(device_toml(config(e.value or suggested))))
        writable = path is not None and path.exists() and os.access(path, os.W_OK) and path.resolve() != DEMO_PLANT.resolve()
        note = f"Write appends them to {path}." if writable else "The plant file cannot be written here (built-in or read-only): copy the lines."
        ui.label(note).classes("text-caption")
        if conflict is not None:
            ui.label("Cannot be adopted: " + conflict[1].split(": ", 1)[-1]).classes("text-body2 text-negative").props("data-adopt-conflict")

        async def take(write: bool) -> None:
            dev = config(name.value or suggested)
            user, role = current_user()

            async def adopt() -> None:
                if write:
                    await asyncio.to_thread(append_device, path, dev)
                runtime.worker.adopt(dev)

            try:
                # it changes the running plant (and the plant file): an engineer action, audited
                await runtime.worker.engineer_action(
                    adopt, user=user, role=role, target=dev.name, new=device_toml(dev).strip(),
                    describe="adopt discovered device" + (f" and append it to {path.name}" if write else ""))
            except (ValueError, OSError, PermissionDenied, AuditUnavailable) as exc:
                ui.notify(f"Cannot adopt: {exc}", type="negative", multi_line=True)
                return
            with tile_row:
                tiles.append(DeviceTile(dev.name))
            ui.notify(f"{dev.name} added to the running plant" + (f" and to {path.name}" if write else ""), type="positive")
            dialog.close()

        with ui.row().classes("justify-end w-full"):
            ui.button("Cancel", on_click=dialog.close).props("flat")
            add_button = ui.button("Add to the running plant", on_click=lambda: take(False)).props("outline")
            write_button = ui.button("Add and write to the plant file", on_click=lambda: take(True))
            if not writable or conflict is not None:
                write_button.disable()
            if conflict is not None:
                add_button.disable()
    dialog.open()
