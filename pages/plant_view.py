"""Read-only plant view for a tablet: one large tile per device, alarms highlighted, stale data greyed.

There are no write controls on this page by construction: it only reads the state store.
"""

from __future__ import annotations

import json
import logging
import re
import time
import weakref
from dataclasses import replace
from html import escape

from nicegui import ui

from app import i18n
from app import runtime as rt
from app.i18n import N_, Lang
from app.message import Message, said
from app.state import RaisedAlarm, StateStore, point_inputs
from devices.registry import DEVICE_TYPES, TileAlarm, TileBar, TileLine, TileSpec, template_fields
from pages.frame import CSS, fmt_age

# the state of a tile in words and colour (never colour alone): what an operator reads from across the room
BADGE = {"good": ("live", "positive"), "stale": ("stale", "warning"), "offline": ("offline", "negative"),
         "unknown": ("waiting", "grey")}  # the site view's badges
STATE = {"good": (N_("live"), "check_circle"), "unknown": (N_("waiting for values"), "hourglass_empty"),
         "stale": (N_("STALE"), "schedule"), "offline": (N_("OFFLINE"), "cloud_off"), "fault": (N_("FAULT"), "warning")}
# units of a quantity an operator reads as it is; a bar in any other unit (increments, counts) shows its share of full travel
PHYSICAL_UNITS = {"mm", "cm", "m", "%", "V", "A", "°C", "s", "min", "h", "mm/s", "Hz", "W", "kW", "bar"}
HEX_CODE = re.compile(r"^0x[0-9A-Fa-f]+:\s*")
log = logging.getLogger(__name__)


def operator_words(entry: dict | None, lang: Lang | None = None, point: str | None = None) -> dict | None:
    """A live entry as an operator reads it: its enum name, or its text without the code before it
    ("0x7: mains, battery, charger_on" -> "mains, battery, charger on") and without the diagnosis after
    a state word ("lost: CRC 0x5100 received ..." -> "lost"); the store's words only, nothing decoded here.
    With ``lang`` its value, name and text write themselves in that language in a tile's templates (the
    documents' words in German, decimal comma, each a value of ``point``) and still compare as the device's
    own (the tile's conditions)."""
    if entry is None:
        return None
    name, text, value = entry.get("name"), entry.get("text"), entry.get("value")
    words = text
    if name:
        words = str(name)
    elif isinstance(text, str):
        if isinstance(value, str) and value and text.startswith(value) and text[len(value):][:1] in (":", ""):
            words = value  # a state word with the engineer's diagnosis after it
        elif HEX_CODE.match(text):
            words = HEX_CODE.sub("", text).replace("_", " ")
    if lang is None:
        return {**entry, "text": words}
    text = said(words, lang) if isinstance(words, Message) else lang.value(words, point)  # an adapter's own words
    return {**entry, "text": text, "name": lang.value(name, point), "value": lang.value(value, point)}


SHARED_S = 0.25  # a tile evaluated for one page serves every other page (and row) showing it this long, unchanged
_SHARED: dict[tuple[str, str], list] = {}  # (kind, device) -> [state, version, time, tile, inputs]
_INPUT_NAMES: dict[int, tuple[str, ...]] = {}


def _input_names(spec: TileSpec) -> tuple[str, ...]:
    """Every point a tile reads: its lines', alarms' and bar's points and the points of their conditions."""
    names = _INPUT_NAMES.get(id(spec))
    if names is None:
        found = set(spec.point_names())
        found.update(line.unless.point for line in spec.lines if line.unless is not None)
        found.update(alarm.unless.point for alarm in spec.alarms if alarm.unless is not None)
        if spec.bar is not None and spec.bar.full_scale_point:
            found.add(spec.bar.full_scale_point)
        names = _INPUT_NAMES[id(spec)] = tuple(sorted(found))
    return names


def tile_inputs(state) -> tuple:
    """What a device's tile is evaluated from, its times left out: whether the device answers, and each point's
    value, text, raw word and unit (a register parameter's raw value). Far cheaper than evaluating the tile."""
    return (state.online, *point_inputs(state, _input_names(DEVICE_TYPES[state.type].tile)))


def shared(kind: str, make):
    """``make(state)`` once for all pages: the last result of a device's ``kind`` is reused while what it is
    made from has not changed (the device's version, or else the values of the points it reads: most frames
    and polls bring the same values, and counters move without changing a tile) and for at most
    :data:`SHARED_S` (ages and stale marks move on). Twenty pages evaluate each device's tile once per
    change, not forty times; a page that gets the very tile it shows has nothing to do. Readers do not change it."""

    def get(state) -> dict:
        key = (kind, state.name)
        now = time.monotonic()
        hit = _SHARED.get(key)
        if hit is not None and hit[0] is state and now - hit[2] < SHARED_S:
            version = state.version
            if hit[1] == version:
                return hit[3]
            inputs = tile_inputs(state)
            if inputs == hit[4]:
                hit[1] = version
                return hit[3]
        else:
            inputs = tile_inputs(state)
        tile = make(state)
        _SHARED[key] = [state, state.version, now, tile, inputs]
        return tile

    get.__doc__ = make.__doc__
    return get


def evaluate_tile(state) -> dict:
    """The device type's declared tile, evaluated against the device's live points (quality and age included),
    as the overview shows it (an engineer's words)."""
    now = time.time()
    spec = DEVICE_TYPES[state.type].tile

    def entry(name: str):
        return state.entry(name, now)

    # only the values the tile declares: registers and published points alike, each with its quality; a line of
    # the bar's own quantity is left out while the bar shows it ("position: 0 %" beside "0 % open" said it twice)
    tile = (spec if spec.bar is None else _without_bar_lines(spec)).evaluate(entry, now)
    if tile["bar"] is None and spec.bar is not None:  # no bar to show the quantity: its line after all
        tile = spec.evaluate(entry, now)
    if tile["quality"] == "unknown" and state.online is False:  # never heard and given up on: offline, not "waiting"
        tile["quality"] = "offline"
    return tile


def plant_tile(state, lang: Lang | None = None) -> dict:
    """The declared tile in an operator's words: each value once (a line of the bar's quantity is left out
    while the bar shows it, a bar in increments or counts shows its share of full travel), texts without
    codes and diagnoses, the alarms the store found (on good data only) worded by :func:`alarm_words`; with
    ``lang`` in that language (:func:`translated_spec`, :func:`operator_words`)."""
    now = time.time()
    spec = DEVICE_TYPES[state.type].tile
    if lang is not None:
        spec = translated_spec(spec, lang)

    def entry(name: str) -> dict | None:
        return operator_words(state.entry(name, now), lang, name)

    # only the values the tile declares: registers and published points alike, each with its quality
    tile = _without_bar_lines(spec).evaluate(entry, now)
    if tile["bar"] is None:  # no bar to show the quantity: its line after all
        tile = spec.evaluate(entry, now)
    elif (bar_entry := _bar_entry(spec, entry)) is not None and bar_entry.get("unit") not in PHYSICAL_UNITS:
        prefix = spec.bar.label.split("{value", 1)[0].strip()
        percent = f"{tile['bar'][0] * 100:.0f}"
        tile["bar"] = (tile["bar"][0], f"{prefix} {percent} % out".strip() if lang is None else
                       lang.gettext("{prefix} {share} out").format(prefix=prefix, share=f"{percent} %").strip())
    tile["alarms"] = [alarm_words(raised, lang) for raised in rt.current().store.raised_alarms(state.name, now)]
    if tile["quality"] == "unknown" and state.online is False:  # never heard and given up on: offline, not "waiting"
        tile["quality"] = "offline"
    return tile


def alarm_words(raised: RaisedAlarm, lang: Lang | None = None) -> str:
    """An alarm the store found, in an operator's words: its declared text (in ``lang``) with the fields of the
    point it follows as :func:`operator_words` gives them, and a bare state word named by its point ("lost" ->
    "CAN link: lost")."""
    point = operator_words(raised.entry, lang, raised.point)
    template = raised.alarm.text if lang is None else lang.phrase(raised.alarm.text)
    text = template.format(**template_fields(point))
    if point is not None and isinstance(point.get("value"), str) and text == format(point["value"]):
        text = f"{raised.point if lang is None else lang.phrase(raised.point)}: {text}"
    return text


fresh_evaluate_tile, fresh_plant_tile = evaluate_tile, plant_tile
evaluate_tile = shared("tile", fresh_evaluate_tile)
_PLANT_TILES: dict[str, object] = {"": shared("plant", fresh_plant_tile)}


def plant_tile(state, lang: Lang | None = None) -> dict:  # noqa: F811 - the shared form of the one above
    """:func:`fresh_plant_tile` shared by every page of one language (see :func:`shared`)."""
    code = "" if lang is None else lang.code
    get = _PLANT_TILES.get(code)
    if get is None:
        get = _PLANT_TILES[code] = shared(f"plant-{code}", lambda state: fresh_plant_tile(state, lang))
    return get(state)


_TRANSLATED: dict[tuple[int, str], TileSpec] = {}


def translated_spec(spec: TileSpec, lang: Lang) -> TileSpec:
    """``spec`` with its texts in ``lang`` (the catalog's device vocabulary, docs/i18n.md): templates, the texts
    of its cases and of a line with nothing heard, its alarms and its bar's label; its conditions unchanged."""
    key = (id(spec), lang.code)
    found = _TRANSLATED.get(key)
    if found is None:
        word = lang.phrase

        def line(item: TileLine) -> TileLine:
            return replace(item, template=word(item.template), missing=word(item.missing), item=word(item.item),
                           cases=tuple((when, word(text), icon) for when, text, icon in item.cases))

        bar = spec.bar
        found = _TRANSLATED[key] = replace(
            spec, lines=tuple(line(item) for item in spec.lines),
            alarms=tuple(TileAlarm(alarm.when, word(alarm.text), alarm.unless) for alarm in spec.alarms),
            bar=None if bar is None else TileBar(bar.point, word(bar.label), bar.full_scale, bar.full_scale_point, bar.fresher))
    return found


def tile_texts(spec: TileSpec) -> list[str]:
    """Every text of ``spec`` that :func:`translated_spec` translates (the catalog test walks them)."""
    texts = [spec.bar.label] if spec.bar is not None else []
    for item in spec.lines:
        texts += [item.template, item.missing, *(text for _when, text, _icon in item.cases)]
        if item.values:
            texts.append(item.item)
    texts += [alarm.text for alarm in spec.alarms]
    return [text for text in texts if text and i18n.has_words(text)]


_REDUCED: dict[int, TileSpec] = {}


def _without_bar_lines(spec: TileSpec) -> TileSpec:
    """``spec`` without the lines that show the bar's own quantity (the bar says it once)."""
    key = id(spec)  # a translated spec is kept for good (_TRANSLATED): its id is never another's
    if key not in _REDUCED:
        sources = set(spec.bar.sources()) if spec.bar is not None else set()
        _REDUCED[key] = replace(spec, lines=tuple(line for line in spec.lines if not line.point or line.point not in sources))
    return _REDUCED[key]


def _bar_entry(spec: TileSpec, entry) -> dict | None:
    heard = [e for name in spec.bar.sources() if (e := entry(name)) is not None]
    return max(heard, key=lambda e: e.get("time") or 0.0, default=None)


# Tiles of equal width; four columns on a 1024 px wide tablet, three on 768 px: the demo plant's tiles fit 1024x768.
# Names and subtitles wrap rather than being cut; values are large enough to read at arm's length on a tablet.
# A tile that is offline or stale keeps its colour and says so in a band of its own: its old values are greyed,
# the band is not. Faults: red band, red border, the alarm texts in bold.
TILE_CSS = """
.plant-grid { display: grid; grid-template-columns: repeat(auto-fill, minmax(232px, 1fr)); gap: 10px; width: 100%; }
.plant-tile { min-width: 0; border-left: 10px solid #21ba45; font-size: 20px; line-height: 1.3; }
.plant-tile.q-card { padding: 6px 10px 8px; gap: 3px; }
.plant-tile .head { min-width: 0; flex: 1 1 auto; }
.plant-tile .name { font-size: 22px; font-weight: 700; line-height: 1.2; overflow-wrap: anywhere; }
.plant-tile .kind { font-size: 14px; color: #555; line-height: 1.25; overflow-wrap: anywhere; }
.plant-tile .state-band { border-radius: 4px; padding: 1px 8px; font-size: 16px; font-weight: 700; line-height: 1.5;
                          color: #1b5e20; flex-wrap: wrap; column-gap: 6px; row-gap: 0; }
.plant-tile .state-band .age { font-weight: 500; }
.plant-tile .state-band .age:empty { display: none; }
.plant-tile .value-line { font-weight: 500; }
.plant-tile .bar-label { font-size: 18px; white-space: nowrap; }
.plant-tile .alarm-text { color: #b00012; font-weight: 700; font-size: 18px; }
.plant-tile.state-unknown { border-left-color: #9e9e9e; }
.plant-tile.state-unknown .state-band { color: #555; }
.plant-tile.state-stale { border-left-color: #f2a100; background: #fff8e6; }
.plant-tile.state-stale .state-band { background: #f2a100; color: #000; }
.plant-tile.state-offline { border-left-color: #b00012; background: repeating-linear-gradient(135deg, #fff, #fff 12px, #f6e3e5 12px, #f6e3e5 24px); }
.plant-tile.state-offline .state-band { background: #b00012; color: #fff; }
.plant-tile.state-fault { border-left-color: #b00012; background: #ffecee; }
.plant-tile.state-fault .state-band { background: #b00012; color: #fff; }
.plant-tile.state-stale .values, .plant-tile.state-offline .values { color: #666; }
/* the site view's tiles (pages/site_view.py) */
.plant-tile.alarm { border-left-color: #c10015; background: #fff0f0; }
.plant-tile.q-stale, .plant-tile.q-offline { border-left-color: #9e9e9e; text-decoration: none; }
.plant-tile .q-badge { flex: none; white-space: nowrap; }
.plant-more { position: fixed; bottom: 6px; right: 12px; background: #37474f; color: white; padding: 2px 10px; border-radius: 10px; }
"""

# when the tiles do not fit the screen, say so (the page scrolls; the note names how many are below); runs in the browser
MORE_JS = """<script>
(() => { const words = %s; const mark = () => { const more = document.querySelector('.plant-more'); if (!more) return;
  const below = [...document.querySelectorAll('[data-plant-tile]')].filter(t => t.getBoundingClientRect().bottom > window.innerHeight + 1).length;
  more.textContent = below ? words.replace('{n}', below) : ''; more.style.display = below ? '' : 'none'; };
  window.addEventListener('resize', mark); window.addEventListener('scroll', mark); setInterval(mark, 2000); })();
</script>"""


class LabelPool:
    """The labels of a container, reused in order: each new list of ``(text, classes)`` sets only what
    changed; labels left over are hidden, none is built again. ``before``: a later element of the container
    that new labels go in front of (when it is built)."""

    def __init__(self, container: ui.element, before=lambda: None):
        self.container = container
        self.before = before
        self.labels: list[ui.label] = []
        self.shown: list[tuple[str, str]] = []

    def show(self, items: list[tuple[str, str]]) -> None:
        if items == self.shown:
            return
        labels = self.labels
        while len(labels) < len(items):
            with self.container:
                label = ui.label()
            before = self.before()
            if before is not None:
                label.move(target_index=self.container.default_slot.children.index(before))
            labels.append(label)
        for n, label in enumerate(labels):
            if n < len(items):
                text, classes = items[n]
                label.set_text(text)
                if n >= len(self.shown) or self.shown[n][1] != classes:
                    label.classes(replace=classes)
                if not label.visible:
                    label.set_visibility(True)
            elif label.visible:  # emptied too: a hidden label keeps no old text (an alarm that cleared)
                label.set_text("")
                label.set_visibility(False)
        self.shown = list(items)


ICON = '<i class="q-icon notranslate material-icons" aria-hidden="true" role="presentation"%s>%s</i>'


def state_words(quality: str, alarms: list[str], age: float | None, lang: Lang | None = None) -> tuple[str, str, str]:
    """``(state, word, age text)`` of a tile: offline and stale first (old data raises no alarms), then faults."""
    lang = lang or i18n.get("en")
    _ = lang.gettext
    if quality == "offline":
        return "offline", _(STATE["offline"][0]), \
            _("never heard") if age is None else _("no answer, last heard {age}").format(age=fmt_age(age, lang))
    if quality == "stale":
        return "stale", _(STATE["stale"][0]), _("no fresh values") if age is None else _("last heard {age}").format(age=fmt_age(age, lang))
    if alarms:
        return "fault", _(STATE["fault"][0]), ""
    return quality, _(STATE[quality][0]), ""


class PlantTile:
    """One large tile, set in place: what changed when the device changed (the store's push), ages and stale
    marks on the page's one-second tick; each element sent only when what it shows changed. Name and kind
    never change and the state's icon and word change together: one element each."""

    def __init__(self, name: str, lang: Lang | None = None):
        runtime = rt.current()
        self.lang = lang or i18n.get("en")
        self.state = runtime.store.devices[name]
        self.device_type = DEVICE_TYPES[self.state.type]
        self._shown: dict[str, object] = {}
        self._tile: dict | None = None
        self.bar_row = None
        with ui.card().classes("plant-tile") as self.card:
            self.card.props(f'data-plant-tile="{name}"')
            with ui.row().classes("items-center w-full no-wrap gap-2"):
                self.icon = ui.icon("help", size="32px")
                ui.html(f'<div class="name">{escape(name)}</div>'
                        f'<div class="kind">{escape(f"{self.lang.phrase(self.device_type.title)} · {self.state.bus}")}</div>',
                        sanitize=False).classes("head")
            with ui.row().classes("state-band items-center w-full no-wrap").props("data-plant-state") as self.band:
                self.state_word = ui.html("", sanitize=False).style("display: contents")
                self.age_note = ui.label().classes("age")
            self.values = ui.column().classes("values gap-0 w-full")
            self.lines = LabelPool(self.values, lambda: self.bar_row)
            self.alarms = LabelPool(self.card)
        self.refresh()

    @staticmethod
    def shows(state, lang: Lang | None = None) -> tuple:
        """What a plant tile draws, its age left out."""
        tile = plant_tile(state, lang)
        return tile["lines"], tile["alarms"], tile["bar"], tile["icon"], tile["quality"]

    def _changed(self, key: str, value: object) -> bool:
        if self._shown.get(key, self) == value:
            return False
        self._shown[key] = value
        return True

    def refresh(self, ticked: bool = False) -> None:
        """Show the device as it is now (``ticked``: the page's tick; a tile shows nothing that moves
        without being evaluated again, so both are the same here)."""
        tile = plant_tile(self.state, self.lang)
        if tile is self._tile:
            return  # the same evaluation (device unchanged, ages within SHARED_S) is on screen already
        self._tile = tile
        quality = tile["quality"]
        alarms = tile["alarms"] if quality in ("good", "unknown") else []  # old data raises no alarms
        state, word, age_text = state_words(quality, alarms, tile["age"], self.lang)
        marked = quality if quality in ("stale", "offline") else "good"
        if self._changed("quality", marked):  # the values' quality, as everywhere a value is shown (without fading)
            self.card.props(f'data-quality="{marked}"')
        if self._changed("state", state):
            self.card.classes(remove=" ".join(f"state-{s}" for s in STATE), add=f"state-{state}")
            self.band.props(f'data-plant-state="{state}"')
            self.state_word.set_content(ICON % (' style="font-size: 20px"', STATE[state][1])
                                        + f'<span class="word">{escape(word)}</span>')
        self.age_note.set_text(age_text)
        if self._changed("icon", tile["icon"]):
            self.icon.name = tile["icon"]
            self.icon.update()
        self.lines.show([(line, "value-line") for line in tile["lines"] if line])
        bar = tile["bar"]
        if bar is not None and self.bar_row is None:
            with self.values:
                with ui.row().classes("items-center w-full no-wrap gap-2") as self.bar_row:
                    self.bar = ui.linear_progress(value=0, show_value=False, size="14px").classes("col")
                    self.bar_label = ui.label().classes("bar-label")
        if self._changed("bar-shown", bar is not None) and self.bar_row is not None:
            self.bar_row.set_visibility(bar is not None)
        if bar is not None:
            if self._changed("bar", bar[0]):
                self.bar.set_value(bar[0])
            self.bar_label.set_text(bar[1])
        self.alarms.show([(f"⚠ {alarm}", "alarm-text") for alarm in alarms])


FEED_GROUP = "tiles"  # the store's group of the feed's watchers: bounded like one page's (see app/state.py)


class _Feed:
    """Tiles and table rows of every overview and plant view open, followed with one store watcher per
    device for all of them (not one per page and device). A push that changed something a kind of view
    shows (``shows(state)``: what it draws, its ages left out) redraws the views of that kind; the other
    pushes (most frames bring the same values, only counters move) cost one comparison, however many pages
    are open. Ages, counters and stale marks are drawn by each page's own tick."""

    def __init__(self, store: StateStore) -> None:
        self.store = weakref.proxy(store)  # the store keeps its feed (in _FEEDS) as long as it lives, not longer
        self.views: dict[str, dict] = {}  # device -> shows -> [views]
        self.watches: dict = {}
        self.versions: dict[str, int] = {}
        self.shown: dict[tuple, tuple] = {}  # (device, shows) -> what they show now

    @staticmethod
    def of(store: StateStore) -> _Feed:
        """The store's one feed of tiles, made with the first tile that follows it."""
        feed = _FEEDS.get(store)
        if feed is None:
            feed = _FEEDS[store] = _Feed(store)
        return feed

    def add(self, view, shows) -> None:
        name = view.state.name
        if name not in self.watches:
            self.watches[name] = self.store.watch(name, lambda: self._pushed(name), group=FEED_GROUP)
        self.views.setdefault(name, {}).setdefault(shows, []).append(view)

    def remove(self, view, shows) -> None:
        name = view.state.name
        kinds = self.views.get(name, {})
        views = kinds.get(shows, [])
        if view in views:
            views.remove(view)
        if not views:
            kinds.pop(shows, None)
            self.shown.pop((name, shows), None)
        if not kinds and name in self.watches:
            self.views.pop(name, None)
            self.versions.pop(name, None)
            self.watches.pop(name).cancel()

    def _pushed(self, name: str) -> None:
        state = self.store.devices.get(name)
        if state is None:
            return
        version = state.version
        if self.versions.get(name) == version:
            return  # the store's once-a-second round: nothing new
        self.versions[name] = version
        for shows, views in list(self.views.get(name, {}).items()):
            now = shows(state)
            if self.shown.get((name, shows)) == now:
                continue
            self.shown[(name, shows)] = now
            for view in list(views):
                try:
                    view.refresh()
                except Exception:  # one page's failure does not stop the others
                    self.store.push_errors += 1
                    log.exception("a tile of %s failed; it is removed", name)
                    self.remove(view, shows)


_FEEDS: weakref.WeakKeyDictionary[StateStore, _Feed] = weakref.WeakKeyDictionary()  # a store -> its feed of tiles


class Followers:
    """The views of one page on the shared feed, and the page's tick: every view's ages, counters and stale
    marks drawn together, one message a second."""

    def __init__(self) -> None:
        from nicegui import context

        self.feed = _Feed.of(rt.current().store)
        self.views: list[tuple] = []
        context.client.on_delete(self.close)

    def add(self, view, shows=None) -> None:
        shows = shows or type(view).shows
        self.feed.add(view, shows)
        self.views.append((view, shows))

    def close(self) -> None:
        for view, shows in self.views:
            self.feed.remove(view, shows)
        self.views.clear()

    def tick(self) -> None:
        for view, _shows in self.views:
            view.refresh(ticked=True)


_SHOWS: dict[str, object] = {}


def shows_in(lang: Lang):
    """:meth:`PlantTile.shows` in ``lang``: one function per language, so that the feed compares the tiles of
    one language once per change however many pages show them."""
    found = _SHOWS.get(lang.code)
    if found is None:
        found = _SHOWS[lang.code] = lambda state: PlantTile.shows(state, lang)
    return found


def content() -> None:
    runtime = rt.current()
    lang = i18n.page_language()
    _ = lang.gettext
    ui.add_css(CSS + TILE_CSS)
    ui.page_title(_("{plant} - plant view").format(plant=runtime.plant.name))
    with ui.header().classes("items-center bg-blue-grey-9 q-py-sm no-wrap"):
        ui.label(_("Plant {plant}").format(plant=runtime.plant.name)).classes("text-h5 text-white")
        ui.space()
        clock = ui.label().classes("text-h6 text-white")
        i18n.language_switch(lang, size="md")  # a finger's width on a tablet
    followers = Followers()
    with ui.element("div").classes("plant-grid q-pa-sm"):
        tiles = [PlantTile(name, lang) for name in runtime.plant.devices]
    for tile in tiles:
        followers.add(tile, shows_in(lang))
    if not tiles:
        ui.label(_("This plant file lists no devices.")).classes("q-pa-md")
    ui.element("div").classes("plant-more").style("display: none").props("data-plant-more")
    ui.add_body_html(MORE_JS % json.dumps(_("{n} more below: scroll down")))

    def tick() -> None:  # the clock and every tile's ages and stale marks: one message a second
        clock.set_text(lang.clock())
        followers.tick()

    tick()
    ui.timer(1.0, tick)
