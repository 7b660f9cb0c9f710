"""What app/ reads of a device adapter beyond the Protocols of devices/adapter.py, each with the value that
holds for an adapter that does not declare it.

The worker's readers (the OPC UA face, the bus monitor) ask these instead of probing attribute names:
a capability is a ``runtime_checkable`` Protocol, and the helper next to it returns the declared
default for an adapter without it.
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
