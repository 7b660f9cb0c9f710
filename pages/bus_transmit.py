"""The engineer's transmit list of a CAN bus (/monitor/<bus>/transmit).

Rows of ID, DLC and data, sent once or cyclically; frames entered as bytes or built by name
through the device codecs. Every action goes through :mod:`app.transmit` (checked, audited);
cyclic rows stop when this browser stops confirming it is alive. Viewers never see the list.
"""

from __future__ import annotations

import html
import weakref

from nicegui import background_tasks, ui

from app import i18n
from app import runtime as rt
from app import transmit as tx
from app.i18n import N_, Lang
from app.message import said
from app.worker import AuditUnavailable, PermissionDenied
from pages.frame import ACTION_ERRORS, frame, notify_error
from pages.monitor_common import bus_tool_opened
from pages.session import current_user
from pages.widgets import columns as shown_columns
from pages.widgets import range_number
from pages.command_client import all_valid, cancelled, confirm

REFRESH_S = 0.5
COLUMNS = [
    {"name": "id", "label": "ID", "field": "id", "align": "left", "classes": "mono"},
    {"name": "dlc", "label": "DLC", "field": "dlc", "align": "right"},
    {"name": "data", "label": N_("Data"), "field": "data", "align": "left", "classes": "mono"},
    {"name": "label", "label": N_("Message"), "field": "label", "align": "left"},
    {"name": "mode", "label": N_("Send"), "field": "mode", "align": "left"},
    {"name": "sent", "label": N_("Sent"), "field": "sent", "align": "right"},
    {"name": "actions", "label": "", "field": "key", "align": "right"},
]
# a row's buttons: Send (a row sent once), Start (a cyclic row stopped), Stop (a cyclic row running), Remove
ACTION_WORDS = (N_("Send"), N_("Start"), N_("Stop"))
ACTIONS_SLOT = r"""
        <q-td :props="props">
          <q-btn v-if="!props.row.cyclic" dense flat icon="send" label="%s" @click="$parent.$emit('send', props.row.key)" />
          <q-btn v-if="props.row.cyclic && !props.row.running" dense flat color="positive" icon="play_arrow" label="%s"
                 @click="$parent.$emit('start', props.row.key)" />
          <q-btn v-if="props.row.running" dense flat color="negative" icon="stop" label="%s"
                 @click="$parent.$emit('stop', props.row.key)" />
          <q-btn dense flat icon="delete" @click="$parent.$emit('remove', props.row.key)" />
        </q-td>
    """


# the words of the frames the device types offer by name (devices/*/policy.py, ``transmit_forms``): shown in the
# page's language where the catalog has them; the documents' names (DigOut and its outputs) as they are
FORM_WORDS = (N_("register"), N_("Register"), N_("Count"), N_("read holding"), N_("read input"), N_("write holding"))


def form_word(text: str, lang: Lang) -> str:
    return lang.gettext(text) if lang.has(text) else text


def send_modes(lang: Lang) -> dict[str, str]:
    """How a row is sent: once, or cyclically."""
    return {"once": lang.gettext("once"), "cyclic": lang.gettext("cyclic")}


def _parse_int(text: str | float | None, what: str, lang: Lang) -> int:
    """A whole number typed as hex (``123``) or with its base (``0x123``); ``what`` names it in ``lang``'s words."""
    _ = lang.gettext
    if text is None or str(text).strip() == "":
        raise tx.TransmitError(_("{what} is missing").format(what=what))
    try:
        return int(text) if isinstance(text, (int, float)) else int(str(text).strip(), 0 if str(text).strip().lower().startswith("0x") else 16)
    except ValueError:
        raise tx.TransmitError(_("{what} '{text}' is not a number").format(what=what, text=text)) from None


def content(bus: str) -> None:
    runtime = rt.current()
    lang = i18n.page_language()
    _ = lang.gettext
    with frame(_("Transmit list · {bus}").format(bus=bus)):
        can = bus in runtime.worker.can_buses
        if not bus_tool_opened(bus, lang, "" if can else _("{bus} is not a CAN bus: transmit lists are for CAN buses.").format(bus=bus)):
            return
        _user, role = current_user()
        if role != "engineer":
            with ui.row().classes("bg-amber-1 q-pa-sm items-center").props("data-testid=transmit-viewer-note"):
                ui.icon("lock")
                ui.label(_("The transmit list is for engineers: a viewer session does not see or send it."))
            return
        _engineer_view(runtime, bus, lang)


def _who() -> dict:
    """The session's user and role as the account store says now (looked up at every action, never kept)."""
    user, role = current_user()
    return {"user": user or "anonymous", "role": role}


class TransmitView:
    """What the cards of the transmit list share: the bus's list, the session and the checked action."""

    def __init__(self, runtime, bus: str, tl: tx.TransmitList, lang: Lang):
        self.lang = lang
        self.bus = bus
        self.tl = tl
        self.session = ui.context.client.id
        self.cards: list = []

    def refresh(self) -> None:
        for card in self.cards:
            card.refresh()

    async def guarded(self, action, ok: str = "") -> bool:
        try:
            await action()
        except tx.NeedsConfirmation as exc:
            notify_error(said(exc, self.lang))
            return False
        except (tx.TransmitError, PermissionDenied, AuditUnavailable, KeyError) as exc:
            notify_error(said(exc, self.lang))
            return False
        except ACTION_ERRORS as exc:  # shown, never ends the page
            notify_error(f"{type(exc).__name__}: {exc}")
            return False
        if ok:
            ui.notify(ok, type="positive")
        self.refresh()
        return True


class RawFrameCard:
    """A frame entered as ID, DLC and data bytes, sent once or cyclically."""

    def __init__(self, view: TransmitView):
        self.view = view

    def build(self) -> None:
        lang = self.view.lang
        _ = lang.gettext
        with ui.card().classes("w-full"):
            ui.label(_("Frame as bytes")).classes("text-subtitle1")
            with ui.row().classes("items-end gap-3 flex-wrap"):
                self.can_id = ui.input(_("ID (hex)"), value="123").props("dense outlined").classes("w-28 mono")
                self.extended = ui.checkbox(_("extended (29-bit)"))
                self.dlc = range_number("DLC", 0, 8, integer=True, value=2, lang=lang).classes("w-24")
                self.data = ui.input(_("Data (hex bytes)"), value="01 02").props("dense outlined").classes("w-56 mono")
                self.mode = ui.select(send_modes(lang), value="once", label=_("Send")).props(
                    "dense outlined").classes("w-28")
                self.period = range_number(_("Cycle ms"), tx.PERIOD_MIN_MS, tx.PERIOD_MAX_MS, unit="ms", integer=True,
                                           value=100, lang=lang).classes("w-36")
                self.period.bind_visibility_from(self.mode, "value", value="cyclic")
                ui.button(_("Add"), icon="add", on_click=self.add_raw).props("data-testid=transmit-add")

    async def add_raw(self) -> None:
        cyclic = self.mode.value == "cyclic"
        if not all_valid(self.dlc, *([self.period] if cyclic else [])):
            return  # the field says what it allows; nothing is added

        async def do() -> None:
            payload = tx.parse_bytes(self.data.value or "")
            row = tx.make_row(_parse_int(self.can_id.value, "ID", self.view.lang), bool(self.extended.value), payload,
                              int(self.period.value) if self.mode.value == "cyclic" else None,
                              dlc=int(self.dlc.value) if self.dlc.value is not None else None)
            await self.view.tl.add(row, **_who())

        await self.view.guarded(do)

    def refresh(self) -> None:
        pass


class NamedFrameCard:
    """Device messages by name: the frames each device type declares, built through its codec."""

    def __init__(self, view: TransmitView, offered: list):
        self.view = view
        self.offered = offered

    def build(self) -> None:
        lang = self.view.lang
        _ = lang.gettext
        with ui.card().classes("w-full"):
            with ui.row().classes("items-end gap-3"):
                ui.label(_("Device message by name")).classes("text-subtitle1")
                # a row built by name is sent once or cyclically like a raw one
                self.named_mode = ui.select(send_modes(lang), value="once", label=_("Send by name")).props(
                    "dense outlined data-testid=named-mode").classes("w-28")
                self.named_period = range_number(_("Cycle ms by name"), tx.PERIOD_MIN_MS, tx.PERIOD_MAX_MS, unit="ms",
                                                 integer=True, value=500, lang=lang).classes("w-36")
                self.named_period.bind_visibility_from(self.named_mode, "value", value="cyclic")
            for dev, form in self.offered:
                self._form_row(dev, form)

    def _form_row(self, dev, form) -> None:
        lang = self.view.lang
        with ui.row().classes("items-center gap-2 flex-wrap"):
            ui.label(f"{dev.name} {form_word(form.title, lang)}").classes("w-48")
            entries = {}
            for f in form.fields:
                if f.kind == "flag":
                    entries[f.name] = ui.checkbox(form_word(f.name, lang), value=bool(f.default))
                elif f.kind == "choice":
                    choices = {key: form_word(text, lang) for key, text in (f.choices or {}).items()}
                    entries[f.name] = ui.select(choices, value=f.default).props(
                        "dense outlined").classes("w-36")
                else:
                    entries[f.name] = range_number(form_word(f.name.capitalize(), lang), f.low, f.high, integer=True,
                                                   value=f.default, lang=self.view.lang).classes("w-32")

            async def add_form() -> None:
                numbers = [e for f, e in zip(form.fields, entries.values()) if f.kind == "number"]
                if not all_valid(*numbers):
                    return
                await self.add_named(lambda: tx.named_row(dev.type, dev.name, dev.options, form.title,
                                                          {n: e.value for n, e in entries.items()}))

            ui.button(self.view.lang.gettext("Add"), icon="add", on_click=add_form).props("flat dense")

    async def add_named(self, build) -> None:
        if self.named_mode.value == "cyclic" and not all_valid(self.named_period):
            return

        async def do() -> None:
            row = build()
            if self.named_mode.value == "cyclic":
                row = tx.make_row(row.can_id, row.extended, row.data, int(self.named_period.value), row.label)
            await self.view.tl.add(row, **_who())

        await self.view.guarded(do)

    def refresh(self) -> None:
        pass


class RowsCard:
    """The list's rows with Send, Start, Stop and Remove; replaced in place when the list or a count changes."""

    def __init__(self, view: TransmitView):
        self.view = view
        self.shown_version = -1
        self.shown_sent = -1

    def build(self) -> None:
        view, tl = self.view, self.view.tl
        _ = view.lang.gettext
        # one table, its rows replaced in place: a new table on every count would throw away the one whose Stop
        # button the engineer is about to press, and the press would be lost
        with ui.row().classes("items-center gap-2"):
            ui.label(_("Rows")).classes("text-subtitle1")
            ui.button(_("Stop all"), icon="stop", color="negative",
                      on_click=lambda: view.guarded(_stop_all(tl))).props("dense")
        self.note = ui.label().classes("text-grey-7")
        self.error = ui.label().classes("text-negative")
        self.overridden = ui.label().classes("text-orange-10 text-body2").props("data-testid=transmit-overridden")
        self.overridden.set_visibility(False)
        t = ui.table(columns=shown_columns(COLUMNS, view.lang), rows=[], row_key="key").props("dense flat bordered").classes(
            "w-full can-table")
        t.props("data-testid=transmit-table")
        t.add_slot("body-cell-actions", ACTIONS_SLOT % tuple(html.escape(_(word)) for word in ACTION_WORDS))
        t.on("send", lambda e: view.guarded(lambda: self.confirmed_send(e.args, False)))
        t.on("start", lambda e: view.guarded(lambda: self.confirmed_send(e.args, True)))
        t.on("stop", lambda e: view.guarded(lambda: tl.stop(e.args, **_who())))
        t.on("remove", lambda e: view.guarded(lambda: tl.remove(e.args, **_who())))
        self.table = t

    async def confirmed_send(self, key: str, start: bool) -> None:
        """Send or start a row; a risk its device policy names is asked first (and a "no" is audited)."""
        tl, bus = self.view.tl, self.view.bus

        async def go(confirmed: bool) -> str:
            if start:
                return await tl.start(key, session=self.view.session, confirmed=confirmed, **_who())
            return await tl.send_once(key, confirmed=confirmed, **_who())

        row = tl.row(key)
        what = row.describe() if row else key
        lang = self.view.lang
        _ = lang.gettext
        try:
            note = await go(False)
        except tx.NeedsConfirmation as exc:
            if not await confirm(_("Send {what}?").format(what=what), said(exc, lang), ok=_("Send"), lang=lang):
                await cancelled(bus, f"transmit on {bus}: {what}", parameter=row.id_text() if row else "")
                return
            note = await go(True)
        # a frame this tool sends itself replaces it: said again after the send, and kept under the list
        note = said(note, lang)
        told = _("Started {what}; {note}") if start else _("Sent {what}; {note}")
        self.overridden.set_text(told.format(what=what, note=note) if note else "")
        self.overridden.set_visibility(bool(note))
        if note:
            warning = _("Started, but it does not last: {note}") if start else _("Sent once, but it does not last: {note}")
            ui.notify(warning.format(note=note), type="warning", multi_line=True, timeout=10_000)
        self.refresh()

    def refresh(self) -> None:
        tl, t = self.view.tl, self.table
        _ = self.view.lang.gettext
        self.error.set_text(said(tl.load_error, self.view.lang))
        self.error.set_visibility(bool(tl.load_error))
        loaded = tl.loaded.is_set()
        once, running = _("once"), " · " + _("running")

        def mode(r) -> str:
            if r.period_ms is None:
                return once
            return _("every {ms} ms").format(ms=r.period_ms) + (running if tl.is_running(r.key) else "")

        rows = [{
            "key": r.key, "id": r.id_text(), "dlc": r.dlc, "data": r.data.hex(" ").upper(), "label": r.label,
            "mode": mode(r), "running": tl.is_running(r.key), "cyclic": r.period_ms is not None, "sent": tl.sent.get(r.key, 0),
        } for r in tl.rows] if loaded else []
        self.note.set_text(_("loading the saved list ...") if not loaded else "" if rows else _("No rows yet: add a frame above."))
        self.note.set_visibility(not loaded or not rows)
        t.set_visibility(loaded)
        if rows != t.rows:
            t.rows = rows
            t.update()
        self.shown_version = tl.version
        self.shown_sent = sum(tl.sent.values())

    def tick(self) -> None:  # O(1) unless something changed; at most 64 rows sent
        tl = self.view.tl
        if tl.version != self.shown_version or (tl.running and sum(tl.sent.values()) != self.shown_sent):
            self.refresh()


_LOADING: weakref.WeakSet[tx.TransmitList] = weakref.WeakSet()  # the lists whose file is being loaded (once)


def _engineer_view(runtime, bus: str, lang: Lang) -> None:
    tl = tx.transmit_list(runtime.worker, bus, runtime.data_dir)
    if not tl.loaded.is_set() and tl not in _LOADING:
        _LOADING.add(tl)
        background_tasks.create(tl.load(), name=f"load transmit list {bus}")
    view = TransmitView(runtime, bus, tl, lang)
    devices = runtime.plant.devices_on(bus)

    ui.label(lang.gettext(
        "Rows are sent once or cyclically (10 ms .. 10 s). Cyclic rows stop within 0.5 s when this browser closes, "
        "freezes or loses the network. Every send, start and stop is recorded in the audit log. Frames the device "
        "documents forbid (HD-Lock firmware-update requests 0x706/0x707, commands 2-4, FwUpdateCommandRegister) "
        "are refused."
    )).classes("text-caption text-grey-8")
    view.cards.append(RawFrameCard(view))
    offered = [(dev, form) for dev in devices for form in tx.named_forms(dev.type, dev.options)]
    if offered:
        view.cards.append(NamedFrameCard(view, offered))
    rows = RowsCard(view)
    view.cards.append(rows)
    for card in view.cards:
        card.build()
    rows.refresh()
    ui.timer(REFRESH_S, rows.tick)


def _stop_all(tl: tx.TransmitList):
    async def do() -> None:
        for key in list(tl.running):
            await tl.stop(key, **_who())

    return do
