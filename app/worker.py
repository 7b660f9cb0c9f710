"""The bus worker: owns every transport, polls every device, runs commands from pages.

Pages never touch a transport. They read :class:`~app.state.StateStore` and call
:meth:`Worker.command`, which checks the role, runs the adapter method on the bus
task's transport and returns the result or a clear error.
"""

from __future__ import annotations

import asyncio
import importlib
import logging
import time
from collections.abc import Awaitable, Callable
from typing import Any

from app.modbus_line import ModbusLine
from app.plant import Plant
from app.state import BusState, DeviceState, StateStore
from devices.registry import DEVICE_TYPES

log = logging.getLogger(__name__)

WRITE_ROLES = {"engineer"}


class PermissionDenied(Exception):
    """A session without the engineer role asked for a write."""


class Worker:
    """Runs one polling task per bus; every adapter is reached through it."""

    def __init__(self, plant: Plant, store: StateStore | None = None):
        self.plant = plant
        self.store = store or StateStore()
        self.lines: dict[str, ModbusLine] = {}
        self.adapters: dict[str, Any] = {}
        self.tasks: list[asyncio.Task] = []
        self.paused: set[str] = set()  # buses whose polling is held (e.g. during a scan)
        for bus in plant.buses.values():
            bus_state = BusState(bus.name, bus.type, bus.endpoint)
            self.store.buses[bus.name] = bus_state
            if bus.type == "modbus-rtu":
                self.lines[bus.name] = ModbusLine(bus.name, bus.options, bus_state)
        for dev in plant.devices.values():
            device_type = DEVICE_TYPES[dev.type]
            bus = plant.buses[dev.bus]
            period = bus.options.get("poll_period", 0.5)
            state = DeviceState(
                dev.name, dev.type, dev.bus, params=device_type.params,
                stale_after=max(3.0, 3 * period + 2 * bus.options.get("timeout", 0.5)),
            )
            self.store.devices[dev.name] = state
            adapter_cls = device_type.load("adapter")
            self.adapters[dev.name] = adapter_cls(dev, state, self.lines.get(dev.bus))

    async def start(self) -> None:
        for name in self.plant.buses:
            self.tasks.append(asyncio.create_task(self._poll_bus(name), name=f"bus {name}"))

    async def stop(self) -> None:
        for task in self.tasks:
            task.cancel()
        for task in self.tasks:
            try:
                await task
            except (asyncio.CancelledError, Exception):
                pass
        self.tasks.clear()
        for line in self.lines.values():
            line.close()

    async def _poll_bus(self, bus_name: str) -> None:
        """Round-robin polling of every device on the bus, at the configured period."""
        bus = self.plant.buses[bus_name]
        period = bus.options.get("poll_period", 0.5)
        names = [d.name for d in self.plant.devices_on(bus_name)]
        while True:
            started = time.monotonic()
            if bus_name not in self.paused:
                for name in names:
                    try:
                        await self.adapters[name].poll()
                    except asyncio.CancelledError:
                        raise
                    except Exception as exc:  # a bug in one adapter must not stop the bus
                        log.exception("polling %s failed", name)
                        self.store.devices[name].error(f"internal error while polling: {exc}")
            elapsed = time.monotonic() - started
            await asyncio.sleep(max(0.02, period - elapsed))

    async def command(
        self,
        device: str,
        action: Callable[[Any], Awaitable[Any]],
        *,
        role: str = "engineer",
        user: str = "local",
        describe: str = "",
        write: bool = True,
    ) -> Any:
        """Run ``action(adapter)`` for ``device`` on behalf of a session.

        Writes need the engineer role; the check is here, not only in the page.
        """
        if device not in self.adapters:
            raise KeyError(f"no device named {device!r} in this plant")
        state = self.store.devices[device]
        if write and role not in WRITE_ROLES:
            state.event("warning", f"refused for {user} ({role}): {describe or 'write'}")
            raise PermissionDenied(f"{user} has the {role} role and may not write ({describe or 'write'})")
        return await action(self.adapters[device])

    async def discover(self, bus: str, first: int, last: int, progress=None) -> list[dict]:
        """Find devices on a Modbus line (broadcast, then a scan), with polling held meanwhile."""
        if bus not in self.lines:
            raise KeyError(f"{bus} is not a Modbus RTU line")
        by_type = {d.type for d in self.plant.devices_on(bus)} or {"hdlock"}
        found: list[dict] = []
        self.paused.add(bus)
        try:
            for type_name in sorted(by_type):
                scan = getattr(importlib.import_module(f"devices.{type_name}.adapter"), "discover", None)
                if scan is not None:
                    found += await scan(self.lines[bus], first, last, progress)
        finally:
            self.paused.discard(bus)
        return found
