"""What the Ewellix SCU lets this tool do: its declared commands (see :mod:`devices.commands`).

The SCU sits on a point-to-point RS232 line where no raw-byte tool of this program sends, so it
declares no frame rules. Stops (RS, jog release, the emergency stop RE 19, releasing control) are
never refused. Starting a function (RE) is motion and needs control of the unit; Go asks that the
area is clear; releasing the emergency stop (RS 19, table 8) is motion too, asked and by the holder
of control only. The page, the API and the CLI invoke these by name (pages/scu.py). The risks and refusals are
:class:`~devices.message.Message` texts, worded in the reader's language where they are shown; the audit keeps the English.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from devices.commands import Arg, Command, CommandError, param_write, read_parameters
from devices.message import Message, N_
from devices.scu import codec
from devices.scu.adapter import ScuAdapter
from devices.scu.model import PARAMS

TITLE = "Ewellix SCU"
check_can = check_modbus = transmit_forms = None  # hooks of devices/sendpolicy.py this type has none of

_FUNCTION = Arg("function", 0, 9)  # fnc_ID of F1..F10 (motion functions, section 4.4)
_RAMP = Arg("ramp", -1, 1)  # para_ID[1]: 1 soft, 0 fast, -1 as configured
_SWITCHES = frozenset(int(f) for f in (codec.Function.BUZZER, codec.Function.BINARY_OUTPUT_1,
                                        codec.Function.BINARY_OUTPUT_2, codec.Function.LED_1, codec.Function.LED_2))
_STOPPABLE = frozenset(int(f) for f in codec.Function) - {int(codec.Function.EMERGENCY_STOP)}
ESTOP_RELEASE_RISK = Message(N_("Release the emergency stop (RS 19, table 8)? Every drive may be started again. Only the "
                                "person who set it releases it: check that the reason for it is gone and the area is clear."))
WITHHOLD_RC_RISK = Message(N_("Withhold RC on purpose (the watchdog test, section 5): the unit must stop every drive within "
                              "500 ms, leave remote mode and set error bit 22. A drive that goes on moving fails the test: "
                              "stand by the hand switch's stop."))


def _go_risk(values: Mapping[str, Any]) -> str:
    label = codec.FUNCTIONS[codec.Function(values["function"])].label
    motion = codec.MOTION_LABELS.get(codec.Motion(values["motion"]))  # table 9's motions, in the catalog (pages/scu.py)
    return Message(N_("{function} starts motion ({motion}). Check that the area is clear: nobody and nothing in the stroke "
                      "of the actuators it drives."), function=label,
                   motion=Message(motion) if motion else values["motion"])


def _motion(values: dict[str, Any]) -> dict[str, Any]:
    try:
        codec.Motion(values["motion"])
    except ValueError:
        raise CommandError(Message(N_("motion {motion} is not a para_ID[0] of table 9"), motion=values["motion"])) from None
    return values


def _jog(values: dict[str, Any]) -> dict[str, Any]:
    if values["direction"] == 0:
        raise CommandError(Message(N_("direction: -1 (in) or +1 (out); the release is 'jog stop (RS)'")))
    return values


def _switch(values: dict[str, Any]) -> dict[str, Any]:
    if values["function"] not in _SWITCHES:
        raise CommandError(Message(N_("function {function} is not the buzzer, a binary output or an LED (16, 17, 20, 21, 10)"),
                                   function=values["function"]))
    return values


def _stoppable(values: dict[str, Any]) -> dict[str, Any]:
    if values["function"] not in _STOPPABLE:
        raise CommandError(Message(N_("function {function}: RS only to F1..F10, the buzzer, the outputs and LEDs; the "
                                      "emergency stop is released by its own command"), function=values["function"]))
    return values


def _speed_audit(values: Mapping[str, Any], adapter: ScuAdapter) -> dict[str, Any]:
    key = f"F{values['function']} remote speed"
    before = adapter.state.points.get(key)
    return {"action": f"set remote speed F{values['function']}", "parameter": f"Remote Speed F{values['function']} "
            f"(0x{0x3010 + values['function']:04X})", "old": "" if before is None else before.value,
            "new": f"{values['speed']} {adapter.speed_unit}".strip()}


def _position_audit(values: Mapping[str, Any], adapter: Any) -> dict[str, Any]:
    n = values["actuator"]
    before = adapter.state.points.get(f"A{n} remote position")
    unit = "mm" if values.get("mm") else "counts"
    return {"action": f"set remote position A{n}", "parameter": f"Remote Position A{n} (0x{0x3020 + n:04X})",
            "old": "" if before is None else (before.text or before.value), "new": f"{values['value']:g} {unit}"}


COMMANDS = (
    # -- stops: every role, never refused, sent first and audited afterwards -----------------------------------------
    Command("stop (RS)", "stop", run=ScuAdapter.stop, session=True),
    Command("function off (RS)", "stop", run=ScuAdapter.stop, session=True, args=(Arg("function", 0, 21),), prepare=_stoppable),
    Command("jog stop (RS)", "stop", run=ScuAdapter.jog_stop, session=True, args=(_FUNCTION,)),
    Command("emergency stop (RE 19)", "stop", run=ScuAdapter.emergency_stop, session=True, extras=("user",)),
    Command("release control", "stop", run=ScuAdapter.release_control, session=True),
    # -- motion: engineers, with control --------------------------------------------------------------------------------
    Command("go (RE)", "motion", run=ScuAdapter.run_function, session=True, needs_control=True,
            args=(_FUNCTION, Arg("motion", 0, 9), _RAMP), extras=("requested_at",), prepare=_motion, risk=_go_risk),
    Command("jog (RE)", "motion", run=ScuAdapter.jog, session=True, needs_control=True,
            args=(_FUNCTION, Arg("direction", -1, 1), _RAMP), extras=("requested_at",), prepare=_jog),
    Command("release emergency stop (RS 19)", "motion", run=ScuAdapter.release_emergency_stop, session=True,
            needs_control=True, risk=ESTOP_RELEASE_RISK),
    Command("withhold RC", "motion", run=ScuAdapter.withhold_rc, session=True, needs_control=True,
            risk=WITHHOLD_RC_RISK),
    # -- writes: the volatile remote data (table 7), read back --------------------------------------------------------
    Command("function on (RE)", "write", run=ScuAdapter.run_function, session=True, needs_control=True,
            args=(Arg("function", 10, 21),), prepare=_switch),
    Command("set remote speed", "write", run=ScuAdapter.set_remote_speed, session=True, needs_control=True,
            args=(Arg("function", 1, 10), Arg("speed", 0, 1000)), audit=_speed_audit),
    Command("set remote position", "write", run=ScuAdapter.set_remote_target, session=True, needs_control=True,
            args=(Arg("actuator", 1, 6), Arg("value", -(2 ** 31), 2 ** 31 - 1, integer=False)), flags=("mm",),
            audit=_position_audit),
    # the parameter model's settings (remote speeds and positions, devices/scu/model.py): restore, project, batch and
    # the API; the adapter opens the session for it and refuses it while a function runs (devices/scu/settings.py)
    param_write(PARAMS, ScuAdapter.write_accepted),
    # -- the session --------------------------------------------------------------------------------------------------
    Command("take control", "system", run=ScuAdapter.take_control, session=True, extras=("user",)),
    Command("open remote session", "system", run=ScuAdapter.reopen, session=True),
    Command("release the SCU (RA)", "system", run=ScuAdapter.release_scu, session=True),
    # -- reads ---------------------------------------------------------------------------------------------------------
    Command("read data", "read", run=ScuAdapter.read_data, args=(Arg("data_id", 0, 0xFFFF),)),
    read_parameters(ScuAdapter.backup_read),  # the parameter model's values, as a backup reads them (the page's Settings card)
    Command("read 0x", "read", prefix=True),
)
