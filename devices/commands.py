"""Declared commands: what a device type lets pages, the API, the CLI, restore and the bus tools do.

A device type declares its commands in ``devices/<type>/policy.py`` as ``COMMANDS``, a tuple of
:class:`Command`. The worker's gate (:mod:`app.gate`) takes everything it decides on from the
declaration - never from the caller: the kind (who may run it, whether it is audited first or
after), the ranges of its arguments, the risk to confirm, whether the session must control the
device. Callers name the command and give the arguments.

Kinds: ``read`` (any role, not audited), ``stop`` (any role, never refused, sent first and audited
after), ``write``, ``motion``, ``mains``, ``system`` (engineers only, audited before anything is sent).

Pure: no I/O; imported by the gate and by tests.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

KINDS = ("read", "stop", "write", "motion", "mains", "system")
OPEN_KINDS = frozenset({"read", "stop"})  # what every role may run


class CommandError(ValueError):
    """An argument out of its declared range, or a command the device type does not declare."""


@dataclass(frozen=True)
class Arg:
    """One argument of a command, with its range (whole numbers unless ``integer`` is False)."""

    name: str
    low: float
    high: float
    integer: bool = True
    unit: str = ""

    def check(self, value: Any) -> int | float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise CommandError(f"{self.name}: {value!r} is not a number")
        if self.integer and float(value) != int(value):
            raise CommandError(f"{self.name}: {value:g} is not a whole number")
        if not self.low <= value <= self.high:
            raise CommandError(f"{self.name}: {value:g} is outside {self.low:g} .. {self.high:g} {self.unit}".rstrip())
        return int(value) if self.integer else float(value)


Risk = str | Callable[[Mapping[str, Any]], str]


@dataclass(frozen=True)
class Command:
    """A declared command.

    :param name: what callers invoke it by (also the audit's action)
    :param kind: one of :data:`KINDS`
    :param method: the adapter method that runs it: ``method(session?, *args, **options)``
    :param args: the arguments, in the method's order, with their ranges
    :param flags: further keyword arguments the caller may give (true/false), e.g. ``broadcast``
    :param risk: the confirmation text (or a function of the arguments giving it, "" for none)
    :param needs_control: the session must control the device (its adapter's ``holders()``)
    :param session: the method takes the browser session as its first argument
    :param prefix: the command also answers to names that start with ``name`` (an older caller's wording)
    :param refuse_if: ``(args, bus_devices, device) -> reason`` from the device type's send policy
        (e.g. an ID another participant of the bus uses); "" lets it run
    """

    name: str
    kind: str
    method: str = ""
    args: tuple[Arg, ...] = ()
    flags: tuple[str, ...] = ()
    risk: Risk = ""
    needs_control: bool = False
    session: bool = False
    prefix: bool = False
    refuse_if: Callable[[Mapping[str, Any], Any, str], str] | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"{self.name}: kind {self.kind!r} is not one of {', '.join(KINDS)}")

    @property
    def open(self) -> bool:
        """Every role may run it (reads and stops)."""
        return self.kind in OPEN_KINDS

    def checked_args(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """The arguments checked against their ranges (:raises CommandError: missing, unknown or out of range)."""
        known = {a.name for a in self.args} | set(self.flags)
        unknown = set(values) - known
        if unknown:
            raise CommandError(f"{self.name} has no argument {', '.join(sorted(unknown))}")
        out: dict[str, Any] = {}
        for arg in self.args:
            if arg.name not in values:
                raise CommandError(f"{self.name}: {arg.name} is missing")
            out[arg.name] = arg.check(values[arg.name])
        for flag in self.flags:
            if flag in values:
                out[flag] = bool(values[flag])
        return out

    def risk_text(self, values: Mapping[str, Any]) -> str:
        return self.risk(values) if callable(self.risk) else self.risk

    def call(self, adapter: Any, session: str, values: Mapping[str, Any]):
        """Run the adapter method (returns its awaitable or result)."""
        method = getattr(adapter, self.method)
        positional = [session] if self.session else []
        positional += [values[a.name] for a in self.args]
        options = {f: values[f] for f in self.flags if f in values}
        return method(*positional, **options)


def commands_of(type_name: str) -> dict[str, Command]:
    """The declared commands of a device type, by name (none when its package declares none)."""
    from devices.sendpolicy import policy_of

    policy = policy_of(type_name)
    return {c.name: c for c in getattr(policy, "COMMANDS", ())}


def find(type_name: str, name: str) -> Command | None:
    """The command called ``name`` (or one declared with ``prefix`` whose name starts it)."""
    declared = commands_of(type_name)
    if name in declared:
        return declared[name]
    return next((c for c in declared.values() if c.prefix and name.startswith(c.name)), None)
