"""CAN-M3IO I/O module, variants KM, HM and HMR."""

from typing import Any

from devices.m3io import codec
from devices.m3io.params import P2_OPTION, PARAMS
from devices.message import Message, N_
from devices.registry import CanIdUse, DeviceType, TileAlarm, TileLine, TileSpec, When


def _check_config(options: dict[str, Any], bus_type: str) -> list[tuple[str, str]]:
    errors = []
    if options.get("variant") not in {v.value for v in codec.Variant}:
        errors.append(("variant", Message(N_('variant must be "KM", "HM" or "HMR"'))))
    sw1 = options.get("sw1")
    if not isinstance(sw1, int) or isinstance(sw1, bool) or not 0 <= sw1 <= 255:
        errors.append(("sw1", Message(N_("sw1 (the DIP switch SW1, 0..255, e.g. 0x1A) is required"))))
    serial = options.get("serial", 0)
    if not isinstance(serial, int) or not 0 <= serial <= 99_999_999:
        errors.append(("serial", Message(N_("serial (simulated twin) must have at most 8 digits"))))
    if options.get("master", "on-control") not in ("on-control", "always"):
        errors.append(("master", Message(N_('master must be "on-control" (DigOut only while an engineer controls the module, the '
                                            'default) or "always" (this tool is the module\'s only master: it serves the watchdog '
                                            'with every output off whenever nobody controls it and no other master is heard)'))))
    p2 = options.get(P2_OPTION, False)
    if not isinstance(p2, bool):
        errors.append((P2_OPTION, Message(N_("p2 (the HMR's three-phase output loaded on two phases, section 4.3) is true or "
                                              "false"))))
    elif p2 and options.get("variant") != "HMR":
        errors.append((P2_OPTION, Message(N_("p2 = true exists on the HMR only (its three-phase output SSR1-3, section 4.3)"))))
    firmware = options.get("firmware", 0x1201)
    if isinstance(firmware, bool) or not isinstance(firmware, int) or not 0 <= firmware <= 0xFFFF:
        errors.append(("firmware", Message(N_("firmware (simulated twin) is the SW version word, e.g. 0x1201 for 18.1"))))
    store_s = options.get("store_s", 0.03)
    if isinstance(store_s, bool) or not isinstance(store_s, int | float) or not 0 <= store_s <= 2.5:
        errors.append(("store_s", Message(N_("store_s (simulated twin: seconds to store a customer record) is 0 .. 2.5"))))
    for key in sorted(set(options) - {"variant", "sw1", "serial", "master", P2_OPTION, "firmware", "store_s"}):
        errors.append((key, Message(N_("unknown key '{key}' for an M3IO; known: variant, sw1, master, p2, serial, firmware "
                                       "and store_s (simulated twin)"), key=key)))
    return errors


def _identity(options: dict[str, Any], bus_type: str):
    sw1 = options.get("sw1")
    return f"DigOut 0x{codec.derive_ids(sw1).dig_out:03X}" if isinstance(sw1, int) and 0 <= sw1 <= 255 else None


# section 5.8 (function table) and 7.2: what each of the module's IDs carries, and who sends it
_ID_USES = {
    "DigOut": ("set the digital outputs", "master"),
    "DigIn": ("digital inputs", "device"),
    "Temp1-4": ("temperatures 1-4", "device"),
    "Temp5-6": ("temperatures 5-6", "device"),
    "Sync": ("SYNC / addressed data request", "master"),
    "MData": ("addressed data answer", "device"),
}


def _can_ids(options: dict[str, Any], bus_type: str) -> tuple[CanIdUse, ...]:
    """The five (S8 off) or six (S8 on) standard IDs that SW1 gives the module (section 5.8)."""
    sw1 = options.get("sw1")
    if bus_type != "can" or not isinstance(sw1, int) or isinstance(sw1, bool) or not 0 <= sw1 <= 0xFF:
        return ()
    return tuple(
        CanIdUse.one(can_id, f"CAN-M3IO {name} ({_ID_USES[name][0]}) with SW1 0x{sw1:02X}", _ID_USES[name][1])
        for name, can_id in codec.derive_ids(sw1).by_name().items()
    )


# outputs of every variant (KM: LED only; HM: SSR1..6; HMR: SSR1-3 three-phase and SSR4..6, section 4)
_OUTPUTS = ("LED", "SSR1-3", *(f"SSR{i}" for i in range(1, 7)))
TILE = TileSpec(
    lines=(
        TileLine(points=_OUTPUTS, template="outputs on: {list}", missing="none"),
        # TEMPx as heard, "out of range" included (section 7.2.2); HMR has no TEMP2/TEMP3, KM none: left out
        TileLine(values=tuple((f"TEMP{i}", f"T{i}") for i in range(1, 7)), template="{list}"),
    ),
    alarms=(
        TileAlarm(When("Variant check", ("mismatch",)), "{text}"),
        TileAlarm(When("Bit rate check", ("mismatch",)), "{text}"),
        *(TileAlarm(When(f"SSR{i} Si", ("blown",)), f"SSR{i} fuse blown") for i in range(1, 7)),
        *(TileAlarm(When(f"SSR{i} Triac", ("defective",)), f"SSR{i} triac defective") for i in range(1, 7)),
        TileAlarm(When("SSR1-3 load check", ("ok", None), negate=True), "{text}"),
    ),
    icon="electrical_services",
)


DEVICE_TYPE = DeviceType(
    name="m3io",
    title="CAN-M3IO",
    bus_types=("can",),
    params=PARAMS,
    adapters={"can": "devices.m3io.adapter:M3ioAdapter"},
    sims={"can": "devices.m3io.sim:M3ioSim"},
    check_config=_check_config,
    bus_identity=_identity,
    can_ids=_can_ids,
    tile=TILE,
)
