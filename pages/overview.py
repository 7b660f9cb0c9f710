"""Overview: every device of the plant as a tile, grouped by bus."""

from __future__ import annotations

from collections.abc import Callable
from html import escape

from nicegui import ui

from app import i18n
from app import runtime as rt
from app.can_bus import CanBusState
from app.i18n import english, N_, Lang
from app.message import said
from app.state import DeviceState
from devices.registry import DEVICE_TYPES
from pages.frame import fmt_age, frame, set_status_badge, status_text
from pages.plant_view import ICON, Followers, LabelPool, evaluate_tile, plant_tile
from pages.widgets import mark_quality, quality_note
from pages.command_client import enable_unless, viewer_reason
from pages.discover import discovered_section
from pages.monitor_common import controller_state


TILE_CSS = """
.overview-layout { display: grid; grid-template-columns: minmax(280px, 340px) minmax(0, 1fr); gap: 16px; width: 100%;
                   align-items: start; }
.overview-layout > .glance { position: sticky; top: 64px; }
@media (max-width: 899px) { .overview-layout { grid-template-columns: minmax(0, 1fr); }
                             .overview-layout > .glance { position: static; } }
.bus-sections { display: flex; flex-wrap: wrap; gap: 12px 24px; align-items: flex-start; width: 100%; }
.bus-section { max-width: 100%; min-width: 0; }
.tile-grid { display: grid; grid-template-columns: repeat(auto-fill, 240px); gap: 12px; width: 100%; }
a.tile-link { color: inherit; text-decoration: none; display: block; min-width: 0; }
a.tile-link > .tile { min-width: 0; height: 100%; cursor: pointer; }
.tile .tile-name { min-width: 0; flex: 1 1 auto; white-space: nowrap; overflow: hidden; text-overflow: ellipsis; }
.tile .q-badge { flex: none; white-space: nowrap; }
.tile .tile-counters { overflow-wrap: anywhere; font-size: .75rem; line-height: 1.25rem; letter-spacing: .03333em;
                      color: #616161; font-family: ui-monospace, SFMono-Regular, Menlo, Consolas, monospace; }
.tile .q-age:empty { display: none; }
table.glance-table { border-collapse: collapse; width: 100%; font-size: 13px; }
table.glance-table th { text-align: left; font-weight: 500; color: #666; padding: 2px 6px; border-bottom: 1px solid #ddd; }
table.glance-table td { padding: 3px 6px; border-bottom: 1px solid #eee; vertical-align: top; }
table.glance-table td a { color: #1565c0; text-decoration: none; font-weight: 500; }
table.glance-table td:first-child { white-space: nowrap; }  /* a device's name is never broken */
table.glance-table td.alarms { color: #c10015; font-weight: 500; overflow-wrap: break-word; }  /* between words */
table.glance-table td.age { white-space: nowrap; color: #666; }
table.glance-table tr.glance-offline td { background: #fdeaea; }
table.glance-table tr.glance-stale td { background: #fff4d6; }
table.glance-table .glance-drift { color: #8a4b00; font-weight: 500; }
table.glance-table .glance-unsaved { color: #8a4b00; font-weight: 500; cursor: help; }
table.glance-table td a.glance-replaced { color: #b71c1c; font-weight: 700; display: block; }
.drift-badge { align-self: flex-start; cursor: help; white-space: normal !important; }
"""
TILE_WIDTH_PX, TILE_GAP_PX = 240, 12

# what a device's counters mean on its bus: CAN devices are heard (periodic frames), the others answer requests
CAN_COUNTERS = (("responses", N_("frames heard"), True), ("malformed", N_("malformed"), True), ("timeouts", N_("timeouts"), False))
REQUEST_COUNTERS = (("requests", N_("req"), True), ("timeouts", N_("timeouts"), True), ("crc_errors", "CRC", True),
                    ("exceptions", N_("exc"), False), ("malformed", N_("malformed"), False))



def overview_tile(state, lang: Lang | None = None) -> dict:
    """The device type's declared tile as the overview shows it: in English an engineer's words
    (:func:`evaluate_tile`), in another language the plant view's words in it (:func:`plant_tile`: the
    documents' words; the engineer's diagnoses are on the device's page)."""
    if lang is None or lang.code == "en":
        return evaluate_tile(state)
    return plant_tile(state, lang)


def drift_of(state: DeviceState) -> dict:
    """The device's drift from its approved set as app/record.py notes it on the record ({} before the first
    check): the record does not declare it (nor :func:`replaced_of`), so it is read here, once for every page."""
    return state.drift or {}


def replaced_of(state: DeviceState) -> dict | None:
    """The known and the new identity while the device looks replaced (app/replace.py notes it), else None."""
    return state.replaced


def drift_rows(state) -> list[dict]:
    """The parameters of ``state`` that differ from its approved set (app/record.py), [] for none."""
    return list(drift_of(state).get("changed") or [])


def replaced_text(state, lang: Lang | None = None) -> str:
    """"replaced?" with the known and the new identity (app/replace.py), "" while the identity is as known."""
    replaced = replaced_of(state)
    if not replaced:
        return ""
    from app.message import said
    from app.replace import identity_text

    return english(lang).gettext("replaced? known {old}, now {new}").format(
        old=said(identity_text(replaced["old"]), lang), new=said(identity_text(replaced["new"]), lang))


def replaced_short(state, lang: Lang | None = None) -> str:
    """"replaced? serial 660020 → 770077": what differs, old and new."""
    replaced = replaced_of(state)
    if not replaced:
        return ""
    from app.message import Message, said
    from app.replace import FACET_WORDS, facets

    old, new = facets(replaced["old"]), facets(replaced["new"])
    return english(lang).gettext("replaced?") + " " + ", ".join(
        said(Message(FACET_WORDS[k], value=f"{old[k]} → {new[k]}"), lang) for k in replaced["differs"])


def unsaved_text(state: DeviceState, lang: Lang | None = None) -> str:
    """"2 unsaved changes" (written, lost at the device's next reset unless saved), "" for none."""
    count = len(state.unsaved)
    return english(lang).ngettext("{n} unsaved change", "{n} unsaved changes", count).format(n=count) if count else ""


def unsaved_names(state: DeviceState, lang: Lang | None = None) -> str:
    """The unsaved parameters by name (the tile's hover text)."""
    params = state.params
    names = []
    for key in sorted(state.unsaved):
        p = params.by_key.get(key) if params is not None else None
        names.append(key if p is None else (p.label or p.name))
    if not names:
        return ""
    return english(lang).gettext("Written, not saved in the device (lost at its next reset): {names}").format(names=", ".join(names))


def drift_text(rows: list[dict], lang: Lang | None = None) -> str:
    show = (lambda v: v) if lang is None else (lambda v: lang.numbers_in(str(v)))
    return "; ".join(f"{r['name']} {show(r['approved'])} → {show(r['now'])}" for r in rows)


def counters_text(counters: dict[str, int], bus_type: str, age: float | None, lang: Lang | None = None) -> str:
    """The tile's counter line for a device on a ``bus_type`` bus; a counter marked False only when not 0."""
    _ = english(lang).gettext
    chosen = CAN_COUNTERS if bus_type == "can" else REQUEST_COUNTERS
    parts = [f"{_(label)} {counters.get(key, 0)}" for key, label, always in chosen if always or counters.get(key)]
    if counters.get("write_errors"):
        parts.append(_("write err {n}").format(n=counters["write_errors"]))
    last = _("last frame {age}") if bus_type == "can" else _("last answer {age}")
    return " · ".join(parts + [last.format(age=fmt_age(age, lang))])


def overview_shows(state, lang: Lang | None = None) -> tuple:
    """What a tile and a table row of the overview draw, ages and counters left out: redrawn when it changed."""
    tile = overview_tile(state, lang)
    return (tile["lines"], tile["alarms"], tile["bar"], tile["quality"], state.status, state.last_error,
            drift_text(drift_rows(state)), replaced_text(state), unsaved_text(state))


_SHOWS: dict[str, object] = {}


def shows_in(lang: Lang | None):
    """:func:`overview_shows` in ``lang``: one function per language, so the feed compares the tiles of one language
    once per change however many pages show them."""
    if lang is None or lang.code == "en":
        return overview_shows
    found = _SHOWS.get(lang.code)
    if found is None:
        found = _SHOWS[lang.code] = lambda state: overview_shows(state, lang)
    return found


class DeviceTile:
    """One device of the overview, set in place: what its values show when that changed (pushed through
    :class:`pages.plant_view.Followers`), counters and ages once a second on the page's tick (``ticked``),
    every element sent only when what it shows changed. Marks that are seldom shown (changed since
    approved, replaced?, a stale note, the last error) are built the first time they are needed."""

    shows = staticmethod(overview_shows)

    def __init__(self, name: str, lang: Lang | None = None):
        runtime = rt.current()
        self.name = name
        self.lang = lang
        _ = english(lang).gettext
        self.state = runtime.store.devices[name]
        self.device_type = DEVICE_TYPES[self.state.type]
        self.bus_type = runtime.plant.buses[self.state.bus].type
        self._shown: dict[str, object] = {}
        self._tile: dict | None = None
        self.drift = self.replaced = self.unsaved = self.quality_note = self.error = None
        # a real link: a click opens the device page, a middle click or the context menu a new tab
        with ui.link(target=f"/device/{name}").classes("tile-link").props(f'data-device-link="{name}"') as self.link, \
                ui.card().classes("tile") as self.card:
            self.card.props(f'data-device="{name}"')
            with ui.row().classes("items-center w-full no-wrap"):
                ui.label(name).classes("text-subtitle1 text-weight-bold tile-name").props(f'title="{name}"')
                self.badge = ui.badge(_("waiting"), color="grey")
            title = self.device_type.title if lang is None else lang.phrase(self.device_type.title)
            self.kind = ui.label(_("{type} on {bus}").format(type=title, bus=self.state.bus)).classes("text-caption text-grey-8")
            self.values = ui.column().classes("gap-0 w-full").props("data-tile-values")
            self.lines = LabelPool(self.values)
            # they move with every frame: drawn once a second, with every other tile's, on the page's tick
            self.counters = ui.label().classes("tile-counters").props("data-tile-counters")  # one class: sent every second
        self.refresh(ticked=True)

    def _changed(self, key: str, value: object) -> bool:
        if self._shown.get(key, self) == value:
            return False
        self._shown[key] = value
        return True

    def _element(self, attr: str, make: Callable[[], ui.element]) -> ui.element:
        """The seldom shown element ``attr``, built the first time it is needed, in its place in the card."""
        element = getattr(self, attr)
        if element is None:
            with self.card:
                element = make()
            order = [getattr(self, a) for a in TILE_ORDER]
            before = next(e for e in reversed(order[:TILE_ORDER.index(attr)]) if e is not None)
            element.move(target_index=self.card.default_slot.children.index(before) + 1)
            setattr(self, attr, element)
        return element

    def refresh(self, ticked: bool = False) -> None:
        """Show the device as it is now; ``ticked``: the page's once-a-second tick (counters and ages too)."""
        s = self.state
        lang = self.lang
        _ = english(lang).gettext
        status, age = s.status, s.age
        tile = overview_tile(s, lang)  # the device type's declared tile: the same lines and alarms as the plant view
        rows = drift_rows(s)
        replaced = replaced_text(s, lang)
        if self._changed("badge", (status, status_text(status, age, lang))):
            set_status_badge(self.badge, status, age, lang)
        quality = tile["quality"]
        if tile is not self._tile:
            self._tile = tile
            alarms = tile["alarms"] if quality in ("good", "unknown") else []
            self.lines.show([(line, LINE) for line in tile["lines"]] + ([(tile["bar"][1], LINE)] if tile["bar"] else [])
                            + [(f"⚠ {a}", ALARM) for a in alarms])
        marked = quality if quality in ("stale", "offline") else "good"
        if self._changed("quality", marked):
            mark_quality(self.values, marked)
        note = quality_note(quality, tile["age"], lang) if marked != "good" else ""
        if self._changed("note", note) and (note or self.quality_note is not None):
            self._element("quality_note", lambda: ui.label().classes("q-age")).set_text(note)
        error = said(s.last_error, lang) if status != "online" else ""  # a Message of the adapter or the line
        if self._changed("error", error) and (error or self.error is not None):
            self._element("error", lambda: ui.label().classes("text-caption text-negative")).set_text(error)
        if self._changed("replaced", replaced) and (replaced or self.replaced is not None):
            # another serial number (firmware, variant) than known at this address: the replacement assistant
            badge = self._element("replaced", lambda: ui.badge(_("replaced?"), color="red-8").classes("drift-badge")
                                  .props(f'data-replaced="{self.name}"'))
            badge.set_visibility(bool(replaced))
            badge.props["title"] = replaced
            badge.text = replaced_short(s, lang) or _("replaced?")
            badge.update()
        if self._changed("drift", drift_text(rows)) and (rows or self.drift is not None):
            # the commissioning record: the differing parameters on hover (title) and in the record page
            badge = self._element("drift", lambda: ui.badge(_("changed since approved"), color="orange-9")
                                  .classes("drift-badge").props(f'data-drift="{self.name}"'))
            badge.set_visibility(bool(rows))
            badge.text = _("changed since approved ({n})").format(n=len(rows)) if rows else _("changed since approved")
            badge.props["title"] = _("Changed since approved: {rows}").format(rows=drift_text(rows, lang)) if rows else ""
            badge.update()
        unsaved = unsaved_text(s, lang)
        if self._changed("unsaved", unsaved) and (unsaved or self.unsaved is not None):
            # written, not saved: lost at the device's next reset (its page offers Save)
            badge = self._element("unsaved", lambda: ui.badge("", color="amber-10").classes("drift-badge")
                                  .props(f'data-unsaved="{self.name}"'))
            badge.set_visibility(bool(unsaved))
            badge.text = unsaved
            badge.props["title"] = unsaved_names(s, lang)
            badge.update()
        if ticked:
            self.counters.set_text(counters_text(s.counters.as_dict(), self.bus_type, age, lang))


# a tile's card from top to bottom below its name (the seldom shown ones are built when first needed)
TILE_ORDER = ("kind", "drift", "replaced", "unsaved", "values", "quality_note", "counters", "error")
LINE, ALARM = "text-body2", "text-body2 text-negative text-weight-medium"


def _cell(text: str, classes: str = "", attrs: str = "") -> str:
    return f'<div class="{classes}"{attrs}>{escape(text)}</div>' if classes or attrs else f"<div>{escape(text)}</div>"


class GlanceRow:
    """One device in the at-a-glance table: state, alarms and age, one element (the row, its cells as HTML)
    sent again only when one of them changed."""

    shows = staticmethod(overview_shows)

    def __init__(self, name: str, lang: Lang | None = None):
        self.name = name
        self.lang = lang
        self.state = rt.current().store.devices[name]
        self._shown: tuple = ()
        self.rank = RANK_OTHER  # where the row goes in the table: alarms and offline devices first (:func:`rank_of`)
        self.alarmed = False
        self.row = ui.html("", sanitize=False, tag="tr").props(f'data-glance="{name}"')
        self.refresh()

    def refresh(self, ticked: bool = False) -> None:
        s = self.state
        lang = self.lang
        _ = english(lang).gettext
        status, age = s.status, s.age
        tile = overview_tile(s, lang)
        alarms = tile["alarms"] if tile["quality"] in ("good", "unknown") else []
        rows = drift_rows(s)
        replaced = replaced_text(s, lang)
        unsaved = unsaved_text(s, lang)
        self.alarmed = bool(alarms)
        self.rank = rank_of(status, bool(alarms), bool(rows or replaced or unsaved))
        shown = (status, "; ".join(alarms), fmt_age(age, lang) if age is not None else _("never"), drift_text(rows, lang),
                 replaced, unsaved)
        if shown == self._shown:
            return
        self._shown = shown
        name = escape(self.name, quote=True)
        state = _cell(status_text(status, None, lang) if status != "stale" else _("stale"), f"status-{status}")
        if rows:
            state += _cell(_("changed since approved"), "glance-drift", f' data-glance-drift="{name}"')
        if unsaved:
            state += _cell(unsaved, "glance-unsaved", f' data-glance-unsaved="{name}" title="{escape(unsaved_names(s, lang), quote=True)}"')
        if replaced:
            state += (f'<a class="glance-replaced" href="/replace/{name}" data-glance-replaced="{name}" '
                      f'title="{escape(replaced, quote=True)}">{escape(replaced_short(s, lang) or _("replaced?"))}</a>')
        alarm_cell = _cell(shown[1]) + (_cell(_("Changed since approved: {rows}").format(rows=shown[3]), "glance-drift") if rows else "")
        self.row.set_content(f'<td><a href="/device/{name}">{escape(self.name)}</a></td><td>{state}</td>'
                             f'<td class="alarms">{alarm_cell}</td><td class="age">{escape(shown[2])}</td>')
        self.row.classes(replace=f"glance-{status}")


RANK_ATTENTION, RANK_MARKED, RANK_OTHER = 0, 1, 2
LARGE_PLANT = 24  # devices: from here on the overview offers filters and draws a bus's tiles when it is opened
STATE_FILTERS = {"": N_("Every state"), "attention": N_("Alarm, offline or stale"), "alarms": N_("With alarms"),
                 "offline": N_("Offline"), "stale": N_("Stale"), "online": N_("Online")}


def rank_of(status: str, alarmed: bool, marked: bool) -> int:
    """A device's place in the table: alarms and offline first, then stale or changed ones, then the rest."""
    if alarmed or status == "offline":
        return RANK_ATTENTION
    if status == "stale" or marked:
        return RANK_MARKED
    return RANK_OTHER


class OverviewFilter:
    """What the overview lists: a bus, a device type and a state, each "" for all (large plants only; a small
    plant lists everything). The table's rows, the bus sections and their tiles follow it on the page's tick."""

    def __init__(self, runtime) -> None:
        self.runtime = runtime
        self.bus = self.type = self.state = ""

    def matches(self, name: str, row: GlanceRow | None) -> bool:
        dev = self.runtime.plant.devices[name]
        if (self.bus and dev.bus != self.bus) or (self.type and dev.type != self.type):
            return False
        if not self.state or row is None:
            return True
        status = row.state.status
        if self.state == "attention":
            return row.rank == RANK_ATTENTION or status == "stale"
        if self.state == "alarms":
            return row.alarmed
        return status == self.state


class GlanceTable:
    """Every device in one dense table (state, alarms, age of its last value): the plant at a glance, alarms and
    offline devices first. A row is one element; the order is sent again only when a device's rank changed."""

    def __init__(self, runtime, followers: Followers, filt: OverviewFilter, large: bool, lang: Lang | None = None):
        self.runtime = runtime
        self.lang = lang
        _ = english(lang).gettext
        self.filter = filt
        self.rows: dict[str, GlanceRow] = {}
        self.shown_count = None
        with ui.card().classes("glance q-pa-sm").props("data-testid=glance"):
            total = len(runtime.plant.devices)
            self.title = ui.label(_("All devices ({total})").format(total=total)).classes("text-subtitle2")
            if large:
                self._filters(runtime)
            with ui.element("table").classes("glance-table"):
                ui.html("<tr>" + "".join(f"<th>{escape(_(head))}</th>" for head in (N_("Device"), N_("State"), N_("Alarms"),
                                                                                   N_("Last value"))) + "</tr>",
                        sanitize=False, tag="thead")
                with ui.element("tbody") as self.body:
                    for dev in runtime.plant.devices.values():
                        self.rows[dev.name] = row = GlanceRow(dev.name, lang)
                        followers.add(row, shows_in(lang))
        self.order = list(self.rows)
        self.arrange()

    def _filters(self, runtime) -> None:
        lang = english(self.lang)
        _ = lang.gettext
        buses = {"": _("Every bus")} | {b: b for b in runtime.plant.buses}
        present = sorted({d.type for d in runtime.plant.devices.values()})
        types = {"": _("Every type")} | {t: lang.phrase(DEVICE_TYPES[t].title) for t in present}
        states = {key: _(label) for key, label in STATE_FILTERS.items()}
        with ui.row().classes("items-center gap-1 w-full no-wrap").props("data-testid=overview-filters"):
            for attr, options, testid in (("bus", buses, "filter-bus"), ("type", types, "filter-type"),
                                          ("state", states, "filter-state")):
                ui.select(options, value="", on_change=lambda e, a=attr: self.set_filter(a, e.value or "")).props(
                    f"dense options-dense outlined data-testid={testid}").classes("col")

    def set_filter(self, attr: str, value: str) -> None:
        setattr(self.filter, attr, value)
        self.arrange()
        if self.on_filter is not None:
            self.on_filter()

    on_filter = None  # the bus sections' visibility, set by the page

    def arrange(self) -> None:
        """Alarms and offline first, in plant order within a rank; rows outside the filter hidden."""
        place = {name: i for i, name in enumerate(self.rows)}
        order = sorted(place, key=lambda n: (self.rows[n].rank, place[n]))
        if order != self.order:
            self.order = order
            self.body.default_slot.children[:] = [self.rows[n].row for n in order]
            self.body.update()
        shown = 0
        for name, row in self.rows.items():
            visible = self.filter.matches(name, row)
            row.row.set_visibility(visible)
            shown += visible
        if shown != self.shown_count:
            self.shown_count = shown
            total = len(self.rows)
            _ = english(self.lang).gettext
            self.title.set_text(_("All devices ({total})").format(total=total) if shown == total else
                                _("{shown} of {total} devices").format(shown=shown, total=total))


def content() -> None:
    runtime = rt.current()
    lang = i18n.page_language()
    _ = lang.gettext
    with frame("Overview", beat=False):  # a page that starts and holds nothing: no dead-man beats
        ui.add_css(TILE_CSS)
        followers = Followers()
        ticks: list = []  # the bus lines and discovery lists: one timer for the page, not one per bus
        large = len(runtime.plant.devices) > LARGE_PLANT
        filt = OverviewFilter(runtime)
        with ui.element("div").classes("overview-layout"):
            table = GlanceTable(runtime, followers, filt, large, lang) if runtime.plant.devices else None
            with ui.element("div").classes("bus-sections"):
                sections = []
                for bus in runtime.plant.buses.values():
                    if large:
                        sections.append(_large_bus_section(runtime, bus, followers, ticks, filt, table, lang))
                        continue
                    count = max(1, len(runtime.plant.devices_on(bus.name)))
                    width = count * TILE_WIDTH_PX + (count - 1) * TILE_GAP_PX
                    with ui.column().classes("bus-section gap-1").style(f"width: max({width}px, 30rem)"):
                        _bus_section(runtime, bus, followers, ticks, lang=lang)
                # one tick for the page: every tile's counters and ages, the table's ages and the bus lines
                # go to the browser together, in one message a second
                ticks.insert(0, (1, followers.tick))
                if table is not None:
                    def arrange() -> None:
                        table.arrange()
                        for section in sections:
                            section()

                    table.on_filter = arrange
                    ticks.insert(1, (1, arrange))
                ui.timer(1.0, lambda count=[0]: _tick(ticks, count))
        if not runtime.plant.devices:
            ui.label(_("This plant file lists no devices.")).classes("text-grey-8")


def _large_bus_section(runtime, bus, followers: Followers, ticks: list, filt: OverviewFilter,
                       table: GlanceTable | None, lang: Lang | None = None) -> Callable[[], None]:
    """A bus of a large plant: a closed section with its device count and their states in its caption; its tiles
    are drawn the first time it is opened (a hundred tiles at once would be a slow page nobody reads whole).
    Returns what the page's tick calls: the caption and the visibility under the filter."""
    names = [d.name for d in runtime.plant.devices_on(bus.name)]
    built: list = []
    tiles: dict[str, DeviceTile] = {}
    shown: list = [None]
    expansion = ui.expansion(bus.name, icon="cable").classes("bus-section w-full").props(
        f'dense data-bus-section="{escape(bus.name, quote=True)}"')

    def build() -> None:
        if built:
            return
        built.append(True)
        with expansion:
            _bus_section(runtime, bus, followers, ticks, tiles, lang)
        update()

    def update() -> None:
        rows = table.rows if table is not None else {}
        states = [rows[n] for n in names if n in rows]
        attention = sum(1 for r in states if r.rank == RANK_ATTENTION)
        online = sum(1 for r in states if r.state.status == "online")
        words = english(lang)
        caption = f"{bus.type} · " + words.ngettext("{n} device", "{n} devices", len(names)).format(n=len(names)) + \
            " · " + words.gettext("{n} online").format(n=online) + (
                " · " + words.gettext("{n} with alarms or offline").format(n=attention) if attention else "")
        visible = [n for n in names if filt.matches(n, rows.get(n))]
        if (caption, len(visible)) != shown[0]:
            shown[0] = (caption, len(visible))
            expansion.props(f'caption="{escape(caption, quote=True)}"')
            expansion.set_visibility(bool(visible) or (not names and not (filt.bus or filt.type or filt.state)))
        if filt.bus == bus.name and not expansion.value:
            expansion.set_value(True)
        for name, tile in tiles.items():
            tile.link.set_visibility(name in visible)

    expansion.on_value_change(lambda e: build() if e.value else None)
    update()
    return update


def _tick(ticks: list, count: list) -> None:
    """Once a second: every tile, table row and bus line (and every other second the discovery lists) of
    the page, each setting only what changed."""
    count[0] += 1
    for every, tick in ticks:
        if count[0] % every == 0:
            tick()


def _bus_section(runtime, bus, followers: Followers, ticks: list, tiles: dict | None = None, lang: Lang | None = None) -> None:
    bus_state = runtime.store.buses[bus.name]
    lang = english(lang)
    _ = lang.gettext
    with ui.row().classes("items-center gap-x-2 gap-y-0"):
        # icon, name and endpoint never change: one element, its parts laid out in the row as before
        ui.html(f'{ICON % ("", "cable")}<span class="text-h6">{escape(bus.name)}</span>'
                f'<span class="text-caption text-grey-8">{escape(f"{bus.type} · {bus.endpoint}")}</span>',
                sanitize=False).style("display: contents")
        ui.button(_("Bus monitor"), icon="monitor_heart", on_click=lambda b=bus.name: ui.navigate.to(f"/monitor/{b}")).props("flat dense")
        if bus.type == "modbus-rtu":
            from pages.discover import open_discover_dialog

            discover = ui.button(_("Discover locks"), icon="search", on_click=lambda b=bus.name: open_discover_dialog(b)).props(
                "flat dense data-testid=discover-locks")
            enable_unless(discover, viewer_reason(lang))  # it sends to the line: an engineer's action
    conn = ui.label().classes("text-caption")
    shown: list = [None]

    def show_conn(label=conn, state=bus_state) -> None:
        text = _("connected") if state.connected else _("not connected: {error}").format(error=said(state.last_error, lang) or _("opening..."))
        can = isinstance(state, CanBusState)
        if state.connected and can:
            text += " · " + _("{state} · {rx} frames in, {errors} error frames").format(
                state=controller_state(state.bus_state, lang), rx=state.rx_frames, errors=state.error_frames)
        if state.cycle_s:  # Modbus: the measured time to poll every device once
            text += " · " + _("cycle {seconds} s").format(seconds=lang.number(state.cycle_s, 2))
        if state.address_conflicts:
            text += " · " + _("{n} answers from another unit: address conflict on the line?").format(n=state.address_conflicts)
        shed = state.shed if can else 0
        if shed:  # the program could not keep up with this bus: say so rather than lag
            text += " · " + _("{n} frames shed: more traffic than this program can handle").format(n=shed)
        ok = state.connected and not (can and state.bus_state == "bus-off")
        classes = "text-caption " + (("text-warning" if shed else "text-positive") if ok else "text-negative")
        if (text, classes) == shown[0]:
            return  # unchanged: nothing goes to the browser
        shown[0] = (text, classes)
        label.set_text(text)
        label.classes(replace=classes)

    show_conn()
    ticks.append((1, show_conn))
    with ui.element("div").classes("tile-grid") as row:
        for dev in runtime.plant.devices_on(bus.name):
            tile = DeviceTile(dev.name, lang)
            followers.add(tile, shows_in(lang))
            if tiles is not None:
                tiles[dev.name] = tile
    if bus.type == "can":
        ticks.append((2, discovered_section(bus.name, row, lambda name: followers.add(DeviceTile(name, lang), shows_in(lang)), lang)))
