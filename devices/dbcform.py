"""Shared pieces of the DBC descriptions each CAN device type gives in ``devices/<type>/dbc.py``
(``dbc_messages(device, options) -> list[cantools Message]``, and optionally
``dbc_bus_messages(devices) -> list[Message]`` for frames shared by every device of the type on a bus).

Pure: cantools' database classes only, no I/O; app/dbc.py assembles a bus's database from them.
"""

from __future__ import annotations

import re
from typing import Any

from cantools.database.can import Signal
from cantools.database.conversion import BaseConversion

from devices.errors import CommissionError

NODE = "commission"  # this tool (or the controller it stands for) as a DBC node


class DbcError(CommissionError):
    """The bus cannot be exported (no such bus, not CAN, a device without its IDs); the message says why."""


def ident(text: str) -> str:
    """A DBC identifier: letters, digits and underscores, not starting with a digit."""
    name = re.sub(r"[^A-Za-z0-9_]+", "_", text).strip("_") or "x"
    return name if not name[0].isdigit() else f"_{name}"


def sig(name: str, start: int, length: int, *, signed: bool = False, scale: float = 1, unit: str = "",
         comment: str = "", choices: dict[int, str] | None = None, receivers: list[str] | None = None, **kw: Any) -> Signal:
    """A little-endian signal (every word of these devices is little-endian: HD-Lock 6.5,
    M3IO 7.2.2, Electrak control/status tables)."""
    return Signal(
        ident(name), start, length, byte_order="little_endian", is_signed=signed,
        conversion=BaseConversion.factory(scale=scale, offset=0, choices=choices, is_float=False),
        unit=unit or None, comment=comment or None, receivers=receivers or [], **kw,
    )


def bits(names: dict[int, str], first_bit: int) -> list[Signal]:
    return [sig(name, first_bit + bit, 1) for bit, name in sorted(names.items())]


