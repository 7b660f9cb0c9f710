"""Modbus transactions named through the parameter model of the device at their unit."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from app.capabilities import bus_address
from app.i18n import N_
from app.line_base import Transaction
from app.message import Message, joined, message_of
from app.recording.base import MAX_CACHE
from devices.params import ParamMap
from devices.registry import DEVICE_TYPES


# -- Modbus transactions ------------------------------------------------------------------------------

MAX_DECODED_REGISTERS = 16  # registers named in one transaction's text; the rest are counted


def describe_registers(params: ParamMap, space: str, address: int, values: Iterable[int]) -> Message:
    """Registers from ``address`` on as ``Name = value`` through the parameter model (signed, scaled,
    enum and bit names, unit); a value of several words is joined; unlisted registers by number. The names and
    values are the parameter model's; the words around them (``first word``, ``word 2 of 2``, ``3 more``) a
    page words in its language."""
    values = [int(v) & 0xFFFF for v in values]
    parts: list[str | Message] = []
    i = 0
    while i < len(values) and len(parts) < MAX_DECODED_REGISTERS:
        addr = address + i
        param = params.get(space, addr)
        if param is not None and param.words > 1 and i + param.words <= len(values):
            raw = param.combine(values[i:i + param.words])
            parts.append(f"{param.label or param.name} = {param.display(raw)}")
            i += param.words
            continue
        if param is not None and param.words == 1:
            parts.append(f"{param.label or param.name} = {param.display(values[i])}")
        elif param is not None:
            parts.append(Message(N_("{name} (first word) = {value}"), name=param.label or param.name, value=values[i]))
        else:
            whole = next((p for p in params.space(space) if addr in p.addresses), None)
            parts.append(Message(N_("{name} (word {n} of {words}) = {value}"), name=whole.label or whole.name,
                                 n=addr - whole.address + 1, words=whole.words, value=values[i])
                         if whole is not None else f"{space} {addr} = {values[i]}")
        i += 1
    if i < len(values):
        parts.append(Message(N_("... {n} more"), n=len(values) - i))
    return joined(parts, "; ")


class TransactionDecoder:
    """Names the device at a Modbus unit and decodes a transaction through its parameter model.

    The unit of a device is its adapter's current ``address`` (it follows a Set Modbus Address),
    else its type's ``bus_identity``. A unit no configured device has (a line scan) is decoded with
    the parameter model of the line's device type when the line carries one type only.
    """

    def __init__(self, worker: Any, bus: str):
        self.worker = worker
        self.bus = bus
        self.units: dict[int, tuple[str, ParamMap | None]] = {}
        self.line_params: ParamMap | None = None
        self._cache: dict[tuple, str | Message] = {}
        self.refresh()

    def refresh(self) -> None:
        """Read the units again (an address may have changed)."""
        bus_config = self.worker.plant.buses.get(self.bus)
        bus_type = bus_config.type if bus_config is not None else "modbus-rtu"
        units: dict[int, tuple[str, ParamMap | None]] = {}
        types: set[str] = set()
        for dev in self.worker.plant.devices_on(self.bus):
            device_type = DEVICE_TYPES.get(dev.type)
            types.add(dev.type)
            unit = bus_address(self.worker.adapters.get(dev.name))
            if unit is None and device_type is not None:
                unit = device_type.bus_identity(dev.options, bus_type)
            if isinstance(unit, int):
                units[unit] = (dev.name, device_type.params if device_type is not None else None)
        line_params = DEVICE_TYPES[next(iter(types))].params if len(types) == 1 and next(iter(types)) in DEVICE_TYPES else None
        self.modbus = bus_type == "modbus-rtu"
        names = [dev.name for dev in self.worker.plant.devices_on(self.bus)]
        self.only = names[0] if len(names) == 1 and not self.modbus else ""  # a point-to-point line or a TCP link
        if units != self.units or line_params is not self.line_params:
            self.units, self.line_params = units, line_params
            self._cache.clear()

    def device(self, unit: int) -> str | Message:
        """``door-1 (unit 1)``; ``broadcast (unit 0)``; ``unit 7`` for an address no device has.

        Other lines name their device by its bus address (``barrier-out-1 (address 16)``), or name
        the one device of a point-to-point line or TCP link.
        """
        if self.only:
            return self.only
        if not self.modbus:
            if unit in self.units:
                return Message(N_("{device} (address {address})"), device=self.units[unit][0], address=unit)
            return Message(N_("address {address}"), address=unit) if unit else ""
        if unit in self.units:
            return Message(N_("{device} (unit {unit})"), device=self.units[unit][0], unit=unit)
        if unit in (0, 255):  # Modbus broadcast 0; 255 broadcast of the HD-Lock's Set Modbus Address (section 4.3)
            return Message(N_("broadcast (unit {unit})"), unit=unit)
        return Message(N_("unit {unit}"), unit=unit)

    def decoded(self, t: Transaction) -> str | Message:
        """The transaction's registers by name and value, else the line's own text."""
        if t.error or not t.space or t.address is None or not t.values:
            return t.decoded
        params = self.units[t.unit][1] if t.unit in self.units else self.line_params
        if params is None:
            return t.decoded
        write = "write" in t.request.split()
        key = (t.unit, t.space, t.address, t.values, write)
        text = self._cache.get(key)
        if text is None:
            if len(self._cache) >= MAX_CACHE:
                self._cache.clear()
            try:
                body = describe_registers(params, t.space, t.address, t.values)
            except (LookupError, ValueError) as exc:  # words the model cannot decode (a ValueError) are shown as such
                body = Message(N_("decode failed: {error}"), error=message_of(exc))
            text = self._cache[key] = Message(N_("wrote {registers}"), registers=body) if write else body
        return text
