"""What this tool never sends to an Electrak HD network as raw bytes, and what it confirms first.

Asked through :mod:`devices.sendpolicy` by the transmit list and the replay. A raw frame is judged as
the declared command it amounts to:

- the control telegram 0x06 with enable set moves the actuators: only the Electrak page sends it
  (hold-to-run, a visible stop, the dead-man rule); with override/reset set it asks what the declared
  override asks (it resets the number of actuators the network expects); only with both cleared is it
  a stop;
- a service write 0x0A of a parameter is checked by that parameter's range and value table and asks
  its own confirmation, like the parameter's declared write;
- what the actuators send (status 0x07, service answers 0x0B, their internal traffic 0x600-0x6FF)
  is never sent by this tool: it would speak for an actuator.

Go and jog ask that the area is clear, as the SCU's and the MO 64's motion commands do. Refusals, risks and names
are :class:`~devices.message.Message` texts: the bus tools and the Electrak page word them in their language, the audit
keeps the English.
"""

from __future__ import annotations

from devices.commands import Arg, Command, CommandError, param_write, read_parameters
from devices.electrak.adapter import ElectrakAdapter
from devices.electrak import codec
from devices.electrak.control import OVERRIDE_RISK, is_stop
from devices.electrak.params import PARAMS, SERVICE, length_of, refusal
from devices.message import Message, N_, message_of
from devices.params import ParamError
from devices.sendpolicy import Verdict

TITLE = "Electrak HD"
check_modbus = transmit_forms = None  # hooks of devices/sendpolicy.py this type has none of

MOTION_REFUSED = Message(N_("Electrak control telegram with enable set drives the actuators: use the Electrak page "
                            "(hold-to-run, a visible stop) instead"))
SERVICE_WRITE_RISK = Message(N_("Electrak service write: changes a parameter of the actuators of this network "
                                "(permanent once saved; section 'Service-Telegramm')."))
SAVE_RISK = Message(N_("Electrak save (specifier 0xF0): writes the service parameters to the actuators' non-volatile memory."))
AREA_CLEAR_RISK = Message(N_("The actuators move: check that the area is clear (nobody and nothing in the stroke of any "
                             "actuator of the network, nor under the load they carry)."))
SHORT_CONTROL_RISK = N_("Electrak control telegram of {n} bytes: the document defines 8 (target, current limit, speed, "
                        "control bits); what the actuators do with it is not known.")
DEVICE_SENT = {
    codec.STATUS_ID: Message(N_("the status telegram 0x07")),
    codec.SERVICE_RESPONSE_ID: Message(N_("the service answer 0x0B")),
}


def _device_sent(can_id: int) -> str:
    what = DEVICE_SENT.get(can_id) or (Message(N_("internal traffic 0x{id:03X} (0x600-0x6FF)"), id=can_id)
                                       if can_id in codec.INTERNAL_IDS else "")
    if not what:
        return ""
    return Message(N_("Electrak {what} is sent by the actuators themselves (document, 'Das Netzwerk im Überblick'): this "
                      "tool never sends it, as it would speak for an actuator. Leave it out of the list (a replay skips "
                      "it)."), what=what)


def check_can(can_id: int, extended: bool, data: bytes, devices, bus=()) -> Verdict | None:
    if extended:
        return None
    sent_by_devices = _device_sent(can_id)
    if sent_by_devices:
        return Verdict(refused=sent_by_devices, name=Message(N_("Electrak 0x{id:03X} (sent by the actuators)"), id=can_id),
                       kind="write")
    if can_id == codec.CONTROL_ID:
        return _control(data)
    if can_id == codec.SERVICE_REQUEST_ID and len(data) >= 2:
        if data[0] == codec.ServiceType.READ_REQUEST:
            return Verdict(name=Message(N_("Electrak service read 0x{specifier:02X}"), specifier=data[1]), kind="read")
        if data[1] == codec.SAVE_SPECIFIER:
            return Verdict(confirm=(SAVE_RISK,), name=Message(N_("Electrak service save")), kind="system")
        return _service_write(data)
    return None


def _control(data: bytes) -> Verdict:
    """A raw control telegram 0x06 as the command it amounts to: Go (refused), override/reset (asked), or a stop."""
    if len(data) >= 8 and data[7] & codec.ENABLE:
        return Verdict(refused=MOTION_REFUSED, name=Message(N_("Electrak control (enable)")), kind="motion")
    if len(data) < 8:
        return Verdict(confirm=(Message(SHORT_CONTROL_RISK, n=len(data)),), name=Message(N_("Electrak control (short)")),
                       kind="write")
    if not is_stop(bytes(data[:8])):  # override/reset set
        return Verdict(confirm=(OVERRIDE_RISK,), name=Message(N_("Electrak control (override/reset)")), kind="write")
    return Verdict(name=Message(N_("Electrak control (enable and override cleared: stops)")), kind="stop")


def _service_write(data: bytes) -> Verdict:
    """A raw service write 0x0A as the declared write of the parameter it amounts to: the same range, value table
    and confirmation (the value as the actuators store it: the parameter's length in bytes of the payload)."""
    name = Message(N_("Electrak service write 0x{specifier:02X}"), specifier=data[1])
    param = PARAMS.get(SERVICE, data[1]) if data[0] == codec.ServiceType.WRITE_REQUEST else None
    if param is None or len(data) < 8:
        return Verdict(confirm=(SERVICE_WRITE_RISK,), name=name, kind="write")
    name = Message(N_("Electrak {name} (service 0x{specifier:02X})"), name=param.name, specifier=data[1])
    length = length_of(param)
    if data[2] != length:
        wrong_size = (N_("{name} is {length} byte long (length byte 2 = {length}), not {got}: the actuators answer "
                         "WRONG_SIZE. Build the frame with length {length}, or write it on the Electrak page") if length == 1
                      else N_("{name} is {length} bytes long (length byte 2 = {length}), not {got}: the actuators answer "
                              "WRONG_SIZE. Build the frame with length {length}, or write it on the Electrak page"))
        return Verdict(refused=Message(wrong_size, name=param.name, length=length, got=data[2]), name=name)
    payload = int.from_bytes(data[4:8], "little")
    raw = payload & ((1 << 8 * length) - 1)
    if raw != payload:
        return Verdict(refused=Message(N_("{name}: the payload 0x{payload:08X} does not fit its {length} byte(s): send the "
                                          "value in bytes 4.. of the payload only"), name=param.name, payload=payload,
                                       length=length), name=name)
    value = param.decode(raw)
    reason = refusal(param, value)
    accepted = None
    if not reason:
        try:
            accepted = param.accept(value)
        except ParamError as exc:
            reason = message_of(exc)
    if accepted is None:  # refused: by the document, or by the parameter model
        return Verdict(refused=Message(N_("{reason} ({allowed}). Write a value in range, or use the Electrak page's entry"),
                                       reason=reason, allowed=_allowed(param)), name=name)
    own = accepted.risk
    return Verdict(confirm=(SERVICE_WRITE_RISK, *((own,) if own else ())),
                   name=Message("{name} = {value}", name=name, value=accepted.text), kind="write")


def _allowed(param) -> Message:
    """What ``param`` takes: its range (with its unit) or its value table."""
    if param.enum is not None:
        return Message(N_("allowed: {values}"), values=", ".join(f"{k} ({v})" for k, v in param.enum.items()))
    low, high = param.limits()
    if param.unit:
        return Message(N_("allowed {low:g} .. {high:g} {unit}"), low=low, high=high, unit=param.unit)
    return Message(N_("allowed {low:g} .. {high:g}"), low=low, high=high)


def _set_target_audit(values, adapter) -> dict:
    current = values["current_a"]
    return {"action": f"set target: position {values['position_mm']:g} mm, speed {values['speed_mm_s']:g} mm/s, "
                      f"current limit {current:g} A" + (" (calibrated)" if not current else "")}


def _go_audit(values, adapter) -> dict:
    c = adapter.command  # what Go enables: the target set before
    return {"action": f"go: target {c.position_mm:g} mm, speed {c.speed_mm_s:g} mm/s, current limit {c.current_a:g} A"}


def _jog(values: dict) -> dict:
    if values["direction"] not in (-1, 1):
        raise CommandError(Message(N_("direction: -1 (in) or 1 (out); a released button is 'jog stop'")))
    return values


def _jog_audit(values, adapter) -> dict:
    return {"action": f"jog {'out' if values['direction'] > 0 else 'in'}: speed {values['speed_mm_s']:g} mm/s, "
                      f"current limit {adapter.command.current_a:g} A"}


def _override(values: dict) -> dict:
    return {**values, "active": bool(values["active"])}


def _override_risk(values) -> str:
    return OVERRIDE_RISK if values.get("active") else ""


# the wire's ranges (0.1 units in 16 bits); the network's own (stroke, gearing, model) are the adapter's check
_POSITION = Arg("position_mm", 0, 6553.5, integer=False, unit="mm")
_SPEED = Arg("speed_mm_s", 0, 6553.5, integer=False, unit="mm/s")
_CURRENT = Arg("current_a", 0, 6553.5, integer=False, unit="A")

COMMANDS = (
    # -- stops: every role, never refused, sent first and audited afterwards -------------------------------------
    Command("stop", "stop", run=ElectrakAdapter.stop, session=True),
    Command("jog stop", "stop", run=ElectrakAdapter.jog_stop, session=True),
    Command("release control", "stop", run=ElectrakAdapter.release_control, session=True, extras=("reason",)),
    # -- control and motion: engineers; the adapter checks that the session holds control -----------------------
    Command("take control", "system", run=ElectrakAdapter.take_control, session=True, extras=("user",)),
    Command("set target", "write", run=ElectrakAdapter.set_command, session=True, args=(_POSITION, _SPEED, _CURRENT),
            audit=_set_target_audit),
    Command("go", "motion", run=ElectrakAdapter.go, session=True, audit=_go_audit, risk=AREA_CLEAR_RISK),
    Command("jog", "motion", run=ElectrakAdapter.jog, session=True, args=(Arg("direction", -1, 1), _SPEED), prepare=_jog,
            audit=_jog_audit, risk=AREA_CLEAR_RISK),
    # asked when set (it resets the number of actuators the network expects); the adapter refuses it unconfirmed
    Command("override", "write", run=ElectrakAdapter.override, session=True, args=(Arg("active", 0, 1),), prepare=_override,
            risk=_override_risk, confirmation=True),
    # -- service parameters ----------------------------------------------------------------------------------------
    Command("read service parameters", "read", run=ElectrakAdapter.read_all),
    Command("save parameters", "system", run=ElectrakAdapter.save_parameters),
    param_write(PARAMS, ElectrakAdapter.write_accepted),  # the parameter's own confirmation (e.g. a Timeout above the default)
    read_parameters(ElectrakAdapter.backup_read),
)
