"""What this tool never sends to an Electrak HD network as raw bytes, and what it confirms first.

Asked through :mod:`devices.sendpolicy` by the transmit list and the replay. The control
telegram with enable set moves the actuators: only the Electrak page sends it (hold-to-run,
a visible stop, the dead-man rule); without enable it stops them.
"""

from __future__ import annotations

from devices.electrak import codec
from devices.commands import Command, param_write
from devices.electrak.params import PARAMS
from devices.sendpolicy import Verdict

TITLE = "Electrak HD"

MOTION_REFUSED = ("Electrak control telegram with enable set drives the actuators: use the Electrak page "
                  "(hold-to-run, a visible stop) instead")
SERVICE_WRITE_RISK = ("Electrak service write: changes a parameter of the actuators of this network "
                      "(permanent once saved; section 'Service-Telegramm').")
SAVE_RISK = "Electrak save (specifier 0xF0): writes the service parameters to the actuators' non-volatile memory."


def check_can(can_id: int, extended: bool, data: bytes, devices, bus=()) -> Verdict | None:
    if extended:
        return None
    if can_id == codec.CONTROL_ID:
        if len(data) >= 8 and data[7] & codec.ENABLE:
            return Verdict(refused=MOTION_REFUSED, name="Electrak control (enable)", kind="motion")
        return Verdict(name="Electrak control (no enable: stops)", kind="stop")
    if can_id == codec.SERVICE_REQUEST_ID and len(data) >= 2:
        if data[0] == codec.ServiceType.READ_REQUEST:
            return Verdict(name=f"Electrak service read 0x{data[1]:02X}", kind="read")
        if data[1] == codec.SAVE_SPECIFIER:
            return Verdict(confirm=(SAVE_RISK,), name="Electrak service save", kind="system")
        return Verdict(confirm=(SERVICE_WRITE_RISK,), name=f"Electrak service write 0x{data[1]:02X}", kind="write")
    return None


COMMANDS = (
    Command("stop", "stop", method="stop", session=True),
    Command("jog stop", "stop"),
    Command("release control", "stop", method="release_control", session=True),
    Command("read service parameters", "read", method="read_all"),
    param_write(PARAMS),  # the parameter's own confirmation (e.g. a Timeout above the default)
)
