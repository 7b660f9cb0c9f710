"""The plant file (TOML): buses and devices, with errors that name file, line and problem.

The device options the running tool keeps in the file (an M3IO's P2) are written by app/plant_options.py.
"""

from __future__ import annotations

import difflib
import math
import re
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomllib

from app.i18n import N_
from app.message import Message, message_of
from devices.errors import CommissionError
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
        "port": (int, 0),  # udp_multicast only: its UDP port (0 = python-can's default, or a port of its own when simulated)
        "filter_own": (bool, False),  # drop the frames this instance sent when the interface hands them back
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
CAN_OPTIONS_TABLE = "can_options"  # [bus.can_options]: further python-can keys, passed on unchecked
COMMON_BUS_KEYS = {"name", "type", "description"}
UDP_MULTICAST_DEFAULT_PORT = 43113  # python-can's UdpMulticastBus default
SIM_UDP_PORTS = (43114, 2000)  # first port and span of the ports derived for simulated udp_multicast buses
STANDARD_BAUDRATES = (1200, 2400, 4800, 9600, 14400, 19200, 38400, 57600, 115200)
SERIAL_SIM_TYPES = {"modbus-rtu", "serial", "logited-rs485"}  # their twins serve a TCP port (socket://host:port)
CAN_SIM_INTERFACES = ("virtual", "udp_multicast")  # python-can interfaces the twins can sit on
TYPE_WORDS = {bool: N_("true or false (without quotes)"), int: N_("a whole number (without quotes)"), str: N_("a text in quotes")}
COMMON_DEVICE_KEYS = {"name", "type", "bus", "description"}
OUTSIDE = N_("{owner}: {key} {value} is outside {range}")
NOT_ONE_OF = N_("{owner}: {key} {value} is not one of {known}")


class PlantError(CommissionError, ValueError):
    """A plant file that cannot be used; the message says where and what (a :class:`~app.message.Message`)."""


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
    project: dict[str, Any] | str | None = None  # intended parameters: a table, or a parameter file (app/project.py)


@dataclass
class PlantViewConfig:
    public: bool = False


MQTT_SCHEMES = {"mqtt": 1883, "mqtts": 8883}  # mqtts: TLS, the broker checked against the system's or ca_file's CAs
MQTT_KEYS = ("url", "site", "instance", "username", "password_env", "password_file", "ca_file", "rate", "heartbeat", "buffer",
             "sparkplug", "primary_host")


@dataclass
class MqttConfig:
    """``[mqtt]``: publish the plant's live data to a broker (docs/mqtt.md). Never carries a password itself."""

    url: str
    host: str
    port: int
    tls: bool
    site: str
    instance: str
    username: str | None = None
    password_env: str | None = None  # the name of an environment variable holding the password
    password_file: Path | None = None  # a file holding the password (relative paths: to the plant file)
    ca_file: Path | None = None  # mqtts: the CA certificate(s) that signed the broker's certificate
    rate: float = 2.0  # messages per second and device at most (changes only)
    heartbeat: float = 10.0  # seconds: an unchanged device is re-sent this often, so subscribers can tell stale data
    buffer: int = 1000  # alarm events kept while the broker is away (states keep only their newest message)
    sparkplug: bool = False  # also publish Sparkplug B (app/sparkplug.py): group id = site, edge node id = instance
    primary_host: str | None = None  # Sparkplug: publish only while this host application's STATE is online


@dataclass
class OpcuaConfig:
    """``[opcua]``: the read-only OPC UA server (app/opcua_server.py)."""

    endpoint: str = "opc.tcp://127.0.0.1:4840"
    anonymous: bool = True  # False: sessions log in with an account of the accounts file
    certificate: Path | None = None  # with private_key: Basic256Sha256 SignAndEncrypt is offered beside None
    private_key: Path | None = None
    rate: float = 10.0  # live values written into the address space at most this often a second


@dataclass
class Plant:
    name: str
    path: Path | None
    buses: dict[str, BusConfig] = field(default_factory=dict)
    devices: dict[str, DeviceConfig] = field(default_factory=dict)
    sim_devices: dict[str, DeviceConfig] = field(default_factory=dict)  # simulated, not (yet) in the plant
    plant_view: PlantViewConfig = field(default_factory=PlantViewConfig)
    mqtt: MqttConfig | None = None
    opcua: OpcuaConfig | None = None

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


TOP_LEVEL = ("name", "bus", "device", "sim_device", "plant_view", "mqtt", "opcua")


def _section(key: str) -> str:
    return "name" if key == "name" else f"[{key}]" if key in ("plant_view", "mqtt", "opcua") else f"[[{key}]]"


def _section_line(text: str, key: str) -> int:
    """Line of a top-level ``[key]``, ``[[key]]`` or ``key =`` (1 when not found)."""
    pattern = re.compile(rf"^\s*(\[\[?\s*{re.escape(key)}\s*[\].]|{re.escape(key)}\s*=)")
    return next((i + 1 for i, line in enumerate(text.splitlines()) if pattern.match(line)), 1)


def _did_you_mean(key: str, known) -> str | None:
    found = difflib.get_close_matches(key, list(known), n=1, cutoff=0.6)
    return found[0] if found else None


def _unknown_key(owner: str, key: str, known) -> Message:
    guess = _did_you_mean(key, known)
    return Message(N_("{owner}: unknown key '{key}'; did you mean '{guess}'? known: {known}") if guess else
                   N_("{owner}: unknown key '{key}'; known: {known}"), owner=owner, key=key, guess=guess, known=", ".join(known))


def _wrong_type(owner: str, key: str, value: Any, typ) -> Message:
    want = Message(N_("a number (without quotes)") if typ == (int, float) else TYPE_WORDS.get(
        typ, "a " + " or ".join(t.__name__ for t in typ) if isinstance(typ, tuple) else typ.__name__))
    if isinstance(typ, tuple) and str in typ:
        want = Message(N_("a text in quotes or a whole number"))
    return Message(N_("{owner}: {key} must be {want}, not {value!r}"), owner=owner, key=key, want=want, value=value)


def _sub_table_line(text: str, start: int, table: str) -> int:
    """Line of the ``[bus.<table>]`` header that belongs to the bus at ``start``."""
    lines = text.splitlines()
    pattern = re.compile(rf"^\s*\[\s*bus\s*\.\s*{re.escape(table)}\s*\]")
    for i in range(start, len(lines)):
        if pattern.match(lines[i]):
            return i + 1
        if re.match(r"^\s*\[\[", lines[i]):
            break
    return start


def _seconds(value: Any) -> bool:
    return not isinstance(value, bool) and isinstance(value, int | float) and math.isfinite(value) and value > 0


def _parse_bus(text: str, raw: dict[str, Any], line: int, plant: Plant, fail) -> BusConfig:
    name = raw.get("name")
    if not isinstance(name, str) or not name:
        raise fail(line, Message(N_("bus without a name (add name = \"...\")")))
    if name in plant.buses:
        raise fail(line, Message(N_("duplicate bus name '{name}' (first at line {line})"), name=name, line=plant.buses[name].line))
    btype = raw.get("type")
    if btype not in BUS_KEYS:
        guess = _did_you_mean(str(btype), BUS_KEYS)
        raise fail(_key_line(text, line, "type"), Message(
            N_("bus '{name}': unknown type {type!r}; did you mean '{guess}'? known: {known}") if guess else
            N_("bus '{name}': unknown type {type!r}; known: {known}"), name=name, type=btype, guess=guess, known=", ".join(BUS_KEYS)))
    spec = BUS_KEYS[btype]
    owner = Message(N_("bus '{name}'"), name=name)
    at = lambda key: _key_line(text, line, key)  # noqa: E731
    options: dict[str, Any] = {}
    extra: dict[str, Any] = {}
    for key, value in raw.items():
        if key in COMMON_BUS_KEYS:
            continue
        if key == CAN_OPTIONS_TABLE and btype == "can":
            sub_line = _sub_table_line(text, line, key)
            if not isinstance(value, dict):
                raise fail(at(key), Message(N_("{owner}: {key} must be a table: [bus.{key}] with one python-can key per line"),
                                            owner=owner, key=key))
            for sub_key in value:
                if sub_key in spec or sub_key in COMMON_BUS_KEYS:
                    raise fail(_key_line(text, sub_line, sub_key),
                               Message(N_("{owner}: {sub_key} belongs in the [[bus]] table, not in [bus.{key}] (which is for further "
                                          "python-can keys)"), owner=owner, sub_key=sub_key, key=key))
            extra = dict(value)
            continue
        if key not in spec:
            message = _unknown_key(owner, key, spec)
            if btype == "can":
                message = Message(N_("{message}; keys of a python-can interface go in a [bus.{table}] table below this one"),
                                  message=message, table=CAN_OPTIONS_TABLE)
            raise fail(at(key), message)
        typ = spec[key][0]
        if isinstance(value, bool) and typ is not bool or not isinstance(value, typ):
            raise fail(at(key), _wrong_type(owner, key, value, typ))
        options[key] = value
    for key, (_typ, default) in spec.items():
        if key not in options:
            if default is None:
                raise fail(line, Message(N_("{owner}: '{key}' is required (add {key} = ...)"), owner=owner, key=key))
            options[key] = default
    for key in ("timeout", "poll_period"):
        if not _seconds(options[key]):
            raise fail(at(key), Message(N_("{owner}: {key} must be a number of seconds above 0, not {value!r}"), owner=owner, key=key,
                                        value=options[key]))
    if btype == "modbus-rtu":
        if options["parity"] not in ("N", "E", "O"):
            raise fail(at("parity"), Message(N_("{owner}: parity must be \"N\", \"E\" or \"O\", not {value!r}"), owner=owner,
                                             value=options["parity"]))
        if options["stopbits"] not in (1, 2):
            raise fail(at("stopbits"), Message(N_("{owner}: stopbits must be 1 or 2, not {value}"), owner=owner, value=options["stopbits"]))
        if options["bytesize"] not in (7, 8):
            raise fail(at("bytesize"), Message(N_("{owner}: bytesize must be 7 or 8, not {value}"), owner=owner, value=options["bytesize"]))
        if not 0 <= options["retries"] <= 10:
            raise fail(at("retries"), Message(OUTSIDE, owner=owner, key="retries", value=options["retries"], range="0..10"))
    if btype in ("modbus-rtu", "logited-rs485") and options["baudrate"] not in STANDARD_BAUDRATES:
        raise fail(at("baudrate"), Message(NOT_ONE_OF, owner=owner, key="baudrate", value=options["baudrate"],
                                           known=", ".join(map(str, STANDARD_BAUDRATES))))
    if btype == "logited-rs485":
        for key in ("master_address", "next_master"):
            if not 0 <= options[key] <= 255:
                raise fail(at(key), Message(OUTSIDE, owner=owner, key=key, value=options[key], range="0..255"))
        if options["shared"] and options["next_master"] == options["master_address"]:
            raise fail(at("next_master"), Message(N_("{owner}: next_master must be another master than this tool ({address})"),
                                                  owner=owner, address=options["master_address"]))
    if btype == "serial" and options["baudrate"] not in (9600, 19200, 38400):
        raise fail(at("baudrate"), Message(NOT_ONE_OF, owner=owner, key="baudrate", value=options["baudrate"], known="9600, 19200, 38400"))
    if btype == "logited-tcp" and not 1 <= options["port"] <= 65535:
        raise fail(at("port"), Message(OUTSIDE, owner=owner, key="port", value=options["port"], range="1..65535"))
    if btype == "can":
        if not 5000 <= options["bitrate"] <= 1_000_000:
            raise fail(at("bitrate"), Message(OUTSIDE, owner=owner, key="bitrate", value=options["bitrate"], range="5000..1000000 bit/s"))
        udp = options["interface"] == "udp_multicast"
        if "port" in raw and not udp:
            raise fail(at("port"), Message(N_("{owner}: port is the UDP port of interface \"udp_multicast\"; keys of interface "
                                              "{interface!r} go in [bus.{table}]"), owner=owner, interface=options["interface"],
                                           table=CAN_OPTIONS_TABLE))
        if udp and "port" in raw and not 1024 <= options["port"] <= 65535:
            raise fail(at("port"), Message(OUTSIDE, owner=owner, key="port", value=options["port"], range="1024..65535"))
        if not udp:
            del options["port"]
        elif "port" not in raw:
            options["port"] = _udp_port(options) if options["simulate"] else UDP_MULTICAST_DEFAULT_PORT
        if "filter_own" not in raw:
            del options["filter_own"]  # the CAN bus picks its own default per interface
        if options["simulate"] and options["interface"] not in CAN_SIM_INTERFACES:
            raise fail(at("simulate"), Message(N_("{owner}: simulate = true needs interface \"virtual\" (one process) or "
                                                  "\"udp_multicast\" (across processes), not {interface!r}; remove simulate for a "
                                                  "real bus"), owner=owner, interface=options["interface"]))
        options.update(extra)  # the CAN bus passes them to python-can
    if btype in SERIAL_SIM_TYPES and options["simulate"] and not re.fullmatch(r"socket://[^/:]*:\d+", options["port"]):
        raise fail(at("simulate"), Message(N_("{owner}: simulate = true needs a port of the form \"socket://127.0.0.1:PORT\" (the "
                                              "simulated devices serve a TCP port), not {port!r}; remove simulate for a real line"),
                                           owner=owner, port=options["port"]))
    return BusConfig(name, btype, options, line)


def _udp_port(options: dict[str, Any]) -> int:
    """A UDP port of its own for a simulated udp_multicast bus, the same in every process that loads the file.

    python-can binds every group to one port, so groups on one port hear each other (issue 14, item 2).
    """
    first, span = SIM_UDP_PORTS
    return first + zlib.crc32(f"{options['channel']}".encode()) % span


def _check_udp_ports(text: str, plant: Plant, fail) -> None:
    seen: dict[int, BusConfig] = {}
    for bus in plant.buses.values():
        if bus.type != "can" or bus.options.get("interface") != "udp_multicast":
            continue
        port = bus.options["port"]
        if port in seen:
            other = seen[port]
            raise fail(_key_line(text, bus.line, "port") if _key_line(text, bus.line, "port") != bus.line else bus.line,
                       Message(N_("bus '{name}': udp_multicast port {port} is already used by bus '{other}' (line {line}); "
                                  "udp_multicast groups on one port receive each other's frames: give this bus port = <another port>"),
                               name=bus.name, port=port, other=other.name, line=other.line))
        seen[port] = bus


def load_plant(path: str | Path) -> Plant:
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise PlantError(Message(N_("{path}: cannot read the plant file: {error}"), path=path, error=exc.strerror or exc)) from None
    except UnicodeDecodeError as exc:
        line = path.read_bytes()[:exc.start].count(b"\n") + 1
        raise PlantError(Message(N_("{path}:{line}: the plant file is not UTF-8 text (byte 0x{byte:02x} at offset {offset}); "
                                    "save it as UTF-8"), path=path, line=line, byte=exc.object[exc.start], offset=exc.start)) from None
    return parse_plant(text, path)


def parse_plant(text: str, path: Path | None = None) -> Plant:
    where = str(path) if path else "<plant>"
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise PlantError(Message(N_("{where}: not valid TOML: {error}"), where=where, error=exc)) from None

    def fail(line: int, message: str) -> PlantError:
        return PlantError(Message("{where}:{line}: {message}", where=where, line=line, message=message))

    for key in data:
        if key not in TOP_LEVEL:
            guess = _did_you_mean(key, TOP_LEVEL)
            known = "[[bus]], [[device]], [[sim_device]], [plant_view], [mqtt], [opcua], name"
            raise fail(_section_line(text, key), Message(
                N_("unknown section {section}; did you mean {guess}? known: {known}") if guess else
                N_("unknown section {section}; known: {known}"), section=_section(key), guess=guess and _section(guess), known=known))
    for key in ("bus", "device", "sim_device"):
        if key in data and not (isinstance(data[key], list) and all(isinstance(t, dict) for t in data[key])):
            raise fail(_section_line(text, key), Message(
                N_("[{key}] is one table; write [[{key}]] (double brackets): one [[{key}]] table per {what}"), key=key,
                what=Message({"bus": N_("bus"), "device": N_("device"), "sim_device": N_("simulated device")}[key])))
    if "name" in data and not isinstance(data["name"], str):
        raise fail(_section_line(text, "name"), Message(N_("name must be a text in quotes, e.g. name = \"hall-3\", not {value!r}"),
                                                        value=data["name"]))
    plant = Plant(name=str(data.get("name") or (path.stem if path else "plant")), path=path)
    pv = data.get("plant_view", {})
    pv_line = _section_line(text, "plant_view")
    if not isinstance(pv, dict):
        raise fail(pv_line, Message(N_("[plant_view] must be a table, e.g. [plant_view] public = true")))
    for key in sorted(set(pv) - {"public"}):
        guess = _did_you_mean(key, ["public"])
        raise fail(_key_line(text, pv_line, key), Message(
            N_("[plant_view]: unknown key '{key}'; did you mean {guess!r}? known: public (true or false)") if guess else
            N_("[plant_view]: unknown key '{key}'; known: public (true or false)"), key=key, guess=guess))
    public = pv.get("public", False)
    if not isinstance(public, bool):
        # a string such as "false" would be true in Python: only a real boolean opens the view
        raise fail(_key_line(text, pv_line, "public"), Message(N_("[plant_view] public must be true or false (without quotes), not "
                                                                  "{value!r}"), value=public))
    plant.plant_view = PlantViewConfig(public=public)
    if "mqtt" in data:
        plant.mqtt = parse_mqtt(text, data["mqtt"], plant.name, path, fail)
    if "opcua" in data:
        plant.opcua = parse_opcua(text, data["opcua"], path, fail)

    bus_lines = _header_lines(text, "bus")
    for index, raw in enumerate(data.get("bus", [])):
        line = bus_lines[index] if index < len(bus_lines) else 1
        bus = _parse_bus(text, raw, line, plant, fail)
        plant.buses[bus.name] = bus
    _check_udp_ports(text, plant, fail)

    _parse_devices(text, data, plant, "device", plant.devices, fail)
    _parse_devices(text, data, plant, "sim_device", plant.sim_devices, fail)

    for bus in plant.buses.values():
        seen: dict[Any, str] = {}
        for dev in plant.devices_on(bus.name) + [d for d in plant.sim_devices.values() if d.bus == bus.name]:
            ident = DEVICE_TYPES[dev.type].bus_identity(dev.options, bus.type)
            if ident is not None and ident in seen:
                what = Message(N_("address {address}"), address=ident) if isinstance(ident, int) else str(ident)  # a type may name its own
                raise fail(dev.line, Message(N_("device '{name}': {what} is already used by '{other}' on bus '{bus}'"), name=dev.name,
                                             what=what, other=seen[ident], bus=bus.name))
            if ident is not None:
                seen[ident] = dev.name
        conflict = can_id_conflict(plant.devices_on(bus.name) + [d for d in plant.sim_devices.values() if d.bus == bus.name], bus)
        if conflict is not None:
            raise fail(conflict[0].line, conflict[1])
    return plant


TOPIC_PART = re.compile(r"[A-Za-z0-9_.-]+")  # a topic level: no '/', '+', '#' or '$' (docs/mqtt.md)


def parse_mqtt_url(url: str) -> tuple[str, int, bool]:
    """``mqtt://host[:port]`` or ``mqtts://host[:port]`` -> (host, port, tls); ValueError says what is wrong."""
    from urllib.parse import urlsplit

    try:
        parts = urlsplit(url)
        port = parts.port
    except ValueError as exc:
        raise ValueError(Message(N_("{url!r} is not a broker URL ({error})"), url=url, error=exc)) from None
    if parts.scheme not in MQTT_SCHEMES:
        raise ValueError(Message(N_("{url!r} must start with mqtt:// or mqtts:// (TLS)"), url=url))
    if not parts.hostname:
        raise ValueError(Message(N_("{url!r} names no broker host, e.g. mqtt://broker.local:1883"), url=url))
    if parts.username or parts.password:
        raise ValueError(Message(N_("{url!r} carries a user or password; use username = ... and password_env or password_file"), url=url))
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise ValueError(Message(N_("{url!r}: a broker URL has no path or query, e.g. mqtt://broker.local:1883"), url=url))
    return parts.hostname, port or MQTT_SCHEMES[parts.scheme], parts.scheme == "mqtts"


def parse_mqtt(text: str, raw: Any, plant_name: str, path: Path | None, fail) -> MqttConfig:
    """The ``[mqtt]`` table: every key checked, errors as ``file:line: what is wrong``."""
    line = _section_line(text, "mqtt")
    if not isinstance(raw, dict):
        raise fail(line, Message(N_('[mqtt] must be a table, e.g. [mqtt] url = "mqtt://broker.local:1883"')))
    at = lambda key: _key_line(text, line, key)  # noqa: E731
    for key in raw:
        if key == "password":
            raise fail(at(key), Message(N_("[mqtt]: a password never goes in the plant file; name an environment variable "
                                           "(password_env = \"MQTT_PASSWORD\") or a file (password_file = \"mqtt-password.txt\") "
                                           "that holds it")))
        if key not in MQTT_KEYS:
            raise fail(at(key), _unknown_key("[mqtt]", key, MQTT_KEYS))
    for key in ("url", "site", "instance", "username", "password_env", "password_file", "ca_file"):
        if key in raw and not isinstance(raw[key], str):
            raise fail(at(key), _wrong_type("[mqtt]", key, raw[key], str))
    if "url" not in raw:
        raise fail(line, Message(N_('[mqtt]: \'url\' is required (add url = "mqtt://broker.local:1883")')))
    try:
        host, port, tls = parse_mqtt_url(raw["url"])
    except ValueError as exc:
        raise fail(at("url"), Message(N_("[mqtt]: url {problem}"), problem=message_of(exc))) from None
    site = raw.get("site", plant_name)
    instance = raw.get("instance", plant_name)
    for key, value in (("site", site), ("instance", instance)):
        if not TOPIC_PART.fullmatch(value):
            where = at(key) if key in raw else line
            raise fail(where, Message(N_("[mqtt]: {key} {value!r} becomes a topic level: use letters, digits, '_', '.', '-' only")
                                      if key in raw else
                                      N_("[mqtt]: {key} {value!r} becomes a topic level: use letters, digits, '_', '.', '-' only "
                                         "(it defaults to the plant name; set {key} = \"...\")"), key=key, value=value))
    if "password_env" in raw and "password_file" in raw:
        raise fail(at("password_file"), Message(N_("[mqtt]: give password_env or password_file, not both")))
    if "password_env" in raw and not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", raw["password_env"]):
        raise fail(at("password_env"), Message(N_("[mqtt]: password_env names an environment variable (e.g. \"MQTT_PASSWORD\"), "
                                                  "not {value!r}"), value=raw["password_env"]))
    if ("password_env" in raw or "password_file" in raw) and "username" not in raw:
        raise fail(at("password_env" if "password_env" in raw else "password_file"),
                   Message(N_("[mqtt]: a password needs username = \"...\"")))
    if "ca_file" in raw and not tls:
        raise fail(at("ca_file"), Message(N_("[mqtt]: ca_file is for TLS: write the url as mqtts://...")))
    base = path.parent if path else Path.cwd()
    files = {key: (base / raw[key]) if key in raw else None for key in ("password_file", "ca_file")}
    for key in ("rate", "heartbeat"):
        if key in raw and not (_seconds(raw[key]) and raw[key] <= 3600):
            raise fail(at(key), Message(N_("[mqtt]: {key} must be a number above 0 (and at most 3600), not {value!r}"), key=key,
                                        value=raw[key]))
    rate = float(raw.get("rate", 2.0))
    if rate > 50:
        raise fail(at("rate"), Message(N_("[mqtt]: rate {rate} messages/s per device is more than any subscriber needs; at most 50"),
                                       rate=f"{rate:g}"))
    buffer = raw.get("buffer", 1000)
    if isinstance(buffer, bool) or not isinstance(buffer, int) or not 10 <= buffer <= 100_000:
        raise fail(at("buffer"), Message(N_("[mqtt]: buffer must be a whole number of messages in 10..100000, not {value!r}"),
                                         value=buffer))
    if "sparkplug" in raw and not isinstance(raw["sparkplug"], bool):
        raise fail(at("sparkplug"), Message(N_("[mqtt]: sparkplug must be true or false (without quotes), not {value!r}"),
                                            value=raw["sparkplug"]))
    if "primary_host" in raw and not TOPIC_PART.fullmatch(raw["primary_host"]):
        raise fail(at("primary_host"), Message(N_("[mqtt]: primary_host {value!r} becomes a topic level: use letters, digits, '_', "
                                                  "'.', '-' only"), value=raw["primary_host"]))
    if "primary_host" in raw and not raw.get("sparkplug"):
        raise fail(at("primary_host"), Message(N_("[mqtt]: primary_host is a Sparkplug setting: add sparkplug = true")))
    return MqttConfig(url=raw["url"], host=host, port=port, tls=tls, site=site, instance=instance,
                      username=raw.get("username"), password_env=raw.get("password_env"),
                      password_file=files["password_file"], ca_file=files["ca_file"], rate=rate,
                      heartbeat=float(raw.get("heartbeat", 10.0)), buffer=buffer,
                      sparkplug=raw.get("sparkplug", False), primary_host=raw.get("primary_host"))


OPCUA_KEYS = ("endpoint", "anonymous", "certificate", "private_key", "rate")


def parse_opcua(text: str, raw: Any, path: Path | None, fail) -> OpcuaConfig:
    """The ``[opcua]`` table (the read-only OPC UA server; off without it)."""
    line = _section_line(text, "opcua")
    if not isinstance(raw, dict):
        raise fail(line, Message(N_('[opcua] must be a table, e.g. [opcua] endpoint = "opc.tcp://127.0.0.1:4840"')))
    at = lambda key: _key_line(text, line, key)  # noqa: E731
    for key in raw:
        if key not in OPCUA_KEYS:
            raise fail(at(key), _unknown_key("[opcua]", key, OPCUA_KEYS))
    for key in ("endpoint", "certificate", "private_key"):
        if key in raw and not isinstance(raw[key], str):
            raise fail(at(key), _wrong_type("[opcua]", key, raw[key], str))
    endpoint = raw.get("endpoint", OpcuaConfig.endpoint)
    if not re.fullmatch(r"opc\.tcp://[^/:]+(:\d{1,5})?(/.*)?", endpoint):
        raise fail(at("endpoint"), Message(N_("[opcua]: endpoint must look like opc.tcp://127.0.0.1:4840, not {value!r}"),
                                           value=endpoint))
    if "anonymous" in raw and not isinstance(raw["anonymous"], bool):
        raise fail(at("anonymous"), Message(N_("[opcua]: anonymous must be true or false (without quotes), not {value!r}"),
                                            value=raw["anonymous"]))
    if ("certificate" in raw) != ("private_key" in raw):
        raise fail(at("certificate" if "certificate" in raw else "private_key"),
                   Message(N_("[opcua]: encryption needs both certificate and private_key")))
    if "rate" in raw and not (_seconds(raw["rate"]) and raw["rate"] <= 100):
        raise fail(at("rate"), Message(N_("[opcua]: rate must be a number above 0 and at most 100 (updates a second), not {value!r}"),
                                       value=raw["rate"]))
    base = path.parent if path else Path.cwd()
    files = {key: (base / raw[key]) if key in raw else None for key in ("certificate", "private_key")}
    return OpcuaConfig(endpoint=endpoint, anonymous=raw.get("anonymous", True), rate=float(raw.get("rate", 10.0)), **files)


def _can_ids(span: tuple[int, int], extended: bool) -> Message:
    return Message(N_("CAN ID {ids}") if span[0] == span[1] else N_("CAN IDs {ids}"), ids=format_can_ids(*span, extended))


def can_id_conflict(devices: list[DeviceConfig], bus: BusConfig) -> tuple[DeviceConfig, Message] | None:
    """The first CAN ID that two devices on ``bus`` (or one device twice) would both use.

    Each device type declares the IDs it sends and receives (``DeviceType.can_id_uses``).
    Returns ``(the later device, message naming both devices, the ID and its use in each)``.
    """
    if bus.type != "can":
        return None
    # HD-Lock document 6.2 b: "jede CAN-ID [darf] jeweils nur von einem Busteilnehmer verwendet werden"
    rule = Message(N_("A CAN ID may carry one sender's messages only: change an address or use separate buses."))
    earlier = []
    for dev in devices:
        device_type = DEVICE_TYPES[dev.type]
        uses = device_type.can_id_uses(dev.options, bus.type)
        for i, a in enumerate(uses):
            for b in uses[i + 1:]:
                span = None if a.shared and b.shared else a.overlap(b)
                if span:
                    ids = _can_ids(span, a.extended)
                    return dev, Message(N_("device '{name}': {ids} is used twice by this {type} on bus '{bus}', as {use} and as "
                                           "{other_use}. {rule}"), name=dev.name, ids=ids, type=device_type.title, bus=bus.name,
                                        use=a.use, other_use=b.use, rule=rule)
        for other, other_type, other_uses in earlier:
            same_type = other.type == dev.type
            for a in uses:
                for b in other_uses:
                    span = None if same_type and a.shared and b.shared else a.overlap(b)
                    if span:
                        ids = _can_ids(span, a.extended)
                        return dev, Message(N_("device '{name}': {ids} is used twice on bus '{bus}': by '{name}' ({type}) as "
                                               "{use}, and by '{other}' ({other_type}) as {other_use}. {rule}"), name=dev.name,
                                            ids=ids, bus=bus.name, type=device_type.title, use=a.use, other=other.name,
                                            other_type=other_type.title, other_use=b.use, rule=rule)
        earlier.append((dev, device_type, uses))
    return None


def _parse_devices(text, data, plant, table, target, fail) -> None:
    """``[[device]]`` (in the plant) and ``[[sim_device]]`` (only in the simulation, to be discovered)."""
    device_lines = _header_lines(text, table)
    for index, raw in enumerate(data.get(table, [])):
        line = device_lines[index] if index < len(device_lines) else 1
        name = raw.get("name")
        if not isinstance(name, str) or not name:
            raise fail(line, Message(N_("device without a name (add name = \"...\")")))
        if not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
            raise fail(line, Message(N_("device name '{name}' may only contain letters, digits, '_', '.', '-'"), name=name))
        if name in plant.devices or name in plant.sim_devices:
            first = (plant.devices.get(name) or plant.sim_devices[name]).line
            raise fail(line, Message(N_("duplicate device name '{name}' (first at line {line})"), name=name, line=first))
        dtype = raw.get("type")
        if dtype not in DEVICE_TYPES:
            raise fail(_key_line(text, line, "type"), Message(N_("device '{name}': unknown type {type!r}; known: {known}"), name=name,
                                                              type=dtype, known=", ".join(DEVICE_TYPES)))
        bus = raw.get("bus")
        if bus not in plant.buses:
            raise fail(_key_line(text, line, "bus"), Message(N_("device '{name}': unknown bus {bus!r}; defined buses: {known}"), name=name,
                                                             bus=bus, known=", ".join(plant.buses) or Message(N_("none"))))
        device_type = DEVICE_TYPES[dtype]
        if plant.buses[bus].type not in device_type.bus_types:
            raise fail(_key_line(text, line, "bus"), Message(N_("device '{name}': a {type} cannot sit on a {bus_type} bus"), name=name,
                                                             type=dtype, bus_type=plant.buses[bus].type))
        options = {k: v for k, v in raw.items() if k not in COMMON_DEVICE_KEYS}
        project = options.pop("project", None)  # the device's intended parameters, checked by app/project.py
        if project is not None and not isinstance(project, dict | str):
            raise fail(_key_line(text, line, "project"), Message(N_("device '{name}': project must be a table of parameter = value or "
                                                                    "the name of a parameter file in quotes, not {value!r}"),
                                                                 name=name, value=project))
        for key, message in device_type.check_config(options, plant.buses[bus].type):
            raise fail(*_device_problem(text, line, name, options, key, message))
        target[name] = DeviceConfig(name, dtype, bus, options, line, project)


def _device_problem(text: str, line: int, name: str, options: dict[str, Any], key: str, message: str) -> tuple[int, Message]:
    """The line and message of a device-type check, naming a misspelt or mistyped key where that is the cause (the
    type's own words, ``message``, as it gives them)."""
    owner = Message(N_("device '{name}'"), name=name)
    if key not in options and "required" in message:
        guess = _did_you_mean(key, [k for k in options if isinstance(k, str)])
        if guess is not None:
            return _key_line(text, line, guess), Message(N_("{owner}: unknown key '{guess}'; did you mean '{key}'? ({message})"),
                                                         owner=owner, guess=guess, key=key, message=message)
    elif key in options and "required" in message:
        value = options[key]
        if isinstance(value, str) and re.fullmatch(r"\s*[-+]?(0x)?[0-9a-fA-F_.]+\s*", value):
            return _key_line(text, line, key), Message(N_("{owner}: {key} must be a number (without quotes), not {value!r}; write "
                                                          "{key} = {written}"), owner=owner, key=key, value=value, written=value.strip())
        return _key_line(text, line, key), Message(N_("{owner}: {key} = {value!r} has the wrong kind of value: {message}"),
                                                   owner=owner, key=key, value=value, message=message)
    return _key_line(text, line, key), Message("{owner}: {message}", owner=owner, message=message)


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
