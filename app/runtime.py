"""The running plant: state store, bus worker and (in simulation) the device twins."""

from __future__ import annotations

import logging
import tempfile
from pathlib import Path
from typing import Any

from app.audit import AuditLog
from app.plant import Plant
from app.state import StateStore
from app.users import UserStore
from app.worker import Worker
from devices.registry import DEVICE_TYPES

log = logging.getLogger(__name__)


class SimulatedPlant:
    """The twins of every simulated bus of a plant, on the buses' own endpoints."""

    def __init__(self, plant: Plant, only_flagged: bool = True):
        self.plant = plant
        self.servers: list[Any] = []
        self.twins: dict[str, Any] = {}
        for bus in plant.buses.values():
            if only_flagged and not bus.simulated:
                continue
            by_type: dict[str, list] = {}
            extra = [d for d in plant.sim_devices.values() if d.bus == bus.name]
            for dev in plant.devices_on(bus.name) + extra:
                by_type.setdefault(dev.type, []).append(dev)
            for type_name, devs in by_type.items():
                sim_class = DEVICE_TYPES[type_name].sim_class(bus.type)
                if sim_class is None:
                    continue
                server = sim_class(bus, devs)
                self.servers.append(server)
                self.twins.update(server.twins)

    async def start(self) -> list[str]:
        """Start every twin server; returns the errors of those that could not start."""
        errors = []
        for server in self.servers:
            try:
                await server.start()
            except OSError as exc:
                errors.append(str(exc))
        return errors

    async def stop(self) -> None:
        for server in self.servers:
            await server.stop()


class Runtime:
    """Everything one ``commission`` process runs for one plant.

    :param data_dir: accounts, the audit database and backups (default: a temporary
        folder, so tests and throw-away runs leave nothing behind; the CLI passes the
        user's data folder)
    :param auth_required: sessions must log in (the GUI listens beyond the loopback address)
    """

    def __init__(self, plant: Plant, simulate: bool = True, data_dir: str | Path | None = None, auth_required: bool = False):
        self.plant = plant
        if data_dir is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="commission-")
            data_dir = self._tmp.name
        self.data_dir = Path(data_dir)
        self.audit = AuditLog(self.data_dir / "audit.sqlite")
        self.users = UserStore(self.data_dir / "users.toml")
        self.backups_dir = self.data_dir / "backups"
        self.auth_required = auth_required
        self.store = StateStore()
        self.sim = SimulatedPlant(plant) if simulate else None
        self.worker = Worker(plant, self.store, audit=self.audit)

    @property
    def twins(self) -> dict[str, Any]:
        return self.sim.twins if self.sim else {}

    async def start(self) -> None:
        if self.sim:
            for error in await self.sim.start():
                log.error("%s", error)
                for bus in self.store.buses.values():
                    if bus.name in error:
                        bus.last_error = error
        await self.worker.start()

    async def stop(self) -> None:
        await self.worker.stop()
        if self.sim:
            await self.sim.stop()


_current: Runtime | None = None


def current() -> Runtime:
    if _current is None:
        raise RuntimeError("no plant is running")
    return _current


def set_current(runtime: Runtime | None) -> None:
    global _current
    _current = runtime
