"""Every declared command of every device type runs on code its bus kind's adapter has.

A command names the function of the adapter class that runs it (devices/commands.py). For each bus
kind of each type, every command the type offers on it resolves to a function of that kind's adapter
class whose parameters take what the gate passes (the session first where declared, the arguments in
their order, the flags, extras and ``confirmed=`` by keyword); a command no adapter of the type serves
is a declaration error; a command one bus kind cannot serve is not offered there.
"""

from __future__ import annotations

import inspect

import pytest

from devices.commands import READ_PARAMETERS, Command, CommandError, commands_of, find
from devices.registry import DEVICE_TYPES
from devices.sendpolicy import policy_of

WALKED = [(type_name, bus_type) for type_name, device_type in sorted(DEVICE_TYPES.items())
          for bus_type in device_type.bus_types]


def _call_shape(command: Command) -> tuple[list[object], dict[str, object]]:
    """What :meth:`Command.call` passes after the adapter: placeholders in the declared order."""
    positional: list[object] = ["session"] if command.session else []
    positional += [arg.name for arg in command.sent_args]
    options: dict[str, object] = {name: name for name in (*command.flags, *command.extras)}
    if command.confirmation:
        options["confirmed"] = True
    return positional, options


@pytest.mark.parametrize(("type_name", "bus_type"), WALKED)
def test_every_offered_command_resolves_to_a_callable_taking_its_arguments(type_name, bus_type):
    adapter_class = DEVICE_TYPES[type_name].adapter_class(bus_type)
    offered = commands_of(type_name, bus_type)
    assert offered, f"{type_name} on {bus_type} offers no command"
    for command in offered.values():
        if not command.functions:
            continue  # declared for its kind only (a wording the worker's own callers run)
        function = command.function_for(adapter_class)
        assert callable(function), command.name
        positional, options = _call_shape(command)
        try:
            inspect.signature(function).bind("adapter", *positional, **options)
        except TypeError as exc:
            pytest.fail(f"{type_name} {bus_type}: {command.name!r} -> {adapter_class.__name__}.{function.__name__}: {exc}")


@pytest.mark.parametrize("type_name", sorted(DEVICE_TYPES))
def test_every_declared_command_is_served_on_some_bus_kind_and_reads_its_parameters(type_name):
    device_type = DEVICE_TYPES[type_name]
    declared = commands_of(type_name)
    served = set().union(*(commands_of(type_name, bus) for bus in device_type.bus_types))
    assert set(declared) == served, set(declared) - served
    for bus_type in device_type.bus_types:
        assert READ_PARAMETERS in commands_of(type_name, bus_type), bus_type


def test_a_command_an_hdlock_bus_kind_cannot_serve_is_not_offered_there():
    modbus, can = commands_of("hdlock", "modbus-rtu"), commands_of("hdlock", "can")
    for name in ("cmdSetLockRequestSource", "cmdSetCANbaudrate", "Set Device Address"):
        assert name in can and name not in modbus, name
    for name in ("Broadcast Set Modbus Address (255)", "Set Modbus Address"):
        assert name in modbus and name not in can, name
    assert find("hdlock", "Set Modbus Address 7", "can") is None
    assert find("hdlock", "Set Modbus Address 7", "modbus-rtu") is commands_of("hdlock")["Set Modbus Address"]


def test_running_a_command_on_an_adapter_that_does_not_serve_it_is_refused_before_anything_runs():
    command = commands_of("hdlock")["Set Device Address"]
    modbus_adapter = object.__new__(DEVICE_TYPES["hdlock"].adapter_class("modbus-rtu"))
    with pytest.raises(CommandError, match="not a command"):
        command.call(modbus_adapter, "", {"new_value": 5})


@pytest.mark.parametrize("type_name", sorted(DEVICE_TYPES))
def test_every_policy_declares_its_commands_and_each_send_policy_hook(type_name):
    policy = policy_of(type_name)
    assert policy is not None and isinstance(policy.COMMANDS, tuple)
    for hook in ("check_can", "check_modbus", "transmit_forms"):
        assert hook in vars(policy) and (vars(policy)[hook] is None or callable(vars(policy)[hook])), hook
