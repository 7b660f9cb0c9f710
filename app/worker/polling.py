"""Polling: one task per bus asks every device on it in turn, at the bus's ``poll_period``.

A CAN bus that is not connected marks its devices offline instead (with the bus's error); a bus
held for a line scan (:meth:`Polling.held`) is left alone meanwhile. A failing adapter marks its
device's record with the error and the bus goes on.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Iterator, Mapping
from typing import Any

from app.can_bus import CanBus
from app.plant import Plant
from app.state import StateStore

log = logging.getLogger(__name__)


class Polling:
    """The polling loops of a plant's buses.

    :param adapters: device name -> adapter, read at every round (an adopted device is polled from its next round)
    """

    def __init__(self, plant: Plant, store: StateStore, adapters: Mapping[str, Any], can_buses: Mapping[str, CanBus]):
        self.plant = plant
        self.store = store
        self.adapters = adapters
        self.can_buses = can_buses
        self.paused: set[str] = set()

    @contextlib.contextmanager
    def held(self, bus: str) -> Iterator[None]:
        """Polling of ``bus`` held while the block runs (a line scan has the line to itself)."""
        self.paused.add(bus)
        try:
            yield
        finally:
            self.paused.discard(bus)

    async def run(self, bus_name: str) -> None:
        """Round-robin polling of every device on the bus, at the configured period (until cancelled)."""
        period = self.plant.buses[bus_name].options.get("poll_period", 0.5)
        while True:
            started = time.monotonic()
            can_bus = self.can_buses.get(bus_name)
            if can_bus is not None and not can_bus.state.connected:
                self._bus_down(bus_name, can_bus)
            elif bus_name not in self.paused:
                await self.poll_round(bus_name)
            elapsed = time.monotonic() - started
            await asyncio.sleep(max(0.02, period - elapsed))

    def _bus_down(self, bus_name: str, can_bus: CanBus) -> None:
        for name in [d.name for d in self.plant.devices_on(bus_name)]:
            if self.store.devices[name].online is not False and can_bus.state.last_error:
                self.store.devices[name].mark_offline(f"bus {bus_name}: {can_bus.state.last_error}")

    async def poll_round(self, bus_name: str) -> None:
        """Poll each device of the bus once."""
        for name in [d.name for d in self.plant.devices_on(bus_name)]:
            try:
                await self.adapters[name].poll()
            except asyncio.CancelledError:
                raise
            except Exception as exc:  # a bug in one adapter must not stop the bus
                log.exception("polling %s failed", name)
                self.store.devices[name].error(f"internal error while polling: {exc}")
