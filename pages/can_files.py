"""The CAN bus monitor's files: recording the bus to a file (an engineer action, audited), the folder of
recordings, and a recorded file opened in the monitor (uploaded or from that folder), filtered and paged."""

from __future__ import annotations

import asyncio
import tempfile
from collections.abc import Awaitable, Callable
from datetime import datetime
from pathlib import Path

from nicegui import events, run, ui

from app import recording as rec
from app import runtime as rt
from app.can_bus import CanBusState, FrameRecord
from app.i18n import N_, Lang
from app.message import said
from app.worker import AuditUnavailable, PermissionDenied
from pages.can_trace import SCROLL_HEIGHT, BusDecoding, FilterCard, clicked_key, frame_rows, frame_table, set_deltas, show_frame_details
from pages.command_client import enable_unless, viewer_reason
from pages.frame import notify_error
from pages.monitor_common import SHOWN
from pages.session import current_user
from pages.widgets import upload_button

MAX_UPLOAD_BYTES = 200 * 1024 * 1024


class RecordingCard:
    """Recording the bus to a file (an engineer action), the last recording, and the folder of recordings.

    :param open_file: opens a recorded file in the monitor's file tab
    """

    def __init__(self, bus: str, state: CanBusState, options: dict, open_file: Callable[[Path], Awaitable[None]],
                 lang: Lang):
        self.lang = lang
        self.bus = bus
        self.state = state
        self.options = options
        self.open_file = open_file
        self.last: rec.Recording | None = None

    def build(self) -> None:
        _ = self.lang.gettext
        with ui.card().classes("w-full q-pa-sm"):
            with ui.row().classes("items-center gap-3 w-full"):
                ui.icon("fiber_manual_record", color="negative")
                ui.label(_("Recording")).classes("text-subtitle2")
                self.format = ui.select({s: label for s, (_w, label) in rec.WRITERS.items()}, value=".log", label=_("Format")).props("dense outlined").classes("w-40")
                self.format.mark("format")
                self.record_button = ui.button(self.lang.pgettext("recording", "Record"), icon="fiber_manual_record", color="negative", on_click=self.start)
                self.record_button.mark("record")
                self.read_only = viewer_reason(self.lang)  # recording writes files on disk: an engineer's action
                self.stop_button = ui.button(_("Stop"), icon="stop", on_click=self.stop).mark("stop")
                self.status = ui.label().classes("text-body2").mark("record-status")
                self.status.props("data-monitor=record-status")
                self.download_button = ui.button(_("Download"), icon="download", on_click=self.download_last).props("flat").mark("download")
            with ui.expansion(_("Recordings"), icon="folder", on_value_change=lambda e: e.value and self.refresh_list()).classes("w-full").props("dense") as self.panel:
                self.files_box = ui.column().classes("w-full gap-0")

    def refresh(self) -> None:
        lang = self.lang
        _ = lang.gettext
        active = rec.active_recording(self.state)
        if active is not None:
            self.status.set_text(_("recording {name}: {seconds} s, {frames} frames, {size}").format(
                name=active.path.name, seconds=lang.number(active.elapsed, 1, group=False), frames=active.frames,
                size=_size(active.size, lang)))
            self.last = active
        elif self.last is not None:
            last = self.last
            if last.active:  # detached by the bus after a write error
                last.close()
            problem = f" - {said(last.error, lang)}" if last.error else ""
            self.status.set_text(_("{name}: {seconds} s, {frames} frames, {size}").format(
                name=last.path.name, seconds=lang.number(last.elapsed, 1, group=False), frames=last.frames,
                size=_size(last.size, lang)) + problem)
        else:
            self.status.set_text(_("not recording"))
        enable_unless(self.record_button, self.read_only or (_("recording: stop it first") if active is not None else ""))
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
            notify_error(said(exc, self.lang))
            return
        ui.notify(self.lang.gettext("Recording {bus} to {path}").format(bus=self.bus, path=self.last.path), type="info")
        self.refresh()

    async def stop(self) -> None:
        user, role = current_user()

        async def stop():
            return await asyncio.to_thread(rec.stop_recording, self.state)  # writes what is queued, then closes

        # stopping only ends a file: allowed for everyone, audited
        stopped = await rt.current().worker.gate.run(stop, device=self.bus, role=role, user=user,
                                                     describe=f"stop recording {self.bus}", kind="stop")
        _ = self.lang.gettext
        if stopped is None:
            ui.notify(_("Nothing was being recorded."), type="warning")
            return
        self.last = stopped
        if stopped.error:
            notify_error(_("Recording {name}: {error}").format(name=stopped.path.name, error=said(stopped.error, self.lang)))
        else:
            ui.notify(_("Saved {n} frames to {name}").format(n=stopped.frames, name=stopped.path.name), type="positive")
        self.refresh()
        await self.refresh_list()

    async def download_last(self) -> None:
        if self.last is not None:
            await self.download(self.last.path)

    async def download(self, path: Path) -> None:
        if not path.is_file():
            notify_error(self.lang.gettext("{name} is gone from {folder}").format(name=path.name, folder=path.parent))
            await self.refresh_list()
            return
        ui.download.file(path, path.name)

    async def refresh_list(self) -> None:
        files = await asyncio.to_thread(rec.list_recordings)  # a folder listing: not on the event loop
        _ = self.lang.gettext
        self.panel.set_text(_("Recordings ({n}) in {folder}").format(n=len(files), folder=rec.recordings_dir()))
        self.files_box.clear()
        with self.files_box:
            if not files:
                ui.label(_("No recordings yet.")).classes("text-caption text-grey-8")
            for f in files[:50]:
                with ui.row().classes("items-center gap-2"):
                    ui.label(f.name).classes("mono text-body2")
                    ui.label(f"{_size(f.size, self.lang)} · {datetime.fromtimestamp(f.mtime):%Y-%m-%d %H:%M:%S}").classes("text-caption text-grey-8")
                    ui.button(icon="download", on_click=lambda p=f.path: self.download(p)).props("flat dense round").tooltip(
                        _("Download {name}").format(name=f.name))
                    ui.button(icon="table_view", on_click=lambda p=f.path: self.open_file(p)).props("flat dense round").tooltip(
                        _("Open {name} here").format(name=f.name))


class FileView:
    """A recorded file opened in the monitor (uploaded, or from the recordings folder), filtered and paged.

    :param show: brings the file tab to the front
    """

    def __init__(self, state: CanBusState, filters: FilterCard, decoding: BusDecoding, show: Callable[[], None], lang: Lang):
        self.lang = lang
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
        _ = self.lang.gettext
        open_label = _("Open a recorded file ({suffixes})").format(suffixes=" ".join(rec.READ_SUFFIXES))
        refused = _("The file was refused: files up to {n} MB can be opened.").format(n=MAX_UPLOAD_BYTES // 2**20)
        with ui.row().classes("items-center gap-4 w-full"):
            self.upload = ui.upload(
                label=open_label,
                auto_upload=True,
                max_file_size=MAX_UPLOAD_BYTES,
                on_upload=self.on_upload,
                on_rejected=lambda: notify_error(refused),
            ).props("accept=" + ",".join(rec.READ_SUFFIXES) + " flat bordered").classes("w-96").style("max-height: 100px")
            self.upload.add_slot("header", upload_button(open_label, "monitor-upload"))
            self.upload.mark("upload")
            self.upload.props("data-monitor=upload")
            with ui.column().classes("gap-1"):
                self.file_info = ui.label(_("No file opened.")).classes("text-body2").mark("file-info")
                self.file_info.props("data-monitor=file-info")
                self.progress = ui.linear_progress(0, show_value=False).classes("w-96").props("data-monitor=file-progress")
                self.progress.set_visibility(False)
                self.pages = ui.pagination(1, 1, direction_links=True, on_change=self.show_page).props("dense max-pages=9 boundary-numbers")
                self.pages.mark("file-pages")
                self.pages.props("data-monitor=file-pages")
        with ui.element("div").classes("w-full monitor-scroll").style(SCROLL_HEIGHT):
            self.table = frame_table("file-frames", self.lang, time_label=N_("Time s"))
        self.table.on("rowClick", self._clicked)

    def _clicked(self, event) -> None:
        f = self.shown.get(clicked_key(event))
        if f is not None:
            show_frame_details(f, self.decoder, None if self.loaded is None else self.loaded.frames[0].time, self.lang)

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
            notify_error(self.lang.gettext("{name} is still being recorded; stop the recording first.").format(name=path.name))
            return
        loaded = await self._load(path, path.name)
        if loaded is not None:
            await self._show_loaded(loaded)

    async def _load(self, path: Path, name: str) -> rec.LoadedLog | None:
        """Read a file in a thread with its progress on the page; a file that cannot be read is named
        with where and why (on the page and in a message)."""
        lang = self.lang
        _ = lang.gettext
        if self._loading:
            notify_error(_("A file is being opened already; wait until it is loaded."))
            return None
        self._loading = True
        self.show()
        self.progress.set_value(0)
        self.progress.set_visibility(True)
        self.file_info.set_text(_("opening {name} ...").format(name=name))

        def report(frames: int, fraction: float) -> None:
            self.progress.set_value(fraction)
            self.file_info.set_text(_("opening {name}: {frames} frames read ({percent} %)").format(
                name=name, frames=lang.number(frames), percent=lang.number(round(fraction * 100))))

        try:
            loaded = await rec.load_log(path, name, progress=report)
            await run.io_bound(set_deltas, loaded.frames)  # O(n) once, off the event loop
            return loaded
        except rec.RecordingError as exc:
            self.file_info.set_text(_("cannot open: {error}").format(error=said(exc, lang)))
            notify_error(said(exc, lang))
        except OSError as exc:  # a failing save/temp dir: still a message, never a crash
            self.file_info.set_text(_("{name}: cannot open: {error}").format(name=name, error=exc))
            notify_error(_("{name}: cannot open: {error}").format(name=name, error=exc))
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
        ui.notify(self.lang.gettext("Opened {name}: {n} frames").format(name=loaded.name, n=len(loaded.frames)), type="positive")

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
        lang = self.lang
        _ = lang.gettext
        first = loaded.frames[0].time
        start = _(", starts {time}").format(time=f"{datetime.fromtimestamp(first):%Y-%m-%d %H:%M:%S}") if first > 1e8 else ""
        fmt = " " + _("({format} file)").format(format=loaded.format) if loaded.format else ""
        frames = _("{n} frames").format(n=len(loaded.frames)) + (" " + _("(file truncated)") if loaded.truncated else "")
        self.file_info.set_text(
            f"{loaded.name}{fmt}: {frames}, {lang.number(loaded.duration, 1, group=False)} s{start}, "
            + _("{n} error frames").format(n=loaded.error_frames) + "; "
            + _("{n} match the filters; {shown} per page").format(n=len(self.matches), shown=SHOWN)
        )
        self.show_page()

    def show_page(self) -> None:
        if self.loaded is None:
            return
        page = max(1, int(self.pages.value or 1))
        first = (page - 1) * SHOWN
        shown = self.matches[first:first + SHOWN]
        self.shown = {first + i: f for i, f in enumerate(shown)}
        self.table.rows = frame_rows(shown, self.decoder, self.lang, relative_to=self.loaded.frames[0].time, first_key=first)
        self.table.update()


def _size(n: int, lang: Lang) -> str:
    if n < 1024:
        return f"{n} B"
    if n < 1024**2:
        return f"{lang.number(n / 1024, 1, group=False)} KiB"
    return f"{lang.number(n / 1024**2, 1, group=False)} MiB"


__all__ = ["FileView", "RecordingCard"]
