"""What the Ewellix SCU lets this tool do: its declared commands (see :mod:`devices.commands`).

The SCU sits on a point-to-point RS232 line where no raw-byte tool of this program sends, so it
declares no frame rules. Stops (RS, the emergency stop RE 19) are never refused; releasing control
stops first. Wording as the SCU page submits it.
"""

from __future__ import annotations

from devices.commands import Command

TITLE = "Ewellix SCU"

COMMANDS = (
    Command("stop (RS)", "stop", method="stop", session=True),
    Command("jog stop (RS)", "stop"),
    Command("emergency stop (RE 19)", "stop", method="emergency_stop", session=True),
    Command("release control", "stop", method="release_control", session=True),
    Command("read 0x", "read", prefix=True),
)
