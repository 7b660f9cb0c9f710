"""Device types, found by looking at the packages under ``devices/``.

A device package exposes ``DEVICE_TYPE`` in its ``__init__.py``; nothing here
or in ``app/`` needs to change when a package is added.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any

from devices.params import ParamMap


@dataclass(frozen=True)
class DeviceType:
    """What the application needs to know about one kind of device.

    :param adapters: bus type -> ``"module:Class"`` of ``(config, state, transport) -> adapter``
    :param sims: bus type -> ``"module:Class"`` of ``(bus_config, device_configs) -> twin server``
    :param check_config: ``(options, bus_type) -> [(key, message)]`` for the plant-file loader
    :param bus_identity: ``(options, bus_type) -> address`` that must be unique on a bus, or None
    :param can_codec: ``"module"`` with ``describe_frame(id, ext, data, known) -> str | None`` and
        ``discovered(id, ext, data) -> dict | None`` for the bus monitor and discovery
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
    key_values: tuple[str, ...] = ()  # parameter names shown on tiles
    summary: Callable[[Any], list[str]] | None = None  # state -> tile lines, where key_values do not fit
    # state -> {"lines": [...], "alarms": [...], "bar": (fraction, label) | None, "icon": str} for /plant
    plant_tile: Callable[[Any], dict] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

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
