"""What a device page reads by itself when it opens, as the device type declares it (``DeviceType.open_reads``).

The Electrak's service parameters are read on request only (each read writes the password to every actuator
first); a page opened on a network whose parameters were never read reads them once, so that its entries start at
the actuators' values. The type declares the read; this keeps when each device was last read so, for every page
of the plant: once per device per ``again_s``, however many pages open.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable

from devices.errors import CommissionError
from devices.registry import DEVICE_TYPES, OpenRead

log = logging.getLogger(__name__)


class OpenReads:
    """The open reads of one runtime's devices (``runtime.open_reads``)."""

    def __init__(self, runtime, clock: Callable[[], float] = time.monotonic):
        self.runtime = runtime
        self.clock = clock
        self._last: dict[tuple[str, str], float] = {}  # (device, command) -> when a page last read it by itself

    def never_read(self, device: str) -> bool:
        """The device answers and none of its parameters was ever read."""
        state = self.runtime.store.devices.get(device)
        if state is None or state.status != "online" or state.params is None:
            return False
        return all(state.raw(param) is None for param in state.params)

    def due(self, device: str) -> list[OpenRead]:
        """The declared reads a page opening now runs (none unless :meth:`never_read`, none read in their time)."""
        config = self.runtime.plant.devices.get(device)
        device_type = DEVICE_TYPES.get(config.type) if config is not None else None
        if device_type is None or not device_type.open_reads or not self.never_read(device):
            return []
        now = self.clock()
        return [read for read in device_type.open_reads if now - self._last.get((device, read.command), -math.inf) >= read.again_s]

    async def run(self, device: str, *, user: str, role: str, session: str = "") -> list[str]:
        """Run the due reads through the gate (audited and checked as any read); the commands run."""
        ran = []
        for read in self.due(device):
            self._last[(device, read.command)] = self.clock()
            try:
                await self.runtime.worker.gate.invoke(device, read.command, None, user=user or "anonymous", role=role,
                                                      session=session)
                ran.append(read.command)
            except CommissionError as exc:  # the page shows "not read" and its own read button retries
                log.info("%s: %s not run on opening the page: %s", device, read.command, exc)
        return ran
