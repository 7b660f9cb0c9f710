"""Live state of one plant: the device records (see :mod:`devices.live`) and the bus states.

Written only by the bus worker; read by pages and the API. No UI imports. The device-facing
records live in ``devices/live.py`` so adapters never import ``app``; their names are
re-exported here for the pages, the API and the tests.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from devices.live import EVENT_LIMIT, HISTORY_SECONDS, QUALITIES, Counters, DeviceState, Event, Point

__all__ = [
    "EVENT_LIMIT", "HISTORY_SECONDS", "QUALITIES", "BusState", "Counters", "DeviceState", "Event", "Point", "StateStore",
]


@dataclass
class BusState:
    name: str
    type: str
    endpoint: str
    connected: bool = False
    last_error: str = ""
    reconnects: int = 0
    transactions: deque = field(default_factory=lambda: deque(maxlen=2000))  # monitor ring buffer


class StateStore:
    """All live state of one plant."""

    def __init__(self) -> None:
        self.devices: dict[str, DeviceState] = {}
        self.buses: dict[str, BusState] = {}

    def device(self, name: str) -> DeviceState:
        return self.devices[name]
