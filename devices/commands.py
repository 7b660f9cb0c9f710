"""Declared commands: what a device type lets pages, the API, the CLI, restore and the bus tools do.

A device type declares its commands in ``devices/<type>/policy.py`` as ``COMMANDS``, a tuple of
:class:`Command`. The worker's gate (:mod:`app.gate`) takes everything it decides on from the
declaration - never from the caller: the kind (who may run it, whether it is audited first or
after), the ranges of its arguments, the risk to confirm, whether the session must control the
device. Callers name the command and give the arguments.

Kinds: ``read`` (any role, not audited), ``stop`` (any role, never refused, sent first and audited
after), ``write``, ``motion``, ``mains``, ``system`` (engineers only, audited before anything is sent).

A command is bound to code, not to a method name: it names the function of the adapter class that runs
it (``run=ElectrakAdapter.jog``), or one per adapter class where a type has several (the HD-Lock's Modbus
and CAN adapters). A bus kind whose adapter class defines none of them does not offer the command
(:func:`commands_of` with ``bus_type``); tests/devices/test_command_contract.py walks every declaration.

Pure: no I/O; imported by the gate and by tests.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from devices.errors import DeviceError
from devices.message import message_of
from devices.params import Accepted

KINDS = ("read", "stop", "write", "motion", "mains", "system")
OPEN_KINDS = frozenset({"read", "stop"})  # what every role may run


class CommandError(DeviceError, ValueError):
    """An argument out of its declared range, or a command the device type does not declare."""


@dataclass(frozen=True)
class Arg:
    """One argument of a command, with its range (whole numbers unless ``integer`` is False)."""

    name: str
    low: float
    high: float
    integer: bool = True
    unit: str = ""
    sent: bool = True  # handed to the declared function (see ParamArg)

    def check(self, value: Any) -> int | float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise CommandError(f"{self.name}: {value!r} is not a number")
        if self.integer and float(value) != int(value):
            raise CommandError(f"{self.name}: {value:g} is not a whole number")
        if not self.low <= value <= self.high:
            raise CommandError(f"{self.name}: {value:g} is outside {self.low:g} .. {self.high:g} {self.unit}".rstrip())
        return int(value) if self.integer else float(value)


@dataclass(frozen=True)
class ParamArg:
    """An argument naming a writable parameter of the device type's model (by key, name or the
    :class:`~devices.params.Param` itself); it becomes the parameter. Not handed to the declared function:
    the value the model accepted for it (:class:`~devices.params.Accepted`) names it."""

    name: str
    params: Any  # the type's ParamMap
    sent: bool = False

    def check(self, value: Any) -> Any:
        model = self.params
        if any(value is p for p in model.params):
            param = value
        elif isinstance(value, str):
            param = model.by_key.get(value) or model.by_name.get(value)
        else:
            param = None
        if param is None:
            raise CommandError(f"{self.name}: {value!r} is not a parameter of this device type")
        if not param.writable or param.never_write:
            raise CommandError(f"{param.label or param.name} is {param.access.value}: not writable")
        return param


@dataclass(frozen=True)
class ValueArg:
    """A value checked by the parameter model for a :class:`ParamArg` of the same command (a number, an enum
    name, or what the model accepted already: an :class:`~devices.params.Accepted`, carried as it is)."""

    name: str
    sent: bool = True

    def check(self, value: Any) -> Any:
        if isinstance(value, Accepted):
            return value
        if isinstance(value, bool) or not isinstance(value, int | float | str):
            raise CommandError(f"{self.name}: {value!r} is not a value")
        return value


Risk = str | Callable[[Mapping[str, Any]], str]


@dataclass(frozen=True)
class Command:
    """A declared command.

    :param name: what callers invoke it by (also the audit's action)
    :param kind: one of :data:`KINDS`
    :param run: the function of the adapter class that runs it, ``run(adapter, session?, *args, **options)``
        (e.g. ``ElectrakAdapter.jog``), or a tuple of them, one per adapter class of the type; none for a
        command declared only for its kind (a wording the worker's own callers run with a callable of theirs)
    :param args: the arguments, in the method's order, with their ranges
    :param flags: further keyword arguments the caller may give (true/false), e.g. ``broadcast``
    :param risk: the confirmation text (or a function of the arguments giving it, "" for none)
    :param needs_control: the session must control the device (its adapter's ``holders()``)
    :param session: the method takes the browser session as its first argument
    :param prefix: the command also answers to names that start with ``name`` (an older caller's wording)
    :param refuse_if: ``(args, bus_devices, device) -> reason`` from the device type's send policy
        (e.g. an ID another participant of the bus uses); "" lets it run
    :param extras: further keyword arguments passed through unchecked: context the method reports with
        (e.g. the locks known on a line), never what is sent
    :param prepare: ``args -> args`` after each argument's own check: checks across arguments (a value
        against its parameter), raising :class:`CommandError`
    :param confirmation: the method takes ``confirmed=`` (True when the declared risk was confirmed)
    :param audit: ``(args, adapter) -> {action, parameter, old, new}`` for the audit row (old read before
        the command runs); the command's name and its arguments where not given
    """

    name: str
    kind: str
    run: Callable[..., Any] | tuple[Callable[..., Any], ...] = ()
    args: tuple[Arg, ...] = ()
    flags: tuple[str, ...] = ()
    risk: Risk = ""
    needs_control: bool = False
    session: bool = False
    prefix: bool = False
    refuse_if: Callable[[Mapping[str, Any], Any, str], str] | None = None
    extras: tuple[str, ...] = ()
    prepare: Callable[[dict[str, Any]], dict[str, Any]] | None = None
    confirmation: bool = False
    audit: Callable[[Mapping[str, Any], Any], Mapping[str, Any]] | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"{self.name}: kind {self.kind!r} is not one of {', '.join(KINDS)}")

    @property
    def open(self) -> bool:
        """Every role may run it (reads and stops)."""
        return self.kind in OPEN_KINDS

    def checked_args(self, values: Mapping[str, Any]) -> dict[str, Any]:
        """The arguments checked against their ranges (:raises CommandError: missing, unknown or out of range)."""
        known = {a.name for a in self.args} | set(self.flags) | set(self.extras)
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
        for extra in self.extras:
            if extra in values:
                out[extra] = values[extra]
        return self.prepare(out) if self.prepare is not None else out

    def risk_text(self, values: Mapping[str, Any]) -> str:
        return self.risk(values) if callable(self.risk) else self.risk

    @property
    def sent_args(self) -> tuple[Any, ...]:
        """The arguments handed to the declared function, in its order (a :class:`ParamArg` is not: the value
        the model accepted for it names the parameter)."""
        return tuple(a for a in self.args if a.sent)

    @property
    def functions(self) -> tuple[Callable[..., Any], ...]:
        """The declared functions, one per adapter class that serves the command."""
        return self.run if isinstance(self.run, tuple) else (self.run,)

    def function_for(self, adapter_class: type) -> Callable[..., Any] | None:
        """The declared function an adapter of ``adapter_class`` runs this command with: the one a class in
        its method resolution order defines; None where the adapter class serves the command with none."""
        for function in self.functions:
            if any(vars(owner).get(function.__name__) is function for owner in adapter_class.__mro__):
                return function
        return None

    def bound(self, adapter: Any) -> Callable[..., Any] | None:
        """The adapter's own binding of the declared function (its class's override, or what was put in its
        place on the adapter), or None where the adapter's class serves this command with none."""
        function = self.function_for(type(adapter))
        return None if function is None else getattr(adapter, function.__name__)

    def call(self, adapter: Any, session: str, values: Mapping[str, Any], confirmed: bool = False):
        """Run the declared function of the adapter's class (returns its awaitable or result).

        :raises CommandError: the adapter's class serves this command with no function (its bus kind does
            not offer it)
        """
        method = self.bound(adapter)
        if method is None:
            raise CommandError(f"{self.name} is not a command of a {type(adapter).__name__}")
        positional = [session] if self.session else []
        positional += [values[a.name] for a in self.sent_args]
        options = {f: values[f] for f in (*self.flags, *self.extras) if f in values}
        if self.confirmation:
            options["confirmed"] = confirmed
        return method(*positional, **options)


# -- frames the transmit list builds by name (declared as ``transmit_forms(options)`` in policy.py) ------------


@dataclass(frozen=True)
class TxField:
    """One entry of a :class:`TxForm`: ``number`` (whole, ``low`` .. ``high``), ``choice`` (of ``choices``,
    value -> text) or ``flag`` (a tick box)."""

    name: str
    kind: str = "number"
    low: int = 0
    high: int = 0xFFFF
    default: Any = None
    choices: Mapping[Any, str] | None = None


@dataclass(frozen=True)
class TxForm:
    """A device frame the transmit list builds by name: ``build(device, options, values)`` returns
    ``(can_id, extended, data, label)`` and raises ``ValueError`` (a codec error) for values it cannot send."""

    title: str
    fields: tuple[TxField, ...]
    build: Callable[[str, Mapping[str, Any], Mapping[str, Any]], tuple[int, bool, bytes, str]]


def transmit_forms(type_name: str, options: Mapping[str, Any]) -> list[TxForm]:
    """The frames a device of ``type_name`` with ``options`` offers to build by name (none when it declares none)."""
    from devices.sendpolicy import policy_of

    policy = policy_of(type_name)
    forms = policy.transmit_forms if policy is not None else None
    return list(forms(options)) if forms is not None else []


WRITE_PARAMETER = "write parameter"


def param_write(params: Any, run: Callable[..., Any] | tuple[Callable[..., Any], ...],
                verdict: Callable[[Accepted], tuple[str, str]] | None = None, session: bool = False) -> Command:
    """The declared write of one parameter of ``params`` (the page's entry, the API, restore).

    The entry is checked once, by the parameter model (:meth:`~devices.params.Param.accept`: type, range,
    access, the confirmation it needs), unless the caller hands what the model accepted already; the result
    (an :class:`~devices.params.Accepted`) is the ``value`` the send policy judges and the adapter writes.
    ``verdict(accepted) -> (refused, risk)`` is the type's send policy for that write (default: the parameter's
    own confirmation). ``run`` is the adapter class's ``write_accepted(accepted, confirmed=)``
    (``write_accepted(session, accepted, confirmed=)`` with ``session``)."""

    def judged(values: Mapping[str, Any]) -> tuple[str, str]:
        accepted = values["value"]
        return verdict(accepted) if verdict is not None else ("", accepted.risk)

    def prepare(values: dict[str, Any]) -> dict[str, Any]:
        param, value = values["param"], values["value"]
        if isinstance(value, Accepted):
            if value.param is not param:
                raise CommandError(f"{param.label or param.name}: the value was accepted for {value.param.name}")
            return values
        try:
            return {**values, "value": param.accept(value)}
        except ValueError as exc:  # ParamError, or a codec's refusal of text it cannot read
            raise CommandError(message_of(exc)) from None

    def audit(values: Mapping[str, Any], adapter: Any) -> dict[str, Any]:
        accepted = values["value"]
        param = accepted.param
        before = adapter.state.raw(param)
        return {"action": f"write {param.name}", "parameter": param.label or param.name,
                "old": "" if before is None else param.display(before), "new": accepted.text}

    return Command(WRITE_PARAMETER, "write", run=run, args=(ParamArg("param", params), ValueArg("value")),
                   session=session, prepare=prepare, confirmation=True, audit=audit,
                   risk=lambda values: judged(values)[1], refuse_if=lambda values, bus, device: judged(values)[0])


def commands_of(type_name: str, bus_type: str = "") -> dict[str, Command]:
    """The declared commands of a device type, by name (none when its package declares none); with
    ``bus_type``, only those the type's adapter for that bus kind serves (and those declared for their kind only)."""
    from devices.registry import DEVICE_TYPES
    from devices.sendpolicy import policy_of

    policy = policy_of(type_name)
    declared: tuple[Command, ...] = policy.COMMANDS if policy is not None else ()
    if bus_type:
        adapter_class = DEVICE_TYPES[type_name].adapter_class(bus_type)
        declared = tuple(c for c in declared if not c.functions or c.function_for(adapter_class) is not None)
    return {c.name: c for c in declared}


READ_PARAMETERS = "read parameters"


def read_parameters(run: Callable[..., Any] | tuple[Callable[..., Any], ...]) -> Command:
    """What every device type declares whose adapter reads its parameter set (backup, records, batch copies):
    ``run`` is the adapter class's ``backup_read``."""
    return Command(READ_PARAMETERS, "read", run=run)


def find(type_name: str, name: str, bus_type: str = "") -> Command | None:
    """The command called ``name`` (or one declared with ``prefix`` whose name starts it); with ``bus_type``,
    only one the type's adapter for that bus kind serves."""
    declared = commands_of(type_name, bus_type)
    if name in declared:
        return declared[name]
    return next((c for c in declared.values() if c.prefix and name.startswith(c.name)), None)
