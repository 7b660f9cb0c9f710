"""BSS HD-Lock 102000.X door lock: Modbus RTU on RS485, or its CAN protocol."""

from typing import Any

from devices.hdlock import codec
from devices.hdlock.params import PARAMS
from devices.message import Message, N_
from devices.registry import CanIdUse, DeviceType, TileAlarm, TileBar, TileLine, TileSpec, When

SIM_KEYS = {"serial": "simulated twin: serial number", "door": 'simulated twin: "open" or "closed"'}


def _check_config(options: dict[str, Any], bus_type: str) -> list[tuple[str, str]]:
    errors = []
    if bus_type == "modbus-rtu":
        known = {"address"}
        address = options.get("address")
        if not isinstance(address, int) or isinstance(address, bool):
            errors.append(("address", Message(N_("'address' (Modbus slave address 1..254) is required"))))
        elif not codec.MODBUS_ADDRESS_MIN <= address <= codec.MODBUS_ADDRESS_MAX:
            errors.append(("address", Message(N_("address {address} is outside {low}..{high}"), address=address,
                                              low=codec.MODBUS_ADDRESS_MIN, high=codec.MODBUS_ADDRESS_MAX)))
    else:
        known = {"device_id", "extended"}
        device_id = options.get("device_id")
        if not isinstance(device_id, int) or isinstance(device_id, bool):
            errors.append(("device_id", Message(N_("'device_id' (the lock's CAN device ID; factory default: its serial number) is "
                                                  "required"))))
        elif not 1 <= device_id <= codec.EXT_ID_MAX:
            errors.append(("device_id", Message(N_("device_id {device_id} is outside 1..0x1FFFFFFF"), device_id=device_id)))
        if "extended" in options and not isinstance(options["extended"], bool):
            errors.append(("extended", Message(N_("extended must be true or false"))))
    serial = options.get("serial", 0)
    if not isinstance(serial, int) or not 0 <= serial <= 0xFFFFFFFF:
        errors.append(("serial", Message(N_("serial must be a 32-bit number"))))
    for key in sorted(set(options) - known - set(SIM_KEYS)):
        allowed = ", ".join(sorted(known | set(SIM_KEYS)))
        errors.append((key, Message(N_("unknown key '{key}' for an HD-Lock on a {bus_type} bus; known: {allowed}"), key=key,
                                   bus_type=bus_type, allowed=allowed)))
    return errors


# section 6.6: every lock listens to the contiguous standard-ID block 0x700-0x707, one ID per request
CAN_FIXED_IDS = tuple(
    CanIdUse.one(can_id, f"{name} request (HD-Lock request block 0x700-0x707)", "master", shared=True)
    for can_id, name in codec.CAN_REQUEST_NAMES.items()
)


def _can_ids(options: dict[str, Any], bus_type: str) -> tuple[CanIdUse, ...]:
    """Section 6.3/6.5: a lock sends its status and answers under its device ID as CAN ID."""
    device_id = options.get("device_id")
    if bus_type != "can" or not isinstance(device_id, int) or isinstance(device_id, bool):
        return ()
    try:
        ident = codec.DeviceId.make(device_id, options.get("extended"))
    except codec.CodecError:
        return ()
    return (CanIdUse.one(ident.value, f"HD-Lock device ID {ident.value} (status every 1 s, register answers)", "device", ident.extended),)


def _identity(options: dict[str, Any], bus_type: str):
    if bus_type == "modbus-rtu":
        return options.get("address")
    device_id = options.get("device_id")
    if not isinstance(device_id, int):
        return None
    return str(codec.DeviceId.make(device_id, options.get("extended")))


_LOCK = "LockStatus"
STATUS_FRAME_BOLT = "BoltPosition (status frame)"  # published by the CAN adapter from every status frame
TILE = TileSpec(
    lines=(
        TileLine("DoorState", "{name}", missing="door: unknown"),
        TileLine(cases=(
            (When(_LOCK, (1,), field="BoltLocked"), "bolt locked", "lock"),
            (When(_LOCK, (1,), field="BoltUnlocked"), "bolt unlocked", "lock_open"),
            (When(_LOCK, (1,), field="BoltMovingOut"), "bolt moving", "sync"),
            (When(_LOCK, (1,), field="BoltMovingIn"), "bolt moving", "sync"),
        ), missing="bolt: unknown"),
    ),
    alarms=(
        TileAlarm(When("StateMachineState", of="name", prefix="Error"), "{name}"),
        TileAlarm(When(_LOCK, (1,), field="ProximityOverrange"), "hall sensors overdriven (magnet)"),
    ),
    # input register 2 (0 retracted, about 115 extended); on CAN the 1 s status frame's motorPos is fresher (section 6.5.1)
    bar=TileBar("BoltPosition", "bolt {value} Inc", full_scale=115, fresher=(STATUS_FRAME_BOLT,)),
    icon="help",
)


DEVICE_TYPE = DeviceType(
    name="hdlock",
    title="HD-Lock",
    manufacturer="BSS",
    bus_types=("modbus-rtu", "can"),
    params=PARAMS,
    adapters={"modbus-rtu": "devices.hdlock.adapter:HdLockAdapter", "can": "devices.hdlock.can_adapter:HdLockCanAdapter"},
    sims={"modbus-rtu": "devices.hdlock.sim:HdLockSim", "can": "devices.hdlock.sim:HdLockCanSim"},
    scans={"modbus-rtu": "devices.hdlock.adapter:discover"},
    check_config=_check_config,
    bus_identity=_identity,
    can_codec="devices.hdlock.codec",
    can_fixed_ids=CAN_FIXED_IDS,
    can_ids=_can_ids,
    tile=TILE,
)
