"""Bauer MO 64 barrier motor control, LogiTed bus over TCP/IP and RS485 (document 003).

Codec (:mod:`devices.mo64.codec`), adapter (:mod:`devices.mo64.adapter`), twin
(:mod:`devices.mo64.sim`) and page (:mod:`pages.mo64`).
"""

from typing import Any

from devices.message import Message, N_
from devices.mo64.params import PARAMS
from devices.registry import DeviceType, TileAlarm, TileBar, TileLine, TileSpec, When

# all but the address set up the simulated barrier (devices/mo64/sim.py): its strict modes among them
_KEYS = {"address", "serial_number", "travel_s", "refuse_queries", "query_form", "refuse_selectors", "eeprom_write_s"}


def _check_config(options: dict[str, Any], bus_type: str) -> list[tuple[str, str]]:
    errors = []
    address = options.get("address")
    if bus_type == "logited-rs485":
        if address is None:
            errors.append(("address", Message(N_("an MO 64 on RS485 needs its bus address: address = 1 .. 254"))))
        elif isinstance(address, bool) or not isinstance(address, int) or not 1 <= address <= 254:
            errors.append(("address", Message(N_("address = {address!r}: an MO 64 bus address is 1 .. 254"), address=address)))
    elif address is not None:
        errors.append(("address", Message(N_("an MO 64 on TCP has no bus address: the connection names it (remove address)"))))
    for key in sorted(set(options) - _KEYS):
        errors.append((key, Message(N_("unknown key '{key}' for an MO 64; known: {known}"), key=key, known=", ".join(sorted(_KEYS)))))
    return errors


def _bus_identity(options: dict[str, Any], bus_type: str) -> Any:
    if bus_type == "logited-rs485":
        return options.get("address")
    return "the TCP connection (the MO 64 serves one client at a time, chapter 3)"


TILE = TileSpec(
    lines=(
        TileLine("Gate state", "gate: {text}", missing="gate state: not read yet"),
        TileLine("Position", "position: {text}", missing=""),
    ),
    alarms=(
        TileAlarm(When("F_ereignis", (True,)), "fault event (F_ereignis)"),
        TileAlarm(When("LS", (True,)), "light barrier interrupted"),
        TileAlarm(When("Baum ab", (True,)), "boom off (Baum ab)"),
    ),
    bar=TileBar("Position", "{value} % open", full_scale=100),
    icon="fence",
)

DEVICE_TYPE = DeviceType(
    worded_names=True,  # its parameter names are the tool's words, worded by the catalogs (docs/i18n.md)
    name="mo64",
    title="Bauer MO 64",
    manufacturer="Bauer",
    line_codec="devices.mo64.codec",  # the RS485 line's framing and token passing (app/logited.py)
    bus_types=("logited-tcp", "logited-rs485"),
    params=PARAMS,  # every EEPROM setting the document names (devices/mo64/params.py)
    adapters={"logited-tcp": "devices.mo64.adapter:Mo64Adapter", "logited-rs485": "devices.mo64.adapter:Mo64Adapter"},
    sims={"logited-tcp": "devices.mo64.sim:Mo64TcpSim", "logited-rs485": "devices.mo64.sim:Mo64Rs485Sim"},
    check_config=_check_config,
    bus_identity=_bus_identity,
    tile=TILE,
)
