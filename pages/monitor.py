"""Bus monitor.

CAN buses: live frame list and overwrite view (one row per ID) from the bus's bounded
buffers, decoded by the device codecs, with ID-range/device filters, pause, error frames
and bus state; recording to candump/ASC/BLF/CSV files and browsing recorded files.
Modbus/serial lines: the transaction log of the worker (bounded ring buffer).
Decoded columns name parameters and show decoded values (signed, scaled, enum names, units)
through the device codecs and parameter models; a Device column names the plant device
that sent or answered each frame or transaction.

The tables are refreshed by one timer a few times a second, never once per frame, and
show at most ``SHOWN`` frames and ``SHOWN_IDS`` IDs.
"""

from __future__ import annotations

import asyncio
import heapq
import tempfile
import time
from datetime import datetime
from pathlib import Path

from nicegui import events, run, ui

from app import recording as rec
from app import runtime as rt
from app.can_bus import MONITOR_FRAMES, CanBusState, FrameRecord
from app.worker import AuditUnavailable, PermissionDenied
from pages.frame import fmt_age, frame, notify_error
from pages.session import current_user

# -- Modbus / serial lines: transaction log ----------------------------------------------------------

COLUMNS = [
    {"name": "time", "label": "Time", "field": "time", "align": "left"},
    {"name": "device", "label": "Device", "field": "device", "align": "left"},
    {"name": "request", "label": "Request", "field": "request", "align": "left"},
    {"name": "tx", "label": "Request hex", "field": "tx", "align": "left", "classes": "mono hex"},
    {"name": "rx", "label": "Response hex", "field": "rx", "align": "left", "classes": "mono hex"},
    {"name": "decoded", "label": "Decoded", "field": "decoded", "align": "left", "classes": "decoded"},
    {"name": "rtt", "label": "RTT ms", "field": "rtt", "align": "right"},
    {"name": "error", "label": "Error", "field": "error", "align": "left", "classes": "text-negative"},
]
SHOWN = 200  # rows of a frame/transaction list
SHOWN_IDS = 300  # rows of the overwrite view
REFRESH_S = 0.3
MAX_UPLOAD_BYTES = 200 * 1024 * 1024

CSS = """
.can-table .q-table td, .can-table .q-table th { padding: 1px 8px; height: 24px; font-size: 13px; }
.can-table .q-table td.mono, .can-table .q-table td .mono { white-space: pre; }
.byte { margin-right: 0.45em; }
.byte-changed { color: #e65100; font-weight: 700; background: #fff3e0; border-radius: 2px; }
.row-error td { background: #fde8ea; }
.can-table .q-table td.decoded, .reg-table .q-table td.decoded { white-space: normal; min-width: 320px; }
.reg-table .q-table td.hex { white-space: normal; min-width: 140px; max-width: 230px; }
"""


def content(bus: str) -> None:
    runtime = rt.current()
    if bus in runtime.worker.can_buses:
        CanMonitor(bus)
    else:
        modbus_content(bus)


def modbus_content(bus: str) -> None:
    runtime = rt.current()
    bus_state = runtime.store.buses[bus]
    with frame(f"Bus monitor {bus}"):
        ui.add_css(CSS)
        ui.label(f"{bus_state.type} · {bus_state.endpoint}").classes("text-caption text-grey-8")
        with ui.row().classes("items-center"):
            paused = ui.switch("Pause")
            errors_only = ui.switch("Errors only")
            summary = ui.label().classes("text-body2")
        table = ui.table(columns=COLUMNS, rows=[], row_key="id", pagination=0).classes("w-full reg-table")
        table.props("dense flat bordered")
        table.mark("transactions")
        decoder = rec.TransactionDecoder(runtime.worker, bus)

        def update() -> None:
            log = list(bus_state.transactions)
            errors = sum(1 for t in log if t.error)
            summary.set_text(f"{len(log)} transactions buffered, {errors} with errors")
            if paused.value:
                return
            decoder.refresh()
            selected = [t for t in log if t.error] if errors_only.value else log
            table.rows = [
                {
                    "id": i,
                    "time": datetime.fromtimestamp(t.time).strftime("%H:%M:%S.%f")[:-3],
                    "unit": t.unit,
                    "device": decoder.device(t.unit),
                    "request": t.request,
                    "tx": t.request_hex,
                    "rx": t.response_hex,
                    "decoded": decoder.decoded(t),
                    "rtt": "-" if t.rtt_ms is None else f"{t.rtt_ms:.1f}",
                    "error": t.error,
                }
                for i, t in enumerate(reversed(selected[-SHOWN:]))
            ]
            table.update()

        update()
        ui.timer(0.5, update)


# -- CAN buses --------------------------------------------------------------------------------------------

FRAME_COLUMNS = [
    {"name": "time", "label": "Time", "field": "time", "align": "left", "classes": "mono"},
    {"name": "dir", "label": "Dir", "field": "dir", "align": "center"},
    {"name": "id", "label": "ID", "field": "id", "align": "left", "classes": "mono"},
    {"name": "device", "label": "Device", "field": "device", "align": "left"},
    {"name": "dlc", "label": "DLC", "field": "dlc", "align": "right"},
    {"name": "data", "label": "Data", "field": "data", "align": "left", "classes": "mono"},
    {"name": "decoded", "label": "Decoded", "field": "decoded", "align": "left"},
]
ID_COLUMNS = [
    {"name": "id", "label": "ID", "field": "id", "align": "left", "classes": "mono"},
    {"name": "dir", "label": "Dir", "field": "dir", "align": "center"},
    {"name": "device", "label": "Device", "field": "device", "align": "left"},
    {"name": "count", "label": "Count", "field": "count", "align": "right"},
    {"name": "period", "label": "Period ms", "field": "period", "align": "right"},
    {"name": "data", "label": "Data (changed bytes marked)", "field": "data", "align": "left"},
    {"name": "decoded", "label": "Decoded", "field": "decoded", "align": "left"},
    {"name": "age", "label": "Last", "field": "age", "align": "right"},
]
DECODED_SLOT = (
    '<q-td :props="props" class="decoded" :class="props.row.err ? \'text-negative text-weight-bold\' : '
    "(props.value === 'unknown' ? 'text-grey-6' : '')\">{{ props.value }}</q-td>"
)
BYTES_SLOT = (
    '<q-td :props="props" class="mono">'
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
            "dlc": f.dlc,
            "data": "remote" if f.is_remote_frame else rec.format_data(f.data),
            "decoded": decoder.record(f),
            "err": f.is_error_frame,
        })
    return rows


class CanMonitor:
    """One browser's view of one CAN bus."""

    def __init__(self, bus: str):
        runtime = rt.current()
        self.bus = bus
        self.worker = runtime.worker
        self.plant = runtime.plant
        self.can_bus = runtime.worker.can_buses[bus]
        self.state: CanBusState = self.can_bus.state
        self.devices = [d.name for d in runtime.plant.devices_on(bus)]
        self.decoder = rec.FrameDecoder(self.worker.known_ids(bus), rec.describers(self.worker, bus, self._types_on_bus()),
                                        rec.device_owners(self.worker, bus))
        self.filter = rec.FrameFilter()
        self.filter_version = 0
        self._frames_signature: tuple | None = None
        self.last_recording: rec.Recording | None = None
        self.loaded: rec.LoadedLog | None = None
        self.file_decoder = rec.FrameDecoder()
        self.file_matches: list[FrameRecord] = []
        with frame(f"Bus monitor {bus}"):
            ui.add_css(CSS)
            self._build()
        self.refresh()
        ui.timer(0, self.refresh_recordings, once=True)
        ui.timer(REFRESH_S, self.refresh)

    # -- layout ---------------------------------------------------------------------------------------
    def _build(self) -> None:
        state = self.state
        with ui.row().classes("items-center gap-3 w-full"):
            ui.label(f"CAN · {state.endpoint} · {self.can_bus.options.get('bitrate', '?')} bit/s").classes("text-caption text-grey-8")
            self.state_badge = ui.badge("unknown").mark("bus-state")
            self.connected_badge = ui.badge("").mark("connected")
            self.counts = ui.label().classes("text-body2 mono").mark("counters")
            self.error_label = ui.label().classes("text-body2 text-negative")

        with ui.row().classes("items-end gap-3 w-full"):
            self.id_from = ui.input("ID from (hex)", on_change=self._filters_changed).props("dense outlined clearable").classes("w-36 mono")
            self.id_to = ui.input("ID to (hex)", on_change=self._filters_changed).props("dense outlined clearable").classes("w-36 mono")
            self.id_from.mark("id-from")
            self.id_to.mark("id-to")
            options = {"": "all devices", **{name: name for name in self.devices}}
            self.device = ui.select(options, value="", label="Device", on_change=self._filters_changed).props("dense outlined").classes("w-44")
            self.device.mark("device")
            self.errors_only = ui.switch("Error frames only", on_change=self._filters_changed)
            self.paused = ui.switch("Pause").mark("pause")
            self.filter_info = ui.label().classes("text-caption text-grey-8")

        with ui.card().classes("w-full q-pa-sm"):
            with ui.row().classes("items-center gap-3 w-full"):
                ui.icon("fiber_manual_record", color="negative")
                ui.label("Recording").classes("text-subtitle2")
                self.format = ui.select({s: label for s, (_, label) in rec.WRITERS.items()}, value=".log", label="Format").props("dense outlined").classes("w-40")
                self.format.mark("format")
                self.record_button = ui.button("Record", icon="fiber_manual_record", color="negative", on_click=self.start_recording)
                self.record_button.mark("record")
                self.stop_button = ui.button("Stop", icon="stop", on_click=self.stop_recording).mark("stop")
                self.record_status = ui.label().classes("text-body2").mark("record-status")
                self.record_status.props("data-monitor=record-status")
                self.download_button = ui.button("Download", icon="download", on_click=self.download_last).props("flat").mark("download")
            with ui.expansion("Recordings", icon="folder", on_value_change=lambda e: e.value and self.refresh_recordings()).classes("w-full").props("dense") as self.recordings_panel:
                self.recordings_box = ui.column().classes("w-full gap-0")

        with ui.tabs(value="live").classes("w-full").props("dense align=left") as self.tabs:
            self.live_tab = ui.tab("live", "Live")
            self.file_tab = ui.tab("file", "Recorded file")
        with ui.tab_panels(self.tabs, value=self.live_tab).classes("w-full").props("keep-alive"):
            with ui.tab_panel(self.live_tab).classes("q-pa-none gap-2"):
                with ui.row().classes("items-center gap-2"):
                    ui.label("Overwrite view: one row per ID").classes("text-subtitle2")
                    self.ids_info = ui.label().classes("text-caption text-grey-8")
                self.id_table = ui.table(columns=ID_COLUMNS, rows=[], row_key="k", pagination=0).classes("w-full can-table")
                self.id_table.props("dense flat bordered")
                self.id_table.add_slot("body-cell-data", BYTES_SLOT)
                self.id_table.add_slot("body-cell-decoded", DECODED_SLOT)
                self.id_table.mark("overwrite")
                self.id_table.props("data-monitor=overwrite hide-bottom")
                with ui.row().classes("items-center gap-2"):
                    ui.label("Frames, newest first").classes("text-subtitle2")
                    self.frames_info = ui.label().classes("text-caption text-grey-8")
                self.frames_table = _frame_table("frames")
            with ui.tab_panel(self.file_tab).classes("q-pa-none gap-2"):
                with ui.row().classes("items-center gap-4 w-full"):
                    self.upload = ui.upload(
                        label="Open a recorded file (" + " ".join(rec.READ_SUFFIXES) + ")",
                        auto_upload=True,
                        max_file_size=MAX_UPLOAD_BYTES,
                        on_upload=self.on_upload,
                        on_rejected=lambda: notify_error(f"The file was refused: files up to {MAX_UPLOAD_BYTES // 2**20} MB can be opened."),
                    ).props("accept=" + ",".join(rec.READ_SUFFIXES) + " flat bordered").classes("w-96").style("max-height: 100px")
                    self.upload.mark("upload")
                    self.upload.props("data-monitor=upload")
                    with ui.column().classes("gap-1"):
                        self.file_info = ui.label("No file opened.").classes("text-body2").mark("file-info")
                        self.file_pages = ui.pagination(1, 1, direction_links=True, on_change=self._show_file_page).props("dense max-pages=9 boundary-numbers")
                        self.file_pages.mark("file-pages")
                        self.file_pages.props("data-monitor=file-pages")
                self.file_table = _frame_table("file-frames", time_label="Time s")

    # -- filters ---------------------------------------------------------------------------------------
    def _filters_changed(self) -> None:
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
        owner = None
        if self.device.value:  # the same ownership as the Device column (adapter, else the type's CAN IDs)
            owner = dict(rec.device_owners(self.worker, self.bus)).get(self.device.value) or rec.owner_of(None)
        self.filter = rec.FrameFilter(bounds[0], bounds[1], owner, bool(self.errors_only.value))
        self.filter_version += 1
        self.filter_info.set_text("; ".join(problems))
        self.filter_info.classes(replace="text-caption " + ("text-negative" if problems else "text-grey-8"))
        self.refresh(force=True)
        self.filter_file()

    # -- live ----------------------------------------------------------------------------------------------
    def refresh(self, force: bool = False) -> None:
        self._refresh_status()
        if self.paused.value and not force:
            return
        if self._tab() != "live" and not force:
            return
        self.decoder.set_known_ids(self.worker.known_ids(self.bus))
        self.decoder.set_codecs(rec.describers(self.worker, self.bus, self._types_on_bus()))
        self.decoder.set_owners(rec.device_owners(self.worker, self.bus))
        self._refresh_frames()
        self._refresh_ids()

    def _types_on_bus(self) -> list[str]:
        """Device types in the plant on this bus and discovered on it: their codecs decode first."""
        types = [d.type for d in self.plant.devices_on(self.bus)]
        types += [entry.get("type", "") for entry in self.worker.discovered.get(self.bus, {}).values()]
        return types

    def _tab(self) -> str:
        value = self.tabs.value
        return value.props["name"] if isinstance(value, ui.tab) else str(value)

    def _refresh_status(self) -> None:
        s = self.state
        bus_state = s.bus_state if s.connected else "not connected"
        self.state_badge.set_text(bus_state)
        self.state_badge.props(f"color={STATE_COLOR.get(bus_state, 'grey')}")
        self.connected_badge.set_text("connected" if s.connected else "disconnected")
        self.connected_badge.props(f"color={'positive' if s.connected else 'negative'} outline")
        self.counts.set_text(
            f"rx {s.rx_frames} · tx {s.tx_frames} · error frames {s.error_frames} · "
            f"tx errors {s.tx_errors} · dropped {s.dropped} (shed under load {s.shed}) · buffered {len(s.frames)}/{MONITOR_FRAMES}"
        )
        self.error_label.set_text(s.last_error)
        active = rec.active_recording(s)
        if active is not None:
            self.record_status.set_text(f"recording {active.path.name}: {active.elapsed:.1f} s, {active.frames} frames, {_size(active.size)}")
            self.last_recording = active
        elif self.last_recording is not None:
            last = self.last_recording
            if last.active:  # detached by the bus after a write error
                last.close()
            problem = f" - {last.error}" if last.error else ""
            self.record_status.set_text(f"{last.path.name}: {last.elapsed:.1f} s, {last.frames} frames, {_size(last.size)}{problem}")
        else:
            self.record_status.set_text("not recording")
        self.record_button.set_enabled(active is None)
        self.format.set_enabled(active is None)
        self.stop_button.set_enabled(active is not None)
        self.download_button.set_visibility(active is None and self.last_recording is not None)

    def _refresh_frames(self) -> None:
        s = self.state
        signature = (s.rx_frames, s.tx_frames, len(s.frames), self.filter_version, len(self.decoder.known_ids))
        if signature == self._frames_signature:
            return
        self._frames_signature = signature
        shown = rec.newest(s.frames, self.filter, SHOWN)
        rows = _frame_rows(shown, self.decoder)
        what = "matching " if self.filter.active else ""
        self.frames_info.set_text(f"newest {len(rows)} {what}of {len(s.frames)} buffered frames")
        if rows != self.frames_table.rows:
            self.frames_table.rows = rows
            self.frames_table.update()

    def _refresh_ids(self) -> None:
        now = time.time()
        flt = self.filter
        items = self.state.ids.items()
        if flt.active:
            items = [(key, stats) for key, stats in items if flt.matches(key[1], key[0], stats.data)]
        rows = []
        for (ext, can_id), stats in heapq.nsmallest(SHOWN_IDS, items, key=lambda item: (item[0][1], item[0][0])):
            rows.append({
                "k": f"{int(ext)}:{can_id}",
                "id": rec.format_id(can_id, ext),
                "dir": stats.direction,
                "device": self.decoder.device(can_id, ext, stats.data),
                "count": stats.count,
                "period": "-" if stats.period is None else f"{stats.period * 1000:.0f}",
                "data": rec.format_data(stats.data),
                "bytes": rec.changed_bytes(stats.data, stats.changed),
                "decoded": self.decoder(can_id, ext, stats.data),
                "age": fmt_age(now - stats.last_time),
                "err": False,
            })
        total = len(self.state.ids)
        matching = len(items) if flt.active else total
        shown = f"first {len(rows)} of " if len(rows) < matching else ""
        self.ids_info.set_text(f"{shown}{matching} ID{'' if matching == 1 else 's'}" + (f" (of {total})" if flt.active else ""))
        if rows != self.id_table.rows:
            self.id_table.rows = rows
            self.id_table.update()

    # -- recording ---------------------------------------------------------------------------------------
    async def start_recording(self) -> None:
        """An engineer action (it writes files on disk): checked and audited in the worker; the file
        is created in a thread."""
        user, role = current_user()
        suffix = self.format.value or ".log"

        async def start():
            return await asyncio.to_thread(rec.start_recording, self.state, suffix, None, self.can_bus.options)

        try:
            self.last_recording = await self.worker.engineer_action(
                start, user=user, role=role, describe=f"start recording {self.bus} ({suffix})", target=self.bus)
        except (rec.RecordingError, PermissionDenied, AuditUnavailable) as exc:
            notify_error(str(exc))
            return
        ui.notify(f"Recording {self.bus} to {self.last_recording.path}", type="info")
        self._refresh_status()

    async def stop_recording(self) -> None:
        user, role = current_user()

        async def stop():
            return await asyncio.to_thread(rec.stop_recording, self.state)  # writes what is queued, then closes

        # stopping only ends a file: allowed for everyone, audited
        stopped = await self.worker.checked(stop, device=self.bus, role=role, user=user, describe=f"stop recording {self.bus}",
                                            write=False)
        if stopped is None:
            ui.notify("Nothing was being recorded.", type="warning")
            return
        self.last_recording = stopped
        if stopped.error:
            notify_error(f"Recording {stopped.path.name}: {stopped.error}")
        else:
            ui.notify(f"Saved {stopped.frames} frames to {stopped.path.name}", type="positive")
        self._refresh_status()
        await self.refresh_recordings()

    async def download_last(self) -> None:
        if self.last_recording is not None:
            await self._download(self.last_recording.path)

    async def _download(self, path: Path) -> None:
        if not path.is_file():
            notify_error(f"{path.name} is gone from {path.parent}")
            await self.refresh_recordings()
            return
        ui.download.file(path, path.name)

    async def refresh_recordings(self) -> None:
        files = await asyncio.to_thread(rec.list_recordings)  # a folder listing: not on the event loop
        self.recordings_panel.set_text(f"Recordings ({len(files)}) in {rec.recordings_dir()}")
        self.recordings_box.clear()
        with self.recordings_box:
            if not files:
                ui.label("No recordings yet.").classes("text-caption text-grey-8")
            for f in files[:50]:
                with ui.row().classes("items-center gap-2"):
                    ui.label(f.name).classes("mono text-body2")
                    ui.label(f"{_size(f.size)} · {datetime.fromtimestamp(f.mtime):%Y-%m-%d %H:%M:%S}").classes("text-caption text-grey-8")
                    ui.button(icon="download", on_click=lambda p=f.path: self._download(p)).props("flat dense round").tooltip(f"Download {f.name}")
                    ui.button(icon="table_view", on_click=lambda p=f.path: self.open_recording(p)).props("flat dense round").tooltip(f"Open {f.name} here")

    # -- recorded files ------------------------------------------------------------------------------
    async def on_upload(self, e: events.UploadEventArguments) -> None:
        name = Path(e.file.name).name
        suffix = Path(name).suffix.lower()
        try:
            if suffix not in rec.READ_SUFFIXES:
                raise rec.RecordingError(f"{name}: unsupported file type {suffix or '(none)'}; readable are {', '.join(rec.READ_SUFFIXES)}")
            with tempfile.TemporaryDirectory(prefix="commission-") as tmp:
                path = Path(tmp) / f"upload{suffix}"
                await e.file.save(path)
                loaded = await run.io_bound(rec.read_log, path, name)
        except rec.RecordingError as exc:
            notify_error(str(exc))
            return
        except Exception as exc:  # noqa: BLE001 - a failing save/temp dir: still a message, never a crash
            notify_error(f"{name}: cannot open: {exc}")
            return
        finally:
            self.upload.reset()
        await self._show_loaded(loaded)

    async def open_recording(self, path: Path) -> None:
        if rec.active_recording(self.state) is not None and rec.active_recording(self.state).path == path:
            notify_error(f"{path.name} is still being recorded; stop the recording first.")
            return
        try:
            loaded = await run.io_bound(rec.read_log, path)
        except rec.RecordingError as exc:
            notify_error(str(exc))
            return
        await self._show_loaded(loaded)

    async def _show_loaded(self, loaded: rec.LoadedLog) -> None:
        self.loaded = loaded
        known = await run.io_bound(rec.ids_of_devices, loaded.frames)
        self.file_decoder = rec.FrameDecoder(self.worker.known_ids(self.bus) | known, rec.describers(self.worker, self.bus, self._types_on_bus()),
                                             rec.device_owners(self.worker, self.bus))
        self.tabs.set_value("file")
        self.filter_file()
        ui.notify(f"Opened {loaded.name}: {len(loaded.frames)} frames", type="positive")

    def filter_file(self) -> None:
        loaded = self.loaded
        if loaded is None:
            return
        flt = self.filter
        self.file_matches = [f for f in loaded.frames if flt.matches_record(f)] if flt.active else loaded.frames
        pages = max(1, -(-len(self.file_matches) // SHOWN))
        self.file_pages.max = pages
        self.file_pages.value = 1
        self.file_pages.update()
        first = loaded.frames[0].time
        start = f", starts {datetime.fromtimestamp(first):%Y-%m-%d %H:%M:%S}" if first > 1e8 else ""
        self.file_info.set_text(
            f"{loaded.name}: {len(loaded.frames)} frames{' (file truncated)' if loaded.truncated else ''}, "
            f"{loaded.duration:.1f} s{start}, {loaded.error_frames} error frames; "
            f"{len(self.file_matches)} match the filters; {SHOWN} per page"
        )
        self._show_file_page()

    def _show_file_page(self) -> None:
        if self.loaded is None:
            return
        page = max(1, int(self.file_pages.value or 1))
        first = (page - 1) * SHOWN
        shown = self.file_matches[first:first + SHOWN]
        self.file_table.rows = _frame_rows(shown, self.file_decoder, relative_to=self.loaded.frames[0].time, first_key=first)
        self.file_table.update()


def _size(n: int) -> str:
    if n < 1024:
        return f"{n} B"
    if n < 1024**2:
        return f"{n / 1024:.1f} KiB"
    return f"{n / 1024**2:.1f} MiB"
