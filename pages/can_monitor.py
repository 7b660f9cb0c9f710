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
from app import recording as rec
from app import runtime as rt
from app.can_bus import MONITOR_FRAMES, CanBusState, FrameRecord
from pages.can_files import FileView, RecordingCard
from pages.can_trace import BusDecoding, FilterCard, DECODED_SLOT, SCROLL_HEIGHT, clicked_key, frame_rows, frame_table, show_frame_details
from pages.frame import fmt_age, frame, notify_error
from pages.monitor_common import CSS, SHOWN, tool_links

SHOWN_IDS = 300  # rows of the overwrite view
REFRESH_S = 0.3
ID_COLUMNS = [
    {"name": "id", "label": "ID", "field": "id", "align": "left", "classes": "mono"},
    {"name": "dir", "label": "Dir", "field": "dir", "align": "center"},
    {"name": "device", "label": "Device", "field": "device", "align": "left"},
    {"name": "count", "label": "Count", "field": "count", "align": "right"},
    {"name": "cycle", "label": "Cycle ms", "field": "cycle", "align": "right", "classes": "cycle"},
    {"name": "data", "label": "Data (changed bytes marked)", "field": "data", "align": "left"},
    {"name": "decoded", "label": "Decoded", "field": "decoded", "align": "left"},
    {"name": "age", "label": "Last", "field": "age", "align": "right", "classes": "nowrap", "headerClasses": "nowrap"},
]
BYTES_SLOT = (
    '<q-td :props="props" class="mono bytes">'
    '<span v-for="(b, i) in props.row.bytes" :key="i" :class="b[1] ? \'byte byte-changed\' : \'byte\'">{{ b[0] }}</span>'
    "</q-td>"
)
STATE_COLOR = {"error-active": "positive", "error-passive": "warning", "bus-off": "negative"}


def cycle_text(cycles: list[tuple[int, int, float, float]]) -> str:
    """The cycle time of an ID: ``1000``; bursts as ``2000 (bursts of 12)``; several frame lengths
    on one ID each with its length, most frequent first: ``1000 (8 B) · 2000 (6 B, bursts of 12)``."""
    if not cycles:
        return "-"
    parts = []
    for length, _count, cycle, burst in cycles[:3]:
        notes = [] if len(cycles) == 1 else [f"{length} B" if length >= 0 else "other lengths"]
        if burst >= 1.5:
            notes.append(f"bursts of {burst:.0f}")
        parts.append(f"{cycle * 1000:.0f}" + (f" ({', '.join(notes)})" if notes else ""))
    return " · ".join(parts)


class BusStatusCard:
    """The bus state, connection, load and counters, the bus tools and the DBC download."""

    def __init__(self, bus: str, state: CanBusState, options: dict):
        self.bus = bus
        self.state = state
        self.options = options

    def build(self) -> None:
        with ui.row().classes("items-center gap-3 w-full"):
            ui.label(f"CAN · {self.state.endpoint} · {self.options.get('bitrate', '?')} bit/s").classes("text-caption text-grey-8")
            self.state_badge = ui.badge("unknown").mark("bus-state")
            self.connected_badge = ui.badge("").mark("connected")
            self.load = ui.label().classes("text-body2 mono").mark("load")
            self.load.props("data-monitor=load")
            self.counts = ui.label().classes("text-body2 mono").mark("counters")
            self.counts.props("data-monitor=counters")
            self.error_label = ui.label().classes("text-body2 text-negative")
            tool_links(self.bus, [("Transmit", "transmit", "send"), ("Replay", "replay", "replay")])
            ui.button("DBC", icon="download", on_click=self.download_dbc).props(
                "flat dense no-caps data-monitor=dbc").tooltip(
                "A DBC of this bus's devices (cantools), so other tools decode recordings with names")

    def download_dbc(self) -> None:
        from app import dbc

        try:
            text = dbc.dbc_text(rt.current().plant, self.bus)  # the running plant: adopted devices included
        except dbc.DbcError as exc:
            notify_error(f"No DBC for {self.bus}: {exc}")
            return
        ui.download.content(text.encode(), f"{self.bus}.dbc", "application/octet-stream")

    def refresh(self) -> None:
        s = self.state
        bus_state = s.bus_state if s.connected else "not connected"
        self.state_badge.set_text(bus_state)
        self.state_badge.props(f"color={STATE_COLOR.get(bus_state, 'grey')}")
        self.connected_badge.set_text("connected" if s.connected else "disconnected")
        self.connected_badge.props(f"color={'positive' if s.connected else 'negative'} outline")
        self.counts.set_text(
            f"rx {s.rx_frames} · tx {s.tx_frames} · error frames {s.error_frames} · "
            f"tx errors {s.tx_errors} · dropped {s.dropped} (shed under load {s.shed}) · "
            + (f"interface drops {s.interface_dropped} ({s.drop_source})" if s.interface_dropped is not None
               else f"interface drops: not reported by {self.options.get('interface', '?')}")
            + f" · buffered {len(s.frames)}/{MONITOR_FRAMES}"
        )
        self.load.set_text(f"{self._load_text()} · {s.frames_per_s:.0f} frames/s")
        self.error_label.set_text(s.last_error)

    def _load_text(self) -> str:
        s = self.state
        if s.load_pct is None:
            return "load: bit rate unknown"
        # the average is the steady figure (frames reach the program in batches); the peak is the worst second
        average = s.load_avg_pct if s.load_avg_pct is not None else s.load_pct
        peak = s.load_peak_pct if s.load_peak_pct is not None else s.load_pct
        return (f"load {average:.1f} % of {self.options.get('bitrate') / 1000:g} kbit/s ({cb.LOAD_AVERAGE_S:g} s average), "
                f"peak {peak:.1f} % (highest second of the last {cb.LOAD_PEAK_S:g} s)")


class OverwriteCard:
    """The overwrite view: one row per ID (count, cycle, data with the changed bytes marked, decoded)."""

    def __init__(self, state: CanBusState, filters: FilterCard, decoder: rec.FrameDecoder):
        self.state = state
        self.filters = filters
        self.decoder = decoder

    def build(self) -> None:
        with ui.row().classes("items-center gap-2"):
            ui.label("Overwrite view: one row per ID").classes("text-subtitle2")
            self.ids_info = ui.label().classes("text-caption text-grey-8")
        with ui.element("div").classes("w-full monitor-scroll").style("max-height: 34vh; overflow-y: auto").props("data-monitor=overwrite-box"):
            self.table = ui.table(columns=ID_COLUMNS, rows=[], row_key="k", pagination=0).classes("w-full can-table")
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
        shown = f"first {len(rows)} of " if len(rows) < matching else ""
        self.ids_info.set_text(f"{shown}{matching} ID{'' if matching == 1 else 's'}" + (f" (of {total})" if flt.active else ""))
        if rows != self.table.rows:
            self.table.rows = rows
            self.table.update()

    def _row(self, ext: bool, can_id: int, stats, now: float) -> dict:
        return {
            "k": f"{int(ext)}:{can_id}",
            "id": rec.format_id(can_id, ext),
            "dir": stats.direction,
            "device": self.decoder.device(can_id, ext, stats.data),
            "count": stats.count,
            "cycle": cycle_text(stats.cycles()),
            "data": rec.format_data(stats.data),
            "bytes": rec.changed_bytes(stats.data, stats.changed),
            "decoded": self.decoder(can_id, ext, stats.data),
            "age": fmt_age(now - stats.last_time),
            "err": False,
        }


class FramesCard:
    """The newest frames of the bus; while paused, the whole buffer as it was, in pages."""

    def __init__(self, state: CanBusState, filters: FilterCard, decoder: rec.FrameDecoder):
        self.state = state
        self.filters = filters
        self.decoder = decoder
        self.snapshot: list[FrameRecord] = []  # the whole buffer (matching the filters), newest first, while paused
        self.shown: dict[int, FrameRecord] = {}  # row key -> frame of the rows on screen
        self._signature: tuple | None = None

    def build(self) -> None:
        with ui.row().classes("items-center gap-2"):
            ui.label("Frames, newest first").classes("text-subtitle2")
            self.frames_info = ui.label().classes("text-caption text-grey-8")
            self.frames_info.props("data-monitor=frames-info")
            self.pages = ui.pagination(1, 1, direction_links=True, on_change=self.show_paused_page).props(
                "dense max-pages=7 boundary-numbers data-monitor=live-pages")
            self.pages.set_visibility(False)
            ui.label("click a frame for its full decoding").classes("text-caption text-grey-6")
        with ui.element("div").classes("w-full monitor-scroll").style(SCROLL_HEIGHT):
            self.table = frame_table("frames")
        self.table.on("rowClick", self._clicked)

    def _clicked(self, event) -> None:
        f = self.shown.get(clicked_key(event))
        if f is not None:
            show_frame_details(f, self.decoder, None)

    def refresh(self) -> None:
        s = self.state
        signature = (s.rx_frames, s.tx_frames, len(s.frames), self.filters.version, len(self.decoder.known_ids))
        if signature == self._signature:
            return
        self._signature = signature
        flt = self.filters.filter
        shown = rec.newest(s.frames, flt, SHOWN)
        self.shown = dict(enumerate(shown))
        rows = frame_rows(shown, self.decoder)
        what = "matching " if flt.active else ""
        self.frames_info.set_text(f"newest {len(rows)} {what}of {len(s.frames)} buffered frames")
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
        what = "matching " if self.filters.filter.active else ""
        self.frames_info.set_text(f"paused: frames {first + 1 if shown else 0}-{first + len(shown)} of {len(self.snapshot)} {what}buffered, "
                           f"page {page} of {self.pages.max}")
        self.table.rows = frame_rows(shown, self.decoder, first_key=first)
        self.table.update()


class CanMonitor:
    """One browser's view of one CAN bus: status, filters, recording, and the live and recorded-file tabs.

    The cards read the bus's record in the store (frames, counters, ID statistics, the recording) and
    name frames through one :class:`BusDecoding`; one timer refreshes them a few times a second.
    """

    def __init__(self, bus: str):
        runtime = rt.current()
        self.bus = bus
        self.state: CanBusState = runtime.store.buses[bus]
        options = runtime.plant.buses[bus].options
        self.decoding = BusDecoding(bus)
        devices = [d.name for d in runtime.plant.devices_on(bus)]
        self.status = BusStatusCard(bus, self.state, options)
        self.filters = FilterCard(devices, self.decoding, on_change=self._filters_changed, on_pause=self._pause_changed)
        self.file = FileView(self.state, self.filters, self.decoding, show=lambda: self.tabs.set_value("file"))
        self.recording = RecordingCard(bus, self.state, options, open_file=self.file.open_recording)
        self.overwrite = OverwriteCard(self.state, self.filters, self.decoding.decoder)
        self.frames = FramesCard(self.state, self.filters, self.decoding.decoder)
        with frame(f"Bus monitor {bus}"):
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
            live_tab = ui.tab("live", "Live")
            file_tab = ui.tab("file", "Recorded file")
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
