"""The card every device page is made of, and the one way a card skips a refresh that would draw the same.

A card has ``build()`` (in the page's layout) and ``refresh()`` (on every change the store pushes, on the
store's once-a-second round of the device, and on a refresh of the page's own). :meth:`DeviceCard.unchanged`
tells it whether it may skip this refresh; a :class:`DrawnCard` asks it for itself and draws with ``draw()``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from nicegui import ui

from pages.command_client import WriteGuard

if TYPE_CHECKING:
    from app.state import DeviceState
    from pages.device_page import DeviceView


class DeviceCard:
    """One part of a device page."""

    _drawn: object = None  # the inputs the card last drew (see :meth:`unchanged`)
    _ages: object = None  # and what its ages were drawn from
    aging = False  # the card shows a value stale or offline: its mark and age move without a new value

    def __init__(self, view: DeviceView):
        self.view = view

    def unchanged(self, inputs: object, ages: Callable[[], object] | None = None) -> bool:
        """Whether the card may skip this refresh: ``inputs`` (what its values are drawn from, e.g.
        :meth:`DeviceView.inputs`; the device's online state is added here) are what it last drew, no age is due
        (:meth:`ages_due`) and nothing it shows is stale or offline (:attr:`aging`). Otherwise the inputs
        are noted as drawn and the card draws. A card whose read times or counters alone moved does nothing.

        ``ages()``: what the card's time-dependent marks are drawn from (the qualities of its values,
        :meth:`DeviceView.qualities`; an age it shows in words): when ages are due and they are what the card
        last drew, the once-a-second round skips it as well. Without it the round always draws."""
        inputs = (self.view.state.online, inputs)
        if inputs == self._drawn and not self.aging:
            if not self.ages_due():
                return True
            if ages is not None:
                now = ages()
                if now == self._ages:
                    return True
                self._ages = now
                return False
        self._drawn = inputs
        self._ages = None if ages is None else ages()
        return False

    def ages_due(self) -> bool:
        """Whether this refresh draws what time alone changes: :attr:`DeviceView.ages_due`."""
        return self.view.ages_due

    @property
    def guard(self) -> WriteGuard:
        """The page's write guard: controls added to it are off, with the reason, while they may not be used."""
        return self.view.guard

    def build(self) -> None:
        raise NotImplementedError

    def refresh(self) -> None:
        """Show what the store holds now (a card that follows the store itself has nothing to do)."""


def point_values(state: DeviceState, names) -> tuple:
    """What the named points of ``state`` show, not when they were heard: (value, raw, text) of each, None for one
    not published. A card compares it with what it drew last: a telegram or poll with the same values draws
    nothing. What it then draws it reads as :class:`app.state.LiveValue` (``view.live()``, ``view.fact()``)."""
    return tuple([None if p is None else (p.value, p.raw, p.text) for p in map(state.points.get, names)])


class DrawnCard(DeviceCard):
    """A card drawn by ``draw()`` only when what it shows changed (``inputs()``, see :meth:`DeviceCard.unchanged`);
    ``draw()`` returns False when it showed a value as stale or offline (it is then drawn again with the next
    push, which may bring the value back). ``context``: what the page passes to every card's refresh (the SCU
    page: what the user may do).

    By default what it shows is the page's ``context``, the device's status, the page's write guard and its
    :attr:`POINTS`."""

    POINTS: tuple[str, ...] = ()

    def inputs(self, *context) -> object:
        view = self.view
        return (context, view.state.status, view.guard.reason if view.guard is not None else "",
                point_values(view.state, self.POINTS))

    def ages_due(self) -> bool:
        """Only on the store's once-a-second round: a refresh of the page's own draws what changed."""
        return self.view.store.age_round

    def draw(self, *context) -> bool | None:
        raise NotImplementedError

    def refresh(self, *context) -> None:
        if self.unchanged(self.inputs(*context)):
            return
        self.aging = self.draw(*context) is False


@contextmanager
def titled_card(title: str, classes: str = "w-full") -> Iterator[ui.card]:
    """A card with its title on top."""
    with ui.card().classes(classes) as card:
        ui.label(title).classes("text-subtitle1")
        yield card


__all__ = ["DeviceCard", "DrawnCard", "point_values", "titled_card"]
