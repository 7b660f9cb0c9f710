"""Device types, found by looking at the packages under ``devices/``.

A device package exposes ``DEVICE_TYPE`` in its ``__init__.py``; nothing here
or in ``app/`` needs to change when a package is added.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from devices.params import ParamMap


@dataclass(frozen=True)
class CanIdUse:
    """CAN IDs ``first..last`` (one ID when equal) that a device sends or receives, and their use in words.

    :param sender: ``"device"`` (the device sends it) or ``"master"`` (this tool or a controller sends it)
    :param shared: used alike by every device of the type on one bus (the HD-Lock request block,
        the IDs of an Electrak network): two devices of that type do not collide on it
    """

    first: int
    last: int
    use: str
    sender: str = "device"
    extended: bool = False
    shared: bool = False

    @classmethod
    def one(cls, can_id: int, use: str, sender: str = "device", extended: bool = False, shared: bool = False) -> CanIdUse:
        return cls(can_id, can_id, use, sender, extended, shared)

    def covers(self, extended: bool, can_id: int) -> bool:
        return extended == self.extended and self.first <= can_id <= self.last

    def overlap(self, other: CanIdUse) -> tuple[int, int] | None:
        """The IDs both use, as ``(first, last)``, or None."""
        if self.extended != other.extended:
            return None
        first, last = max(self.first, other.first), min(self.last, other.last)
        return (first, last) if first <= last else None


QUALITY_RANK = {"good": 0, "unknown": 1, "stale": 2, "offline": 3}  # worst quality wins on a tile


@dataclass(frozen=True)
class When:
    """A condition on one live point: its ``value`` (or one bit ``field``, or its enum ``name`` / ``text``)
    is one of ``values``, or starts with ``prefix``; ``negate`` inverts it."""

    point: str
    values: tuple[Any, ...] = ()
    field: str = ""
    of: str = "value"  # "value", "name" or "text"
    prefix: str = ""
    negate: bool = False

    def holds(self, entry: dict[str, Any] | None) -> bool:
        if entry is None:
            return False
        if self.field:
            subject = (entry.get("fields") or {}).get(self.field)
        else:
            subject = entry.get(self.of)
        if self.prefix:
            hit = isinstance(subject, str) and subject.startswith(self.prefix)
        else:
            hit = subject in self.values
        return hit != self.negate


@dataclass(frozen=True)
class TileLine:
    """One line of a tile: ``template`` filled with the point's ``value``, ``text``, ``name``, ``unit``;
    a ``cases`` line shows the first case that holds (text, and the tile's icon if one is given)."""

    point: str = ""
    template: str = "{text}"
    missing: str = ""
    cases: tuple[tuple[When, str, str], ...] = ()  # (condition, text, icon or "")
    points: tuple[str, ...] = ()  # a list line: the names of these points whose value is true
    unless: When | None = None  # hide the line while this holds
    values: tuple[tuple[str, str], ...] = ()  # a values line: (point, label) of each point heard, ``item`` each, in ``{list}``
    item: str = "{label} {text}"


@dataclass(frozen=True)
class TileAlarm:
    """An alarm text shown while ``when`` holds (``{text}``/``{name}``/``{value}`` of the point), except while ``unless`` holds."""

    when: When
    text: str
    unless: When | None = None


@dataclass(frozen=True)
class TileBar:
    """A bar of ``point`` against a full scale: the constant ``full_scale`` or the value of ``full_scale_point``."""

    point: str
    label: str  # format with {value}, {full}, {unit}
    full_scale: float | None = None
    full_scale_point: str = ""
    fresher: tuple[str, ...] = ()  # other points of the same quantity: the most recently heard of all is shown

    def sources(self) -> tuple[str, ...]:
        return (self.point, *self.fresher)


@dataclass(frozen=True)
class TileSpec:
    """What a device's tile shows, declared as data; pages evaluate it against the live points."""

    lines: tuple[TileLine, ...] = ()
    alarms: tuple[TileAlarm, ...] = ()
    bar: TileBar | None = None
    icon: str = "memory"

    def point_names(self) -> set[str]:
        names = set()
        for line in self.lines:
            names.update(n for n in (line.point, *line.points, *(v[0] for v in line.values)) if n)
            names.update(case[0].point for case in line.cases)
        names.update(a.when.point for a in self.alarms)
        if self.bar is not None:
            names.update(self.bar.sources())
        return names

    def evaluate(self, point: Callable[[str], dict[str, Any] | None], now: float) -> dict[str, Any]:
        """``{"lines", "alarms", "raised", "bar": (fraction, label) | None, "icon", "quality", "age"}`` from the points.

        ``alarms`` are the texts of the alarms that hold, ``raised`` the same alarms as ``(TileAlarm, entry)``:
        the declaration and the entry of the point it follows (what another language words them from).
        ``quality`` is the worst quality of the points the tile shows, ``age`` the age of the oldest of them.
        """
        entries = {name: point(name) for name in self.point_names()}
        icon = self.icon
        lines = []
        for line in self.lines:
            if line.unless is not None and line.unless.holds(entries.get(line.unless.point) or point(line.unless.point)):
                continue
            if line.cases:
                chosen = next(((text, case_icon) for when, text, case_icon in line.cases if when.holds(entries.get(when.point))), None)
                if chosen is None:
                    lines.append(line.missing)
                    continue
                lines.append(chosen[0])
                icon = chosen[1] or icon
            elif line.points:
                on = [n for n in line.points if (entries.get(n) or {}).get("value")]
                lines.append(line.template.format(list=", ".join(on) if on else line.missing))
            elif line.values:
                # no-break spaces inside an item: a wrapped line breaks between items only
                items = [line.item.format(label=label, **template_fields(entry)).replace(" ", "\u00a0") for name, label in line.values
                         if (entry := entries.get(name)) is not None]
                if items or line.missing:  # a values line with nothing heard and no ``missing`` text is left out
                    lines.append(line.template.format(list=" · ".join(items)) if items else line.missing)
            else:
                entry = entries.get(line.point)
                lines.append(line.missing if entry is None else line.template.format(**template_fields(entry)))
        raised = [(alarm, entry) for alarm in self.alarms if alarm.when.holds(entry := entries.get(alarm.when.point))
                  and not (alarm.unless is not None and alarm.unless.holds(point(alarm.unless.point)))]
        alarms = [alarm.text.format(**template_fields(entry)) for alarm, entry in raised]
        bar = None
        if self.bar is not None:
            heard = [e for name in self.bar.sources() if (e := entries.get(name)) is not None]
            entry = max(heard, key=lambda e: e.get("time") or 0.0, default=None)  # the freshest source wins
            full = self.bar.full_scale
            if self.bar.full_scale_point:
                full_entry = point(self.bar.full_scale_point)
                full = None if full_entry is None else full_entry.get("value")
            if entry is not None and isinstance(entry.get("value"), int | float) and full:
                value = entry["value"]
                bar = (max(0.0, min(1.0, value / full)), self.bar.label.format(value=value, full=full, unit=entry.get("unit", "")))
        shown = [e for e in entries.values() if e is not None]
        quality = max((e["quality"] for e in shown), key=QUALITY_RANK.__getitem__, default="unknown")
        times = [e["time"] for e in shown if e.get("time") is not None]
        age = max(0.0, now - min(times)) if times else None
        return {"lines": lines, "alarms": alarms, "raised": raised, "bar": bar, "icon": icon, "quality": quality, "age": age}


def template_fields(entry: dict[str, Any]) -> dict[str, Any]:
    """The fields a tile's template may name (``{value}``, ``{unit}``, ``{name}``, ``{text}``) of one live entry."""
    text = entry.get("text")
    value = entry.get("value")
    return {"value": value, "unit": entry.get("unit", ""), "name": entry.get("name") or text or value,
            "text": text if text is not None else (f"{value} {entry.get('unit', '')}".strip() if value is not None else "-")}


def format_can_ids(first: int, last: int, extended: bool) -> str:
    """``0x705``, ``0x600-0x6FF``, ``0x000A1234 (ext)``."""
    width = 8 if extended else 2
    text = f"0x{first:0{width}X}" if first == last else f"0x{first:0{width}X}-0x{last:0{width}X}"
    return text + (" (ext)" if extended else "")


@dataclass(frozen=True)
class OpenRead:
    """A read a device page runs by itself when it opens on a device that answers and none of whose parameters was
    ever read, so that its entries start at the device's values (a read changes nothing): the declared command
    ``command``, once per device per ``again_s`` whatever the number of pages (app/open_reads.py)."""

    command: str
    again_s: float = 30.0


@dataclass(frozen=True)
class DeviceType:
    """What the application needs to know about one kind of device.

    :param adapters: bus type -> ``"module:Class"`` of ``(config, state, transport) -> adapter``
    :param sims: bus type -> ``"module:Class"`` of ``(bus_config, device_configs) -> twin server``
    :param check_config: ``(options, bus_type) -> [(key, message)]`` for the plant-file loader
    :param bus_identity: ``(options, bus_type) -> address`` that must be unique on a bus, or None
    :param can_codec: ``"module"`` with ``describe_frame(id, ext, data, known) -> str | None`` and
        ``discovered(id, ext, data) -> dict | None`` for the bus monitor and discovery; a dict that
        carries ``"evidence": {"period_s", "tolerance", "frames"}`` is listed only after that many
        such frames at that period
    :param can_fixed_ids: CAN IDs the type occupies on any CAN bus it sits on, whatever its
        configuration (the plant loader refuses other devices on them; discovery never lists them)
    :param can_ids: ``(options, bus_type) -> [CanIdUse]``: the further IDs one configured device
        sends and receives
    :param manufacturer: who makes it (the OPC UA server's DI identification); the title where empty
    :param line_codec: ``"module"`` of the framing of a line the type's own protocol runs on (its
        bus types that are no shared field bus), for the line's transport: e.g. the token passing of
        a multi-master RS485 line
    :param open_reads: the reads a device page runs by itself when it opens on a device never read (:class:`OpenRead`)
    :param scans: bus type -> ``"module:function"`` of ``discover(line, first, last, progress)``, the scan
        for devices of this type on a line of that bus type
    :param worded_names: the parameter model's names are this tool's words, in the catalogs (the barrier's "Open
        time"), not the document's register names (``LockRequestDelay``), which pages show as the document prints them
    """

    name: str
    title: str
    bus_types: tuple[str, ...]
    params: ParamMap | None
    adapters: dict[str, str]
    sims: dict[str, str] = field(default_factory=dict)
    check_config: Callable[[dict[str, Any], str], list[tuple[str, str]]] = lambda options, bus_type: []
    bus_identity: Callable[[dict[str, Any], str], Any] = lambda options, bus_type: None
    can_codec: str = ""
    can_fixed_ids: tuple[CanIdUse, ...] = ()
    can_ids: Callable[[dict[str, Any], str], Sequence[CanIdUse]] = lambda options, bus_type: ()
    tile: TileSpec = field(default_factory=TileSpec)  # the overview tile and the /plant tile, declared
    extra: dict[str, Any] = field(default_factory=dict)
    manufacturer: str = ""
    line_codec: str = ""
    scans: dict[str, str] = field(default_factory=dict)
    open_reads: tuple[OpenRead, ...] = ()  # what a device page reads by itself on opening
    worded_names: bool = False

    def can_id_uses(self, options: dict[str, Any], bus_type: str) -> tuple[CanIdUse, ...]:
        """Every CAN ID a device of this type with ``options`` uses on a bus of ``bus_type``."""
        if bus_type != "can":
            return ()
        return self.can_fixed_ids + tuple(self.can_ids(options, bus_type))

    def adapter_class(self, bus_type: str) -> Callable[..., Any]:
        return _load(self.adapters[bus_type])

    def sim_class(self, bus_type: str) -> Callable[..., Any] | None:
        return _load(self.sims[bus_type]) if bus_type in self.sims else None

    def line_scan(self, bus_type: str) -> Callable[..., Any] | None:
        """The scan for devices of this type on a line of ``bus_type`` (declared in ``scans``), or None where it
        offers none."""
        return _load(self.scans[bus_type]) if bus_type in self.scans else None


def _load(spec: str) -> Callable[..., Any]:
    module, _, attr = spec.partition(":")
    return getattr(importlib.import_module(module), attr)


def _discover() -> dict[str, DeviceType]:
    import devices

    found: dict[str, DeviceType] = {}
    for info in pkgutil.iter_modules(devices.__path__):
        if not info.ispkg:
            continue
        module = importlib.import_module(f"devices.{info.name}")
        device_type = getattr(module, "DEVICE_TYPE", None)
        if isinstance(device_type, DeviceType):
            found[device_type.name] = device_type
    return found


class _DeviceTypes(Mapping[str, DeviceType]):
    """Found on first use, so a device package may import this module while it loads."""

    def __init__(self) -> None:
        self._types: dict[str, DeviceType] | None = None

    def _all(self) -> dict[str, DeviceType]:
        if self._types is None:
            self._types = _discover()
        return self._types

    def __getitem__(self, name: str) -> DeviceType:
        return self._all()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._all())

    def __len__(self) -> int:
        return len(self._all())


DEVICE_TYPES: Mapping[str, DeviceType] = _DeviceTypes()


def iter_types() -> Iterator[DeviceType]:
    return iter(DEVICE_TYPES.values())


def line_codec(bus_type: str) -> Any:
    """The framing module of the device type that declares one for ``bus_type`` (see ``DeviceType.line_codec``).

    :raises LookupError: no type declares one
    """
    for device_type in iter_types():
        if device_type.line_codec and bus_type in device_type.bus_types:
            return importlib.import_module(device_type.line_codec)
    raise LookupError(f"no device type declares the framing of a {bus_type} line")


def fixed_can_id_uses() -> Iterator[tuple[DeviceType, CanIdUse]]:
    """The CAN IDs every CAN device type occupies whatever its configuration."""
    for device_type in iter_types():
        if "can" in device_type.bus_types:
            for use in device_type.can_fixed_ids:
                yield device_type, use
