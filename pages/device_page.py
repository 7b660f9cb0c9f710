"""What every device page is made of: a view of one device's live record, small cards with ``build()``
(in the page's layout) and ``refresh()`` (on every change the store pushes; :mod:`pages.cards`), the status
badge and row every page starts with, and the page around the cards (frame, event log, the way out, following
the store).

A device page reads::

    class LampsCard(DeviceCard):
        def build(self) -> None:
            with titled_card("Status"):
                ...

        def refresh(self) -> None:
            if self.unchanged(self.view.inputs(LAMP_POINTS)):
                return  # the same values as drawn, nothing ageing: nothing to do on this push
            ...

    def content(name: str) -> None:
        view = DeviceView(name)
        with device_page(view, f"My device {name}"):
            view.add(LampsCard(view))
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager

from nicegui import ui

from app import i18n
from app import runtime as rt
from app.i18n import Lang
from app.state import DeviceState, LiveValue, session_tag
from pages.frame import frame, set_status_badge
from devices.params import Param
from pages.widgets import counter_line, event_log, follow, stop_bar
from pages.command_client import run_command, WriteGuard


class DeviceView:
    """What every card of one device page shares: the device's live record, the page session (outputs and
    control taken here belong to it), the device's declared commands and the page's language (:attr:`lang`, handed
    to what draws: a store push runs outside the page)."""

    def __init__(self, name: str, lang: Lang | None = None):
        runtime = rt.current()
        self.lang = lang or i18n.page_language()
        self.name = name
        self.runtime = runtime
        self.store = runtime.store
        self.state: DeviceState = runtime.store.devices[name]
        self.session = ui.context.client.id
        self.tag = session_tag(self.session)
        self.cards: list = []  # its cards (pages.cards), refreshed with the page
        self.guard: WriteGuard | None = None  # the page's write and command controls, off with the reason while silent
        self.pushing = False  # while the store's push runs the page's refresh (see :attr:`ages_due`)
        self._keys: dict[str, tuple] = {}  # a register parameter's name -> the (space, address) of its words

    @property
    def ages_due(self) -> bool:
        """Whether this refresh draws ages and what time alone changes (stale marks, "last seen"): on the store's
        once-a-second round of the device, and on a refresh of the page's own (built, after a command, an entry
        changed); not on a push that only brought values (that draws the values that changed)."""
        return not self.pushing or self.store.age_round

    def pushed(self) -> None:
        """The store pushed a change of the device (or its once-a-second round): refresh the cards."""
        self.pushing = True
        try:
            self.refresh()
        finally:
            self.pushing = False

    def inputs(self, names: Iterable[str]) -> tuple:
        """What the values named ``names`` (published points or register parameters, as :meth:`live` finds them)
        are drawn from now, without their read times: a point's value, text and unit, a parameter's register
        words. Equal inputs draw the same values (their qualities and ages aside: see :meth:`DeviceCard.unchanged`).
        O(names), no record built."""
        state = self.state
        points, registers, keys = state.points, state.registers, self._keys
        out = []
        for name in names:
            p = points.get(name)
            if p is not None:
                out.append((p.value, p.text, p.unit))
                continue
            key = keys.get(name)
            if key is None:
                param = state.params.by_name.get(name) if state.params is not None else None
                key = keys[name] = () if param is None else tuple((param.space, a) for a in param.addresses)
            if len(key) == 1:  # one word (most parameters): no tuple of one
                e = registers.get(key[0])
                out.append(None if e is None else e[0])
            else:
                out.append(tuple(None if (e := registers.get(k)) is None else e[0] for k in key))
        return tuple(out)

    def qualities(self, names: Iterable[str]) -> tuple:
        """The qualities of the values named ``names`` now (as :meth:`live` gives them), without a record built:
        what a card's stale and offline marks are drawn from."""
        state = self.state
        points, params, now = state.points, state.params, time.time()
        out = []
        for name in names:
            p = points.get(name)
            if p is not None:
                out.append(state.quality(p.time, p.periodic, now, p.every))
                continue
            param = params.by_name.get(name) if params is not None else None
            out.append(None if param is None or state.raw(param) is None else state.param_quality(param, now))
        return tuple(out)

    def words(self, params: Iterable[Param]) -> tuple:
        """The register words of ``params`` now (None for a word not read yet), without their read times."""
        registers = self.state.registers
        return tuple(None if (e := registers.get((p.space, a))) is None else e[0] for p in params for a in p.addresses)

    def readings(self, params: Iterable[Param]) -> tuple:
        """The register words of ``params`` with their read times, (word, time) each (None for a word not read
        yet): what a card that shows when each value was read is drawn from."""
        registers = self.state.registers
        return tuple([registers.get((p.space, a)) for p in params for a in p.addresses])

    def live(self, point: str) -> LiveValue | None:
        return self.state.live(point)

    def fact(self, point: str, default=None):
        """The value of a point the adapter publishes, ``default`` while there is none."""
        value = self.state.live(point)
        return default if value is None or value.value is None else value.value

    def text(self, point: str, default: str = "-") -> str:
        value = self.state.live(point)
        return default if value is None else value.shown

    def add(self, card):
        """Build ``card`` here in the layout; it is refreshed with the page from now on."""
        card.build()
        self.cards.append(card)
        return card

    def refresh(self) -> None:
        for card in self.cards:
            card.refresh()

    async def act(self, command: str, args: dict | None = None, success: str = "", **options) -> tuple[bool, object]:
        """Invoke a declared command of the device (``devices/<type>/policy.py``) by name: the gate decides on
        its kind and the role and asks its declared risk here (``confirmed``, ``title`` and ``ok``: see
        :func:`pages.widgets.run_command`). What the command changed is shown at once, not at the next push."""
        result = await run_command(self.name, command, args=args, session=self.session, success=success, **options)
        self.refresh()
        return result


class StatusBadge:
    """The device's status (waiting, online, stale, offline) with the age of its last answer."""

    def __init__(self, state: DeviceState, lang: Lang | None = None):
        self.state = state
        self.lang = lang

    def build(self) -> None:
        self.badge = ui.badge((self.lang or i18n.get("en")).gettext("waiting"), color="grey").classes("text-body2")

    def refresh(self) -> None:
        set_status_badge(self.badge, self.state.status, self.state.age, self.lang)


class StatusRow:
    """The first row of a device's main card: the status badge, the card's own labels (built inside
    ``with row.build():``) and the line's counters (``counters(state.counters)``, redrawn once a second; in the
    page's language, as ``lang`` words the badge)."""

    def __init__(self, state: DeviceState, counters: Callable[[object], str], lang: Lang | None = None):
        self.state, self.counters = state, counters
        self.badge = StatusBadge(state, lang)

    @contextmanager
    def build(self) -> Iterator[ui.row]:
        with ui.row().classes("items-center gap-6 w-full") as row:
            self.badge.build()
            yield row
            counter_line(self.state, self.counters)

    def refresh(self) -> None:
        self.badge.refresh()


@contextmanager
def device_page(view: DeviceView, title: str, stop: Callable[[], object] | None = None) -> Iterator[None]:
    """The page around a device's cards: the shared frame, the device's events at its end (state changes,
    faults rising and clearing, offline and back, commands; newest first), ``stop()`` (the way out, a
    :func:`pages.widgets.stop_bar`) below it; then every card is refreshed on every change the store pushes
    (at most 10/s) and once a second for the ages."""
    with frame(title):
        yield
        with ui.expansion(view.lang.gettext("Events"), icon="list", value=True).classes("w-full"):
            event_log(view.state, view.lang)
    if stop is not None:
        stop()
    view.refresh()
    follow(view.state, view.pushed)


@contextmanager
def motion_page(view: DeviceView, title: str, stop_note: str, stop_command: str) -> Iterator[None]:
    """The page of a device that moves something: :func:`device_page` with a large STOP in the way-out bar (it sends
    the declared command ``stop_command``; ``stop_note`` says what it does and who may press it) and the page's
    write guard (:attr:`DeviceView.guard`: write and motion-start controls off, with the reason, while the device
    does not answer), made before the cards."""
    _ = view.lang.gettext

    def stop() -> None:
        stop_bar(stop_note, _("STOP"), "stop_circle", lambda: view.act(stop_command), "stop-bar", "big-stop").classes("text-h6")

    with device_page(view, title, stop=stop):
        view.guard = WriteGuard(view.state, lang=view.lang)
        yield


__all__ = ["DeviceView", "StatusBadge", "StatusRow", "device_page", "motion_page"]
