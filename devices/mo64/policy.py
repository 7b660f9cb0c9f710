"""What the MO 64 barrier control lets this tool do: its declared commands (see :mod:`devices.commands`).

The MO 64 sits on LogiTed lines (TCP or RS485), where no raw-byte tool of this program sends, so
it declares no frame rules; its commands carry the kinds the gate decides on. Clearing levels
deactivates open/close levels and moves the barrier; releasing the TCP connection hands the
barrier to another client.
"""

from __future__ import annotations

from devices.commands import Command

TITLE = "MO 64"

COMMANDS = (
    Command("clear levels", "motion", method="clear_levels", session=True),
    Command("release the connection", "system", method="release", session=True),
    Command("take the connection back", "system", method="resume", session=True),
    Command("read error memory", "read", method="read_error_memory"),
)
