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

from app.audit import AuditLog
from app.can_bus import CanBus, CanBusState
from app.modbus_line import ModbusLine
from app.plant import DeviceConfig, Plant
from app.state import BusState, DeviceState, StateStore
from devices.registry import DEVICE_TYPES

log = logging.getLogger(__name__)

WRITE_ROLES = {"engineer"}


class PermissionDenied(Exception):
    """A session without the engineer role asked for a write."""


class Worker:
    """Runs one polling task per bus; every adapter is reached through it."""

    def __init__(self, plant: Plant, store: StateStore | None = None, audit: AuditLog | None = None):
        self.plant = plant
        self.audit = audit
        self.store = store or StateStore()
        self.lines: dict[str, ModbusLine] = {}
        self.adapters: dict[str, Any] = {}
        self.tasks: list[asyncio.Task] = []
        self.paused: set[str] = set()
        self.sessions: dict[str, str] = {}  # connected browser sessions -> role  # buses whose polling is held (e.g. during a scan)
        self.can_buses: dict[str, CanBus] = {}
        for bus in plant.buses.values():
            if bus.type == "can":
                can_state = CanBusState(bus.name, bus.type, f"{bus.options['interface']} {bus.options['channel']}")
                self.store.buses[bus.name] = can_state
                self.can_buses[bus.name] = CanBus(bus.name, bus.options, can_state)
            else:
                bus_state = BusState(bus.name, bus.type, bus.endpoint)
                self.store.buses[bus.name] = bus_state
                self.lines[bus.name] = ModbusLine(bus.name, bus.options, bus_state)
        self.discovered: dict[str, dict[tuple[bool, int], dict]] = {name: {} for name in self.can_buses}
        for name, can_bus in self.can_buses.items():
            can_bus.listeners.append(lambda msg, bus=name: self._discover_frame(bus, msg))
        for dev in plant.devices.values():
            self._add_adapter(dev)

    def _add_adapter(self, dev: DeviceConfig) -> None:
        device_type = DEVICE_TYPES[dev.type]
        bus = self.plant.buses[dev.bus]
        period = bus.options.get("poll_period", 0.5)
        state = DeviceState(
            dev.name, dev.type, dev.bus, params=device_type.params,
            stale_after=max(3.0, 3 * period + 2 * bus.options.get("timeout", 0.5)),
        )
        self.store.devices[dev.name] = state
        transport = self.lines.get(dev.bus) or self.can_buses.get(dev.bus)
        self.adapters[dev.name] = device_type.adapter_class(bus.type)(dev, state, transport)

    # -- CAN discovery -----------------------------------------------------------------------
    def _discover_frame(self, bus: str, msg) -> None:
        """A frame whose ID no adapter owns: does some device type recognise it?"""
        key = (msg.is_extended_id, msg.arbitration_id)
        known = self.discovered[bus].get(key)
        if known is not None:
            known["last_seen"] = time.time()
            known["frames"] += 1
            return
        for device_type in DEVICE_TYPES.values():
            if not device_type.can_codec or "can" not in device_type.bus_types:
                continue
            entry = importlib.import_module(device_type.can_codec).discovered(msg.arbitration_id, msg.is_extended_id, bytes(msg.data))
            if entry:
                entry.update(first_seen=time.time(), last_seen=time.time(), frames=1, bus=bus)
                self.discovered[bus][key] = entry
                log.info("%s: discovered %s at %s", bus, entry["type"], key)
                return

    # -- browser sessions -------------------------------------------------------------------
    def session_opened(self, session: str, role: str = "engineer") -> None:
        self.sessions[session] = role

    def session_closed(self, session: str) -> None:
        """A browser went away: release what it controlled; outputs off when no engineer is left."""
        self.sessions.pop(session, None)
        for adapter in self.adapters.values():
            release = getattr(adapter, "release_control", None)
            if release is not None:
                release(session, "released: the controlling browser disconnected")
        if not any(role in WRITE_ROLES for role in self.sessions.values()):
            for adapter in self.adapters.values():
                hook = getattr(adapter, "on_no_sessions", None)
                if hook is not None:
                    hook()

    def known_ids(self, bus: str) -> set[tuple[bool, int]]:
        """IDs of devices on a CAN bus (in the plant or discovered): for decoding in the monitor."""
        can_bus = self.can_buses.get(bus)
        if can_bus is None:
            return set()
        return set(can_bus.handlers) | set(self.discovered.get(bus, {}))

    def adopt(self, dev: DeviceConfig) -> None:
        """Take a discovered device into the running plant (the plant file is the caller's business)."""
        if dev.name in self.plant.devices:
            raise ValueError(f"a device named {dev.name!r} exists already")
        self.plant.devices[dev.name] = dev
        self._add_adapter(dev)
        for key, entry in list(self.discovered.get(dev.bus, {}).items()):
            if DEVICE_TYPES[dev.type].bus_identity(dev.options, "can") == DEVICE_TYPES[entry["type"]].bus_identity(
                {"device_id": entry["device_id"], "extended": entry["extended"]}, "can"
            ):
                del self.discovered[dev.bus][key]

    async def start(self) -> None:
        for can_bus in self.can_buses.values():
            await can_bus.start()
        for name in self.plant.buses:
            self.tasks.append(asyncio.create_task(self._poll_bus(name), name=f"bus {name}"))

    async def stop(self) -> None:
        # A cancellation can be swallowed when pymodbus's wait_for gets its answer in the same
        # loop iteration: cancel again until every task has really ended (bounded).
        pending = set(self.tasks)
        loop = asyncio.get_running_loop()
        end = loop.time() + 5.0
        while pending and loop.time() < end:
            for task in pending:
                task.cancel()
            _done, pending = await asyncio.wait(pending, timeout=0.2)
        for task in pending:
            log.error("bus task %s did not end", task.get_name())
        self.tasks.clear()
        for line in self.lines.values():
            line.close()
        for can_bus in self.can_buses.values():
            await can_bus.stop()

    async def _poll_bus(self, bus_name: str) -> None:
        """Round-robin polling of every device on the bus, at the configured period."""
        bus = self.plant.buses[bus_name]
        period = bus.options.get("poll_period", 0.5)
        while True:
            started = time.monotonic()
            can_bus = self.can_buses.get(bus_name)
            if can_bus is not None and not can_bus.state.connected:
                for name in [d.name for d in self.plant.devices_on(bus_name)]:
                    if self.store.devices[name].online is not False and can_bus.state.last_error:
                        self.store.devices[name].mark_offline(f"bus {bus_name}: {can_bus.state.last_error}")
            elif bus_name not in self.paused:
                for name in [d.name for d in self.plant.devices_on(bus_name)]:
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
        record: bool = True,
        parameter: str = "",
        old: Any = "",
        new: Any = "",
    ) -> Any:
        """Run ``action(adapter)`` for ``device`` on behalf of a session.

        Writes need the engineer role; the check is here, not only in the page. Every
        write and command (``record``) lands in the audit log with its outcome.
        """
        if device not in self.adapters:
            raise KeyError(f"no device named {device!r} in this plant")
        state = self.store.devices[device]

        def audit(result: str) -> None:
            if record and self.audit is not None:
                self.audit.record(user=user, role=role, device=device, action=describe or "command",
                                  parameter=parameter, old=old, new=new, result=result)

        if write and role not in WRITE_ROLES:
            state.event("warning", f"refused for {user} ({role}): {describe or 'write'}")
            audit(f"refused: the {role} role may not write")
            raise PermissionDenied(f"{user} has the {role} role and may not write ({describe or 'write'})")
        try:
            result = await action(self.adapters[device])
        except Exception as exc:
            audit(f"failed: {exc}")
            raise
        audit("ok")
        return result

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
