"""What app/ reads of a device adapter or a parameter beyond the Protocols of devices/adapter.py and the
fields of devices/params.Param, each with the value that holds for one that does not declare it.

The worker's readers (the OPC UA face, the bus monitor) and backup and project ask these instead of probing
attribute names: a capability is a ``runtime_checkable`` Protocol, and the helper next to it returns the
declared default for an object without it.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable


@runtime_checkable
class Controllable(Protocol):
    """One engineer's session at a time controls the device; ``controller`` is its holder (None: nobody)."""

    @property
    def controller(self) -> Any: ...


def controller_of(adapter: object) -> Any:
    """The holder of control of the device (None: nobody, or a device without control)."""
    return adapter.controller if isinstance(adapter, Controllable) else None


@runtime_checkable
class BusAddressed(Protocol):
    """Answers at a bus address it knows now (it follows a change made on the device)."""

    address: int | None


def bus_address(adapter: object) -> int | None:
    """The address the adapter talks to now; None where it names none (the plant file's then holds)."""
    address = adapter.address if isinstance(adapter, BusAddressed) else None
    return address if isinstance(address, int) else None


@runtime_checkable
class TextParam(Protocol):
    """A parameter whose value is text, not a number (an M3IO customer record's hex bytes): a backup or a
    project takes the text itself, and ``allowed_text`` says what it may be."""

    text_value: bool
    allowed_text: str


def takes_text(param: object) -> bool:
    """Whether an entry of ``param`` is text (False: a number, the default of every parameter model)."""
    return isinstance(param, TextParam) and param.text_value


def allowed_text(param: object) -> str:
    """What a text entry of ``param`` may be, in words ("": a number; its range says it)."""
    return param.allowed_text if isinstance(param, TextParam) else ""
