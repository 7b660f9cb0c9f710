"""The plant's devices on their transports, and adoption of a discovered device into the running plant.

Each device gets its live record in the store (its stale threshold from the bus's period and timeout)
and an adapter of its type on its bus's transport (adapters get their transport passed in, never
construct one). A line that tracks its cycle is told the device's address, so the record's stale
threshold follows the line's measured cycle.
"""

from __future__ import annotations

import asyncio
import logging
from typing import Any

from app.i18n import N_
from app.message import Message
from app.modbus_line import ModbusLine
from app.plant import DeviceConfig, Plant, can_id_conflict
from app.state import DeviceState, StateStore
from app.worker.discovery import CanDiscovery
from app.worker.transports import Transports
from devices.adapter import ShutdownAdapter
from devices.registry import DEVICE_TYPES

log = logging.getLogger(__name__)

SHUTDOWN_S = 5.0  # the adapters' last words on their lines, all together, at most this long


class Devices:
    """Device name -> adapter (:attr:`adapters`), each with its record in the store."""

    def __init__(self, plant: Plant, store: StateStore, transports: Transports):
        self.plant = plant
        self.store = store
        self.transports = transports
        self.adapters: dict[str, Any] = {}
        for dev in plant.devices.values():
            self.add(dev)

    def add(self, dev: DeviceConfig) -> None:
        """The record and the adapter of ``dev`` (a device of the plant)."""
        device_type = DEVICE_TYPES[dev.type]
        bus = self.plant.buses[dev.bus]
        period = bus.options.get("poll_period", 0.5)
        state = DeviceState(
            dev.name, dev.type, dev.bus, params=device_type.params,
            stale_after=max(3.0, 3 * period + 2 * bus.options.get("timeout", 0.5)),
        )
        self.store.add(state)
        transport = self.transports.of(dev.bus)
        self.adapters[dev.name] = device_type.adapter_class(bus.type)(dev, state, transport)
        if isinstance(transport, ModbusLine) and isinstance(dev.options.get("address"), int):
            # its stale threshold follows the line's measured cycle
            transport.attach_device(dev.options["address"], state)

    def adopt(self, dev: DeviceConfig, discovery: CanDiscovery) -> None:
        """Take a discovered device into the running plant (the plant file is the caller's business).

        :raises ValueError: the name exists, or the device would share a CAN ID with a device of the bus (its message a
            :class:`~app.message.Message`)
        """
        if dev.name in self.plant.devices:
            raise ValueError(Message(N_("a device named {name} exists already"), name=repr(dev.name)))
        bus = self.plant.buses.get(dev.bus)
        if bus is None:
            raise ValueError(Message(N_("no bus named {name} in this plant"), name=repr(dev.bus)))
        conflict = can_id_conflict(self.plant.devices_on(dev.bus) + [dev], bus)
        if conflict is not None:
            raise ValueError(conflict[1])
        self.plant.devices[dev.name] = dev
        self.add(dev)
        discovery.adopted(dev.bus, dev.type, dev.options)

    async def shutdown(self) -> None:
        """The adapters' last words on their still open lines, answered (e.g. MO 64 levels deactivated
        and acknowledged)."""
        last = [a.shutdown() for a in self.adapters.values() if isinstance(a, ShutdownAdapter)]
        if last:
            try:
                await asyncio.wait_for(asyncio.gather(*last, return_exceptions=True), SHUTDOWN_S)
            except asyncio.TimeoutError:
                log.error("the adapters' shutdown steps did not end within %.0f s", SHUTDOWN_S)
