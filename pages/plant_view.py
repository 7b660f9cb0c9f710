"""Read-only plant view for a tablet: one large tile per device, alarms highlighted, stale data greyed.

There are no write controls on this page by construction: it only reads the state store.
"""

from __future__ import annotations

from nicegui import ui

from app import runtime as rt
from devices.registry import DEVICE_TYPES
from pages.frame import CSS, fmt_age
from pages.widgets import mark_quality

BADGE = {"good": ("live", "positive"), "stale": ("stale: {age}", "warning"), "offline": ("offline: last {age}", "negative"),
         "unknown": ("waiting", "grey")}


def evaluate_tile(state) -> dict:
    """The device type's declared tile, evaluated against the device's live points (quality and age included)."""
    import time

    now = time.time()
    # only the values the tile declares: registers and published points alike, each with its quality
    return DEVICE_TYPES[state.type].tile.evaluate(lambda name: state.entry(name, now), now)

TILE_CSS = """
.plant-grid { display: grid; grid-template-columns: repeat(auto-fill, minmax(300px, 1fr)); gap: 16px; width: 100%; }
.plant-tile { min-height: 170px; border-left: 10px solid #21ba45; font-size: 18px; }
.plant-tile.alarm { border-left-color: #c10015; background: #fff0f0; }
.plant-tile.q-stale, .plant-tile.q-offline { border-left-color: #9e9e9e; text-decoration: none; }
.plant-tile .name { font-size: 22px; font-weight: 600; white-space: nowrap; }
.plant-tile .head { min-width: 0; flex: 1 1 auto; }
.plant-tile .q-badge { flex: 0 1 auto; max-width: 45%; white-space: normal; text-align: right; }
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
                with ui.column().classes("gap-0 head"):
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
        tile = evaluate_tile(self.state)
        quality = tile["quality"]
        text, color = BADGE[quality]
        self.status.set_text(text.format(age=fmt_age(tile["age"])))
        self.status.props(f"color={color}")
        self.icon.name = tile["icon"]
        self.icon.update()
        if tile["lines"] != getattr(self, "_lines", None):
            self._lines = tile["lines"]
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
        alarms = tile["alarms"] if quality in ("good", "unknown") else []  # old data raises no alarms
        if alarms != getattr(self, "_alarms", None):
            self._alarms = alarms
            self.alarms.clear()
            with self.alarms:
                for alarm in alarms:
                    ui.label(f"⚠ {alarm}").classes("alarm-text")
        mark_quality(self.card, quality if quality in ("stale", "offline") else "good")
        self.card.classes(remove="alarm")
        if alarms:
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
