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


def format_can_ids(first: int, last: int, extended: bool) -> str:
    """``0x705``, ``0x600-0x6FF``, ``0x000A1234 (ext)``."""
    width = 8 if extended else 2
    text = f"0x{first:0{width}X}" if first == last else f"0x{first:0{width}X}-0x{last:0{width}X}"
    return text + (" (ext)" if extended else "")


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
    key_values: tuple[str, ...] = ()  # parameter names shown on tiles
    summary: Callable[[Any], list[str]] | None = None  # state -> tile lines, where key_values do not fit
    # state -> {"lines": [...], "alarms": [...], "bar": (fraction, label) | None, "icon": str} for /plant
    plant_tile: Callable[[Any], dict] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def can_id_uses(self, options: dict[str, Any], bus_type: str) -> tuple[CanIdUse, ...]:
        """Every CAN ID a device of this type with ``options`` uses on a bus of ``bus_type``."""
        if bus_type != "can":
            return ()
        return self.can_fixed_ids + tuple(self.can_ids(options, bus_type))

    def adapter_class(self, bus_type: str) -> Callable[..., Any]:
        return _load(self.adapters[bus_type])

    def sim_class(self, bus_type: str) -> Callable[..., Any] | None:
        return _load(self.sims[bus_type]) if bus_type in self.sims else None


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


def fixed_can_id_uses() -> Iterator[tuple[DeviceType, CanIdUse]]:
    """The CAN IDs every CAN device type occupies whatever its configuration."""
    for device_type in iter_types():
        if "can" in device_type.bus_types:
            for use in device_type.can_fixed_ids:
                yield device_type, use
