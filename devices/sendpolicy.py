"""The one send policy: may these bytes go to this bus, and what must be confirmed first.

Each device type declares its rules as data in its own package (``devices/<type>/policy.py``):
frames, registers and command codes it never sends (firmware update, MFR, factory reset,
erase), values that need a confirmation naming the risk, and the CAN IDs it uses. This module
asks those rules; every path that sends raw bytes (transmit list, replay, Modbus poll window,
restore, device commands) calls :func:`check_send` (or one of its two halves) and nothing else.

A policy module declares ``COMMANDS`` (:mod:`devices.commands`) and each of these hooks, None where the
type has none:

- ``check_can(can_id, extended, data, devices, bus) -> Verdict | None``: ``devices`` are the plant's
  devices of the type on the bus (``.name``, ``.options``), ``bus`` all devices of the bus; called for every frame on a CAN bus
  where the type is configured or whose fixed IDs it reserves on every CAN bus;
- ``check_modbus(function, address, values, device) -> Verdict``: a write to a unit of the type
  (``device`` None for a unit that is not in the plant, on a line of that type);
- ``transmit_forms(options) -> [TxForm]``: the frames the transmit list builds by name (devices/commands.py).

Pure: no I/O, no imports of ``app`` or ``pages``.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from types import ModuleType
from typing import Any

from devices.message import N_, Message, joined

# how much each kind of action weighs: a verdict over several findings takes the heaviest
KINDS = ("read", "stop", "write", "system", "mains", "motion")
_WEIGHT = {k: i for i, k in enumerate(KINDS)}
READ_FUNCTIONS = (1, 2, 3, 4)
WRITE_FUNCTIONS = (5, 6, 15, 16)


@dataclass(frozen=True)
class Verdict:
    """The answer: ``refused`` says why the bytes are never sent ("" = they may be); ``confirm``
    lists the risks to confirm first; ``name`` names the bytes for the audit (e.g. "door-1
    LockRequestDelay (holding 3000)"); ``kind`` is what sending them does."""

    refused: str = ""
    confirm: tuple[str, ...] = ()
    name: str = ""
    kind: str = "write"

    @property
    def allowed(self) -> bool:
        return not self.refused

    @property
    def question(self) -> str:
        """The confirmation text (every risk, each once; a Message its reader words), or ""."""
        return joined(list(dict.fromkeys(self.confirm)), " ") if self.confirm else ""


def combine(verdicts: Sequence[Verdict], default: Verdict | None = None) -> Verdict:
    """One verdict from several findings: refused when any refuses, every risk, the heaviest kind."""
    found = [v for v in verdicts if v is not None]
    if not found:
        return default or Verdict()
    refusals = list(dict.fromkeys(v.refused for v in found if v.refused))
    refused = joined(refusals, "; ") if refusals else ""
    confirm = tuple(dict.fromkeys(c for v in found for c in v.confirm))
    name = next((v.name for v in found if v.name), "")
    kind = max((v.kind for v in found), key=lambda k: _WEIGHT.get(k, _WEIGHT["write"]))
    return Verdict(refused, confirm, name, kind)


@dataclass(frozen=True)
class CanMessage:
    can_id: int
    extended: bool
    data: bytes


@dataclass(frozen=True)
class ModbusMessage:
    """A Modbus request: ``function`` 1-4 reads, 5/15 coil writes, 6/16 register writes."""

    unit: int
    function: int
    address: int
    values: tuple[int, ...] = ()


@dataclass(frozen=True)
class BusDevice:
    """A device of the plant on the bus (the plant's DeviceConfig has the same fields)."""

    name: str
    type: str
    options: dict[str, Any] = field(default_factory=dict)


_modules: dict[str, ModuleType | None] = {}


def policy_of(type_name: str) -> ModuleType | None:
    """``devices.<type>.policy``, or None when the type declares none."""
    if type_name not in _modules:
        try:
            _modules[type_name] = importlib.import_module(f"devices.{type_name}.policy")
        except ModuleNotFoundError as exc:
            if exc.name != f"devices.{type_name}.policy":
                raise
            _modules[type_name] = None
    return _modules[type_name]


def _can_types(bus_devices: Sequence[Any]) -> list[str]:
    """The types configured on the bus, and every type that reserves fixed IDs on every CAN bus."""
    from devices.registry import DEVICE_TYPES

    names = {d.type for d in bus_devices}
    names |= {t.name for t in DEVICE_TYPES.values() if "can" in t.bus_types and t.can_fixed_ids}
    return sorted(names)


def check_can(bus_devices: Sequence[Any], can_id: int, extended: bool, data: bytes) -> Verdict:
    """The verdict on one CAN frame for a bus with ``bus_devices`` (objects with ``name``, ``type``, ``options``).

    A frame on an ID that no policy knows is a write nobody declared: allowed, no confirmation
    (a raw frame of the engineer's own, e.g. for a device this tool does not know).
    """
    data = bytes(data)
    verdicts = []
    for type_name in _can_types(bus_devices):
        policy = policy_of(type_name)
        check = policy.check_can if policy is not None else None
        if check is None:
            continue
        verdicts.append(check(can_id, extended, data, [d for d in bus_devices if d.type == type_name], bus_devices))
    return combine(verdicts)


UNKNOWN_UNIT_RISK = N_("unit {unit} is not a device of the plant and the device type on this line is not known: "
                       "nothing checks what {what} does to it.")


def check_modbus(line_devices: Sequence[Any], message: ModbusMessage) -> Verdict:
    """The verdict on one Modbus request on a line with ``line_devices``.

    The unit's device type decides: the plant's device at that address, else the type of the
    line (every device of the line of one type, e.g. a lock right after a scan or an address
    change); a unit of no known type gets a confirmation for every write.
    """
    if message.function in READ_FUNCTIONS:
        return Verdict(kind="read")
    if message.function not in WRITE_FUNCTIONS:
        return Verdict(refused=Message(N_("function {function:02d} is not sent by this tool"), function=message.function))
    device = next((d for d in line_devices if d.options.get("address") == message.unit), None)
    types = {d.type for d in line_devices}
    type_name = device.type if device is not None else (next(iter(types)) if len(types) == 1 else "")
    policy = policy_of(type_name) if type_name else None
    check = policy.check_modbus if policy is not None else None
    if check is None:
        what = Message(N_("this write")) if message.function in (6, 16) else Message(N_("this coil write"))
        where = N_("unit {unit} coil {address}") if message.function in (5, 15) else N_("unit {unit} holding {address}")
        return Verdict(confirm=(Message(UNKNOWN_UNIT_RISK, unit=message.unit, what=what),),
                       name=Message(where, unit=message.unit, address=message.address), kind="write")
    verdict = check(message.function, message.address, list(message.values), device)
    if device is None:
        note = Message(N_("unit {unit} is not in the plant file: checked as {type} (the type of every device on this line)."),
                       unit=message.unit, type=type_name)
        name = (Message(N_("unit {unit} {name}"), unit=message.unit, name=verdict.name) if verdict.name
                else Message(N_("unit {unit}"), unit=message.unit))
        verdict = Verdict(verdict.refused, (*verdict.confirm, note) if not verdict.refused else (), name, verdict.kind)
    return verdict


def check_send(bus_devices: Sequence[Any], message: CanMessage | ModbusMessage) -> Verdict:
    """May ``message`` go to a bus with ``bus_devices``, and what must be confirmed first."""
    if isinstance(message, CanMessage):
        return check_can(bus_devices, message.can_id, message.extended, message.data)
    return check_modbus(bus_devices, message)


def can_id_owner(bus_devices: Sequence[Any], can_id: int, extended: bool, *, exclude: str = "") -> str:
    """Who uses ``can_id`` on a bus already: any device type's fixed IDs, or a device of the bus (but
    ``exclude``); "" when nobody does (section 6.2 b of the HD-Lock document: one participant per ID)."""
    from devices.registry import DEVICE_TYPES, fixed_can_id_uses

    for device_type, use in fixed_can_id_uses():
        if use.covers(extended, can_id):
            return f"{use.use} ({device_type.title})"
    for dev in bus_devices:
        if dev.name == exclude or dev.type not in DEVICE_TYPES:
            continue
        for use in DEVICE_TYPES[dev.type].can_ids(dev.options, "can"):
            if use.covers(extended, can_id):
                return f"{dev.name}: {use.use}"
    return ""
