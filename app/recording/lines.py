"""The telegrams of the request/answer lines that are not Modbus, in the words of their device pages.

The bus monitor lists every telegram of an RS232 or LogiTed line as a :class:`app.line_base.Transaction` with its
bytes. A device type whose protocol runs on such a line words them itself, in a module ``linewords.py`` beside its
adapter (the contract: :mod:`devices.linewords`): what its page calls the same thing, and the filters that fit its
telegrams. Here that module is found through the registry for the line's device type. No UI here.
"""

from __future__ import annotations

import importlib
from types import ModuleType
from typing import Any

from devices.linewords import LineDecoder, LineFilter, LineText
from devices.registry import DEVICE_TYPES


def linewords_module(type_name: str, bus_type: str) -> ModuleType | None:
    """The ``linewords`` module beside the adapter of ``type_name`` for ``bus_type``, or None."""
    device_type = DEVICE_TYPES.get(type_name)
    if device_type is None or bus_type not in device_type.adapters:
        return None
    package = device_type.adapters[bus_type].partition(":")[0].rpartition(".")[0]
    try:
        return importlib.import_module(f"{package}.linewords")
    except ModuleNotFoundError:
        return None


class LineWords:
    """A line's decoder and filters, as its device type declares them."""

    def __init__(self, decoder: LineDecoder, filters: tuple[LineFilter, ...]):
        self.decoder = decoder
        self.filters = tuple(filters)

    def refresh(self) -> None:
        self.decoder.refresh()

    def text(self, t: Any) -> LineText:
        return self.decoder.text(t)


def line_words(worker: Any, bus: str) -> LineWords | None:
    """The words and filters of a line by the device type on it (None: Modbus, a CAN bus, or a type that declares
    none; a line of several types is worded by the first that declares them)."""
    config = worker.plant.buses.get(bus)
    if config is None or config.type in ("modbus-rtu", "can"):
        return None
    devices = list(worker.plant.devices_on(bus))
    for type_name in dict.fromkeys(d.type for d in devices):
        module = linewords_module(type_name, config.type)
        if module is not None:
            mine = [d for d in devices if d.type == type_name]
            return LineWords(module.decoder(mine, worker.adapters, config.type, dict(config.options)), module.FILTERS)
    return None
