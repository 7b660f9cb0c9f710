"""Bus monitor of a CAN bus.

Live frame list and overwrite view (one row per ID) from the bus's bounded buffers in the store,
decoded by the device codecs, with ID-range/device filters, pause, error frames and bus state;
recording to candump/ASC/BLF/CSV files and browsing recorded files. A Device column names the
plant device that sent or answered each frame.

The page is small cards with ``build()``/``refresh()`` (bus status, filters, recording, the
overwrite view, the frame list, the recorded file) composed by :class:`CanMonitor`; the frame table
is :mod:`pages.can_trace`'s, recording and the recorded file :mod:`pages.can_files`'. The tables
are refreshed by one timer a few times a second, never once per frame, and show at most
``SHOWN`` frames and ``SHOWN_IDS`` IDs.
"""

from __future__ import annotations

import heapq
import time

from nicegui import background_tasks, ui

from app import can_bus as cb
from app import i18n
from app import recording as rec
from app import runtime as rt
from app.can_bus import MONITOR_FRAMES, CanBusState, FrameRecord
from app.i18n import N_, Lang
from pages.can_files import FileView, RecordingCard
from pages.can_trace import (BusDecoding, FilterCard, DECODED_SLOT, SCROLL_HEIGHT, clicked_key, decoded_text, frame_rows, frame_table,
                             show_frame_details)
from pages.frame import fmt_age, frame, notify_error
from pages.monitor_common import CSS, SHOWN, controller_state, tool_links
from pages.widgets import columns as shown_columns

SHOWN_IDS = 300  # rows of the overwrite view
REFRESH_S = 0.3
ID_COLUMNS = [
    {"name": "id", "label": "ID", "field": "id", "align": "left", "classes": "mono"},
    {"name": "dir", "label": N_("Dir"), "field": "dir", "align": "center"},
    {"name": "device", "label": N_("Device"), "field": "device", "align": "left"},
    {"name": "count", "label": N_("Count"), "field": "count", "align": "right"},
    {"name": "cycle", "label": N_("Cycle ms"), "field": "cycle", "align": "right", "classes": "cycle"},
    {"name": "data", "label": N_("Data (changed bytes marked)"), "field": "data", "align": "left"},
    {"name": "decoded", "label": N_("Decoded"), "field": "decoded", "align": "left"},
    {"name": "age", "label": N_("Last"), "field": "age", "align": "right", "classes": "nowrap", "headerClasses": "nowrap"},
]
BYTES_SLOT = (
    '<q-td :props="props" class="mono bytes">'
    '<span v-for="(b, i) in props.row.bytes" :key="i" :class="b[1] ? \'byte byte-changed\' : \'byte\'">{{ b[0] }}</span>'
    "</q-td>"
)
STATE_COLOR = {"error-active": "positive", "error-passive": "warning", "bus-off": "negative"}


def cycle_text(cycles: list[tuple[int, int, float, float]], lang: Lang | None = None) -> str:
    """The cycle time of an ID: ``1000``; bursts as ``2000 (bursts of 12)``; several frame lengths
    on one ID each with its length, most frequent first: ``1000 (8 B) · 2000 (6 B, bursts of 12)``
    (its words in ``lang``, English without)."""
    if not cycles:
        return "-"
    lang = i18n.english(lang)
    _ = lang.gettext
    parts = []
    for length, _count, cycle, burst in cycles[:3]:
        notes = [] if len(cycles) == 1 else [f"{length} B" if length >= 0 else _("other lengths")]
        if burst >= 1.5:
            notes.append(_("bursts of {n}").format(n=f"{burst:.0f}"))
        parts.append(f"{cycle * 1000:.0f}" + (f" ({', '.join(notes)})" if notes else ""))
    return " · ".join(parts)


class BusStatusCard:
    """The bus state, connection, load and counters, the bus tools and the DBC download."""

    def __init__(self, bus: str, state: CanBusState, options: dict, lang: Lang):
        self.bus = bus
        self.state = state
        self.options = options
        self.lang = lang

    def build(self) -> None:
        _ = self.lang.gettext
        with ui.row().classes("items-center gap-3 w-full"):
            ui.label(f"CAN · {self.state.endpoint} · {self.options.get('bitrate', '?')} bit/s").classes("text-caption text-grey-8")
            self.state_badge = ui.badge(_("unknown")).mark("bus-state")
            self.connected_badge = ui.badge("").mark("connected")
            self.load = ui.label().classes("text-body2 mono").mark("load")
            self.load.props("data-monitor=load")
            self.counts = ui.label().classes("text-body2 mono").mark("counters")
            self.counts.props("data-monitor=counters")
            self.error_label = ui.label().classes("text-body2 text-negative")
            tool_links(self.bus, [(_("Transmit"), "transmit", "send"), (_("Replay"), "replay", "replay")])
            ui.button("DBC", icon="download", on_click=self.download_dbc).props(
                "flat dense no-caps data-monitor=dbc").tooltip(
                _("A DBC of this bus's devices (cantools), so other tools decode recordings with names"))

    def download_dbc(self) -> None:
        from app import dbc

        try:
            text = dbc.dbc_text(rt.current().plant, self.bus)  # the running plant: adopted devices included
        except dbc.DbcError as exc:
            notify_error(self.lang.gettext("No DBC for {bus}: {error}").format(bus=self.bus, error=exc))
            return
        ui.download.content(text.encode(), f"{self.bus}.dbc", "application/octet-stream")

    def refresh(self) -> None:
        s = self.state
        lang = self.lang
        _ = lang.gettext
        bus_state = s.bus_state if s.connected else "not connected"
        self.state_badge.set_text(controller_state(bus_state, lang))
        self.state_badge.props(f"color={STATE_COLOR.get(bus_state, 'grey')}")
        self.connected_badge.set_text(_("connected") if s.connected else _("disconnected"))
        self.connected_badge.props(f"color={'positive' if s.connected else 'negative'} outline")
        drops = (_("interface drops {n} ({source})").format(n=s.interface_dropped, source=s.drop_source)
                 if s.interface_dropped is not None else
                 _("interface drops: not reported by {interface}").format(interface=self.options.get("interface", "?")))
        self.counts.set_text(" · ".join((
            _("rx {rx} · tx {tx} · error frames {errors}").format(rx=s.rx_frames, tx=s.tx_frames, errors=s.error_frames),
            _("tx errors {errors} · dropped {dropped} (shed under load {shed})").format(
                errors=s.tx_errors, dropped=s.dropped, shed=s.shed),
            drops, _("buffered {n}/{max}").format(n=len(s.frames), max=MONITOR_FRAMES))))
        self.load.set_text(self._load_text() + " · " + _("{n} frames/s").format(n=f"{s.frames_per_s:.0f}"))
        self.error_label.set_text(s.last_error)

    def _load_text(self) -> str:
        s = self.state
        lang = self.lang
        if s.load_pct is None:
            return lang.gettext("load: bit rate unknown")
        # the average is the steady figure (frames reach the program in batches); the peak is the worst second
        average = s.load_avg_pct if s.load_avg_pct is not None else s.load_pct
        peak = s.load_peak_pct if s.load_peak_pct is not None else s.load_pct
        return lang.gettext("load {average} of {kbit} kbit/s ({seconds} s average), peak {peak} (highest second of "
                            "the last {last} s)").format(  # the percentages with their sign: "%" in a text reads as a format
            average=f"{lang.number(average, 1, group=False)} %", kbit=lang.numbers_in(f"{self.options.get('bitrate') / 1000:g}"),
            seconds=lang.numbers_in(f"{cb.LOAD_AVERAGE_S:g}"), peak=f"{lang.number(peak, 1, group=False)} %",
            last=lang.numbers_in(f"{cb.LOAD_PEAK_S:g}"))


class FrameView:
    """A view of the bus's frames: its state, the filters that choose them, their decoder and the page's language."""

    def __init__(self, state: CanBusState, filters: FilterCard, decoder: rec.FrameDecoder, lang: Lang):
        self.state = state
        self.filters = filters
        self.decoder = decoder
        self.lang = lang


class OverwriteCard(FrameView):
    """The overwrite view: one row per ID (count, cycle, data with the changed bytes marked, decoded)."""

    def build(self) -> None:
        with ui.row().classes("items-center gap-2"):
            ui.label(self.lang.gettext("Overwrite view: one row per ID")).classes("text-subtitle2")
            self.ids_info = ui.label().classes("text-caption text-grey-8")
        with ui.element("div").classes("w-full monitor-scroll").style("max-height: 34vh; overflow-y: auto").props("data-monitor=overwrite-box"):
            self.table = ui.table(columns=shown_columns(ID_COLUMNS, self.lang), rows=[], row_key="k", pagination=0).classes("w-full can-table")
        self.table.props("dense flat bordered")
        self.table.add_slot("body-cell-data", BYTES_SLOT)
        self.table.add_slot("body-cell-decoded", DECODED_SLOT)
        self.table.mark("overwrite")
        self.table.props("data-monitor=overwrite hide-bottom")

    def refresh(self) -> None:
        now = time.time()
        flt = self.filters.filter
        items = self.state.ids.items()
        if flt.active:
            items = [(key, stats) for key, stats in items if flt.matches(key[1], key[0], stats.data)]
        first = heapq.nsmallest(SHOWN_IDS, items, key=lambda item: (item[0][1], item[0][0]))
        rows = [self._row(ext, can_id, stats, now) for (ext, can_id), stats in first]
        total = len(self.state.ids)
        matching = len(items) if flt.active else total
        lang = self.lang
        text = lang.ngettext("{n} ID", "{n} IDs", matching).format(n=matching)
        if len(rows) < matching:
            text = lang.gettext("first {shown} of {ids}").format(shown=len(rows), ids=text)
        if flt.active:
            text += " " + lang.gettext("(of {total})").format(total=total)
        self.ids_info.set_text(text)
        if rows != self.table.rows:
            self.table.rows = rows
            self.table.update()

    def _row(self, ext: bool, can_id: int, stats, now: float) -> dict:
        decoded = self.decoder(can_id, ext, stats.data)
        return {
            "k": f"{int(ext)}:{can_id}",
            "id": rec.format_id(can_id, ext),
            "dir": stats.direction,
            "device": self.decoder.device(can_id, ext, stats.data),
            "count": stats.count,
            "cycle": cycle_text(stats.cycles(), self.lang),
            "data": rec.format_data(stats.data),
            "bytes": rec.changed_bytes(stats.data, stats.changed),
            "decoded": decoded_text(decoded, self.lang),
            "unknown": decoded == rec.UNKNOWN,
            "age": fmt_age(now - stats.last_time, self.lang),
            "err": False,
        }


class FramesCard(FrameView):
    """The newest frames of the bus; while paused, the whole buffer as it was, in pages."""

    def __init__(self, state: CanBusState, filters: FilterCard, decoder: rec.FrameDecoder, lang: Lang):
        super().__init__(state, filters, decoder, lang)
        self.snapshot: list[FrameRecord] = []  # the whole buffer (matching the filters), newest first, while paused
        self.shown: dict[int, FrameRecord] = {}  # row key -> frame of the rows on screen
        self._signature: tuple | None = None

    def build(self) -> None:
        _ = self.lang.gettext
        with ui.row().classes("items-center gap-2"):
            ui.label(_("Frames, newest first")).classes("text-subtitle2")
            self.frames_info = ui.label().classes("text-caption text-grey-8")
            self.frames_info.props("data-monitor=frames-info")
            self.pages = ui.pagination(1, 1, direction_links=True, on_change=self.show_paused_page).props(
                "dense max-pages=7 boundary-numbers data-monitor=live-pages")
            self.pages.set_visibility(False)
            ui.label(_("click a frame for its full decoding")).classes("text-caption text-grey-6")
        with ui.element("div").classes("w-full monitor-scroll").style(SCROLL_HEIGHT):
            self.table = frame_table("frames", self.lang)
        self.table.on("rowClick", self._clicked)

    def _clicked(self, event) -> None:
        f = self.shown.get(clicked_key(event))
        if f is not None:
            show_frame_details(f, self.decoder, None, self.lang)

    def refresh(self) -> None:
        s = self.state
        signature = (s.rx_frames, s.tx_frames, len(s.frames), self.filters.version, len(self.decoder.known_ids))
        if signature == self._signature:
            return
        self._signature = signature
        flt = self.filters.filter
        shown = rec.newest(s.frames, flt, SHOWN)
        self.shown = dict(enumerate(shown))
        rows = frame_rows(shown, self.decoder, self.lang)
        _ = self.lang.gettext
        info = _("newest {n} matching of {total} buffered frames") if flt.active else _("newest {n} of {total} buffered frames")
        self.frames_info.set_text(info.format(n=len(rows), total=len(s.frames)))
        if rows != self.table.rows:
            self.table.rows = rows
            self.table.update()

    def take_snapshot(self) -> None:
        """The buffer as it is now (at most MONITOR_FRAMES references, newest first), paged by SHOWN."""
        self.snapshot = rec.newest(self.state.frames, self.filters.filter, MONITOR_FRAMES)
        self.pages.max = max(1, -(-len(self.snapshot) // SHOWN))
        self.pages.value = 1
        self.pages.set_visibility(True)
        self.pages.update()
        self.show_paused_page()

    def resume(self) -> None:
        """Back to the newest frames (the next refresh lists them)."""
        self.snapshot = []
        self.pages.set_visibility(False)
        self._signature = None

    def show_paused_page(self) -> None:
        if not self.filters.paused:
            return
        page = max(1, int(self.pages.value or 1))
        first = (page - 1) * SHOWN
        shown = self.snapshot[first:first + SHOWN]
        self.shown = {first + i: f for i, f in enumerate(shown)}
        _ = self.lang.gettext
        info = (_("paused: frames {first}-{last} of {total} matching buffered, page {page} of {pages}")
                if self.filters.filter.active else _("paused: frames {first}-{last} of {total} buffered, page {page} of {pages}"))
        self.frames_info.set_text(info.format(first=first + 1 if shown else 0, last=first + len(shown), total=len(self.snapshot),
                                              page=page, pages=self.pages.max))
        self.table.rows = frame_rows(shown, self.decoder, self.lang, first_key=first)
        self.table.update()


class CanMonitor:
    """One browser's view of one CAN bus: status, filters, recording, and the live and recorded-file tabs.

    The cards read the bus's record in the store (frames, counters, ID statistics, the recording) and
    name frames through one :class:`BusDecoding`; one timer refreshes them a few times a second.
    """

    def __init__(self, bus: str):
        runtime = rt.current()
        self.bus = bus
        self.lang = lang = i18n.page_language()
        self.state: CanBusState = runtime.store.buses[bus]
        options = runtime.plant.buses[bus].options
        self.decoding = BusDecoding(bus)
        devices = [d.name for d in runtime.plant.devices_on(bus)]
        self.status = BusStatusCard(bus, self.state, options, lang)
        self.filters = FilterCard(devices, self.decoding, on_change=self._filters_changed, on_pause=self._pause_changed,
                                  lang=lang)
        self.file = FileView(self.state, self.filters, self.decoding, show=lambda: self.tabs.set_value("file"), lang=lang)
        self.recording = RecordingCard(bus, self.state, options, open_file=self.file.open_recording, lang=lang)
        self.overwrite = OverwriteCard(self.state, self.filters, self.decoding.decoder, lang)
        self.frames = FramesCard(self.state, self.filters, self.decoding.decoder, lang)
        with frame(lang.gettext("Bus monitor {bus}").format(bus=bus)):
            ui.add_css(CSS)
            self.status.build()
            self.filters.build()
            self.recording.build()
            self._build_tabs()
        self.refresh()
        ui.timer(0, self.recording.refresh_list, once=True)
        ui.timer(REFRESH_S, self.refresh)

    def _build_tabs(self) -> None:
        with ui.tabs(value="live").classes("w-full").props("dense align=left") as self.tabs:
            live_tab = ui.tab("live", self.lang.gettext("Live"))
            file_tab = ui.tab("file", self.lang.gettext("Recorded file"))
        with ui.tab_panels(self.tabs, value=live_tab).classes("w-full").props("keep-alive"):
            with ui.tab_panel(live_tab).classes("q-pa-none gap-2"):
                self.overwrite.build()
                self.frames.build()
            with ui.tab_panel(file_tab).classes("q-pa-none gap-2"):
                self.file.build()

    def _tab(self) -> str:
        value = self.tabs.value
        return value.props["name"] if isinstance(value, ui.tab) else str(value)

    def refresh(self, force: bool = False) -> None:
        """The status always (also while paused); the live lists while they are shown and not paused."""
        self.status.refresh()
        self.recording.refresh()
        if self.filters.paused and not force:
            return
        if self._tab() != "live" and not force:
            return
        self.decoding.refresh()
        self.frames.refresh()
        self.overwrite.refresh()

    def _filters_changed(self) -> None:
        if self.filters.paused:
            self.frames.take_snapshot()
        else:
            self.refresh(force=True)
        if self.file.loaded is not None:
            background_tasks.create(self.file.refilter(), name="monitor filter file")

    def _pause_changed(self) -> None:
        if self.filters.paused:
            self.frames.take_snapshot()
        else:
            self.frames.resume()
            self.refresh(force=True)
