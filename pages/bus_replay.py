"""Replay a recorded file onto a CAN bus (``/monitor/BUS/replay``): engineers only.

Pick a recording of the data folder or upload one, choose the speed, start: the start asks a
confirmation that says how many frames go out onto the bus and which frames are kept off and why
(frames a device sends, frames the send policy forbids or would ask for); the bus monitor shows
the frames as sent. Progress is shown; Stop ends it at once; leaving the page ends it too (dead-man).
"""

from __future__ import annotations

import asyncio
from pathlib import Path

from nicegui import ui

from app import i18n
from app import recording as rec
from app import replay as rp
from app import runtime as rt
from app.i18n import N_, Lang
from app.message import Message, said
from app.worker import AuditUnavailable, PermissionDenied
from pages.frame import frame, notify_error
from pages.session import current_user
from pages.widgets import upload_button
from pages.command_client import confirm

REFRESH_S = 0.25
SPEEDS = (0.1, 0.5, 1.0, 2.0, 5.0, 10.0)
AS_RECORDED = N_("{speed} x (as recorded)")


def speeds(lang: Lang) -> dict[float, str]:
    """The replay speeds as the select offers them: ``0.5 x`` (``0,5 x`` in German), ``1 x (as recorded)``."""
    return {speed: (lang.gettext(AS_RECORDED) if speed == 1.0 else "{speed} x").format(speed=lang.numbers_in(f"{speed:g}"))
            for speed in SPEEDS}


class RecordingCard:
    """The recording to replay: one of the data folder or an uploaded file, loaded and screened."""

    def __init__(self, worker, bus: str, lang: Lang):
        self.worker = worker
        self.bus = bus
        self.lang = lang
        self.log: rec.LoadedLog | None = None

    def build(self) -> None:
        _ = self.lang.gettext
        with ui.card().classes("w-full"):
            ui.label(_("Recording")).classes("text-subtitle1")
            files = {f.name: f"{f.name} ({f.size // 1024} KiB)" for f in rec.list_recordings()}
            self.choice = ui.select(files, label=_("Recordings in the data folder"), with_input=True).classes(
                "w-full").props("outlined dense")
            ui.upload(auto_upload=True, on_upload=lambda e: self.handle_upload(e)).props(
                "flat bordered accept=" + ",".join(rec.READ_SUFFIXES)).classes("w-96").add_slot(
                "header", upload_button(_("or open a file ({suffixes})").format(suffixes=" ".join(rec.READ_SUFFIXES)),
                                        "replay-upload"))
            self.file_status = ui.label(_("no file loaded")).props("data-testid=replay-file")
            self.load_bar = ui.linear_progress(value=0, show_value=False).classes("w-full")
            self.load_bar.set_visibility(False)

    async def load(self, path: Path, name: str) -> None:
        load_bar, file_status = self.load_bar, self.file_status
        lang = self.lang
        _ = lang.gettext
        load_bar.set_visibility(True)
        load_bar.set_value(0)
        file_status.set_text(_("reading {name} ...").format(name=name))

        def report(frames: int, fraction: float) -> None:
            load_bar.set_value(fraction)
            file_status.set_text(_("reading {name}: {frames} frames").format(name=name, frames=frames))

        try:
            log = await rec.load_log(path, name, progress=report)
        except rec.RecordingError as exc:
            file_status.set_text(said(exc, lang))
            load_bar.set_visibility(False)
            return
        self.log = log
        screening = await asyncio.to_thread(rp.screen, self.worker, self.bus, log.frames)
        load_bar.set_visibility(False)
        file_status.set_text(_("{name}: {frames} frames, {seconds} s ({format})").format(
            name=name, frames=len(log.frames), seconds=lang.number(log.duration, 1, group=False), format=log.format)
                             + (" - " + _("only the first frames (file too long)") if log.truncated else "")
                             + (f". {said(screening.text(), lang)}" if screening.blocked else ""))

    async def on_choice(self) -> None:
        if self.choice.value:
            try:
                path = await asyncio.to_thread(rec.recording_path, self.choice.value)
            except rec.RecordingError as exc:
                self.file_status.set_text(said(exc, self.lang))
                return
            await self.load(path, self.choice.value)

    async def handle_upload(self, event) -> None:
        try:  # streamed into the one uploads folder under a safe name ('..' is refused by name)
            path = await rec.store_upload(event.file)
        except rec.RecordingError as exc:
            self.file_status.set_text(said(exc, self.lang))
            return
        await self.load(path, rec.upload_name(event.file.name))


class ReplayCard:
    """Speed, start and stop of the replay, its progress and status."""

    def __init__(self, worker, bus: str, session: str, recording: RecordingCard, lang: Lang):
        self.lang = lang
        self.worker = worker
        self.bus = bus
        self.session = session
        self.recording = recording
        self.last: rp.Replay | None = None

    def build(self) -> None:
        _ = self.lang.gettext
        with ui.card().classes("w-full"):
            ui.label(_("Replay")).classes("text-subtitle1")
            with ui.row().classes("items-center gap-4"):
                self.speed = ui.select(speeds(self.lang), value=1.0, label=_("Speed")).props("outlined dense").classes("w-48")
                self.start_button = ui.button(_("Start replay"), icon="play_arrow", on_click=lambda: self.start()).props(
                    "data-testid=replay-start")
                self.stop_button = ui.button(_("Stop"), icon="stop", color="negative", on_click=lambda: self.stop()).props(
                    "data-testid=replay-stop")
            self.progress = ui.linear_progress(value=0, show_value=False).classes("w-full")
            self.status = ui.label("").props("data-testid=replay-status")
            ui.label(_("Start asks first, naming how many frames go out. Frames a device sends (status, answers, "
                       "internal traffic) and frames the device policies forbid or would ask for are never replayed. "
                       "Refused while a device on this bus is under control; it stops by itself when one is taken "
                       "under control, and when this page closes.")).classes("text-caption text-grey-7")

    async def start(self) -> None:
        log = self.recording.log
        _ = self.lang.gettext
        if log is None:
            notify_error(_("Choose a recording first."))
            return
        speed = float(self.speed.value or 1.0)
        confirmed = False
        while True:
            user, role = current_user()  # the account store's answer now, not the page's when it was built
            try:
                await rp.start_replay(self.worker, self.bus, log.frames, name=log.name, speed=speed,
                                      session=self.session, user=user or "anonymous", role=role, confirmed=confirmed)
            except rp.NeedsConfirmation as question:
                if confirmed or not await confirm(_("Replay onto {bus}?").format(bus=self.bus), said(question.question, self.lang),
                                                  ok=_("Send {n} frames").format(n=question.frames), lang=self.lang):
                    self.status.set_text(_("not started: the replay was not confirmed"))
                    break
                confirmed = True
                continue
            except (rp.ReplayError, PermissionDenied, AuditUnavailable) as exc:
                self.status.set_text(_("refused: {error}").format(error=said(exc, self.lang)))
            break
        self.refresh()

    async def stop(self) -> None:
        worker, bus = self.worker, self.bus
        replay = rp.running_replay(worker, bus)
        user, role = current_user()
        if replay is not None and replay.running:
            replay.stop(Message(N_("stopped by {user}"), user=user or "anonymous"))  # at once, whatever the audit log says

            async def stopped() -> str:
                return f"after {replay.sent} of {replay.total} frames"

            try:  # a stop is recorded afterwards, never refused
                await worker.gate.run(stopped, device=bus, role=role, user=user or "anonymous", kind="stop",
                                      describe=f"stop replay {replay.name} onto {bus}")
            except AuditUnavailable:
                pass
        self.refresh()

    def refresh(self) -> None:
        replay = rp.running_replay(self.worker, self.bus) or self.last
        if replay is not None and replay.session == self.session:
            self.last = replay
        if replay is None:
            self.status.set_text(self.status.text or self.lang.gettext("no replay yet"))
            self.progress.set_value(0)
        else:
            self.progress.set_value(replay.fraction)
            self.status.set_text(f"{replay.name}: {said(replay.summary(), self.lang)}")
        running = replay is not None and replay.running
        self.start_button.set_enabled(not running)
        self.stop_button.set_enabled(running)


def content(bus: str) -> None:
    runtime = rt.current()
    worker = runtime.worker
    lang = i18n.page_language()
    _ = lang.gettext
    with frame(_("Replay onto {bus}").format(bus=bus)):
        user, role = current_user()
        ui.link(_("Back to the monitor of {bus}").format(bus=bus), f"/monitor/{bus}")
        if role != "engineer":
            ui.label(_("Replaying a recording sends frames onto the bus: engineers only. "
                       "This read-only session can watch the bus on its monitor page.")).props("data-testid=replay-readonly")
            return
        if bus not in worker.can_buses:
            ui.label(_("{bus} is not a CAN bus: only CAN recordings can be replayed.").format(bus=bus))
            return
        recording = RecordingCard(worker, bus, lang)
        recording.build()
        replay = ReplayCard(worker, bus, ui.context.client.id, recording, lang)
        replay.build()
        recording.choice.on_value_change(recording.on_choice)
        replay.refresh()
        ui.timer(REFRESH_S, replay.refresh)
