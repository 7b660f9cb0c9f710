"""What this tool never sends to an Electrak HD network as raw bytes, and what it confirms first.

Asked through :mod:`devices.sendpolicy` by the transmit list and the replay. The control
telegram with enable set moves the actuators: only the Electrak page sends it (hold-to-run,
a visible stop, the dead-man rule); without enable it stops them.
"""

from __future__ import annotations

from devices.electrak import codec
from devices.commands import Arg, Command, CommandError, param_write
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


def _set_target_audit(values, adapter) -> dict:
    current = values["current_a"]
    return {"action": f"set target: position {values['position_mm']:g} mm, speed {values['speed_mm_s']:g} mm/s, "
                      f"current limit {current:g} A" + (" (calibrated)" if not current else "")}


def _go_audit(values, adapter) -> dict:
    c = adapter.command  # what Go enables: the target set before
    return {"action": f"go: target {c.position_mm:g} mm, speed {c.speed_mm_s:g} mm/s, current limit {c.current_a:g} A"}


def _jog(values: dict) -> dict:
    if values["direction"] not in (-1, 1):
        raise CommandError("direction: -1 (in) or 1 (out); a released button is 'jog stop'")
    return values


def _jog_audit(values, adapter) -> dict:
    return {"action": f"jog {'out' if values['direction'] > 0 else 'in'}: speed {values['speed_mm_s']:g} mm/s, "
                      f"current limit {adapter.command.current_a:g} A"}


def _override(values: dict) -> dict:
    return {**values, "active": bool(values["active"])}


# the wire's ranges (0.1 units in 16 bits); the network's own (stroke, gearing, model) are the adapter's check
_POSITION = Arg("position_mm", 0, 6553.5, integer=False, unit="mm")
_SPEED = Arg("speed_mm_s", 0, 6553.5, integer=False, unit="mm/s")
_CURRENT = Arg("current_a", 0, 6553.5, integer=False, unit="A")

COMMANDS = (
    # -- stops: every role, never refused, sent first and audited afterwards -------------------------------------
    Command("stop", "stop", method="stop", session=True),
    Command("jog stop", "stop", method="jog_stop", session=True),
    Command("release control", "stop", method="release_control", session=True, extras=("reason",)),
    # -- control and motion: engineers; the adapter checks that the session holds control -----------------------
    Command("take control", "system", method="take_control", session=True, extras=("user",)),
    Command("set target", "write", method="set_command", session=True, args=(_POSITION, _SPEED, _CURRENT),
            audit=_set_target_audit),
    Command("go", "motion", method="go", session=True, audit=_go_audit),
    Command("jog", "motion", method="jog", session=True, args=(Arg("direction", -1, 1), _SPEED), prepare=_jog,
            audit=_jog_audit),
    Command("override", "write", method="override", session=True, args=(Arg("active", 0, 1),), prepare=_override),
    # -- service parameters ----------------------------------------------------------------------------------------
    Command("read service parameters", "read", method="read_all"),
    Command("save parameters", "system", method="save_parameters"),
    param_write(PARAMS),  # the parameter's own confirmation (e.g. a Timeout above the default)
)
