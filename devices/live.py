"""The live record of one device as its adapter writes it: values, live points, counters, events.

Device-facing half of the state store. Adapters (``devices/*/adapter.py``) write a
:class:`DeviceState`; ``app.state.StateStore`` holds one per device and the pages, API and
exporters read it. Pure data: no I/O, no ``app`` or ``pages`` imports.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from devices.params import Param, ParamMap

_now = time.time

HISTORY_SECONDS = 600  # charts show "the last minutes"
EVENT_LIMIT = 200
STALE_READINGS = 2.5  # a point read in turn is stale once this many of its own periods passed without it


@dataclass
class Counters:
    requests: int = 0
    responses: int = 0
    timeouts: int = 0
    crc_errors: int = 0
    exceptions: int = 0
    write_errors: int = 0
    malformed: int = 0  # frames that could not be decoded
    address_conflicts: int = 0  # answers to this device's requests from another unit address

    @property
    def errors(self) -> int:
        return self.timeouts + self.crc_errors + self.exceptions + self.write_errors + self.malformed

    def as_dict(self) -> dict[str, int]:
        return {
            "requests": self.requests,
            "responses": self.responses,
            "timeouts": self.timeouts,
            "crc_errors": self.crc_errors,
            "exceptions": self.exceptions,
            "write_errors": self.write_errors,
            "malformed": self.malformed,
            "address_conflicts": self.address_conflicts,
        }


@dataclass
class Event:
    time: float
    level: str  # "info", "warning", "error"
    text: str


QUALITIES = ("good", "stale", "offline", "unknown")


@dataclass
class Point:
    """One live value as the adapter decoded it (value, unit, time heard, raw word, text or enum name).

    ``periodic`` points arrive by themselves and age; the others (service parameters, identity)
    are read on demand and stay good while the device is online. ``every``: the measured time
    between two readings of a point read in turn with others (slower than the device's own
    cycle); such a point is stale after :data:`STALE_READINGS` of its own periods, not the device's.
    """

    value: Any
    unit: str = ""
    time: float | None = None
    raw: Any = None
    text: str | None = None
    periodic: bool = True
    every: float | None = None


@dataclass
class DeviceState:
    name: str
    type: str
    bus: str
    params: ParamMap | None = None
    stale_after: float = 3.0
    online: bool | None = None  # None: not asked yet
    last_seen: float | None = None
    last_error: str = ""
    last_error_time: float | None = None
    counters: Counters = field(default_factory=Counters)
    registers: dict[tuple[str, int], tuple[int, float]] = field(default_factory=dict)
    history: deque = field(default_factory=lambda: deque(maxlen=HISTORY_SECONDS * 10))
    events: deque = field(default_factory=lambda: deque(maxlen=EVENT_LIMIT))
    unsaved: set[str] = field(default_factory=set)  # parameter keys written since Save-Settings
    info: dict[str, Any] = field(default_factory=dict)  # adapter-specific live facts
    points: dict[str, Point] = field(default_factory=dict)  # live points by the document's names
    registers_periodic: bool = True  # False: register values are read on demand (they do not age)
    version: int = 0  # bumped by every write below: readers follow changes by comparing it (O(1))

    def touch(self) -> None:
        """Say that something changed that the writers below do not cover (an adapter's ``info``)."""
        self.version += 1

    # -- written by adapters -------------------------------------------------------
    def update_registers(self, space: str, start: int, values: list[int], now: float | None = None) -> None:
        now = time.time() if now is None else now
        for offset, value in enumerate(values):
            self.registers[(space, start + offset)] = (int(value) & 0xFFFF, now)
        self.mark_seen(now)

    def publish(self, name: str, value: Any, unit: str = "", *, raw: Any = None, text: str | None = None,
                time: float | None = None, periodic: bool = True, every: float | None = None) -> None:
        """Record the live point ``name`` (O(1); one record per name, replaced on every update)."""
        self.points[name] = Point(value, unit, _now() if time is None else time, raw, text, periodic, every)
        self.version += 1

    def mark_seen(self, now: float | None = None) -> None:
        if self.online is False and self.last_error:  # recovered: the old error stays in the event log only
            self.event("info", f"back online (last error: {self.last_error})")
            self.last_error = ""
            self.last_error_time = None
        self.online = True
        self.last_seen = time.time() if now is None else now
        self.version += 1

    def mark_offline(self, message: str) -> None:
        if self.online is not False:
            self.event("error", message)
        self.online = False
        self.error(message, log=False)

    def error(self, message: str, log: bool = True) -> None:
        self.last_error = message
        self.last_error_time = time.time()
        self.version += 1
        if log:
            self.event("error", message)

    def event(self, level: str, text: str) -> None:
        self.events.append(Event(time.time(), level, text))
        self.version += 1

    def add_history(self, sample: dict[str, float], now: float | None = None) -> None:
        """One chart sample; the history keeps HISTORY_SECONDS of them (and at most 10 a second):
        a device sampled slowly (a lock polled every 2 s) must not keep hours of them."""
        now = time.time() if now is None else now
        history = self.history
        history.append((now, sample))
        while history[0][0] < now - HISTORY_SECONDS:
            history.popleft()
        self.version += 1

    # -- read by pages -------------------------------------------------------------
    @property
    def status(self) -> str:
        """"online", "stale", "offline" or "unknown" (never asked)."""
        if self.online is None:
            return "unknown"
        if not self.online:
            return "offline"
        if self.age is not None and self.age > self.stale_after:
            return "stale"
        return "online"

    def quality(self, read_time: float | None, periodic: bool = True, now: float | None = None,
                every: float | None = None) -> str:
        """The one place quality is derived: "good", "stale", "offline" or "unknown"."""
        if self.online is None or read_time is None:
            return "unknown"
        if not self.online:
            return "offline"
        limit = self.stale_after if every is None else max(self.stale_after, STALE_READINGS * every)
        if periodic and (_now() if now is None else now) - read_time > limit:
            return "stale"
        return "good"

    def point(self, name: str) -> dict[str, Any] | None:
        """One live point as the API shows it (with its quality), or None if never published."""
        p = self.points.get(name)
        return None if p is None else self._point_entry(p, _now())

    def _point_entry(self, p: Point, now: float) -> dict[str, Any]:
        return {"value": p.value, "unit": p.unit, "time": p.time, "quality": self.quality(p.time, p.periodic, now, p.every),
                "raw": p.raw, "text": p.text}

    @property
    def age(self) -> float | None:
        return None if self.last_seen is None else max(0.0, time.time() - self.last_seen)

    def raw(self, param: Param) -> int | None:
        """Combined raw value of a parameter, or None until every word was read."""
        words = []
        for address in param.addresses:
            entry = self.registers.get((param.space, address))
            if entry is None:
                return None
            words.append(entry[0])
        return param.combine(words)

    def read_time(self, param: Param) -> float | None:
        entry = self.registers.get((param.space, param.address))
        return None if entry is None else entry[1]

    def value(self, name: str) -> int | float | None:
        if self.params is None or name not in self.params.by_name:
            return None
        param = self.params.by_name[name]
        raw = self.raw(param)
        return None if raw is None else param.decode(raw)

    def _param_entry(self, param: Param, raw: int, now: float) -> dict[str, Any]:
        entry: dict[str, Any] = {
            "value": param.decode(raw),
            "raw": raw,
            "unit": param.unit,
            "text": param.display(raw),
            "address": param.address,
            "space": param.space,
            "access": param.access.value,
            "time": self.read_time(param),
        }
        entry["quality"] = self.quality(entry["time"], self.registers_periodic, now)
        if param.enum is not None:
            entry["name"] = param.enum_name(raw)
        if param.fields:
            entry["fields"] = param.field_values(raw)
        return entry

    def entry(self, name: str, now: float | None = None) -> dict[str, Any] | None:
        """One value by name, a register parameter or a published point alike, as :meth:`values`
        lists it (with its quality); None until it was read or heard. O(1) for a point."""
        now = _now() if now is None else now
        p = self.points.get(name)
        if p is not None:
            return self._point_entry(p, now)
        param = self.params.by_name.get(name) if self.params is not None else None
        raw = None if param is None else self.raw(param)
        return None if raw is None else self._param_entry(param, raw, now)

    def values(self) -> dict[str, dict[str, Any]]:
        """Every known parameter and live point by name: decoded value, raw, unit, text, read time, quality."""
        result: dict[str, dict[str, Any]] = {}
        now = _now()
        for param in self.params if self.params is not None else ():
            raw = self.raw(param)
            if raw is not None:
                result[param.label or param.name] = self._param_entry(param, raw, now)
        for name, p in self.points.items():
            result[name] = self._point_entry(p, now)
        return result

    def history_since(self, seconds: float, now: float | None = None) -> list[tuple[float, dict[str, Any]]]:
        """The recorded samples of the last ``seconds`` (the charts' data), oldest first; O(returned)."""
        cutoff = (_now() if now is None else now) - seconds
        newest: list[tuple[float, dict[str, Any]]] = []
        for sample in reversed(self.history):
            if sample[0] < cutoff:
                break
            newest.append(sample)
        newest.reverse()
        return newest

    def summary(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "type": self.type,
            "bus": self.bus,
            "online": self.status == "online",
            "status": self.status,
            "last_seen": self.last_seen,
            "last_error": self.last_error,
            "counters": self.counters.as_dict(),
        }
