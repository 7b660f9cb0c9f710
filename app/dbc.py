"""DBC export of the CAN devices on one bus, through cantools.

SavvyCAN, CANalyzer and cantools users decode recorded traces with the names of this tool:
HD-Lock frames under their device IDs (status, FWU status and register answers, told apart
by bytes 0-1 as a multiplexer; register answers are 6 of the 8 bytes, so cantools users
decode them with ``allow_truncated=True``), the M3IO's DigOut, DigIn and temperature frames under the
IDs its SW1 gives, the Electrak network's control, status and service telegrams.

Each device type describes its own frames in ``devices/<type>/dbc.py`` (``dbc_messages`` per
device, ``dbc_bus_messages`` for frames its devices share); this module names no device type.
The descriptions are checked against the codecs' decoders in tests/devices/test_dbc.py.

CLI: ``commission dbc --plant P --bus B --out FILE.dbc`` (:func:`add_parser`, :func:`run`);
the monitor gets the text with :func:`dbc_text`.
"""

from __future__ import annotations

import argparse
import importlib
from pathlib import Path
from types import ModuleType
from typing import Any

from cantools.database import Database
from cantools.database.can import Message

from app.cli_lang import _
from app.plant import Plant
from devices.dbcform import NODE, DbcError, ident

__all__ = ["DbcError", "NODE", "bus_database", "dbc_text"]

def _description(type_name: str) -> ModuleType | None:
    """``devices.<type>.dbc``, or None for a type without CAN frames to describe."""
    try:
        return importlib.import_module(f"devices.{type_name}.dbc")
    except ModuleNotFoundError as exc:
        if exc.name != f"devices.{type_name}.dbc":
            raise
        return None


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
    by_type: dict[str, list[Any]] = {}
    for dev in plant.devices_on(bus):
        description = _description(dev.type)
        if description is None:
            continue
        messages += description.dbc_messages(dev.name, dev.options)
        nodes.add(ident(dev.name))
        by_type.setdefault(dev.type, []).append(dev)
    for type_name, devices in sorted(by_type.items()):  # frames every device of a type shares (request blocks)
        shared = getattr(_description(type_name), "dbc_bus_messages", None)
        if shared is not None:
            messages += shared(devices)
    from cantools.database.can import Node  # noqa: PLC0415

    db = Database(messages=messages, nodes=[Node(n) for n in sorted(nodes)], version="")
    db.refresh()
    return db


def dbc_text(worker_or_plant: Any, bus: str) -> str:
    """The DBC text of ``bus``, from a :class:`~app.plant.Plant` or anything with ``.plant`` (the worker).

    The running plant (the runtime's, which the worker shares) includes adopted devices. Pure
    computation (no I/O): fine on the event loop.
    """
    plant = worker_or_plant if isinstance(worker_or_plant, Plant) else worker_or_plant.plant
    return bus_database(plant, bus).as_dbc_string()


# -- command line -----------------------------------------------------------------------------------------

def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """``commission dbc --plant P --bus B --out FILE.dbc``."""
    parser = subparsers.add_parser("dbc", help=_("write a DBC of the CAN devices on one bus"),
                                   description=_("Write a DBC file (cantools) of the CAN devices on one bus of a plant file."))
    parser.add_argument("--plant", type=Path, required=True, help=_("plant file (TOML)"))
    parser.add_argument("--bus", required=True, help=_("name of a CAN bus in the plant file"))
    parser.add_argument("--out", type=Path, required=True, help=_("the DBC file to write"))
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
    print(_("wrote {path}: {count} frames of bus {bus}").format(path=args.out, count=count, bus=args.bus))
    return 0
