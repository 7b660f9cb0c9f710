"""Bus monitor of a CAN bus.

Live frame list and overwrite view (one row per ID) from the bus's bounded buffers in the store,
decoded by the device codecs, with ID-range/device filters, pause, error frames and bus state;
recording to candump/ASC/BLF/CSV files and browsing recorded files. A Device column names the
plant device that sent or answered each frame.

The page is small cards with ``build()``/``refresh()`` (bus status, filters, recording, the
overwrite view, the frame list, the recorded file) composed by :class:`CanMonitor`. The tables
are refreshed by one timer a few times a second, never once per frame, and show at most
``SHOWN`` frames and ``SHOWN_IDS`` IDs.
"""

from __future__ import annotations

import asyncio
import heapq
import re
import tempfile
import time
from collections.abc import Awaitable, Callable
from datetime import datetime
from pathlib import Path

from nicegui import background_tasks, events, run, ui

from app import can_bus as cb
from app import recording as rec
from app import runtime as rt
from app.can_bus import MONITOR_FRAMES, CanBusState, FrameRecord
from app.worker import AuditUnavailable, PermissionDenied
from pages.frame import fmt_age, frame, notify_error
from pages.monitor_common import CSS, SHOWN, tool_links
from pages.session import current_user
from pages.widgets import upload_button
from pages.command_client import enable_unless, viewer_reason

SCROLL_HEIGHT = "max-height: 56vh; overflow-y: auto"  # each table scrolls inside its box: the page height stays bounded
SHOWN_IDS = 300  # rows of the overwrite view
REFRESH_S = 0.3
MAX_UPLOAD_BYTES = 200 * 1024 * 1024

FRAME_COLUMNS = [
    {"name": "time", "label": "Time", "field": "time", "align": "left", "classes": "mono"},
    {"name": "dir", "label": "Dir", "field": "dir", "align": "center"},
    {"name": "id", "label": "ID", "field": "id", "align": "left", "classes": "mono"},
    {"name": "device", "label": "Device", "field": "device", "align": "left"},
    {"name": "dt", "label": "Δt ms", "field": "dt", "align": "right", "classes": "mono nowrap"},
    {"name": "dlc", "label": "DLC", "field": "dlc", "align": "right"},
    {"name": "data", "label": "Data", "field": "data", "align": "left", "classes": "mono bytes"},
    {"name": "decoded", "label": "Decoded", "field": "decoded", "align": "left"},
]
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
DECODED_SLOT = (
    '<q-td :props="props" class="decoded" :class="props.row.err ? \'text-negative text-weight-bold\' : '
    "(props.value === 'unknown' ? 'text-grey-6' : '')\">{{ props.value }}</q-td>"
)
BYTES_SLOT = (
    '<q-td :props="props" class="mono bytes">'
    '<span v-for="(b, i) in props.row.bytes" :key="i" :class="b[1] ? \'byte byte-changed\' : \'byte\'">{{ b[0] }}</span>'
    "</q-td>"
)
STATE_COLOR = {"error-active": "positive", "error-passive": "warning", "bus-off": "negative"}
ROW_CLASS_FN = ":table-row-class-fn"  # Quasar: a JS function (row) -> class


def _frame_table(mark: str, time_label: str = "Time") -> ui.table:
    columns = [dict(c) for c in FRAME_COLUMNS]
    columns[0]["label"] = time_label
    table = ui.table(columns=columns, rows=[], row_key="k", pagination=0).classes("w-full can-table")
    table.props("dense flat bordered hide-bottom")
    table.props(f'{ROW_CLASS_FN}="row => row.err ? \'row-error\' : \'\'"')
    table.add_slot("body-cell-decoded", DECODED_SLOT)
    table.mark(mark)
    table.props(f"data-monitor={mark}")
    return table


def _frame_rows(frames: list[FrameRecord], decoder: rec.FrameDecoder, relative_to: float | None = None, first_key: int = 0) -> list[dict]:
    rows = []
    for i, f in enumerate(frames):
        rows.append({
            "k": first_key + i,
            "time": rec.format_time(f.time, relative_to),
            "dir": f.direction,
            "id": "error frame" if f.is_error_frame else rec.format_id(f.arbitration_id, f.is_extended_id),
            "device": decoder.record_device(f),
            "dt": _ms(f.dt),
            "dlc": f.dlc,
            "data": "remote" if f.is_remote_frame else rec.format_data(f.data),
            "decoded": decoder.record(f),
            "err": f.is_error_frame,
        })
    return rows


def _ms(seconds: float | None) -> str:
    return "-" if seconds is None else f"{seconds * 1000:.1f}"


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


_FIELD_SPLIT = re.compile(r";\s+|,\s+(?![^\[]*\])")


def decoded_fields(text: str) -> tuple[str, list[str]]:
    """The message name and its fields from a decoded text (``name: field, field; field``)."""
    head, sep, rest = text.partition(": ")
    if not sep:
        return text, []
    return head, [part for part in _FIELD_SPLIT.split(rest) if part]


def show_frame_details(f: FrameRecord, decoder: rec.FrameDecoder, relative_to: float | None) -> None:
    """A dialog with one frame's full decoding: its device, message, fields and bytes."""
    text = decoder.record(f)
    name, fields = decoded_fields(text)
    with ui.dialog() as dialog, ui.card().classes("q-pa-md").style("min-width: 520px; max-width: 90vw") as card:
        card.props("data-monitor=frame-details")
        ui.label(f"{'error frame' if f.is_error_frame else rec.format_id(f.arbitration_id, f.is_extended_id)} · "
                 f"{f.direction} · {rec.format_time(f.time, relative_to)}").classes("text-h6 mono")
        facts = [
            ("Device", decoder.record_device(f) or "not a device of this bus"),
            ("Message", name),
            ("DLC", str(f.dlc)),
            ("Data", "remote frame" if f.is_remote_frame else (rec.format_data(f.data) or "(none)")),
            ("Δt to the previous frame of this ID", "first heard" if f.dt is None else f"{f.dt * 1000:.1f} ms"),
        ]
        with ui.grid(columns="auto 1fr").classes("gap-x-4 gap-y-1"):
            for label, value in facts:
                ui.label(label).classes("text-grey-8")
                ui.label(value).classes("mono" if label == "Data" else "")
        if fields:
            ui.label("Fields").classes("text-subtitle2 q-mt-sm")
            with ui.column().classes("gap-0").props("data-monitor=frame-fields"):
                for item in fields:
                    ui.label(item).classes("text-body2")
        if f.data and not f.is_remote_frame:
            ui.label("Bytes").classes("text-subtitle2 q-mt-sm")
            ui.table(columns=[{"name": c, "label": c.capitalize(), "field": c, "align": "left"} for c in ("byte", "hex", "dec", "bin")],
                     rows=[{"byte": i, "hex": f"{b:02X}", "dec": b, "bin": f"{b:08b}"} for i, b in enumerate(f.data)],
                     row_key="byte").props("dense flat bordered hide-bottom").classes("mono")
        ui.button("Close", on_click=dialog.close).props("flat")
    dialog.on("hide", dialog.delete)
    dialog.open()


def _clicked_key(event) -> int | None:
    """The row key of a table's ``rowClick`` event (its second argument is the row)."""
    row = event.args[1] if len(event.args) > 1 else {}
    key = row.get("k") if isinstance(row, dict) else None
    return key if isinstance(key, int) else None


class BusDecoding:
    """How the frames of one CAN bus are named: the device codecs of the types on the bus (in the plant
    and discovered), the IDs of its devices and which device owns a frame (through app.recording)."""

    def __init__(self, bus: str):
        runtime = rt.current()
        self.bus = bus
        self.worker = runtime.worker
        self.plant = runtime.plant
        self.decoder = rec.FrameDecoder(self.worker.known_ids(bus), self.describers(), self.owners())

    def types(self) -> list[str]:
        """Device types in the plant on this bus and discovered on it: their codecs decode first."""
        types = [d.type for d in self.plant.devices_on(self.bus)]
        types += [entry.get("type", "") for entry in self.worker.discovered.get(self.bus, {}).values()]
        return types

    def describers(self):
        return rec.describers(self.worker, self.bus, self.types())

    def owners(self):
        return rec.device_owners(self.worker, self.bus)

    def owner(self, device: str):
        """The frame test of ``device``: the same ownership as the Device column (adapter, else the type's CAN IDs)."""
        return dict(self.owners()).get(device) or rec.owner_of(None)

    def refresh(self) -> None:
        """Devices adopted or discovered since: the live decoder names them too."""
        self.decoder.set_known_ids(self.worker.known_ids(self.bus))
        self.decoder.set_codecs(self.describers())
        self.decoder.set_owners(self.owners())

    def for_file(self, known: set) -> rec.FrameDecoder:
        """A decoder for a recorded file, which also knows the device IDs found in it (``known``)."""
        return rec.FrameDecoder(self.worker.known_ids(self.bus) | known, self.describers(), self.owners())


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


class FilterCard:
    """ID range, device, error frames only, and pause: the filters of the live lists and of an opened file.

    :param on_change: called after the filter changed (:attr:`filter`, :attr:`version`)
    :param on_pause: called after pause was switched (:attr:`paused`)
    """

    def __init__(self, devices: list[str], decoding: BusDecoding, on_change: Callable[[], None],
                 on_pause: Callable[[], None]):
        self.devices = devices
        self.decoding = decoding
        self.on_change = on_change
        self.on_pause = on_pause
        self.filter = rec.FrameFilter()
        self.version = 0  # counts the changes: a list built with an older filter is built again

    def build(self) -> None:
        with ui.row().classes("items-end gap-3 w-full"):
            self.id_from = ui.input("ID from (hex)", on_change=self.changed).props("dense outlined clearable").classes("w-36 mono")
            self.id_to = ui.input("ID to (hex)", on_change=self.changed).props("dense outlined clearable").classes("w-36 mono")
            self.id_from.mark("id-from")
            self.id_to.mark("id-to")
            options = {"": "all devices", **{name: name for name in self.devices}}
            self.device = ui.select(options, value="", label="Device", on_change=self.changed).props("dense outlined").classes("w-44")
            self.device.mark("device")
            self.errors_only = ui.switch("Error frames only", on_change=self.changed)
            self.pause = ui.switch("Pause", on_change=self.on_pause).mark("pause")
            self.pause.props("data-monitor=pause")
            self.filter_info = ui.label().classes("text-caption text-grey-8")

    @property
    def paused(self) -> bool:
        return bool(self.pause.value)

    def changed(self) -> None:
        problems = []
        bounds = []
        for field_input in (self.id_from, self.id_to):
            try:
                bounds.append(rec.parse_id(field_input.value))
                field_input.props(remove="error")
            except ValueError:
                bounds.append(None)
                problems.append(f"'{field_input.value}' is not a hex CAN ID")
                field_input.props("error")
        owner = self.decoding.owner(self.device.value) if self.device.value else None
        self.filter = rec.FrameFilter(bounds[0], bounds[1], owner, bool(self.errors_only.value))
        self.version += 1
        self.filter_info.set_text("; ".join(problems))
        self.filter_info.classes(replace="text-caption " + ("text-negative" if problems else "text-grey-8"))
        self.on_change()


class RecordingCard:
    """Recording the bus to a file (an engineer action), the last recording, and the folder of recordings.

    :param open_file: opens a recorded file in the monitor's file tab
    """

    def __init__(self, bus: str, state: CanBusState, options: dict, open_file: Callable[[Path], Awaitable[None]]):
        self.bus = bus
        self.state = state
        self.options = options
        self.open_file = open_file
        self.last: rec.Recording | None = None

    def build(self) -> None:
        with ui.card().classes("w-full q-pa-sm"):
            with ui.row().classes("items-center gap-3 w-full"):
                ui.icon("fiber_manual_record", color="negative")
                ui.label("Recording").classes("text-subtitle2")
                self.format = ui.select({s: label for s, (_, label) in rec.WRITERS.items()}, value=".log", label="Format").props("dense outlined").classes("w-40")
                self.format.mark("format")
                self.record_button = ui.button("Record", icon="fiber_manual_record", color="negative", on_click=self.start)
                self.record_button.mark("record")
                self.read_only = viewer_reason()  # recording writes files on disk: an engineer's action
                self.stop_button = ui.button("Stop", icon="stop", on_click=self.stop).mark("stop")
                self.status = ui.label().classes("text-body2").mark("record-status")
                self.status.props("data-monitor=record-status")
                self.download_button = ui.button("Download", icon="download", on_click=self.download_last).props("flat").mark("download")
            with ui.expansion("Recordings", icon="folder", on_value_change=lambda e: e.value and self.refresh_list()).classes("w-full").props("dense") as self.panel:
                self.files_box = ui.column().classes("w-full gap-0")

    def refresh(self) -> None:
        active = rec.active_recording(self.state)
        if active is not None:
            self.status.set_text(f"recording {active.path.name}: {active.elapsed:.1f} s, {active.frames} frames, {_size(active.size)}")
            self.last = active
        elif self.last is not None:
            last = self.last
            if last.active:  # detached by the bus after a write error
                last.close()
            problem = f" - {last.error}" if last.error else ""
            self.status.set_text(f"{last.path.name}: {last.elapsed:.1f} s, {last.frames} frames, {_size(last.size)}{problem}")
        else:
            self.status.set_text("not recording")
        enable_unless(self.record_button, self.read_only or ("recording: stop it first" if active is not None else ""))
        self.format.set_enabled(active is None and not self.read_only)
        self.stop_button.set_enabled(active is not None)
        self.download_button.set_visibility(active is None and self.last is not None)

    async def start(self) -> None:
        """An engineer action (it writes files on disk): checked and audited in the worker; the file
        is created in a thread."""
        user, role = current_user()
        suffix = self.format.value or ".log"

        async def start():
            return await asyncio.to_thread(rec.start_recording, self.state, suffix, None, self.options)

        try:
            self.last = await rt.current().worker.gate.run(
                start, user=user, role=role, describe=f"start recording {self.bus} ({suffix})", device=self.bus, kind="write")
        except (rec.RecordingError, PermissionDenied, AuditUnavailable) as exc:
            notify_error(str(exc))
            return
        ui.notify(f"Recording {self.bus} to {self.last.path}", type="info")
        self.refresh()

    async def stop(self) -> None:
        user, role = current_user()

        async def stop():
            return await asyncio.to_thread(rec.stop_recording, self.state)  # writes what is queued, then closes

        # stopping only ends a file: allowed for everyone, audited
        stopped = await rt.current().worker.gate.run(stop, device=self.bus, role=role, user=user,
                                                     describe=f"stop recording {self.bus}", kind="stop")
        if stopped is None:
            ui.notify("Nothing was being recorded.", type="warning")
            return
        self.last = stopped
        if stopped.error:
            notify_error(f"Recording {stopped.path.name}: {stopped.error}")
        else:
            ui.notify(f"Saved {stopped.frames} frames to {stopped.path.name}", type="positive")
        self.refresh()
        await self.refresh_list()

    async def download_last(self) -> None:
        if self.last is not None:
            await self.download(self.last.path)

    async def download(self, path: Path) -> None:
        if not path.is_file():
            notify_error(f"{path.name} is gone from {path.parent}")
            await self.refresh_list()
            return
        ui.download.file(path, path.name)

    async def refresh_list(self) -> None:
        files = await asyncio.to_thread(rec.list_recordings)  # a folder listing: not on the event loop
        self.panel.set_text(f"Recordings ({len(files)}) in {rec.recordings_dir()}")
        self.files_box.clear()
        with self.files_box:
            if not files:
                ui.label("No recordings yet.").classes("text-caption text-grey-8")
            for f in files[:50]:
                with ui.row().classes("items-center gap-2"):
                    ui.label(f.name).classes("mono text-body2")
                    ui.label(f"{_size(f.size)} · {datetime.fromtimestamp(f.mtime):%Y-%m-%d %H:%M:%S}").classes("text-caption text-grey-8")
                    ui.button(icon="download", on_click=lambda p=f.path: self.download(p)).props("flat dense round").tooltip(f"Download {f.name}")
                    ui.button(icon="table_view", on_click=lambda p=f.path: self.open_file(p)).props("flat dense round").tooltip(f"Open {f.name} here")


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
            self.table = _frame_table("frames")
        self.table.on("rowClick", self._clicked)

    def _clicked(self, event) -> None:
        f = self.shown.get(_clicked_key(event))
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
        rows = _frame_rows(shown, self.decoder)
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
        self.table.rows = _frame_rows(shown, self.decoder, first_key=first)
        self.table.update()


class FileView:
    """A recorded file opened in the monitor (uploaded, or from the recordings folder), filtered and paged.

    :param show: brings the file tab to the front
    """

    def __init__(self, state: CanBusState, filters: FilterCard, decoding: BusDecoding, show: Callable[[], None]):
        self.state = state
        self.filters = filters
        self.decoding = decoding
        self.show = show
        self.loaded: rec.LoadedLog | None = None
        self.decoder = rec.FrameDecoder()
        self.matches: list[FrameRecord] = []
        self.shown: dict[int, FrameRecord] = {}
        self._loading = False

    def build(self) -> None:
        with ui.row().classes("items-center gap-4 w-full"):
            self.upload = ui.upload(
                label="Open a recorded file (" + " ".join(rec.READ_SUFFIXES) + ")",
                auto_upload=True,
                max_file_size=MAX_UPLOAD_BYTES,
                on_upload=self.on_upload,
                on_rejected=lambda: notify_error(f"The file was refused: files up to {MAX_UPLOAD_BYTES // 2**20} MB can be opened."),
            ).props("accept=" + ",".join(rec.READ_SUFFIXES) + " flat bordered").classes("w-96").style("max-height: 100px")
            self.upload.add_slot("header", upload_button(
                "Open a recorded file (" + " ".join(rec.READ_SUFFIXES) + ")", "monitor-upload"))
            self.upload.mark("upload")
            self.upload.props("data-monitor=upload")
            with ui.column().classes("gap-1"):
                self.file_info = ui.label("No file opened.").classes("text-body2").mark("file-info")
                self.file_info.props("data-monitor=file-info")
                self.progress = ui.linear_progress(0, show_value=False).classes("w-96").props("data-monitor=file-progress")
                self.progress.set_visibility(False)
                self.pages = ui.pagination(1, 1, direction_links=True, on_change=self.show_page).props("dense max-pages=9 boundary-numbers")
                self.pages.mark("file-pages")
                self.pages.props("data-monitor=file-pages")
        with ui.element("div").classes("w-full monitor-scroll").style(SCROLL_HEIGHT):
            self.table = _frame_table("file-frames", time_label="Time s")
        self.table.on("rowClick", self._clicked)

    def _clicked(self, event) -> None:
        f = self.shown.get(_clicked_key(event))
        if f is not None:
            show_frame_details(f, self.decoder, None if self.loaded is None else self.loaded.frames[0].time)

    async def on_upload(self, e: events.UploadEventArguments) -> None:
        name = Path(e.file.name).name
        suffix = Path(name).suffix.lower()  # only a hint: the format is taken from the content
        try:
            with tempfile.TemporaryDirectory(prefix="commission-") as tmp:
                # the file's own suffix (letters and digits only) so a message can name it; the content decides
                path = Path(tmp) / f"upload{suffix if suffix[1:].isalnum() else ''}"
                await e.file.save(path)
                loaded = await self._load(path, name)
        finally:
            self.upload.reset()
        if loaded is not None:
            await self._show_loaded(loaded)

    async def open_recording(self, path: Path) -> None:
        if rec.active_recording(self.state) is not None and rec.active_recording(self.state).path == path:
            notify_error(f"{path.name} is still being recorded; stop the recording first.")
            return
        loaded = await self._load(path, path.name)
        if loaded is not None:
            await self._show_loaded(loaded)

    async def _load(self, path: Path, name: str) -> rec.LoadedLog | None:
        """Read a file in a thread with its progress on the page; a file that cannot be read is named
        with where and why (on the page and in a message)."""
        if self._loading:
            notify_error("A file is being opened already; wait until it is loaded.")
            return None
        self._loading = True
        self.show()
        self.progress.set_value(0)
        self.progress.set_visibility(True)
        self.file_info.set_text(f"opening {name} ...")

        def report(frames: int, fraction: float) -> None:
            self.progress.set_value(fraction)
            self.file_info.set_text(f"opening {name}: {frames:,} frames read ({fraction * 100:.0f} %)")

        try:
            loaded = await rec.load_log(path, name, progress=report)
            await run.io_bound(_set_deltas, loaded.frames)  # O(n) once, off the event loop
            return loaded
        except rec.RecordingError as exc:
            self.file_info.set_text(f"cannot open: {exc}")
            notify_error(str(exc))
        except Exception as exc:  # noqa: BLE001 - a failing save/temp dir: still a message, never a crash
            self.file_info.set_text(f"{name}: cannot open: {exc}")
            notify_error(f"{name}: cannot open: {exc}")
        finally:
            self._loading = False
            self.progress.set_visibility(False)
        return None

    async def _show_loaded(self, loaded: rec.LoadedLog) -> None:
        self.loaded = loaded
        known = await run.io_bound(rec.ids_of_devices, loaded.frames)
        self.decoder = self.decoding.for_file(known)
        self.show()
        await self.refilter()
        ui.notify(f"Opened {loaded.name}: {len(loaded.frames)} frames", type="positive")

    async def refilter(self) -> None:
        """The opened file's frames that match the filters, from the first page."""
        loaded = self.loaded
        if loaded is None:
            return
        flt = self.filters.filter
        if flt.active:  # up to MAX_FILE_FRAMES frames: filtered in a thread, not on the event loop
            self.matches = await run.io_bound(lambda: [f for f in loaded.frames if flt.matches_record(f)])
        else:
            self.matches = loaded.frames
        self.pages.max = max(1, -(-len(self.matches) // SHOWN))
        self.pages.value = 1
        self.pages.update()
        first = loaded.frames[0].time
        start = f", starts {datetime.fromtimestamp(first):%Y-%m-%d %H:%M:%S}" if first > 1e8 else ""
        fmt = f" ({loaded.format} file)" if getattr(loaded, "format", "") else ""
        self.file_info.set_text(
            f"{loaded.name}{fmt}: {len(loaded.frames)} frames{' (file truncated)' if loaded.truncated else ''}, "
            f"{loaded.duration:.1f} s{start}, {loaded.error_frames} error frames; "
            f"{len(self.matches)} match the filters; {SHOWN} per page"
        )
        self.show_page()

    def show_page(self) -> None:
        if self.loaded is None:
            return
        page = max(1, int(self.pages.value or 1))
        first = (page - 1) * SHOWN
        shown = self.matches[first:first + SHOWN]
        self.shown = {first + i: f for i, f in enumerate(shown)}
        self.table.rows = _frame_rows(shown, self.decoder, relative_to=self.loaded.frames[0].time, first_key=first)
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


def _set_deltas(frames: list[FrameRecord]) -> None:
    """Each frame's time since the previous frame of its ID (a recorded file's Δt column)."""
    last: dict[tuple[bool, int], float] = {}
    for f in frames:
        key = (f.is_extended_id, f.arbitration_id)
        previous = last.get(key)
        f.dt = None if previous is None else f.time - previous
        last[key] = f.time


def _size(n: int) -> str:
    if n < 1024:
        return f"{n} B"
    if n < 1024**2:
        return f"{n / 1024:.1f} KiB"
    return f"{n / 1024**2:.1f} MiB"
