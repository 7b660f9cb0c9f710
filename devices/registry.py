"""Device types, found by looking at the packages under ``devices/``.

A device package exposes ``DEVICE_TYPE`` in its ``__init__.py``; nothing here
or in ``app/`` needs to change when a package is added.
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

from devices.params import ParamMap


@dataclass(frozen=True)
class DeviceType:
    """What the application needs to know about one kind of device.

    :param make_adapter: ``(config, state, transport) -> adapter`` (imported lazily)
    :param make_sims: ``(bus_config, device_configs) -> twin server`` for the simulated plant
    :param check_config: ``options -> [(key, message)]`` for the plant-file loader
    :param bus_identity: ``options -> address`` that must be unique on a bus, or None
    """

    name: str
    title: str
    bus_types: tuple[str, ...]
    params: ParamMap | None
    adapter: str  # "module:callable"
    sim: str = ""  # "module:callable"
    check_config: Callable[[dict[str, Any]], list[tuple[str, str]]] = lambda options: []
    bus_identity: Callable[[dict[str, Any]], Any] = lambda options: None
    key_values: tuple[str, ...] = ()  # parameter names shown on tiles
    extra: dict[str, Any] = field(default_factory=dict)

    def load(self, what: str) -> Callable[..., Any]:
        module, _, attr = getattr(self, what).partition(":")
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


DEVICE_TYPES: dict[str, DeviceType] = _discover()


def iter_types() -> Iterator[DeviceType]:
    return iter(DEVICE_TYPES.values())
