"""What a device twin lets an engineer do to it in simulation, declared once (``SimControls``).

Each twin (``devices/<type>/sim.py``) returns its controls from ``controls()``: named actions, each
with its parameters (a range for numbers) or as a switch with its current state. One shared widget
(``pages/simcontrols.py``) shows them; every action runs through the worker's gate (engineers only,
audited "simulation: <action>"), so pages never hold a twin or name its attributes. Pure data: no I/O,
no ``app`` or ``pages`` imports.

The names of the actions and their parameters are the audit's words; the twins mark them with :func:`NP_` (context
``simulation``) where they declare them (the SCU's switches in app/device_words.py), and :meth:`SimControls.describe`
says an action as a :class:`~devices.message.Message` whose names a page words in its language ("Sicherung auslösen
Kanal=4", "Starker Magnet ein").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

from devices.message import N_, Message, Word

CONTEXT = "simulation"  # the catalogs' context of a twin's declared words (app/device_words.py, SIM_WORDS)


def NP_(context: str, message: str) -> str:
    """Marks ``message`` for the catalog with its ``context`` where it is defined (``pybabel extract -k NP_:1c,2``): a
    twin's action and parameter names, context ``simulation``; worded where they are shown."""
    return message


NOT_WHOLE = N_("{label}: {value} is not a whole number")
SWITCH_STATES = (NP_("simulation", "on"), NP_("simulation", "off"))  # a switch's state as describe() says it


@dataclass(frozen=True, slots=True)
class SimParam:
    """One parameter of an action: a whole number in ``low .. high`` (shown in hex with ``hex``)."""

    name: str
    label: str
    default: int = 0
    low: int = 0
    high: int = 0xFFFFFFFF
    hex: bool = False
    kind: Literal["int"] = "int"

    def check(self, value: Any) -> int:
        """The value as the action takes it; :class:`ValueError` says why it is refused (a :class:`Message`, the
        parameter by its label as the simulation card shows it)."""
        label = Word(self.label, CONTEXT)
        if isinstance(value, str):
            try:
                value = int(value.strip(), 0)
            except ValueError:
                raise ValueError(Message(NOT_WHOLE, label=label, value=repr(value))) from None
        if isinstance(value, bool) or not isinstance(value, int | float) or float(value) != int(value):
            raise ValueError(Message(NOT_WHOLE, label=label, value=repr(value)))
        if not self.low <= int(value) <= self.high:
            shown = (lambda x: f"0x{x:X}") if self.hex else str
            raise ValueError(Message(N_("{label}: {value} is outside {low} .. {high}"), label=label, value=value,
                                     low=shown(self.low), high=shown(self.high)))
        return int(value)


@dataclass(frozen=True, slots=True)
class SimAction:
    """A named action of a twin. ``state``: a switch, shown with the twin's current state and run with
    ``on=True/False``; else a button that runs with the parameters' values."""

    name: str  # the words of the audit row and of the event ("simulation: <name>")
    label: str
    run: Callable[..., object]
    params: tuple[SimParam, ...] = ()
    icon: str = ""
    state: Callable[[], bool] | None = None
    testid: str = ""

    @property
    def switch(self) -> bool:
        return self.state is not None


@dataclass(frozen=True, slots=True)
class SimControls:
    """The declared simulation interface of one twin."""

    title: str
    actions: tuple[SimAction, ...]
    note: str = ""

    def action(self, name: str) -> SimAction:
        for action in self.actions:
            if action.name == name:
                return action
        raise KeyError(f"no simulation action {name!r} (declared: {', '.join(a.name for a in self.actions)})")

    def arguments(self, name: str, args: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """The checked arguments of action ``name`` (defaults for those not given); ValueError if refused."""
        action, args = self.action(name), dict(args or {})
        if action.switch:
            if set(args) - {"on"} or not isinstance(args.get("on"), bool):
                raise ValueError(Message(N_("{name}: a switch takes on=True or on=False"), name=name))
            return {"on": args["on"]}
        known = {p.name: p for p in action.params}
        unknown = set(args) - set(known)
        if unknown:
            raise ValueError(Message(N_("{name}: no parameter {names}"), name=name, names=", ".join(sorted(unknown))))
        return {p.name: p.check(args.get(p.name, p.default)) for p in action.params}

    def describe(self, name: str, args: Mapping[str, Any] | None = None) -> str:
        """The action in words for the audit row: ``light barrier interrupted on``, ``raise fault flags=0x1``; the names
        of the actions (a switch's with its state ``on``, ``off``) and of their parameters are the twin's words (context
        ``simulation``), worded where they are shown ("Starker Magnet ein"); the audit keeps the English."""
        action, checked = self.action(name), self.arguments(name, args)
        if action.switch:  # "strong magnet on": its name (marked where the twin declares it) and state, worded where shown
            return Message("{action} {state}", action=Word(name, CONTEXT), state=Word("on" if checked["on"] else "off", CONTEXT))
        fields: dict[str, Any] = {"action": Word(name, CONTEXT)}
        for n, p in enumerate(action.params):
            fields[f"p{n}"] = Word(p.name, CONTEXT)
            fields[f"v{n}"] = f"0x{checked[p.name]:X}" if p.hex else str(checked[p.name])
        return Message(" ".join(["{action}", *(f"{{p{n}}}={{v{n}}}" for n in range(len(action.params)))]), **fields)

    def invoke(self, name: str, args: Mapping[str, Any] | None = None) -> object:
        """Run action ``name`` with checked arguments (the caller is the worker's gate)."""
        action, checked = self.action(name), self.arguments(name, args)
        if action.switch:
            return action.run(checked["on"])
        return action.run(**checked)
