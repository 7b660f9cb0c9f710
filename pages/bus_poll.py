"""A generic Modbus poll on an RTU line (/monitor/<bus>/poll), in the manner of Modbus Poll.

Reads change nothing and are open to every role; writes are engineer only and go through
:class:`app.modbus_poll.ModbusPoll.write` (checked against the known devices' parameter models,
confirmed, audited). Requests share the line with the devices' polls.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from nicegui import app, background_tasks, ui

from app import i18n
from app import modbus_poll as mp
from app import runtime as rt
from app.i18n import N_, Lang
from app.message import said
from app.modbus_line import ModbusLine
from app.worker import AuditUnavailable, PermissionDenied
from pages.frame import ACTION_ERRORS, fmt_age, frame, notify_error
from pages.monitor_common import bus_tool_opened
from pages.session import current_user
from pages.widgets import range_number, range_text
from pages.command_client import all_valid, checked_value

REFRESH_S = 0.5  # the ages and the line cycle; each answer is shown as it comes (ModbusPoll.listeners)
BASES = {0: N_("0-based (protocol)"), 1: N_("1-based (register 1 = address 0)")}
WIDE_KINDS = {"u32": "uint32", "i32": "int32", "f32": "float32"}
PAIR_COLUMNS = [f"{kind} {order}" for kind in WIDE_KINDS for order in mp.WORD_ORDERS]
# which 32-bit columns are shown (a display choice, as Modbus Poll's format): all three need about 1250 px,
# one kind fits a 1024 px window
WIDE_CHOICES = {"all": "uint32, int32, float32", **WIDE_KINDS, "none": N_("none")}
# which word orders those columns show: the two common ones fit beside one kind at 1024 px
ORDER_CHOICES = {"words": "ABCD, CDAB", "swapped": N_("BADC, DCBA (bytes swapped)"), "all": N_("all four")}
ORDERS_SHOWN = {"words": ("ABCD", "CDAB"), "swapped": ("BADC", "DCBA"), "all": tuple(mp.WORD_ORDERS)}
# the poll's functions and value formats as app/modbus_poll.py names them, shown in the page's language
FUNCTION_WORDS = (N_("01 Read Coils"), N_("02 Read Discrete Inputs"), N_("03 Read Holding Registers"),
                  N_("04 Read Input Registers"))
FORMAT_LABELS = {"unsigned": N_("Unsigned"), "signed": N_("Signed"), "hex": N_("Hex"), "binary": N_("Binary")}


def shown(choices: dict, lang: Lang) -> dict:
    """A select's choices in ``lang``: those marked ``N_`` translated, names of types and orders as they are."""
    return {key: lang.gettext(text) if lang.has(text) else text for key, text in choices.items()}


def _columns(base: int, function: int, lang: Lang, wide: str = "all", orders: str = "words") -> list[dict]:
    _ = lang.gettext
    cols = [
        {"name": "address", "label": _("Address ({base}-based)").format(base=base), "field": "address", "align": "right"},
        {"name": "name", "label": _("Known register"), "field": "name", "align": "left"},
    ]
    if function in (1, 2):
        return cols + [{"name": "unsigned", "label": _("Value"), "field": "unsigned", "align": "right"}]
    cols += [{"name": f, "label": _(FORMAT_LABELS[f]), "field": f, "align": "right", "classes": "mono"} for f in mp.FORMATS]
    cols += [{"name": c, "label": f"{WIDE_KINDS[kind]} {order}", "field": c, "align": "right", "classes": "mono"}
             for c in PAIR_COLUMNS for kind, order in [c.split()]
             if wide in ("all", kind) and order in ORDERS_SHOWN[orders]]
    return cols


def content(bus: str) -> None:
    runtime = rt.current()
    lang = i18n.page_language()
    _ = lang.gettext
    with frame(_("Modbus poll · {bus}").format(bus=bus)):
        modbus = isinstance(runtime.worker.lines.get(bus), ModbusLine)
        if bus_tool_opened(bus, lang, "" if modbus else _("{bus} is not a Modbus RTU line: the poll is for Modbus lines.").format(bus=bus)):
            _view(runtime, bus, lang)


class PollView:
    """The page: its poll windows on one line, the known devices, the role and the write card."""

    def __init__(self, runtime, bus: str, lang: Lang):
        self.runtime = runtime
        self.bus = bus
        self.lang = lang
        self.windows = mp.PollWindows(runtime.worker, bus)
        self.role = current_user()[1]  # what the page shows; every write asks again (the gate decides)
        self.known = {d.options.get("address"): d.name for d in runtime.plant.devices_on(bus)}
        self.line = runtime.worker.lines[bus]
        self.cards: list[WindowCard] = []
        self.restored = False  # the windows of the tab's storage are on the page (saving before would lose them)
        self.client = ui.context.client

    @property
    def storage_key(self) -> str:
        return f"modbus-poll:{self.bus}"

    def intro(self) -> None:
        known = self.known
        _ = self.lang.gettext
        at = self.lang.pgettext("unit address", "at")  # a word of its own: "{name} at {address}" would read as any "x at y"
        devices = ", ".join(f"{name} {at} {a}" for a, name in sorted(known.items()))
        ui.label(_(
            "Each window polls on its own clock; the windows take turns on the line, one request each between the "
            "devices' polls, and a window whose unit does not answer tries again ever further apart (up to "
            "{backoff} s). Addresses are protocol addresses; choose how they are counted. Devices on this "
            "line: {devices}.").format(backoff=self.lang.numbers_in(f"{mp.BACKOFF_MAX_S:g}"), devices=devices or _("none"))
        ).classes("text-caption text-grey-8")
        self.cycle = ui.label().classes("text-caption text-grey-7").props("data-testid=poll-line-cycle")

    def build(self) -> None:
        self.intro()
        self.container = ui.column().classes("w-full gap-4")
        with ui.row().classes("items-center gap-3"):
            self.add_button = ui.button(self.lang.gettext("Add window"), icon="add", on_click=lambda: self.add()).props(
                "outline data-testid=poll-add")
            self.count_note = ui.label().classes("text-caption text-grey-7")
        self.show_count()

    def add(self, settings: dict | None = None, save: bool = True):
        try:
            window = self.windows.add()
        except mp.PollError as exc:
            notify_error(said(exc, self.lang))
            return None
        card = WindowCard(self, window)
        with self.container:
            card.build(settings or {})
        self.cards.append(card)
        self.show_count()
        if settings and settings.get("running"):
            card.run(save=False)
        if save:
            self.save()
        return card

    def remove(self, card: WindowCard) -> None:
        self.windows.remove(card.window)
        self.cards.remove(card)
        self.save()  # before the card goes: this handler runs in the card's context
        self.show_count()
        card.card.delete()

    def show_count(self) -> None:
        n = len(self.cards)
        self.add_button.set_enabled(n < mp.MAX_WINDOWS)
        self.count_note.set_text(self.lang.gettext("{n} of at most {max} windows").format(n=n, max=mp.MAX_WINDOWS) if n > 1 else "")

    def save(self) -> None:
        """The windows as they are set up now, kept for this browser tab (a reload brings them back)."""
        if not self.restored:
            return
        try:
            app.storage.tab[self.storage_key] = [card.settings() for card in self.cards]
        except RuntimeError:  # no connection (any more): nothing to keep it for
            pass

    async def restore(self) -> None:
        """The tab's windows from before a reload, polling again where they polled; else one new window."""
        with self.container:  # the page's context in this task (the tab storage is the client's)
            try:
                await self.client.connected(timeout=30)
                saved = list(app.storage.tab.get(self.storage_key) or [])
            except (TimeoutError, RuntimeError):
                saved = []
            for settings in saved[:mp.MAX_WINDOWS]:
                self.add(settings if isinstance(settings, dict) else {}, save=False)
            if not self.cards:
                self.add(save=False)
            self.restored = True
            self.save()

    def resume(self) -> None:
        """The same page connected again (a short network outage): the windows that polled poll again."""
        for card in self.cards:
            if card.wanted and not card.window.running:
                card.run(save=False)

    def tick(self) -> None:
        line = self.line
        if line.cycle_s:
            stale = max((s.stale_after for s in self.runtime.store.devices.values() if s.bus == self.bus), default=0)
            lang = self.lang
            self.cycle.set_text(lang.gettext("line cycle {cycle} s · devices stale after {stale} s").format(
                cycle=lang.number(line.cycle_s, 2, group=False), stale=lang.number(stale, 1, group=False)))
        for card in self.cards:
            card.tick()


class WindowCard:
    """One poll window: what to poll (unit, function, addresses, count, period), Poll and Stop, its counts and
    age, and its table of values, changed in place on every poll."""

    def __init__(self, view: PollView, window: mp.ModbusPoll):
        self.view = view
        self.window = window
        self.wanted = False  # polling as the engineer asked (a dropped connection stops it, a reconnect resumes)
        self.shown_polls = -1
        self.shown_columns = None

    def build(self, settings: dict) -> None:
        view, known, n = self.view, self.view.known, self.window.number
        lang = view.lang
        _ = lang.gettext

        def pick(key: str, default, allowed=None):
            value = settings.get(key, default)
            return value if allowed is None or value in allowed else default

        remove_label = _("Remove window")
        with ui.card().classes("w-full").props(f"data-testid=poll-window-{n}") as self.card:
            with ui.row().classes("items-center w-full gap-3"):
                ui.label(_("Window {n}").format(n=n)).classes("text-subtitle1")
                self.summary = ui.label().classes("text-body2 text-grey-8").props("data-testid=poll-summary")
                ui.space()
                ui.button(icon="close", on_click=lambda: view.remove(self)).props(
                    f'flat dense round data-testid=poll-remove aria-label="{remove_label}"').tooltip(_("Remove this window"))
            with ui.row().classes("items-end gap-3 flex-wrap"):
                self.unit = range_number(lang.pgettext("Modbus", "Unit"), 0, 254, integer=True,
                                         value=pick("unit", min(known) if known else 1), lang=lang).classes("w-28")
                self.function = ui.select(shown(mp.FUNCTIONS, lang), value=pick("function", 3, mp.FUNCTIONS),
                                          label=_("Function")).props("dense outlined").classes("w-60")
                self.base = ui.select(shown(BASES, lang), value=pick("base", 0, BASES), label=_("Addresses")).props(
                    "dense outlined").classes("w-64")
                self.start = _address_field(_("Start address"), pick("start", 1000), self.base, lang).classes("w-36")
                self.count = _count_field(pick("count", 10), self.function, lang).classes("w-32")
                self.period = range_number(_("Period s"), mp.PERIOD_MIN_S, mp.PERIOD_MAX_S, unit="s",
                                           value=pick("period", 1.0), step=0.1, lang=lang).classes("w-32")
                self.run_button = ui.button(_("Poll"), icon="play_arrow", on_click=lambda: self.run()).props(
                    "data-testid=poll-start")
                ui.button(_("Stop"), icon="stop", on_click=self.stop).props("flat data-testid=poll-stop")
            with ui.row().classes("w-full items-start no-wrap"):
                with ui.column().classes("col gap-1"):
                    self.status = ui.label(_("stopped")).props("data-testid=poll-status")
                    self.error = ui.label().classes("text-negative").props("data-testid=poll-error")
                self.wide = ui.select(shown(WIDE_CHOICES, lang), value=pick("wide", "all", WIDE_CHOICES), label=_("32-bit values"),
                                      on_change=self.changed).props("dense outlined data-testid=poll-wide").classes("w-56")
                self.orders = ui.select(shown(ORDER_CHOICES, lang), value=pick("orders", "words", ORDER_CHOICES),
                                        label=_("Word orders"),
                                        on_change=self.changed).props("dense outlined data-testid=poll-orders").classes("w-56")
            self.hint = ui.label(_("Set unit, function, start and count, then Poll.")).classes("text-grey-7")
            # one table, its rows and columns changed in place on every poll (not a new table each time)
            self.grid = ui.table(columns=_columns(0, 3, lang), rows=[], row_key="address").props(
                "dense flat bordered data-testid=poll-table").classes("w-full reg-table")
            self.pairs = ui.label(_("32-bit columns: the register with the next one; ABCD = high word first, CDAB = low "
                                    "word first, BADC and DCBA the same with each word's bytes swapped.")).classes(
                "text-caption text-grey-7")
        for field in (self.unit, self.function, self.start, self.count, self.period):
            field.on_value_change(lambda _: view.save())
        self.window.listeners.append(self.tick)  # each answer on the page as it comes; the page's timer moves the ages
        self.base.on_value_change(self.changed)
        self.error.set_visibility(False)
        self.update_table()
        self.show_status()

    def settings(self) -> dict:
        """What the window is set to, as the tab keeps it over a reload."""
        return {"unit": self.unit.value, "function": self.function.value, "base": self.base.value,
                "start": self.start.value, "count": self.count.value, "period": self.period.value,
                "wide": self.wide.value, "orders": self.orders.value, "running": self.wanted}

    def changed(self, *_args) -> None:
        self.update_table()
        self.view.save()

    def current_spec(self) -> mp.PollSpec:
        shown_start = int(self.start.value or 0)
        protocol = shown_start - int(self.base.value or 0)
        return mp.PollSpec(int(self.unit.value or 0), int(self.function.value), protocol, int(self.count.value or 1),
                           float(self.period.value or 1.0)).check()

    def run(self, save: bool = True) -> None:
        if not all_valid(self.unit, self.start, self.count, self.period):  # each field says what it allows
            return
        try:
            self.window.start(self.current_spec())
        except mp.PollError as exc:
            notify_error(self.view.lang.gettext("window {n}: {error}").format(n=self.window.number, error=said(exc, self.view.lang)))
            return
        self.wanted = True
        self.shown_polls = -1
        self.show_status()
        if save:
            self.view.save()

    def stop(self) -> None:
        self.window.stop()
        self.wanted = False
        self.show_status()
        self.view.save()

    def show_status(self) -> None:
        window = self.window
        spec, last = window.spec, window.last
        lang = self.view.lang
        _ = lang.gettext
        self.summary.set_text("" if spec is None else _("unit {unit} · {function} · {first}+{count} · every {period} s").format(
            unit=spec.unit, function=_(mp.FUNCTIONS[spec.function]), first=spec.address + int(self.base.value or 0),
            count=spec.count, period=lang.numbers_in(f"{spec.period_s:g}")))
        parts = [_("polling") if window.running else _("stopped")]
        if spec is not None:
            parts.append(_("{polls} polls").format(polls=window.polls) + " · "
                         + (_("{errors} errors ({timeouts} timeouts, {crc} CRC)") if window.crc_errors else
                            _("{errors} errors ({timeouts} timeouts)")).format(
                             errors=window.errors, timeouts=window.timeouts, crc=window.crc_errors))
            if window.last_answer is not None:
                parts.append(_("updated {age}").format(age=fmt_age(time.time() - window.last_answer, lang)))
            elif window.polls:
                parts.append(_("no answer yet"))
        if last is not None and last.rtt_ms is not None and not last.error:
            parts.append(f"{lang.numbers_in(str(last.rtt_ms))} ms")
        if window.running and window.silent > 1:
            parts.append(_("no answer {n} times in a row: tries every {interval} s").format(
                n=window.silent, interval=lang.number(window.interval_s(spec), 1, group=False)))
        self.status.set_text(" · ".join(parts))
        error = said(last.error, lang) if last is not None else ""  # the line's diagnosis (app/modbus_line.py)
        self.error.set_text(error)
        self.error.set_visibility(bool(error))

    def update_table(self) -> None:
        window, grid = self.window, self.grid
        spec = window.spec
        self.hint.set_visibility(spec is None)
        grid.set_visibility(spec is not None)
        self.pairs.set_visibility(spec is not None and spec.function not in (1, 2) and self.wide.value != "none")
        if spec is None:
            return
        offset = int(self.base.value or 0)
        rows = []
        for r in window.rows():
            row = {"address": r.address + offset, "name": r.name, **{c: "" for c in (*mp.FORMATS, *PAIR_COLUMNS)}}
            row.update(r.cells)
            rows.append(row)
        columns = _columns(offset, spec.function, self.view.lang, self.wide.value, self.orders.value)
        if columns != self.shown_columns:
            grid.columns = self.shown_columns = columns
        elif rows == grid.rows:
            return
        grid.rows = rows
        grid.update()

    def tick(self) -> None:
        window = self.window
        if window.polls != self.shown_polls:
            self.shown_polls = window.polls
            self.update_table()
        self.show_status()  # the age moves on between polls; an unchanged text is not sent again


class WriteCard:
    """Writes of holding registers or coils (engineer only), through the send policy, confirmed when it asks."""

    def __init__(self, view: PollView):
        self.view = view

    def build(self) -> None:
        view = self.view
        known = view.known
        lang = view.lang
        _ = lang.gettext
        with ui.card().classes("w-full"):
            ui.label(_("Write holding registers or coils")).classes("text-subtitle1")
            if view.role != "engineer":
                ui.label(_("Writes are for engineers (this session may read only).")).classes("text-grey-7").props(
                    "data-testid=poll-write-note")
                return
            with ui.row().classes("items-end gap-3 flex-wrap"):
                self.w_base = base = ui.select(shown(BASES, lang), value=0, label=_("Addresses")).props(
                    "dense outlined data-testid=poll-write-base").classes("w-64")
                self.w_unit = range_number(lang.pgettext("Modbus", "Unit"), 1, 254, integer=True, value=min(known) if known else 1,
                                           lang=lang).classes("w-28")
                self.w_kind = ui.select({"register": _("holding register(s), 06/16"), "coil": _("coil(s), 05/15")},
                                        value="register", label=_("Write")).props(
                    "dense outlined data-testid=poll-write-kind").classes("w-56")
                self.w_address = _address_field(_("Address"), 3000, base, lang).classes("w-32")
                self.w_values = ui.input(_("Value(s)"), value="200", placeholder=_("e.g. 200 or 1, 2, -30 (coils: 1 0 1)")).props(
                    "dense outlined").classes("w-56")
                self.w_multi = ui.checkbox(_("function 16 (multiple)"))
                self.w_multi.bind_visibility_from(self.w_kind, "value", value="register")
                w_button = ui.button(_("Write"), icon="edit")
            ui.label(_("Every write goes through the send policy of the unit's device type "
                       "(by the line's type for a unit not in the plant): a known device's register asks for a "
                       "confirmation; its read-only, MFR and never-written registers, and coils of a device without "
                       "coils, are refused.")).classes("text-caption text-grey-7")
        w_button.on_click(lambda: self.write())

    def _values(self) -> list[int] | None:
        """The entered values, or None (said in a notification) when they are not whole numbers for the kind."""
        text = self.w_values.value
        _ = self.view.lang.gettext
        try:
            values = [int(v, 0) for v in str(text or "").replace(",", " ").split()]
        except ValueError:
            notify_error(_("'{text}' is not a list of whole numbers").format(text=text))
            return None
        if not values:
            notify_error(_("enter at least one value"))
            return None
        if self.w_kind.value == "coil" and any(v not in (0, 1) for v in values):
            notify_error(_("'{text}': a coil is 0 or 1").format(text=text))
            return None
        return values

    def _ask(self, question: str) -> None:
        _ = self.view.lang.gettext
        with ui.dialog() as dialog, ui.card().classes("w-[32rem]"):
            ui.label(question).classes("text-body1")
            with ui.row().classes("justify-end w-full"):
                ui.button(_("Cancel"), on_click=dialog.close).props("flat")

                async def go() -> None:
                    dialog.close()
                    await self.write(confirmed=True)

                ui.button(_("Write"), color="warning", on_click=go).props("data-testid=poll-confirm")
        dialog.open()

    async def write(self, confirmed: bool = False) -> None:
        view = self.view
        bus, poll = view.bus, view.windows.writer
        target = await checked_value(self.w_unit, "", f"Modbus poll write on {bus}", parameter="unit")
        where = await checked_value(self.w_address, "", f"Modbus poll write on {bus}", parameter="address")
        if target is None or where is None:
            return  # the field says what it allows; the refusal is in the audit log
        values = self._values()
        if values is None:
            return
        coils = self.w_kind.value == "coil"
        address = int(self.w_address.value or 0) - int(self.w_base.value or 0)
        user, role = current_user()  # the account store's answer now, not the page's when it was built
        try:
            if coils:
                await poll.write_coils(int(self.w_unit.value or 0), address, [bool(v) for v in values],
                                       user=user or "anonymous", role=role, confirmed=confirmed)
            else:
                await poll.write(int(self.w_unit.value or 0), address, values, user=user or "anonymous", role=role,
                                 confirmed=confirmed, multiple=bool(self.w_multi.value) or len(values) > 1)
        except mp.NeedsConfirmation as exc:
            self._ask(said(exc, view.lang))
            return
        except (mp.PollError, PermissionDenied, AuditUnavailable) as exc:
            notify_error(said(exc, view.lang))
            return
        except ACTION_ERRORS as exc:  # the line's error, shown
            notify_error(view.lang.gettext("write failed: {error}").format(error=said(exc, view.lang)))
            return
        ui.notify(view.lang.gettext("written"), type="positive")


def _view(runtime, bus: str, lang: Lang) -> None:
    view = PollView(runtime, bus, lang)
    client = ui.context.client
    client.on_disconnect(view.windows.stop)
    client.on_connect(view.resume)
    view.build()
    WriteCard(view).build()
    ui.timer(REFRESH_S, view.tick)
    background_tasks.create(view.restore(), name=f"modbus poll windows {bus}")


def _following_field(label: str, value: int, follows, limits: Callable[[], tuple[int, int]], lang: Lang,
                     rule: Callable[[int, int], str] | None = None) -> ui.number:
    """A whole-number entry whose range depends on another field, ``follows``: ``limits()`` is the range now, shown
    as the entry's hint and checked in the field; a wrong entry stays as typed, marked with ``rule(low, high)`` (by
    default the range in words), all in ``lang``."""
    _ = lang.gettext

    def check(v) -> str | None:
        if v is None:
            return None
        low, high = limits()
        text = rule(low, high) if rule is not None else range_text(low, high, lang=lang)
        if float(v) != int(float(v)):
            return _("whole numbers only, {rule}").format(rule=text)
        return None if low <= float(v) <= high else _("out of range: {rule}").format(rule=text)

    field = ui.number(label, value=value, validation=check).props("dense outlined")

    def show_range() -> None:
        field.rule = range_text(*limits(), lang=lang)  # type: ignore[attr-defined]
        field.props(f'hint="{field.rule}"')
        if field.value is not None:
            field.validate()

    show_range()
    follows.on_value_change(lambda _: show_range())
    return field


def _count_field(value: int, function, lang: Lang) -> ui.number:
    """The count entry, its range that of the chosen function (01/02: 1 .. 2000 bits, 03/04: 1 .. 125
    registers, :func:`app.modbus_poll.count_range`), checked in the field before Poll sends anything."""

    def rule(low: int, high: int) -> str:
        return lang.gettext("{range} for function {function}").format(range=range_text(low, high, lang=lang),
                                                                      function=f"{int(function.value or 3):02d}")

    return _following_field(lang.gettext("Count"), value, function, lambda: mp.count_range(int(function.value or 3)), lang, rule)


def _address_field(label: str, value: int, base, lang: Lang) -> ui.number:
    """An address entry whose range follows how addresses are counted: 0 .. 65535 (0-based) or 1 .. 65536
    (1-based, register 1 = address 0); a wrong entry stays as typed, marked with the range."""

    def limits() -> tuple[int, int]:
        first = int(base.value or 0)
        return first, mp.ADDRESS_MAX + first

    return _following_field(label, value, base, limits, lang)
