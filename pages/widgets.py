"""Widgets shared by device pages: lamps, register tables, live charts, write dialogs."""

from __future__ import annotations

import html
import json
import logging
import time
from collections.abc import Callable
from datetime import datetime
from decimal import Decimal

from nicegui import context, ui

from app import i18n
from app import runtime as rt
from app.message import said
from app.i18n import N_, Lang
from app.state import DeviceState, LiveValue
from devices.params import Param

log = logging.getLogger(__name__)


# a lamp of one element (:class:`Lamp` with ``light=True``): its light drawn before its name, as .lamp draws it
LAMP_CSS = """
.lamp-dot { display: inline-flex; align-items: center; gap: 4px; white-space: nowrap; }
.lamp-dot::before { content: ""; width: 14px; height: 14px; border-radius: 50%; display: inline-block;
  border: 1px solid #555; background: #d6d6d6; flex: none; }
.lamp-dot.on::before { background: #21ba45; box-shadow: 0 0 6px #21ba45; }
.lamp-dot.warn.on::before { background: #f2c037; box-shadow: 0 0 6px #f2c037; }
.lamp-dot.alarm.on::before { background: #c10015; box-shadow: 0 0 6px #c10015; }
.lamp-dot.unknown::before { background: repeating-linear-gradient(45deg, #ccc, #ccc 3px, #eee 3px, #eee 6px); }
"""


def add_css_once(key: str, css: str) -> None:
    """Add ``css`` to the page once, however many widgets of a kind it holds."""
    client = context.client
    added = client.__dict__.setdefault("commission_css", set())
    if key not in added:
        ui.add_css(css)
        added.add(key)


class Lamp:
    """A named indicator light; ``kind`` "ok" (green), "warn" (yellow) or "alarm" (red).

    ``light=True``: the lamp is one element (its name, the light drawn before it by CSS, and its tooltip),
    not a row of a light, a name and a tooltip: the same look and the same ``data-lamp``, ``data-on`` and
    ``data-quality``, at a quarter of the elements (a page of 40 lamps)."""

    _on: bool | None | str = "never"  # what the lamp shows now ("never": not set yet)

    def __init__(self, name: str, kind: str = "ok", tooltip: str = "", light: bool = False):
        if light:
            add_css_once("lamp", LAMP_CSS)
            self.row = self.dot = ui.label(name).classes(f"lamp-dot text-body2 {'' if kind == 'ok' else kind}")
            if tooltip:
                with self.row:
                    ui.tooltip(tooltip)
        else:
            with ui.row().classes("items-center gap-1 no-wrap") as self.row:
                self.dot = ui.element("span").classes(f"lamp {'' if kind == 'ok' else kind}")
                ui.label(name).classes("text-body2")
                if tooltip:
                    ui.tooltip(tooltip)
        self.row.props(f'data-lamp="{name}"')
        self.kind = kind

    def set(self, on: bool | None) -> None:
        if self._on == on:
            return  # unchanged: no class or prop work (this runs on every push)
        self._on = on
        self.dot.classes(remove="on unknown")
        if on is None:
            self.dot.classes(add="unknown")
        elif on:
            self.dot.classes(add="on")
        self.row.props(f'data-on="{"unknown" if on is None else int(bool(on))}"')

    def show(self, live: LiveValue | None, value=None) -> None:
        """Show a live value (its value, or ``value`` taken from it) with its quality: offline shows unknown."""
        quality = "unknown" if live is None else live.quality
        self.set(None if live is None or quality == "offline" else bool(live.value if value is None else value))
        mark_quality(self.row, quality)


QUALITY_CLASSES = "q-stale q-offline q-unknown"
QUALITY_WORDS = {"good": N_("good"), "stale": N_("stale"), "offline": N_("offline"), "unknown": N_("unknown")}


def entry_age(live: LiveValue | None) -> float | None:
    """How long ago the value was read or heard (None: never)."""
    import time

    return None if live is None or live.time is None else max(0.0, time.time() - live.time)


def quality_note(quality: str, age: float | None, lang: Lang | None = None) -> str:
    """The words shown next to a value that is not good: ``stale 12 s``, ``offline, last 2 min``."""
    from pages.frame import fmt_age

    _ = (lang or i18n.get("en")).gettext
    if quality == "stale":
        return _("stale {age}").format(age=fmt_age(age, lang))
    if quality == "offline":
        return _("offline, last {age}").format(age=fmt_age(age, lang)) if age is not None else _("offline")
    if quality == "unknown":
        return _("not read")
    return ""


def mark_quality(element: ui.element, quality: str) -> None:
    """Grey an element by the quality of the value it shows (classes q-stale, q-offline, q-unknown)."""
    if element.props.get("data-quality") == quality:
        return  # unchanged: parsing props and sending the element again costs more than this look-up
    element.classes(remove=QUALITY_CLASSES)
    if quality in ("stale", "offline", "unknown"):
        element.classes(add=f"q-{quality}")
    element.props(f'data-quality="{quality}"')


class ValueLine:
    """A value with its quality in one element: its text, greyed with its age beside it while stale or offline
    (classes q-stale, q-offline; ``data-quality``), where a row of a label and an age label took three. The
    browser gets the same row of two blocks (the value with ``classes``, the age) as the row of labels made."""

    def __init__(self, classes: str = "", text: str = "-"):
        self.classes = classes
        self.shown: tuple = ()
        self.element = ui.html("", sanitize=False).classes("nicegui-row items-baseline gap-0 no-wrap")
        self.show(text, "unknown", "")

    def show(self, text: str, quality: str, note: str = "") -> None:
        """Show ``text`` with ``quality`` and its ``note`` (``stale 4 s``; shown only while stale or offline)."""
        shown = (text, note if quality in ("stale", "offline") else "")
        if shown != self.shown:
            self.shown = shown
            self.element.set_content(f'<div class="{self.classes}">{html.escape(text, quote=False)}</div>'
                                     f'<div class="q-age">{html.escape(shown[1], quote=False)}</div>')
        mark_quality(self.element, quality)

    @property
    def text(self) -> str:
        return self.shown[0] if self.shown else ""


REGISTER_COLUMNS = [
    {"name": "address", "label": N_("Addr"), "field": "address", "align": "right", "sortable": True},
    {"name": "name", "label": N_("Name"), "field": "name", "align": "left"},
    # a long value (a register of flags) wraps: every column, Quality too, stays in sight at 1024 px
    {"name": "value", "label": N_("Value"), "field": "value", "align": "left", "style": "white-space: normal; min-width: 8rem"},
    {"name": "raw", "label": N_("Raw"), "field": "raw", "align": "left", "classes": "mono"},
    {"name": "access", "label": N_("Access"), "field": "access", "align": "center"},
    {"name": "age", "label": N_("Read"), "field": "age", "align": "right"},
    {"name": "quality", "label": N_("Quality"), "field": "quality", "align": "left"},
]


def column(name: str, label: str, **more) -> dict:
    """A left-aligned table column showing the rows' field ``name`` under ``label`` (marked ``N_``); ``more``:
    Quasar's other column options (``sortable``, ``style``, a ``field`` of another name ...)."""
    return {"name": name, "label": label, "field": name, "align": "left", **more}


def columns(table: list[dict], lang: Lang | None) -> list[dict]:
    """A table's columns with their labels (marked ``N_``) in ``lang``."""
    if lang is None:
        return table
    return [{**column, "label": lang.gettext(column["label"])} if column["label"] else column for column in table]  # "": no header


# changed cells of a table's rows (by row key) into the rows the browser shows: its reactive rows re-render those cells
ROW_PATCH_JS = ("(function(e,p){if(!e)return;for(const r of e.props.rows){const c=p[r.key];if(c)Object.assign(r,c);}})"
                "(mounted_app.elements[%d],%s)")


def _enclosing_tab_panel(element: ui.element) -> tuple[ui.element | None, ui.element | None]:
    """The ``ui.tab_panel`` around ``element`` and its ``ui.tab_panels``, or (None, None)."""
    from nicegui.elements.tabs import TabPanel, TabPanels

    slot = element.parent_slot
    while slot is not None:
        parent = slot.parent
        if isinstance(parent, TabPanel):
            panels = parent.parent_slot.parent if parent.parent_slot is not None else None
            return (parent, panels) if isinstance(panels, TabPanels) else (None, None)
        slot = parent.parent_slot
    return None, None


# a lamp's or line's words on hover, as Quasar's tooltip shows them, for what is drawn as one element (LampStrip)
TIP_CSS = ("[data-tip]{position:relative}[data-tip]:hover::after{content:attr(data-tip);position:absolute;left:0;"
           "top:100%;margin-top:4px;z-index:9000;background:#757575;color:#fafafa;font-size:10px;line-height:1.4;"
           "padding:6px 10px;border-radius:4px;width:max-content;max-width:20rem;white-space:normal;pointer-events:none}")


def html_attr(text: str) -> str:
    """``text`` as the value of an HTML attribute in double quotes."""
    return html.escape(text, quote=True)


def lamp_html(key: str, name: str, live: LiveValue | None, tip: str = "", kind: str = "ok", idle: bool | None = None) -> str:
    """One lamp as :class:`Lamp` draws it (its data-lamp, data-on and data-quality, the dot's classes;
    ``kind`` "ok", "warn" or "alarm"), in the text of the element that holds it: a lamp costs no element of its own.
    ``idle``: a fault lamp whose fault is the normal state now (grey, never red; data-idle)."""
    quality = "unknown" if live is None else live.quality
    on = None if live is None or quality == "offline" else bool(live.value)
    dot = " ".join(x for x in ("lamp", "" if kind == "ok" or idle else kind, "unknown" if on is None else "on" if on else "") if x)
    marks = f" q-{quality}" if quality in ("stale", "offline", "unknown") else ""
    return (f'<div class="nicegui-row row items-center gap-1 no-wrap{marks}" data-lamp="{html_attr(key)}" '
            f'data-on="{"unknown" if on is None else int(on)}" data-quality="{quality}"'
            + (f' data-tip="{html_attr(tip)}"' if tip else "") + ("" if idle is None else f' data-idle="{int(idle)}"')
            + f'><span class="{dot}"' + (' style="background: #9e9e9e; box-shadow: none"' if idle else "")
            + f'></span><div class="text-body2">{html.escape(name)}</div></div>')


def value_html(point: str, testid: str, text: str, live: LiveValue | None, lang: Lang | None = None) -> str:
    """A value in the text of the element that holds it, greyed with its age while stale or offline."""
    quality = "unknown" if live is None else live.quality
    marks = f" q-{quality}" if quality in ("stale", "offline", "unknown") else ""
    note = quality_note(quality, entry_age(live), lang) if quality in ("stale", "offline") else ""
    return (f'<div class="nicegui-row row items-baseline gap-0 no-wrap{marks}" data-point="{html_attr(point)}" '
            f'data-testid="{testid}" data-quality="{quality}"><div class="mono text-body2">'
            f'{html.escape(text)}</div><div class="q-age">{html.escape(note)}</div></div>')


def clock_text(t: float, lang: Lang | None = None) -> str:
    from pages.frame import fmt_time

    return fmt_time(t, lang)


class LampStrip:
    """Lamps (and values) drawn as one element whose text is redrawn when one of them changes: some 5 KB of server
    memory per page instead of four elements per lamp. Same look, words and data attributes as separate lamps."""

    def __init__(self, classes: str):
        add_css_once("tip", TIP_CSS)
        self.element = ui.html("", sanitize=False).classes(classes)

    def show(self, parts: list[str]) -> None:
        self.element.set_content("".join(parts))


def _tab_name(value: object) -> object:
    """The name of the tab a ``ui.tab_panels`` shows (its value: a tab, a panel or the name itself)."""
    return value.props["name"] if isinstance(value, ui.tab | ui.tab_panel) else value


class RegisterTable:
    """Live table of one register space of a device (address, name, value, raw, access)."""

    def __init__(self, state: DeviceState, params: list[Param], lang: Lang | None = None):
        self.state = state
        self.params = params
        self.lang = lang
        self.table = ui.table(columns=columns(REGISTER_COLUMNS, lang), rows=[], row_key="key", pagination=0).classes("w-full reg-table")
        self.table.props("dense flat bordered")
        unsaved = html.escape((lang or i18n.get("en")).gettext("unsaved"))
        self.table.add_slot(
            "body-cell-name",
            '<q-td :props="props" :title="props.row.description" style="cursor: help; white-space: normal">'
            '{{ props.value }}<q-badge v-if="props.row.unsaved" color="orange" class="q-ml-xs">' + unsaved + '</q-badge></q-td>',
        )
        self.table.props(':table-row-class-fn="row => row.quality_class"')
        self._cache: dict[str, tuple[tuple, float | None, dict]] = {}  # key -> (raw, quality, unsaved), read time, row
        self._keys = [(p.space, a) for p in params for a in p.addresses]  # every word the table shows
        self._owner = [i for i, p in enumerate(params) for _ in p.addresses]  # word -> the row that shows it
        self._words: list | None = None  # the words, online state and unsaved marks last drawn
        self._marks: tuple | None = None
        self._aging = False  # a row is shown stale: it turns good when read again, same word or not
        # in a tab panel (input and holding registers side by side): followed while its tab is shown, brought up to
        # date as it is chosen; a table nobody sees costs nothing on every push
        self._panel, self._panels = _enclosing_tab_panel(self.table)
        if self._panels is not None:
            self._panels.on_value_change(lambda _: self.update(times=True))
        self.update()
        store = rt.current().store
        follow(state, lambda: self.update(times=store.age_round))  # one build per round, read times or not

    def update(self, times: bool = False) -> None:
        """New values, qualities and unsaved marks at once; a new read time alone (every poll) once a
        second, with ``times`` (the device's once-a-second round). A row whose value, quality and mark did
        not change is kept as it was built (outside the once-a-second round its read time waits for that
        round), so a change of one register builds one row, not the table; a push that changed no word,
        no unsaved mark and not the device's online state (a poll that read the same values) costs one
        comparison of the table's words. Once the table is in the browser only the changed cells of the
        changed rows go there (a few bytes, not the whole table with its descriptions and columns, which the
        browser keeps): the table element is sent whole only when its rows are new."""
        panels = self._panels
        if panels is not None and self.table.rows and _tab_name(panels.value) != self._panel.props.get("name"):
            self._words = None  # its tab is not shown: updated when it is chosen
            return
        state = self.state
        registers = state.registers
        words = [None if (e := registers.get(k)) is None else e[0] for k in self._keys]
        marks = (state.online, frozenset(state.unsaved) if state.unsaved else None)
        if not times and words == self._words and marks == self._marks and not self._aging:
            return  # the same words, marks and online state: nothing a row shows moved but read times
        old_words = self._words
        # a push of new words only (no round, same marks, nothing stale): the rows of the words that changed
        only = None if times or old_words is None or marks != self._marks or self._aging or not self.table.rows else \
            {self._owner[i] for i, (a, b) in enumerate(zip(words, old_words)) if a != b}
        self._words, self._marks = words, marks
        now = time.time()
        cache = self._cache
        rows = []
        patch: dict[str, dict] = {}
        aging = False
        for i, p in enumerate(self.params):
            old = cache.get(p.key)
            if only is not None and i not in only and old is not None:
                rows.append(old[2])
                continue
            raw = state.raw(p)
            read = state.read_time(p)
            quality = state.param_quality(p, now)
            if quality == "stale":
                aging = True
            unsaved = p.key in state.unsaved
            sig = (raw, quality, unsaved)
            if old is not None and old[0] == sig:
                if not times or old[1] == read:
                    rows.append(old[2])
                    continue
                if quality == "good":  # the same good value read again: only its Read cell moves (once a second)
                    age = _clock(read)
                    row = old[2] if old[2]["age"] == age else {**old[2], "age": age}
                    if row is not old[2]:
                        patch[p.key] = {"age": age}
                    cache[p.key] = (sig, read, row)
                    rows.append(row)
                    continue
            row = self._row(p, raw, read, quality, unsaved, now, self.lang)
            if old is not None:
                cells = {k: v for k, v in row.items() if old[2].get(k) != v}
                if not cells:
                    row = old[2]
                else:
                    patch[p.key] = cells
            cache[p.key] = (sig, read, row)
            rows.append(row)
        self._aging = aging
        shown = self.table.rows
        if len(rows) != len(shown) or any(a["key"] != b["key"] for a, b in zip(rows, shown)):
            self.table.rows = rows  # new rows: the whole table (at the start); NiceGUI keeps its own copy of them
            return
        if not patch:
            return
        # the browser changes the cells of its own rows in place, and so does the table's copy here, without sending
        # it (a whole update of the element, as for a reconnecting page, sends the rows as the browser has them):
        # only the changed cells are touched, no row is copied again
        with self.table.props.suspend_updates():
            for row in shown:
                cells = patch.get(row["key"])
                if cells:
                    row.update(cells)
        self.table.client.run_javascript(ROW_PATCH_JS % (self.table.id, json.dumps(patch, separators=(",", ":"))))

    @staticmethod
    def _row(p: Param, raw: int | None, read: float | None, quality: str, unsaved: bool, now: float,
             lang: Lang | None = None) -> dict:
        _ = (lang or i18n.get("en")).gettext
        return {
            "key": p.key,
            "address": p.address if p.words == 1 else f"{p.address}-{p.address + p.words - 1}",
            "name": p.label or p.name,
            "value": "-" if raw is None else p.display(raw) if lang is None else _register_value(p, raw, lang),
            "raw": "-" if raw is None else f"0x{raw:0{4 * p.words}X}",
            "access": p.access.value + (" " + _("(never written)") if p.never_write and p.access.value == "RW" else ""),
            "age": _clock(read),
            "description": said(p.description, lang),
            "unsaved": unsaved,
            # good: the Read column gives the time; stale or offline: how old the value is
            "quality": "-" if raw is None else (quality_note(quality, None if read is None else now - read, lang)
                                                or _(QUALITY_WORDS.get(quality, quality))),
            "quality_class": f"q-{quality}" if quality in ("stale", "offline") else "",
        }


def _register_value(p: Param, raw: int, lang: Lang) -> str:
    """A register's value as the table shows it in ``lang``: an enum's name as the device vocabulary words it where
    the catalog has it as a value of this register (``DoorState``: ``Tür geöffnet (1)``), with its number; else as
    the parameter model names it (the document's own word, ``IrsNotLine (4)``)."""
    name = p.enum_name(raw)
    if name and lang.has(name, p.name):
        return f"{lang.pgettext(p.name, name)} ({lang.numbers_in(str(p.decode(raw)))})"
    return lang.with_unit(p.display(raw), p.unit)  # the unit as the language writes it (the SCU's counts: Flanken)


_CLOCKS: dict[int, str] = {}  # whole seconds -> "HH:MM:SS": the rows of one poll share their second


def _clock(t: float | None) -> str:
    """A read time as the Read column shows it (local time, whole seconds); "-" for none."""
    if t is None:
        return "-"
    second = int(t)
    text = _CLOCKS.get(second)
    if text is None:
        if len(_CLOCKS) > 256:
            _CLOCKS.clear()
        text = _CLOCKS[second] = datetime.fromtimestamp(second).strftime("%H:%M:%S")
    return text


def upload_button(label: str, testid: str) -> str:
    """A header slot for ``ui.upload``: one button that picks the file (with a spinner while it
    uploads), instead of Quasar's header with its "0.0B / 0.00%" placeholder."""
    return f"""
    <div class="row no-wrap items-center q-pa-xs">
      <q-btn v-if="props.canAddFiles" flat dense no-caps icon="upload_file" label="{label}"
             @click="props.pickFiles" data-testid="{testid}"><q-uploader-add-trigger /></q-btn>
      <q-spinner v-if="props.isUploading" size="sm" class="q-ml-sm" />
    </div>"""


def follow(state: DeviceState, callback: Callable[[], object], slow: bool = False) -> None:
    """Keep part of a page up to date with one device: ``callback`` runs when the device changed
    (pushed by the store as it changes, at most 10 times a second per device) and once a second for
    ages; it ends with the page. The page's followers run together (what changed on all its devices
    goes to the browser in one message, at most 20 a second).

    ``slow=True`` for what changes with every frame but is read as a statistic (counters): it is
    redrawn once a second, so the browser does not lay the page out again ten times a second for it.
    """
    from nicegui import context

    client = context.client
    watch = rt.current().store.watch(state.name, callback, slow, group=client.id)
    client.on_delete(watch.cancel)


def counter_line(state: DeviceState, text: Callable[[object], str]) -> ui.label:  # text: in the page's language
    """A device's counters as one caption line (``text(state.counters)``), redrawn once a second:
    they move with every frame, and a statistic does not need ten layouts a second in every browser."""
    label = ui.label().classes("text-caption mono text-grey-8").props("data-counters")

    def update() -> None:
        label.set_text(text(state.counters))

    update()
    follow(state, update, slow=True)
    return label


EVENT_COLUMNS = [
    {"name": "time", "label": N_("Time"), "field": "time", "align": "left", "classes": "mono", "headerClasses": "w-24"},
    {"name": "level", "label": N_("Level"), "field": "level", "align": "left"},
    {"name": "text", "label": N_("Event"), "field": "text", "align": "left", "classes": "ev-text"},
]
LEVEL_WORDS = {"info": N_("info"), "warning": N_("warning"), "error": N_("error")}  # an event's level as its badge says it


def event_log(state, lang: Lang | None = None) -> ui.table:
    """The device's events newest first (state changes, faults rising and clearing, offline and back,
    commands and refusals), updated in place when one is added; as bounded as the store's list. An event's text
    that is a :class:`~devices.message.Message` is worded in ``lang``, as its level and time are; the store, MQTT
    and the API keep the English it holds (docs/i18n.md)."""
    _ = (lang or i18n.get("en")).gettext
    table = ui.table(columns=columns(EVENT_COLUMNS, lang), rows=[], row_key="id", pagination=0).classes("w-full")
    table.props("dense flat hide-bottom data-testid=events").style("max-height: 16rem")
    table.add_slot("body-cell-text", '<q-td :props="props" style="white-space: normal">{{ props.value }}</q-td>')
    table.add_slot(
        "body-cell-level",
        '<q-td :props="props"><q-badge :color="props.value == \'error\' ? \'negative\' : props.value == \'warning\' '
        '? \'warning\' : \'grey-6\'">{{ props.row.level_text }}</q-badge></q-td>',
    )
    shown: list = [None, -1]  # newest event and count last shown: O(1) when nothing was added

    def update() -> None:
        events = state.events
        newest = events[-1] if events else None
        if newest is shown[0] and len(events) == shown[1]:
            return
        shown[0], shown[1] = newest, len(events)
        count = len(events)
        table.rows = [{"id": count - i, "time": clock_text(e.time, lang), "level": e.level,
                       "level_text": _(LEVEL_WORDS[e.level]) if e.level in LEVEL_WORDS else e.level, "text": said(e.text, lang)}
                      for i, e in enumerate(reversed(events))]
        table.update()

    update()
    follow(state, update)
    return table


def stop_bar(note: str, label: str, icon: str, on_click: Callable[[], object], bar_id: str, button_id: str) -> ui.button:
    """The way out (STOP, All off) in a bar of its own at the bottom, in sight wherever the page is
    scrolled. The page reserves the bar's height, so it never covers a button of the page, and a
    control scrolled into view stops above it, never under it. ``note`` says what the button does and
    who may press it."""
    # above every dialog and its backdrop (Quasar's dialogs sit at z-index 6000): the way out stays pressable
    # while a confirmation is open; a press outside a dialog also cancels the dialog
    ui.add_css("html { scroll-padding-bottom: 88px; } .stop-bar { z-index: 6100 !important; }")
    with ui.footer().classes("stop-bar bg-grey-2 q-py-xs q-px-md items-center justify-end gap-4").props(f"bordered data-testid={bar_id}"):
        ui.label(note).classes("text-caption text-grey-8")
        return ui.button(label, icon=icon, color="negative", on_click=on_click).props(f"size=lg push data-testid={button_id}")


INT32_LIMIT = 2 ** 31 - 1  # a limit at or beyond it is the width of the value, not a limit an engineer set


def number_text(value: float, lang: Lang | None = None) -> str:
    """A limit as an engineer writes it: never exponent notation; whole numbers as such, with thousands
    separators from six digits on (``214,748,364``; register numbers like ``65535`` stay as they are); with
    ``lang`` that language's signs (``214.748.364``, ``0,5`` in German)."""
    value = float(value)
    if value == int(value):
        text = str(int(value))
    else:
        text = format(Decimal(repr(value)), "f")
    whole, dot, fraction = text.partition(".")
    if abs(int(whole)) >= 100_000:
        whole = f"{int(whole):,}" if whole != "-0" else whole
    if lang is not None:
        symbols = lang.locale.number_symbols["latn"]
        whole, dot = whole.replace(",", symbols["group"]), dot and symbols["decimal"]
    return whole + dot + fraction


def range_text(low: float, high: float, unit: str = "", *, any_beyond: float = INT32_LIMIT, lang: Lang | None = None) -> str:
    """``allowed 1 .. 254 mm``; a limit at or beyond ``any_beyond`` (by default the 32-bit range) is no limit:
    ``allowed up to 500 mm``, ``allowed from 0 mm``, ``allowed: any mm``."""
    _ = (lang or i18n.get("en")).gettext
    unit = lang.unit(unit) if lang is not None else unit
    open_low, open_high = abs(low) >= any_beyond, abs(high) >= any_beyond
    if open_low and open_high:
        text = _("allowed: any {unit}").format(unit=unit) if unit else _("allowed: any value")
    elif open_low:
        text = _("allowed up to {high} {unit}").format(high=number_text(high, lang), unit=unit)
    elif open_high:
        text = _("allowed from {low} {unit}").format(low=number_text(low, lang), unit=unit)
    else:
        text = _("allowed {low} .. {high} {unit}").format(low=number_text(low, lang), high=number_text(high, lang), unit=unit)
    return text.strip()


class RangeNumber(ui.number):
    """A number entry that carries its allowed range in words (:attr:`rule`, shown under it)."""

    rule: str = ""


def range_number(label: str, low: float, high: float, *, unit: str = "", integer: bool = False, value=None,
                 step: float | None = None, fmt: str | None = None, any_beyond: float = INT32_LIMIT,
                 lang: Lang | None = None) -> RangeNumber:
    """A number entry with its allowed range shown under it. What was typed stays as typed: an entry
    outside the range (or a fraction where a whole number is needed) is marked invalid with the
    range, never clamped; :func:`checked_value` refuses it before anything is sent. ``label``: in the
    page's language; ``lang`` words the range and the marks."""
    _ = (lang or i18n.get("en")).gettext
    rule = range_text(low, high, unit, any_beyond=any_beyond, lang=lang)
    bounded = abs(low) < any_beyond and abs(high) < any_beyond

    def check(v) -> str | None:
        if v is None:
            return None
        if integer and float(v) != int(float(v)):
            return _("whole numbers only, {rule}").format(rule=rule)
        if not low <= float(v) <= high:
            if bounded:
                return _("out of range: {rule}").format(rule=rule)
            return _("out of range: allowed {low} .. {high} {unit}").format(
                low=number_text(low, lang), high=number_text(high, lang), unit=lang.unit(unit) if lang else unit).strip()
        return None

    # no "%d" format for whole numbers: it rounded a typed 12.5 to 12 on leaving the field
    field = RangeNumber(label, value=value, step=step, format=fmt, validation=check)
    field.props(f'hint="{rule}" dense outlined')
    field.rule = rule
    return field


