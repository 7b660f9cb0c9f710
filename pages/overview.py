"""Overview: every device of the plant as a tile, grouped by bus."""

from __future__ import annotations

from nicegui import ui

from app import runtime as rt
from devices.registry import DEVICE_TYPES
from pages.frame import fmt_age, frame, set_status_badge


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
            self.values = ui.column().classes("gap-0")
            with self.values:
                self.value_labels = {key: ui.label().classes("text-body2") for key in self.device_type.key_values}
            self.counters = ui.label().classes("text-caption mono text-grey-8")
            self.error = ui.label().classes("text-caption text-negative")
        self.update()

    def update(self) -> None:
        s = self.state
        set_status_badge(self.badge, s.status, s.age)
        self.seen.set_text(f"last seen: {fmt_age(s.age)}")
        values = s.values()
        for key, label in self.value_labels.items():
            entry = values.get(key)
            label.set_text(f"{key}: {entry['text'] if entry else '-'}")
        if s.status in ("stale", "offline"):
            self.values.classes(add="stale")
        else:
            self.values.classes(remove="stale")
        c = s.counters
        self.counters.set_text(
            f"req {c.requests}  timeouts {c.timeouts}  CRC {c.crc_errors}  exc {c.exceptions}  write err {c.write_errors}"
        )
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
                label.set_text("connected" if state.connected else f"not connected: {state.last_error or 'opening...'}")
                label.classes(replace="text-caption " + ("text-positive" if state.connected else "text-negative"))

            show_conn()
            ui.timer(1.0, show_conn)
            with ui.row().classes("gap-4"):
                for dev in runtime.plant.devices_on(bus.name):
                    tiles.append(DeviceTile(dev.name))
        if not runtime.plant.devices:
            ui.label("This plant file lists no devices.").classes("text-grey-8")

        def update() -> None:
            for tile in tiles:
                tile.update()

        ui.timer(1.0, update)
