"""The plant-wide read-only view (``commission view``): every site on the broker, the plant view's tiles.

Reads only an app.site_view.SiteStore (what the broker says); it has no controls that change
anything, and nothing it could call would: MQTT carries no commands.
"""

from __future__ import annotations

import time

from nicegui import ui

from app import i18n
from app.i18n import N_, Lang
from devices.registry import DEVICE_TYPES
from pages.frame import CSS, fmt_age
from pages.plant_view import BADGE, TILE_CSS, operator_words, translated_spec
from pages.widgets import mark_quality

# the view's own marks on top of the device's quality: what the broker tells about its instance
VIEW_BADGE = {"vanished": (N_("vanished: instance lost"), "negative"), "stopped": (N_("instance stopped"), "grey-7"),
              "stale": (N_("stale: {age}"), "warning")}
BADGE_WORDS = (N_("live"), N_("stale"), N_("offline"), N_("waiting"))  # the words of pages/plant_view.py's BADGE
INSTANCE_WORDS = {"online": N_("online"), "offline": N_("offline"), "stopped": N_("stopped"), "vanished": N_("vanished")}
VIEW_QUALITY = {"vanished": "offline", "stopped": "offline", "stale": "stale", "offline": "offline"}

SITE_CSS = """
.site-head { font-size: 24px; font-weight: 600; }
.plant-tile.q-vanished { border-left-color: #6d1b1b; background: #f4eeee; }
"""


def evaluate_remote_tile(device: dict, lang: Lang | None = None) -> dict:
    """The device type's declared tile, evaluated against the values the broker carried.

    The values' qualities are those the publishing instance saw; a stale, stopped or vanished
    instance downgrades every one of them here, so old data raises no alarms and shows greyed. With ``lang`` in
    that language, in the plant view's words (:func:`pages.plant_view.translated_spec`).
    """
    now = time.time()
    values = device.get("values") or {}
    override = VIEW_QUALITY.get(device["view_status"])

    def entry(name: str):
        item = values.get(name)
        if not isinstance(item, dict):
            return None
        found = {**item, "quality": override or item.get("quality") or "unknown"}
        return found if lang is None else operator_words(found, lang, name)

    device_type = DEVICE_TYPES.get(device.get("type", ""))
    if device_type is None:
        return {"lines": [(lang or i18n.get("en")).gettext("{n} values").format(n=len(values))], "alarms": [], "bar": None,
                "icon": "memory", "quality": override or "good", "age": device.get("age")}
    spec = device_type.tile if lang is None else translated_spec(device_type.tile, lang)
    return spec.evaluate(entry, now)


class SiteTile:
    """One device heard on the broker, in the look of the plant view's tile (pages/plant_view.py)."""

    def __init__(self, device: dict, lang: Lang | None = None):
        self.key = (device["site"], device["name"])
        self.lang = lang if lang is not None and lang.code != "en" else None  # English: the tile as it always was
        title = DEVICE_TYPES[device["type"]].title if device.get("type") in DEVICE_TYPES else device.get("type", "?")
        if self.lang is not None:
            title = self.lang.phrase(title)
        with ui.card().classes("plant-tile") as self.card:
            self.card.props(f'data-site-tile="{device["site"]}/{device["name"]}"')
            with ui.row().classes("items-center w-full no-wrap"):
                self.icon = ui.icon("help", size="40px")
                with ui.column().classes("gap-0 head"):
                    ui.label(device["name"]).classes("name")
                    ui.label(f"{title} · {device['instance']} · {device['bus']}").classes("text-body2 text-grey-8")
                ui.space()
                self.status = ui.badge().classes("text-body1")
            self.lines = ui.column().classes("gap-0")
            self.bar = ui.linear_progress(value=0, show_value=False, size="18px").classes("q-mt-sm")
            self.bar_label = ui.label().classes("text-body1")
            self.alarms = ui.column().classes("gap-0")
        self._lines: list | None = None
        self._alarms: list | None = None
        self.update(device)

    def update(self, device: dict) -> None:
        lang = self.lang
        tile = evaluate_remote_tile(device, lang)
        view_status = device["view_status"]
        quality = tile["quality"]
        if view_status in VIEW_BADGE:
            text, color = VIEW_BADGE[view_status]
        else:
            text, color = BADGE[quality]
        if lang is not None:
            text = lang.gettext(text)
        self.status.set_text(text.format(age=fmt_age(device.get("age") if view_status == "stale" else tile["age"], lang)))
        self.status.props(f"color={color}")
        self.card.props(f'data-view-status="{view_status}"')
        self.icon.name = tile["icon"]
        self.icon.update()
        if tile["lines"] != self._lines:
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
        if alarms != self._alarms:
            self._alarms = alarms
            self.alarms.clear()
            with self.alarms:
                for alarm in alarms:
                    ui.label(f"⚠ {alarm}").classes("alarm-text")
        mark_quality(self.card, quality if quality in ("stale", "offline") else "good")
        self.card.classes(remove="alarm q-vanished")
        if alarms:
            self.card.classes(add="alarm")
        if view_status == "vanished":
            self.card.classes(add="q-vanished")


def content(store) -> None:
    lang = i18n.page_language()
    _ = lang.gettext
    ui.add_css(CSS + TILE_CSS + SITE_CSS)
    ui.page_title(_("plant-wide view - commission"))
    with ui.header().classes("items-center bg-blue-grey-9"):
        ui.label(_("Plant-wide view")).classes("text-h5 text-white")
        ui.label(_("read-only, from the broker")).classes("text-caption text-grey-4")
        ui.space()
        broker = ui.badge().classes("text-black").props("data-testid=broker-state")
        clock = ui.label().classes("text-h6 text-white")
        i18n.language_switch(lang)
    body = ui.column().classes("w-full q-pa-md gap-2")
    tiles: dict[tuple[str, str], SiteTile] = {}
    shown: list = []

    def update() -> None:
        snap = store.snapshot()
        clock.set_text(lang.clock())
        b = snap["broker"]
        broker.set_text(_("broker {state}").format(state=lang.phrase(b["state"], "broker")))
        broker.props(f"color={'green-3' if b['connected'] else 'orange-4'}")
        layout = [(s["site"], [(i["name"], i["state"]) for i in s["instances"]], [d["name"] for d in s["devices"]])
                  for s in snap["sites"]]
        if layout != shown:  # a site, instance or device came or went: build the grid again (rare)
            shown[:] = layout
            body.clear()
            tiles.clear()
            with body:
                if not snap["sites"]:
                    ui.label(_("Nothing is published to {url} yet. An instance publishes when its plant file "
                               "has an [mqtt] table with this broker's url.").format(url=b["url"])).classes("text-body1")
                for site in snap["sites"]:
                    with ui.row().classes("items-baseline gap-3 q-mt-md"):
                        ui.label(_("Site {site}").format(site=site["site"])).classes("site-head")
                        for inst in site["instances"]:
                            state = _(INSTANCE_WORDS[inst["state"]]) if inst["state"] in INSTANCE_WORDS else inst["state"]
                            ui.badge(f"{inst['name']}: {state}",
                                     color="positive" if inst["state"] == "online" else "negative").props(
                                f'data-instance="{site["site"]}/{inst["name"]}"')
                    with ui.element("div").classes("plant-grid"):
                        for dev in site["devices"]:
                            tiles[(dev["site"], dev["name"])] = SiteTile(dev, lang)
            return
        for site in snap["sites"]:
            for dev in site["devices"]:
                tile = tiles.get((dev["site"], dev["name"]))
                if tile is not None:
                    tile.update(dev)

    update()
    ui.timer(1.0, update)
