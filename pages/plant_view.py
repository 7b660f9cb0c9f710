"""Read-only plant view for a tablet: one large tile per device, alarms highlighted, stale data greyed.

There are no write controls on this page by construction: it only reads the state store.
"""

from __future__ import annotations

from nicegui import ui

from app import runtime as rt
from devices.registry import DEVICE_TYPES
from pages.frame import CSS, STATUS_COLOR, fmt_age

TILE_CSS = """
.plant-grid { display: grid; grid-template-columns: repeat(auto-fill, minmax(300px, 1fr)); gap: 16px; width: 100%; }
.plant-tile { min-height: 170px; border-left: 10px solid #21ba45; font-size: 18px; }
.plant-tile.alarm { border-left-color: #c10015; background: #fff0f0; }
.plant-tile.stale, .plant-tile.offline { border-left-color: #9e9e9e; filter: grayscale(1); opacity: 0.6; }
.plant-tile .name { font-size: 22px; font-weight: 600; }
.plant-tile .alarm-text { color: #c10015; font-weight: 600; }
"""


class PlantTile:
    def __init__(self, name: str):
        runtime = rt.current()
        self.state = runtime.store.devices[name]
        self.device_type = DEVICE_TYPES[self.state.type]
        with ui.card().classes("plant-tile") as self.card:
            self.card.props(f'data-plant-tile="{name}"')
            with ui.row().classes("items-center w-full no-wrap"):
                self.icon = ui.icon("help", size="40px")
                with ui.column().classes("gap-0"):
                    ui.label(name).classes("name")
                    ui.label(f"{self.device_type.title} · {self.state.bus}").classes("text-body2 text-grey-8")
                ui.space()
                self.status = ui.badge().classes("text-body1")
            self.lines = ui.column().classes("gap-0")
            self.bar = ui.linear_progress(value=0, show_value=False, size="18px").classes("q-mt-sm")
            self.bar_label = ui.label().classes("text-body1")
            self.alarms = ui.column().classes("gap-0")
        self.update()

    def update(self) -> None:
        s = self.state
        tile = self.device_type.plant_tile(s) if self.device_type.plant_tile else {"lines": [], "alarms": [], "bar": None, "icon": "memory"}
        status = s.status
        self.status.set_text({"online": "live", "stale": f"stale: {fmt_age(s.age)}", "offline": f"offline: last {fmt_age(s.age)}",
                              "unknown": "waiting"}[status])
        self.status.props(f"color={STATUS_COLOR[status]}")
        self.icon.name = tile["icon"]
        self.icon.update()
        self.lines.clear()
        with self.lines:
            for line in tile["lines"]:
                ui.label(line)
        bar = tile["bar"]
        self.bar.set_visibility(bar is not None)
        self.bar_label.set_visibility(bar is not None)
        if bar is not None:
            self.bar.set_value(bar[0])
            self.bar_label.set_text(bar[1])
        self.alarms.clear()
        alarms = tile["alarms"] if status == "online" else []
        with self.alarms:
            for alarm in alarms:
                ui.label(f"⚠ {alarm}").classes("alarm-text")
        self.card.classes(remove="alarm stale offline")
        if status in ("stale", "offline"):
            self.card.classes(add=status)
        elif alarms:
            self.card.classes(add="alarm")


def content() -> None:
    runtime = rt.current()
    ui.add_css(CSS + TILE_CSS)
    ui.page_title(f"{runtime.plant.name} - plant view")
    with ui.header().classes("items-center bg-blue-grey-9"):
        ui.label(f"Plant {runtime.plant.name}").classes("text-h5 text-white")
        ui.space()
        clock = ui.label().classes("text-h6 text-white")
    with ui.element("div").classes("plant-grid q-pa-md"):
        tiles = [PlantTile(name) for name in runtime.plant.devices]
    if not tiles:
        ui.label("This plant file lists no devices.").classes("q-pa-md")

    def update() -> None:
        import time

        clock.set_text(time.strftime("%H:%M:%S"))
        for tile in tiles:
            tile.update()

    update()
    ui.timer(1.0, update)
