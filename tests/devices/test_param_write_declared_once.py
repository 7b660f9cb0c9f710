"""The declared parameter write of every device type checks its value once (issue 44).

What the gate does with a "write parameter" (its arguments, the type's send policy, the risk, the call of the
adapter's function) is walked here without a bus: the parameter model accepts the entry once, and the adapter's
function is handed what it accepted (an :class:`~devices.params.Accepted`), for every bus kind of every type. An
entry the page accepted already is carried as it is: no check at all on the way.
"""

from __future__ import annotations

import pytest

from devices.commands import WRITE_PARAMETER, CommandError, commands_of
from devices.params import Accepted, Param
from devices.registry import DEVICE_TYPES

WALKED = [(type_name, bus_type) for type_name, device_type in sorted(DEVICE_TYPES.items())
          for bus_type in device_type.bus_types]


def _writable(type_name: str) -> Param:
    """A parameter the type's declared write takes, without a value table of its own."""
    command = commands_of(type_name)[WRITE_PARAMETER]
    for param in DEVICE_TYPES[type_name].params:
        if not param.setting or param.enum is not None:
            continue
        values = command.checked_args({"param": param.key, "value": param.limits()[0]})
        if not command.refuse_if(values, [], "dev"):
            return param
    raise AssertionError(f"{type_name}: no writable parameter")


@pytest.fixture
def accepted(monkeypatch) -> list[Param]:
    """The parameters the model accepted an entry for, one per check."""
    checked: list[Param] = []
    real = Param.accept

    def counted(self: Param, value):
        checked.append(self)
        return real(self, value)

    monkeypatch.setattr(Param, "accept", counted)
    return checked


@pytest.mark.parametrize(("type_name", "bus_type"), WALKED)
def test_a_declared_write_checks_its_entry_once_and_hands_the_adapter_what_was_accepted(type_name, bus_type, accepted):
    command = commands_of(type_name, bus_type)[WRITE_PARAMETER]
    param = _writable(type_name)
    accepted.clear()
    values = command.checked_args({"param": param.key, "value": param.limits()[0]})
    assert not command.refuse_if(values, [], "dev")
    command.risk_text(values)
    adapter_class = DEVICE_TYPES[type_name].adapter_class(bus_type)
    adapter = adapter_class.__new__(adapter_class)
    written: list[Accepted] = []
    function = command.function_for(adapter_class)
    setattr(adapter, function.__name__, lambda *args, **options: written.append(args[-1]))
    command.call(adapter, "session", values, confirmed=True)
    assert accepted == [param]
    assert written == [values["value"]] and isinstance(written[0], Accepted) and written[0].param is param

    accepted.clear()
    carried = command.checked_args({"param": param.key, "value": written[0]})  # what a page accepted already
    command.refuse_if(carried, [], "dev")
    command.risk_text(carried)
    assert accepted == [] and carried["value"] is written[0]


def test_a_value_accepted_for_another_parameter_is_refused():
    command = commands_of("hdlock")[WRITE_PARAMETER]
    params = [p for p in DEVICE_TYPES["hdlock"].params if p.setting and p.enum is None][:2]
    other = params[1].accept(params[1].limits()[0])
    with pytest.raises(CommandError, match="accepted for"):
        command.checked_args({"param": params[0].key, "value": other})
