"""BSS HD-Lock 102000.X door lock (Modbus RTU on RS485)."""

from typing import Any

from devices.hdlock import codec
from devices.hdlock.params import PARAMS
from devices.registry import DeviceType


def _check_config(options: dict[str, Any]) -> list[tuple[str, str]]:
    errors = []
    address = options.get("address")
    if not isinstance(address, int) or isinstance(address, bool):
        errors.append(("address", "'address' (Modbus slave address 1..254) is required"))
    elif not codec.MODBUS_ADDRESS_MIN <= address <= codec.MODBUS_ADDRESS_MAX:
        errors.append(("address", f"address {address} is outside {codec.MODBUS_ADDRESS_MIN}..{codec.MODBUS_ADDRESS_MAX}"))
    serial = options.get("serial", 0)
    if not isinstance(serial, int) or not 0 <= serial <= 0xFFFFFFFF:
        errors.append(("serial", "serial must be a 32-bit number"))
    unknown = set(options) - {"address", "serial", "door"}
    for key in sorted(unknown):
        errors.append((key, f"unknown key '{key}'; known: address, serial (simulated twin), door (simulated twin: \"open\"/\"closed\")"))
    return errors


DEVICE_TYPE = DeviceType(
    name="hdlock",
    title="HD-Lock",
    bus_types=("modbus-rtu",),
    params=PARAMS,
    adapter="devices.hdlock.adapter:HdLockAdapter",
    sim="devices.hdlock.sim:HdLockSim",
    check_config=_check_config,
    bus_identity=lambda options: options.get("address"),
    key_values=("DoorState", "LockStatus", "BoltPosition"),
)
