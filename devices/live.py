"""The live record of one device as its adapter writes it: values, live points, counters, events.

Device-facing half of the state store. Adapters (``devices/*/adapter.py``) write a
:class:`DeviceState`; ``app.state.StateStore`` holds one per device and the pages, API and
exporters read it. Pure data: no I/O, no ``app`` or ``pages`` imports.

What readers get is one shape, :class:`LiveValue` (name, value, unit, time, quality, raw, text,
enum name, bit fields, register address): :meth:`DeviceState.live` for one, :meth:`DeviceState.
live_values` for all. Its JSON form is :meth:`LiveValue.to_json` (through :func:`jsonable`, the one
function that turns a value, a typed record included, into JSON); the API and the MQTT payload
send that form, and the API's model is made from :func:`json_fields`. A fact that is more than a
number is a small frozen dataclass (a record) published as one point, e.g. the MO 64's error
memory levels.
"""

from __future__ import annotations

import dataclasses
import enum
import hashlib
import math
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal, NamedTuple

from devices.message import Message, N_
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
Quality = Literal["good", "stale", "offline", "unknown"]


def jsonable(value: Any) -> Any:
    """``value`` in JSON's terms, the one conversion the API, MQTT, backups and exports share: a record
    (dataclass) becomes an object of its fields, tuples and lists arrays, sets sorted arrays, bytes hex
    text, enums their number, NaN and infinities null; anything else unknown its text."""
    if value is None or isinstance(value, bool | str):
        return value
    if isinstance(value, enum.Enum):
        return jsonable(value.value)
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return float(value) if math.isfinite(value) else None
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {str(k): jsonable(x) for k, x in value.items()}
    if isinstance(value, bytes | bytearray):
        return bytes(value).hex(" ")
    if isinstance(value, set | frozenset):
        return sorted(jsonable(x) for x in value)
    if isinstance(value, list | tuple):
        return [jsonable(x) for x in value]
    return str(value)


def session_tag(session: str) -> str:
    """A session as a published fact may name it: a short digest, never the page's own id (which must not
    reach the API or a broker). A page finds its own entries by the tag of its session."""
    return hashlib.sha256(session.encode()).hexdigest()[:12]


@dataclass(frozen=True, slots=True)
class Holder:
    """Who holds control, as published: the user, the tag of the browser session (``session_tag``), since when."""

    user: str
    session: str
    since: float


def _doc(text: str, json_key: str | None = None) -> dict[str, str]:
    return {"doc": text, **({"json": json_key} if json_key else {})}


@dataclass(frozen=True, slots=True)
class LiveValue:
    """One live value with its meaning, as every reader gets it (pages, API, MQTT, history, backup).

    A published point or a register parameter alike. The JSON form (:meth:`to_json`) is keyed by the
    field names, except :attr:`enum`, sent as ``name`` (the register parameter's enum name, as the API
    always sent it); :attr:`name` is the key of the values' object and not repeated in it.
    """

    name: str = field(metadata=_doc("the point's name (the device document's)"))
    value: Any = field(default=None, metadata=_doc("decoded: signed, scaled; a record's fields; null while "
                                                   "not measurable (see text)"))
    unit: str = field(default="", metadata=_doc("unit of the value"))
    time: float | None = field(default=None, metadata=_doc("Unix time it was read or heard"))
    quality: Quality = field(default="unknown", metadata=_doc('"good", "stale", "offline" or "unknown"'))
    raw: Any = field(default=None, metadata=_doc("the word(s) on the wire, where the device has one"))
    text: str | None = field(default=None, metadata=_doc("as shown on the device page (enum name, state, "
                                                         "'out of range')"))
    enum: str | None = field(default=None, metadata=_doc("enum name (register parameters)", "name"))
    fields: dict[str, int] | None = field(default=None, metadata=_doc("bit fields (register parameters)"))
    address: int | None = field(default=None, metadata=_doc("register address (register parameters)"))
    space: str | None = field(default=None, metadata=_doc("register space (register parameters)"))
    access: str | None = field(default=None, metadata=_doc("access (register parameters)"))

    @property
    def shown(self) -> str:
        """The value in words as a page shows it: its text, else value and unit, else "-"."""
        if self.text is not None:
            return self.text
        return "-" if self.value is None else f"{self.value} {self.unit}".strip()

    def entry(self) -> dict[str, Any]:
        """The older dict form (``DeviceState.values()``, ``entry()``, ``point()``): the same keys as
        :meth:`to_json`, Python values as published (no JSON conversion), register keys only where set."""
        out: dict[str, Any] = {"value": self.value, "unit": self.unit, "time": self.time, "quality": self.quality,
                               "raw": self.raw, "text": self.text}
        if self.address is not None:  # a register parameter: its register keys, the enum name even when undefined
            out.update(address=self.address, space=self.space, access=self.access, name=self.enum)
            if self.fields is not None:
                out["fields"] = self.fields
        return out

    def to_json(self) -> dict[str, Any]:
        """The JSON form every reader outside the process gets (API, MQTT, exports), keyed as
        :func:`json_fields` says: value, unit, time, quality, raw and text always; the register keys
        (name, fields, address, space, access) where they are set."""
        out = {f.metadata.get("json", f.name): jsonable(getattr(self, f.name)) for f in _JSON_FIELDS[:6]}
        for f in _JSON_FIELDS[6:]:
            x = getattr(self, f.name)
            if x is not None:
                out[f.metadata.get("json", f.name)] = jsonable(x)
        return out


_JSON_FIELDS = tuple(f for f in dataclasses.fields(LiveValue) if f.name != "name")
assert [f.name for f in _JSON_FIELDS[:6]] == ["value", "unit", "time", "quality", "raw", "text"]


def json_fields() -> list[tuple[str, Any, Any, str]]:
    """The JSON form of a :class:`LiveValue`, declared once: (key, type, default, description) per field,
    in order (the API's response model is made from this)."""
    import typing

    hints = typing.get_type_hints(LiveValue)
    return [(f.metadata.get("json", f.name), hints[f.name],
             ... if f.name == "quality" else f.default, f.metadata["doc"]) for f in _JSON_FIELDS]


class Point(NamedTuple):
    """One live value as the adapter decoded it (value, unit, time heard, raw word, text or enum name).

    ``periodic`` points arrive by themselves and age; the others (service parameters, identity)
    are read on demand and stay good while the device is online. ``every``: the measured time
    between two readings of a point read in turn with others (slower than the device's own
    cycle); such a point is stale after :data:`STALE_READINGS` of its own periods, not the device's.

    Immutable like a frozen record, made for every value of every telegram: a named tuple is made in
    a fifth of the time of a frozen dataclass (bench/can_ingest.py).
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
    # the commissioning record's view of the device (app/record.py, app/replace.py), read by the pages and faces:
    drift: dict | None = None  # {"approved": bool, "changed": [rows]}: changed since the approved set; None: not compared yet
    replaced: dict | None = None  # the identity that differs from the known one ("replaced?"); None: the known one
    points: dict[str, Point] = field(default_factory=dict)  # live points by the document's names
    registers_periodic: bool = True  # False: register values are read on demand (they do not age)
    # (space, address) -> seconds between two readings of a register read more slowly than the device's
    # cycle (settings and identity an adapter reads every few seconds): stale after STALE_READINGS of them
    register_every: dict[tuple[str, int], float] = field(default_factory=dict)
    version: int = 0  # bumped by every write below: readers follow changes by comparing it (O(1))
    # the store this record belongs to, told of every change (StateStore.add); None: a record of its own (a test's)
    on_change: Callable[[str], object] | None = field(default=None, repr=False, compare=False)

    def touch(self) -> None:
        """Say that something changed: every writer below ends with it, and so does a writer of what they do not
        cover (the record's ``drift`` or ``replaced``). The version moves on and the store, if any, is told (the
        one call that notifies, as Home Assistant's ``async_write_ha_state``)."""
        self.version += 1
        if self.on_change is not None:
            self.on_change(self.name)

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
        self.touch()

    def publish_telegram(self, now: float, points: Mapping[str, Point], registers: Mapping[tuple[str, int], int] | None = None,
                         sample: Callable[[], dict[str, Any]] | None = None) -> None:
        """Everything one telegram brought, heard at ``now``: live points, register words (read at ``now``) and,
        with ``sample``, a chart sample made once they are in (:meth:`add_history`). Readers see one change (a
        single version bump), not one per value: a device that sends a status of many values many times a
        second costs its readers one notification per telegram."""
        self.points.update(points)
        if registers:
            stored = self.registers
            for key, word in registers.items():
                stored[key] = (int(word) & 0xFFFF, now)
        if sample is not None:
            self._append_history(sample(), now)
        self.mark_seen(now)

    def fact(self, name: str, value: Any, unit: str = "", *, text: str | None = None, raw: Any = None) -> None:
        """Publish a fact that is read on demand or kept by the adapter (a setting, a count, a record: a
        frozen dataclass or a tuple of them), only when it changed: it does not age, and its time is
        when it last changed."""
        old = self.points.get(name)
        if old is not None and not old.periodic and (old.value, old.unit, old.text, old.raw) == (value, unit, text, raw):
            return
        self.publish(name, value, unit, raw=raw, text=text, periodic=False)

    def mark_seen(self, now: float | None = None) -> None:
        if self.online is False and self.last_error:  # recovered: the old error stays in the event log only
            self.event("info", Message(N_("back online (last error: {error})"), error=self.last_error))
            self.last_error = ""
            self.last_error_time = None
        self.online = True
        self.last_seen = time.time() if now is None else now
        self.touch()

    def mark_offline(self, message: str) -> None:
        if self.online is not False:
            self.event("error", message)
        self.online = False
        self.error(message, log=False)

    def error(self, message: str, log: bool = True) -> None:
        self.last_error = message
        self.last_error_time = time.time()
        self.touch()
        if log:
            self.event("error", message)

    def event(self, level: str, text: str) -> None:
        self.events.append(Event(time.time(), level, text))
        self.touch()

    def sample_of(self, names: tuple[str, ...] | list[str]) -> dict[str, Any]:
        """A chart sample of the published points ``names`` as they are now, keyed by the points' own names (so the
        history and ``values()`` name a quantity once); a point not published yet is left out."""
        points = self.points
        return {n: points[n].value for n in names if n in points}

    def record_history(self, names: tuple[str, ...] | list[str], now: float | None = None) -> None:
        """One chart sample of the published points ``names`` (:meth:`sample_of`), if any is published."""
        sample = self.sample_of(names)
        if sample:
            self.add_history(sample, now)

    def add_history(self, sample: dict[str, float], now: float | None = None) -> None:
        """One chart sample; the history keeps HISTORY_SECONDS of them (and at most 10 a second):
        a device sampled slowly (a lock polled every 2 s) must not keep hours of them.

        Families not yet moved key their samples by chart labels (HD-Lock "BoltPosition [Inc]" for the
        point "BoltPosition"); moved ones use :meth:`record_history`, keyed by point names."""
        self._append_history(sample, time.time() if now is None else now)
        self.touch()

    def _append_history(self, sample: dict[str, Any], now: float) -> None:
        history = self.history
        history.append((now, sample))
        while history[0][0] < now - HISTORY_SECONDS:
            history.popleft()

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

    def param_quality(self, param: Param, now: float | None = None) -> str:
        """The quality of a register parameter's value, aged by its own read period (:attr:`register_every`)."""
        return self.quality(self.read_time(param), self.registers_periodic, now,
                            self.register_every.get((param.space, param.address)))

    def point(self, name: str) -> dict[str, Any] | None:
        """One live point in the dict form (:meth:`LiveValue.entry`, with its quality), or None if never published."""
        p = self.points.get(name)
        return None if p is None else self._point_live(name, p, _now()).entry()

    def _point_live(self, name: str, p: Point, now: float) -> LiveValue:
        return LiveValue(name, p.value, p.unit, p.time, self.quality(p.time, p.periodic, now, p.every), p.raw, p.text)

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

    def _param_live(self, param: Param, raw: int, now: float) -> LiveValue:
        read = self.read_time(param)
        return LiveValue(param.label or param.name, param.decode(raw), param.unit, read,
                         self.quality(read, self.registers_periodic, now,
                                      self.register_every.get((param.space, param.address))),
                         raw, param.display(raw),
                         param.enum_name(raw) if param.enum is not None else None,
                         param.field_values(raw) if param.fields else None,
                         param.address, param.space, param.access.value)

    def live(self, name: str, now: float | None = None) -> LiveValue | None:
        """One value by name, a published point or a register parameter alike, with its quality; None until
        it was read or heard. O(1) for a point."""
        now = _now() if now is None else now
        p = self.points.get(name)
        if p is not None:
            return self._point_live(name, p, now)
        param = self.params.by_name.get(name) if self.params is not None else None
        raw = None if param is None else self.raw(param)
        return None if raw is None else self._param_live(param, raw, now)

    def live_values(self, now: float | None = None) -> dict[str, LiveValue]:
        """Every known parameter and live point by name (a point wins over a parameter of the same name)."""
        result: dict[str, LiveValue] = {}
        now = _now() if now is None else now
        for param in self.params if self.params is not None else ():
            raw = self.raw(param)
            if raw is not None:
                value = self._param_live(param, raw, now)
                result[value.name] = value
        for name, p in list(self.points.items()):  # a snapshot: a line's own thread may publish meanwhile
            result[name] = self._point_live(name, p, now)
        return result

    def entry(self, name: str, now: float | None = None) -> dict[str, Any] | None:
        """:meth:`live` in the dict form (:meth:`LiveValue.entry`), as :meth:`values` lists it."""
        value = self.live(name, now)
        return None if value is None else value.entry()

    def values(self) -> dict[str, dict[str, Any]]:
        """Every known parameter and live point by name in the dict form: value, raw, unit, text, read time, quality."""
        return {name: value.entry() for name, value in self.live_values().items()}

    def values_json(self, now: float | None = None) -> dict[str, dict[str, Any]]:
        """Every value in its JSON form (:meth:`LiveValue.to_json`): what the API and the MQTT payload send."""
        return {name: value.to_json() for name, value in self.live_values(now).items()}

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
