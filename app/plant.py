"""The plant file (TOML): buses and devices, with errors that name file, line and problem."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomllib

from devices.registry import DEVICE_TYPES, format_can_ids

PLANTS_DIR = Path(__file__).resolve().parent.parent / "plants"
DEMO_PLANT = PLANTS_DIR / "demo.toml"

# bus type -> key -> (python type, default); None default = required
BUS_KEYS: dict[str, dict[str, tuple[type | tuple[type, ...], Any]]] = {
    "modbus-rtu": {
        "port": (str, None),
        "baudrate": (int, 19200),
        "parity": (str, "E"),
        "stopbits": (int, 1),
        "bytesize": (int, 8),
        "timeout": ((int, float), 0.5),
        "retries": (int, 1),
        "poll_period": ((int, float), 0.5),
        "simulate": (bool, False),
        "wire_delay": (bool, False),
    },
    "can": {
        "interface": (str, None),  # python-can interface: socketcan, pcan, kvaser, slcan, gs_usb, virtual, udp_multicast ...
        "channel": ((str, int), None),
        "bitrate": (int, 250000),
        "timeout": ((int, float), 0.5),
        "poll_period": ((int, float), 2.0),
        "simulate": (bool, False),
    },
    "serial": {  # point-to-point RS232 (Ewellix SCU): a device path or pyserial URL, 8N1, DTR and RTS held on
        "port": (str, None),
        "baudrate": (int, 38400),  # 9600 and 19200 on custom units
        "timeout": ((int, float), 0.3),  # seconds for a complete answer
        "poll_period": ((int, float), 0.2),  # the keep-alive and live-data cycle
        "simulate": (bool, False),
        "wire_delay": (bool, False),  # simulated unit: answer after the 8N1 wire time (benchmarks)
    },
    "logited-tcp": {  # Bauer MO 64 over TCP/IP: the barrier is the server and takes one client at a time
        "host": (str, None),
        "port": (int, 52719),
        "timeout": ((int, float), 1.0),  # seconds for an answer
        "poll_period": ((int, float), 1.0),  # seconds between polls (slower while change monitoring reports)
        "simulate": (bool, False),
    },
    "logited-rs485": {  # Bauer MO 64 on RS485 (38400 8N1), several barriers by bus address, multi-master
        "port": (str, None),
        "baudrate": (int, 38400),
        "master_address": (int, 0),  # this tool's address as a master
        "shared": (bool, False),  # other masters on the line: take part in token passing
        "next_master": (int, 1),  # the master the token is passed to (shared lines)
        "timeout": ((int, float), 0.5),
        "poll_period": ((int, float), 1.0),
        "simulate": (bool, False),
    },
}
PASSTHROUGH_BUS_TYPES = {"can"}  # further keys go to the bus library unchanged
COMMON_BUS_KEYS = {"name", "type", "description"}
COMMON_DEVICE_KEYS = {"name", "type", "bus", "description"}


class PlantError(ValueError):
    """A plant file that cannot be used; the message says where and what."""


@dataclass
class BusConfig:
    name: str
    type: str
    options: dict[str, Any]
    line: int = 0

    @property
    def simulated(self) -> bool:
        return bool(self.options.get("simulate"))

    @property
    def endpoint(self) -> str:
        if self.type == "can":
            return f"{self.options.get('interface')} {self.options.get('channel')}"
        if self.type == "logited-tcp":
            return f"{self.options.get('host')}:{self.options.get('port')}"
        return str(self.options.get("port") or "")


@dataclass
class DeviceConfig:
    name: str
    type: str
    bus: str
    options: dict[str, Any]
    line: int = 0


@dataclass
class PlantViewConfig:
    public: bool = False


@dataclass
class Plant:
    name: str
    path: Path | None
    buses: dict[str, BusConfig] = field(default_factory=dict)
    devices: dict[str, DeviceConfig] = field(default_factory=dict)
    sim_devices: dict[str, DeviceConfig] = field(default_factory=dict)  # simulated, not (yet) in the plant
    plant_view: PlantViewConfig = field(default_factory=PlantViewConfig)

    def devices_on(self, bus: str) -> list[DeviceConfig]:
        return [d for d in self.devices.values() if d.bus == bus]


def _header_lines(text: str, table: str) -> list[int]:
    """Line numbers (1-based) of each ``[[table]]`` header, in order."""
    pattern = re.compile(rf"^\s*\[\[\s*{re.escape(table)}\s*\]\]")
    return [i + 1 for i, line in enumerate(text.splitlines()) if pattern.match(line)]


def _key_line(text: str, start: int, key: str) -> int:
    """Line of ``key =`` in the table that starts at ``start`` (falls back to ``start``)."""
    lines = text.splitlines()
    pattern = re.compile(rf"^\s*{re.escape(key)}\s*=")
    for i in range(start, len(lines)):  # ``start`` is 1-based: this begins below the header
        if lines[i].lstrip().startswith("["):
            break
        if pattern.match(lines[i]):
            return i + 1
    return start


def load_plant(path: str | Path) -> Plant:
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise PlantError(f"{path}: cannot read the plant file: {exc.strerror or exc}") from None
    return parse_plant(text, path)


def parse_plant(text: str, path: Path | None = None) -> Plant:
    where = str(path) if path else "<plant>"
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise PlantError(f"{where}: not valid TOML: {exc}") from None

    def fail(line: int, message: str) -> PlantError:
        return PlantError(f"{where}:{line}: {message}")

    unknown_top = set(data) - {"name", "bus", "device", "sim_device", "plant_view"}
    if unknown_top:
        raise fail(1, f"unknown section(s) {', '.join(sorted(unknown_top))}; expected [[bus]], [[device]], [[sim_device]], [plant_view]")
    plant = Plant(name=str(data.get("name") or (path.stem if path else "plant")), path=path)
    pv = data.get("plant_view", {})
    pv_line = next((i + 1 for i, line in enumerate(text.splitlines()) if re.match(r"^\s*\[\s*plant_view\s*\]", line)), 1)
    if not isinstance(pv, dict):
        raise fail(pv_line, "[plant_view] must be a table, e.g. [plant_view] public = true")
    for key in sorted(set(pv) - {"public"}):
        raise fail(_key_line(text, pv_line, key), f"[plant_view]: unknown key '{key}'; known: public (true or false)")
    public = pv.get("public", False)
    if not isinstance(public, bool):
        # a string such as "false" would be true in Python: only a real boolean opens the view
        raise fail(_key_line(text, pv_line, "public"), f"[plant_view] public must be true or false (without quotes), not {public!r}")
    plant.plant_view = PlantViewConfig(public=public)

    bus_lines = _header_lines(text, "bus")
    for index, raw in enumerate(data.get("bus", [])):
        line = bus_lines[index] if index < len(bus_lines) else 1
        name = raw.get("name")
        if not isinstance(name, str) or not name:
            raise fail(line, "bus without a name (add name = \"...\")")
        if name in plant.buses:
            raise fail(line, f"duplicate bus name '{name}' (first at line {plant.buses[name].line})")
        btype = raw.get("type")
        if btype not in BUS_KEYS:
            raise fail(_key_line(text, line, "type"), f"bus '{name}': unknown type {btype!r}; known: {', '.join(BUS_KEYS)}")
        spec = BUS_KEYS[btype]
        options: dict[str, Any] = {}
        for key, value in raw.items():
            if key in COMMON_BUS_KEYS:
                continue
            if key not in spec and btype in PASSTHROUGH_BUS_TYPES:
                options[key] = value
                continue
            if key not in spec:
                raise fail(_key_line(text, line, key), f"bus '{name}': unknown key '{key}'; known: {', '.join(spec)}")
            typ = spec[key][0]
            if isinstance(value, bool) and typ is not bool or not isinstance(value, typ):
                raise fail(_key_line(text, line, key), f"bus '{name}': '{key}' has the wrong type ({value!r})")
            options[key] = value
        for key, (_typ, default) in spec.items():
            if key not in options:
                if default is None:
                    raise fail(line, f"bus '{name}': '{key}' is required")
                options[key] = default
        if btype == "modbus-rtu":
            if options["parity"] not in ("N", "E", "O"):
                raise fail(_key_line(text, line, "parity"), f"bus '{name}': parity must be \"N\", \"E\" or \"O\"")
        if options["timeout"] <= 0:
            raise fail(_key_line(text, line, "timeout"), f"bus '{name}': timeout must be > 0 s")
        if btype == "logited-rs485":
            for key in ("master_address", "next_master"):
                if not 0 <= options[key] <= 255:
                    raise fail(_key_line(text, line, key), f"bus '{name}': {key} {options[key]} is outside 0..255")
            if options["shared"] and options["next_master"] == options["master_address"]:
                raise fail(_key_line(text, line, "next_master"),
                           f"bus '{name}': next_master must be another master than this tool ({options['master_address']})")
        if btype == "serial" and options["baudrate"] not in (9600, 19200, 38400):
            raise fail(_key_line(text, line, "baudrate"), f"bus '{name}': baudrate {options['baudrate']} is not one of 9600, 19200, 38400")
        if btype == "can" and not 5000 <= options["bitrate"] <= 1_000_000:
            raise fail(_key_line(text, line, "bitrate"), f"bus '{name}': bitrate {options['bitrate']} is outside 5000..1000000 bit/s")
        plant.buses[name] = BusConfig(name, btype, options, line)

    _parse_devices(text, data, plant, "device", plant.devices, fail)
    _parse_devices(text, data, plant, "sim_device", plant.sim_devices, fail)

    for bus in plant.buses.values():
        seen: dict[Any, str] = {}
        for dev in plant.devices_on(bus.name) + [d for d in plant.sim_devices.values() if d.bus == bus.name]:
            ident = DEVICE_TYPES[dev.type].bus_identity(dev.options, bus.type)
            if ident is not None and ident in seen:
                what = f"address {ident}" if isinstance(ident, int) else str(ident)  # a type may name its own identity
                raise fail(dev.line, f"device '{dev.name}': {what} is already used by '{seen[ident]}' on bus '{bus.name}'")
            if ident is not None:
                seen[ident] = dev.name
        conflict = can_id_conflict(plant.devices_on(bus.name) + [d for d in plant.sim_devices.values() if d.bus == bus.name], bus)
        if conflict is not None:
            raise fail(conflict[0].line, conflict[1])
    return plant


def can_id_conflict(devices: list[DeviceConfig], bus: BusConfig) -> tuple[DeviceConfig, str] | None:
    """The first CAN ID that two devices on ``bus`` (or one device twice) would both use.

    Each device type declares the IDs it sends and receives (``DeviceType.can_id_uses``).
    Returns ``(the later device, message naming both devices, the ID and its use in each)``.
    """
    if bus.type != "can":
        return None
    # HD-Lock document 6.2 b: "jede CAN-ID [darf] jeweils nur von einem Busteilnehmer verwendet werden"
    rule = "A CAN ID may carry one sender's messages only: change an address or use separate buses."
    earlier = []
    for dev in devices:
        device_type = DEVICE_TYPES[dev.type]
        uses = device_type.can_id_uses(dev.options, bus.type)
        for i, a in enumerate(uses):
            for b in uses[i + 1:]:
                span = None if a.shared and b.shared else a.overlap(b)
                if span:
                    ids = ("CAN ID " if span[0] == span[1] else "CAN IDs ") + format_can_ids(*span, a.extended)
                    return dev, (f"device '{dev.name}': {ids} is used twice by this {device_type.title} on bus '{bus.name}', "
                                 f"as {a.use} and as {b.use}. {rule}")
        for other, other_type, other_uses in earlier:
            same_type = other.type == dev.type
            for a in uses:
                for b in other_uses:
                    span = None if same_type and a.shared and b.shared else a.overlap(b)
                    if span:
                        ids = ("CAN ID " if span[0] == span[1] else "CAN IDs ") + format_can_ids(*span, a.extended)
                        return dev, (f"device '{dev.name}': {ids} is used twice on bus '{bus.name}': by '{dev.name}' "
                                     f"({device_type.title}) as {a.use}, and by '{other.name}' ({other_type.title}) as {b.use}. {rule}")
        earlier.append((dev, device_type, uses))
    return None


def _parse_devices(text, data, plant, table, target, fail) -> None:
    """``[[device]]`` (in the plant) and ``[[sim_device]]`` (only in the simulation, to be discovered)."""
    device_lines = _header_lines(text, table)
    for index, raw in enumerate(data.get(table, [])):
        line = device_lines[index] if index < len(device_lines) else 1
        name = raw.get("name")
        if not isinstance(name, str) or not name:
            raise fail(line, "device without a name (add name = \"...\")")
        if not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
            raise fail(line, f"device name '{name}' may only contain letters, digits, '_', '.', '-'")
        if name in plant.devices or name in plant.sim_devices:
            first = (plant.devices.get(name) or plant.sim_devices[name]).line
            raise fail(line, f"duplicate device name '{name}' (first at line {first})")
        dtype = raw.get("type")
        if dtype not in DEVICE_TYPES:
            raise fail(_key_line(text, line, "type"), f"device '{name}': unknown type {dtype!r}; known: {', '.join(DEVICE_TYPES)}")
        bus = raw.get("bus")
        if bus not in plant.buses:
            raise fail(_key_line(text, line, "bus"), f"device '{name}': unknown bus {bus!r}; defined buses: {', '.join(plant.buses) or 'none'}")
        device_type = DEVICE_TYPES[dtype]
        if plant.buses[bus].type not in device_type.bus_types:
            raise fail(_key_line(text, line, "bus"), f"device '{name}': a {dtype} cannot sit on a {plant.buses[bus].type} bus")
        options = {k: v for k, v in raw.items() if k not in COMMON_DEVICE_KEYS}
        for key, message in device_type.check_config(options, plant.buses[bus].type):
            raise fail(_key_line(text, line, key), f"device '{name}': {message}")
        target[name] = DeviceConfig(name, dtype, bus, options, line)


def device_toml(dev: DeviceConfig) -> str:
    """The ``[[device]]`` table of a device, to paste into (or append to) a plant file."""
    lines = ["[[device]]", f'name = "{dev.name}"', f'type = "{dev.type}"', f'bus = "{dev.bus}"']
    for key, value in dev.options.items():
        if isinstance(value, bool):
            lines.append(f"{key} = {'true' if value else 'false'}")
        elif isinstance(value, int | float):
            lines.append(f"{key} = {value}")
        else:
            lines.append(f'{key} = "{value}"')
    return "\n".join(lines) + "\n"


def append_device(path: Path, dev: DeviceConfig) -> None:
    """Append a device to a plant file, checking first that the result still loads."""
    text = path.read_text(encoding="utf-8")
    new_text = text.rstrip("\n") + "\n\n" + device_toml(dev)
    parse_plant(new_text, path)  # raises PlantError before anything is written
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(new_text, encoding="utf-8")
    tmp.replace(path)
