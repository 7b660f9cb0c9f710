"""Read-only plant view for a tablet: one large tile per device, alarms highlighted, stale data greyed.

There are no write controls on this page by construction: it only reads the state store.
"""

from __future__ import annotations

import time

from nicegui import ui

from app import runtime as rt
from devices.registry import DEVICE_TYPES
from pages.frame import CSS, fmt_age
from pages.widgets import follow, mark_quality

BADGE = {"good": ("live", "positive"), "stale": ("stale", "warning"), "offline": ("offline", "negative"),
         "unknown": ("waiting", "grey")}
AGE_NOTE = {"stale": "stale: last heard {age}", "offline": "offline: last heard {age}"}  # below the name: the badge stays one word


def evaluate_tile(state) -> dict:
    """The device type's declared tile, evaluated against the device's live points (quality and age included)."""
    now = time.time()
    # only the values the tile declares: registers and published points alike, each with its quality
    tile = DEVICE_TYPES[state.type].tile.evaluate(lambda name: state.entry(name, now), now)
    if tile["quality"] == "unknown" and state.online is False:  # never heard and given up on: offline, not "waiting"
        tile["quality"] = "offline"
    return tile


# Tiles of equal width; four columns on a 1024 px wide tablet, three on 768 px: the demo plant's ten tiles fit 1024x768.
TILE_CSS = """
.plant-grid { display: grid; grid-template-columns: repeat(auto-fill, minmax(232px, 1fr)); gap: 10px; width: 100%; }
.plant-tile { min-width: 0; border-left: 10px solid #21ba45; font-size: 16px; line-height: 1.35; }
.plant-tile.q-card { padding: 8px 10px; gap: 4px; }
.plant-tile .age-note:empty, .plant-tile .q-age:empty { display: none; }
.plant-tile.alarm { border-left-color: #c10015; background: #fff0f0; }
.plant-tile.q-stale, .plant-tile.q-offline { border-left-color: #9e9e9e; text-decoration: none; }
.plant-tile .head { min-width: 0; flex: 1 1 auto; overflow: hidden; }
.plant-tile .head > * { max-width: 100%; }
.plant-tile .name, .plant-tile .kind { white-space: nowrap; overflow: hidden; text-overflow: ellipsis; }
.plant-tile .name { font-size: 20px; font-weight: 600; }
.plant-tile .q-badge { flex: none; white-space: nowrap; }
.plant-tile .alarm-text { color: #c10015; font-weight: 600; }
.plant-tile .age-note { font-size: 14px; color: #555; }
.plant-more { position: fixed; bottom: 6px; right: 12px; background: #37474f; color: white; padding: 2px 10px; border-radius: 10px; }
"""

# when the tiles do not fit the screen, say so (the page scrolls; the note names how many are below); runs in the browser
MORE_JS = """<script>
(() => { const mark = () => { const more = document.querySelector('.plant-more'); if (!more) return;
  const below = [...document.querySelectorAll('[data-plant-tile]')].filter(t => t.getBoundingClientRect().bottom > window.innerHeight + 1).length;
  more.textContent = below ? `${below} more below: scroll down` : ''; more.style.display = below ? '' : 'none'; };
  window.addEventListener('resize', mark); window.addEventListener('scroll', mark); setInterval(mark, 2000); })();
</script>"""


class TextPool:
    """Labels in a column, reused: a new list of texts sets only the texts that changed (rows are not rebuilt)."""

    def __init__(self, classes: str):
        self.column = ui.column().classes("gap-0 w-full")
        self.classes = classes
        self.labels: list[ui.label] = []
        self.texts: list[str] = []

    def show(self, texts: list[str]) -> None:
        if texts == self.texts:
            return
        while len(self.labels) < len(texts):
            with self.column:
                self.labels.append(ui.label().classes(self.classes))
        for n, label in enumerate(self.labels):
            text = texts[n] if n < len(texts) else ""
            label.set_text(text)
            visible = n < len(texts)
            if label.visible != visible:
                label.set_visibility(visible)
        self.texts = list(texts)


class PlantTile:
    """One large tile, following the live store: each push sets only what changed."""

    def __init__(self, name: str):
        runtime = rt.current()
        self.state = runtime.store.devices[name]
        self.device_type = DEVICE_TYPES[self.state.type]
        self._shown: dict[str, object] = {}
        with ui.card().classes("plant-tile") as self.card:
            self.card.props(f'data-plant-tile="{name}"')
            with ui.row().classes("items-center w-full no-wrap gap-2"):
                self.icon = ui.icon("help", size="32px")
                with ui.column().classes("gap-0 head"):
                    ui.label(name).classes("name").props(f'title="{name}"')
                    kind = f"{self.device_type.title} · {self.state.bus}"
                    ui.label(kind).classes("text-body2 text-grey-8 kind").props(f'title="{kind}"')
                self.status = ui.badge().classes("text-body2")
            self.age_note = ui.label().classes("age-note")
            self.lines = TextPool("")
            self.bar = ui.linear_progress(value=0, show_value=False, size="12px").classes("q-mt-xs")
            self.bar_label = ui.label().classes("text-body2")
            self.alarms = TextPool("alarm-text")
        self.update()
        follow(self.state, self.update)

    def _changed(self, key: str, value: object) -> bool:
        if self._shown.get(key, self) == value:
            return False
        self._shown[key] = value
        return True

    def update(self) -> None:
        tile = evaluate_tile(self.state)
        quality = tile["quality"]
        text, color = BADGE[quality]
        if self._changed("badge", quality):
            self.status.set_text(text)
            self.status.props(f"color={color}")
        age = tile["age"]
        note = "" if quality not in AGE_NOTE else f"{quality}: never heard" if age is None else AGE_NOTE[quality].format(age=fmt_age(age))
        self.age_note.set_text(note)
        if self._changed("icon", tile["icon"]):
            self.icon.name = tile["icon"]
            self.icon.update()
        self.lines.show([line for line in tile["lines"] if line])
        bar = tile["bar"]
        if self._changed("bar-shown", bar is not None):
            self.bar.set_visibility(bar is not None)
            self.bar_label.set_visibility(bar is not None)
        if bar is not None:
            if self._changed("bar", bar[0]):
                self.bar.set_value(bar[0])
            self.bar_label.set_text(bar[1])
        alarms = tile["alarms"] if quality in ("good", "unknown") else []  # old data raises no alarms
        self.alarms.show([f"⚠ {alarm}" for alarm in alarms])
        marked = quality if quality in ("stale", "offline") else "good"
        if self._changed("quality", marked):
            mark_quality(self.card, marked)
        if self._changed("alarm", bool(alarms)):
            if alarms:
                self.card.classes(add="alarm")
            else:
                self.card.classes(remove="alarm")


def content() -> None:
    runtime = rt.current()
    ui.add_css(CSS + TILE_CSS)
    ui.page_title(f"{runtime.plant.name} - plant view")
    with ui.header().classes("items-center bg-blue-grey-9 q-py-sm"):
        ui.label(f"Plant {runtime.plant.name}").classes("text-h5 text-white")
        ui.space()
        clock = ui.label().classes("text-h6 text-white")
    with ui.element("div").classes("plant-grid q-pa-sm"):
        tiles = [PlantTile(name) for name in runtime.plant.devices]
    if not tiles:
        ui.label("This plant file lists no devices.").classes("q-pa-md")
    ui.element("div").classes("plant-more").style("display: none").props("data-plant-more")
    ui.add_body_html(MORE_JS)

    def tick() -> None:
        clock.set_text(time.strftime("%H:%M:%S"))

    tick()
    ui.timer(1.0, tick)
