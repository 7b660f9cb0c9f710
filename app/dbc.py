"""DBC export of the CAN devices on one bus, through cantools.

SavvyCAN, CANalyzer and cantools users decode recorded traces with the names of this tool:
HD-Lock frames under their device IDs (status, FWU status and register answers, told apart
by bytes 0-1 as a multiplexer; register answers are 6 of the 8 bytes, so cantools users
decode them with ``allow_truncated=True``), the M3IO's DigOut, DigIn and temperature frames under the
IDs its SW1 gives, the Electrak network's control, status and service telegrams.

IDs, bit names and variants come from the device codecs (``derive_ids``, ``OUTPUT_BITS``,
``LOCK_STATUS_NAMES``, ``MOTION_FLAGS``, ``ERROR_FLAGS``, ``DeviceId``); the byte positions
and scales of the words are the codecs' too, restated here as DBC signals (the codecs have no
describing function yet) and checked against the codecs' decoders in tests/test_dbc.py.

CLI: ``commission dbc --plant P --bus B --out FILE.dbc`` (:func:`add_parser`, :func:`run`);
the monitor gets the text with :func:`dbc_text`.
"""

from __future__ import annotations

import argparse
import re
from pathlib import Path
from typing import Any

from cantools.database import Database
from cantools.database.can import Message, Signal
from cantools.database.conversion import BaseConversion

from app.plant import Plant
from devices.electrak import codec as electrak
from devices.hdlock import codec as hdlock
from devices.m3io import codec as m3io

NODE = "commission"  # this tool (or the controller it stands for) as a DBC node


class DbcError(Exception):
    """The bus cannot be exported (no such bus, not CAN, a device without its IDs); the message says why."""


def _ident(text: str) -> str:
    """A DBC identifier: letters, digits and underscores, not starting with a digit."""
    name = re.sub(r"[^A-Za-z0-9_]+", "_", text).strip("_") or "x"
    return name if not name[0].isdigit() else f"_{name}"


def _sig(name: str, start: int, length: int, *, signed: bool = False, scale: float = 1, unit: str = "",
         comment: str = "", choices: dict[int, str] | None = None, receivers: list[str] | None = None, **kw: Any) -> Signal:
    """A little-endian signal (every word of these devices is little-endian: HD-Lock 6.5,
    M3IO 7.2.2, Electrak control/status tables)."""
    return Signal(
        _ident(name), start, length, byte_order="little_endian", is_signed=signed,
        conversion=BaseConversion.factory(scale=scale, offset=0, choices=choices, is_float=False),
        unit=unit or None, comment=comment or None, receivers=receivers or [], **kw,
    )


def _bits(names: dict[int, str], first_bit: int) -> list[Signal]:
    return [_sig(name, first_bit + bit, 1) for bit, name in sorted(names.items())]


# -- HD-Lock (section 6.5) ------------------------------------------------------------------------------

HDLOCK_KIND_STATUS = 0x0000  # bytes 0-1 = 00 00: status (6.5.1)
HDLOCK_KIND_FWU = 0x0001  # 01 00: firmware-update status (6.5.2)
HDLOCK_KIND_INPUT = 0x0100  # 00 01: input-register answer (6.5.3)
HDLOCK_KIND_HOLDING = 0x0101  # 01 01: holding-register answer (6.5.4)


def hdlock_messages(device: str, options: dict[str, Any]) -> list[Message]:
    """The frames a lock sends under its device ID, multiplexed by bytes 0-1 (read little-endian)."""
    try:
        ident = hdlock.DeviceId.make(options["device_id"], options.get("extended"))
    except (KeyError, TypeError, hdlock.CodecError) as exc:
        raise DbcError(f"{device}: no CAN device ID ({exc})") from None
    status_bits = {bit: name.replace(" (bit 4)", "_bit4") for bit, name in hdlock.LOCK_STATUS_NAMES.items()}
    kinds = {HDLOCK_KIND_STATUS: "Status", HDLOCK_KIND_FWU: "FwuStatus", HDLOCK_KIND_INPUT: "InputRegisterAnswer",
             HDLOCK_KIND_HOLDING: "HoldingRegisterAnswer"}
    signals = [_sig("FrameKind", 0, 16, is_multiplexer=True, choices=kinds, comment="bytes 0-1 (section 6.5)")]
    status = [HDLOCK_KIND_STATUS]
    # bytes 2-7: Status word (= holding 1000), motorPos, (proximity << 6) + LockRequestSource (SPEC-NOTES)
    # the status word (= holding 1000) by its named bits: overlapping signals are refused by cantools' strict check
    signals += [_sig(f"LockStatus_{name}", 16 + bit, 1, multiplexer_ids=status, multiplexer_signal="FrameKind")
                for bit, name in sorted(status_bits.items())]
    signals += [
        _sig("MotorPos", 32, 16, multiplexer_ids=status, multiplexer_signal="FrameKind", unit="increments"),
        _sig("LockRequestSource", 48, 6, multiplexer_ids=status, multiplexer_signal="FrameKind",
             comment="low 6 bits of LockRequestSource; read holding 4 for the whole value"),
        _sig("Proximity", 54, 10, multiplexer_ids=status, multiplexer_signal="FrameKind"),
        _sig("FwuFlashing", 16, 16, multiplexer_ids=[HDLOCK_KIND_FWU], multiplexer_signal="FrameKind"),
        _sig("FwuApplication", 32, 16, multiplexer_ids=[HDLOCK_KIND_FWU], multiplexer_signal="FrameKind"),
    ]
    for kind, space in ((HDLOCK_KIND_INPUT, "Input"), (HDLOCK_KIND_HOLDING, "Holding")):  # one mux value per signal in DBC
        signals += [_sig(f"{space}RegisterAddress", 16, 16, multiplexer_ids=[kind], multiplexer_signal="FrameKind"),
                    _sig(f"{space}RegisterValue", 32, 16, multiplexer_ids=[kind], multiplexer_signal="FrameKind")]
    return [Message(ident.value, _ident(f"{device}_HDLock"), 8, signals, is_extended_frame=ident.extended,
                    senders=[_ident(device)], cycle_time=int(hdlock.STATUS_PERIOD_S * 1000),
                    comment=f"HD-Lock {device}, device ID {ident}: status every 1 s and register answers (section 6.5)")]


# -- CAN-M3IO (sections 5.8, 7.2) -----------------------------------------------------------------------

def m3io_messages(device: str, options: dict[str, Any]) -> list[Message]:
    """DigOut, DigIn and the temperature frames at the IDs SW1 gives (section 5.8)."""
    try:
        ids = m3io.derive_ids(options["sw1"])
        variant = m3io.Variant(options.get("variant", "HM"))
    except (KeyError, TypeError, ValueError) as exc:
        raise DbcError(f"{device}: no SW1/variant to derive its IDs from ({exc})") from None
    node = _ident(device)
    dig_out = _bits({bit: name for name, bit in m3io.OUTPUT_BITS[variant].items()}, 0) + [_sig("REQ", 7, 1, comment="obsolete DigIn request")]
    dig_in = _bits({i: f"E{i + 1}" for i in range(6)}, 0)

    def temp_word(word_number: int, first_bit: int) -> list[Signal]:
        name = f"T{word_number}"
        sensor = m3io.temp_input(variant, word_number)
        return [  # the temperature word (section 7.2.2): 12-bit two's complement in 0.1 C, then sb, Last, Triac, Si
            _sig(f"{name}_Temp", first_bit, 12, signed=True, scale=0.1, unit="degC",
                 comment=f"TEMP{sensor}; below 0 or above 200.0 C: out of measuring range"),
            _sig(f"{name}_sb", first_bit + 12, 1),
            _sig(f"{name}_Last", first_bit + 13, 1, comment="load present; Si and Triac mean nothing while 0"),
            _sig(f"{name}_Triac", first_bit + 14, 1),
            _sig(f"{name}_Si", first_bit + 15, 1, comment="0 = fuse blown"),
        ]

    temp14 = [s for n in range(1, 5) for s in temp_word(n, 16 * (n - 1))]
    temp56 = [s for n in (5, 6) for s in temp_word(n, 16 * (n - 5))]
    return [
        Message(ids.dig_out, _ident(f"{device}_DigOut"), 1, dig_out, senders=[NODE], cycle_time=int(m3io.DIGOUT_PERIOD_S * 1000),
                comment=f"{variant.value} outputs; keep-alive within {m3io.WATCHDOG_S:g} s"),
        Message(ids.dig_in, _ident(f"{device}_DigIn"), 1, dig_in, senders=[node]),
        Message(ids.temp14, _ident(f"{device}_Temp1_4"), 8, temp14, senders=[node], cycle_time=int(m3io.TEMP_PERIOD_S * 1000)),
        Message(ids.temp56, _ident(f"{device}_Temp5_6"), 4, temp56, senders=[node], cycle_time=int(m3io.TEMP_PERIOD_S * 1000)),
    ]


# -- Electrak HD network (control 0x06, status 0x07, service 0x0A/0x0B) ----------------------------------

def electrak_messages(device: str, _options: dict[str, Any]) -> list[Message]:
    node = _ident(device)
    words = [("Position", "mm"), ("Current", "A"), ("Speed", "mm/s")]
    control = [
        _sig("TargetPosition", 0, 16, scale=0.1, unit="mm"),
        _sig("CurrentLimit", 16, 16, scale=0.1, unit="A", comment="0 = calibrated default"),
        _sig("TargetSpeed", 32, 16, scale=0.1, unit="mm/s"),
        _sig("Enable", 56 + electrak.ENABLE.bit_length() - 1, 1),
        _sig("Override", 56 + electrak.OVERRIDE.bit_length() - 1, 1, comment="override / reset"),
    ]
    status = [_sig(name, 16 * i, 16, scale=0.1, unit=unit) for i, (name, unit) in enumerate(words)]
    # byte 6 motion flags, byte 7 error flags, by their named bits (cantools refuses overlapping signals)
    status += _bits({bit: name for bit, (name, _) in electrak.MOTION_FLAGS.items()}, 48)
    status += _bits({bit: name for bit, (name, *_rest) in electrak.ERROR_FLAGS.items()}, 56)
    service_types = {int(t): t.name for t in electrak.ServiceType}
    service = [_sig("Type", 0, 8, choices=service_types), _sig("Specifier", 8, 8), _sig("Length", 16, 8),
               _sig("Payload", 32, 32)]
    return [
        Message(electrak.CONTROL_ID, _ident(f"{device}_Control"), 8, control, senders=[NODE],
                cycle_time=int(electrak.CONTROL_PERIOD_S * 1000), comment="control telegram: every 100 ms while controlling"),
        Message(electrak.STATUS_ID, _ident(f"{device}_Status"), 8, status, senders=[node],
                cycle_time=int(electrak.STATUS_PERIOD_S * 1000), comment="status of each actuator (cannot be told apart)"),
        Message(electrak.SERVICE_REQUEST_ID, _ident(f"{device}_ServiceRequest"), 8, service, senders=[NODE]),
        Message(electrak.SERVICE_RESPONSE_ID, _ident(f"{device}_ServiceResponse"), 8,
                [_sig(s.name, s.start, s.length, choices=service_types if s.name == "Type" else None) for s in service],
                senders=[node]),
    ]


BUILDERS = {"hdlock": hdlock_messages, "m3io": m3io_messages, "electrak": electrak_messages}


def bus_database(plant: Plant, bus: str) -> Database:
    """A cantools database of the devices on CAN bus ``bus``; devices of types without CAN frames are skipped.

    :raises DbcError: no such bus, or not a CAN bus
    """
    config = plant.buses.get(bus)
    if config is None:
        raise DbcError(f"no bus named {bus!r} in plant {plant.name!r} (buses: {', '.join(plant.buses) or 'none'})")
    if config.type != "can":
        raise DbcError(f"{bus} is a {config.type} bus; a DBC describes CAN buses only")
    messages: list[Message] = []
    nodes = {NODE}
    for dev in plant.devices_on(bus):
        build = BUILDERS.get(dev.type)
        if build is None:
            continue
        messages += build(dev.name, dev.options)
        nodes.add(_ident(dev.name))
    from cantools.database.can import Node  # noqa: PLC0415

    db = Database(messages=messages, nodes=[Node(n) for n in sorted(nodes)], version="")
    db.refresh()
    return db


def dbc_text(worker_or_plant: Any, bus: str) -> str:
    """The DBC text of ``bus``, from a :class:`~app.plant.Plant` or anything with ``.plant`` (the worker).

    The worker's plant includes adopted devices. Pure computation (no I/O): fine on the event loop.
    """
    plant = worker_or_plant if isinstance(worker_or_plant, Plant) else worker_or_plant.plant
    return bus_database(plant, bus).as_dbc_string()


# -- command line -----------------------------------------------------------------------------------------

def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """``commission dbc --plant P --bus B --out FILE.dbc``."""
    parser = subparsers.add_parser("dbc", help="write a DBC of the CAN devices on one bus",
                                   description="Write a DBC file (cantools) of the CAN devices on one bus of a plant file.")
    parser.add_argument("--plant", type=Path, required=True, help="plant file (TOML)")
    parser.add_argument("--bus", required=True, help="name of a CAN bus in the plant file")
    parser.add_argument("--out", type=Path, required=True, help="the DBC file to write")
    parser.set_defaults(func=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """Write the DBC; 0 on success, 2 with one line on stderr otherwise."""
    import sys  # noqa: PLC0415

    from app.backup import write_atomic  # noqa: PLC0415
    from app.plant import PlantError, load_plant  # noqa: PLC0415

    try:
        plant = load_plant(args.plant)
        text = dbc_text(plant, args.bus)
        write_atomic(Path(args.out), text)
    except (DbcError, PlantError, OSError) as exc:
        print(f"commission dbc: {exc}", file=sys.stderr)
        return 2
    count = len(bus_database(plant, args.bus).messages)
    print(f"wrote {args.out}: {count} frames of bus {args.bus}")
    return 0
