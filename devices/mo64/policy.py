"""What the MO 64 barrier control lets this tool do: its declared commands (see :mod:`devices.commands`).

The MO 64 sits on LogiTed lines (TCP or RS485). Its commands carry the kinds the gate decides on, and the
risks the gate asks before it runs them (the page asks nothing of its own); a raw telegram of a bus tool is
judged by :func:`check_telegram`, the same rule (devices/mo64/control.py):

- operating commands (chapter 5.2.1) as ``"<open|close|reverse> <pulse|activate|deactivate>"``:
  motion, asking that the area is clear every time (a confirmation is never remembered); deactivating a
  close or reverse level is a stop (what the dead-man rule does), deactivating the open level is motion
  (it lets the boom close, page 33);
- ``"clear levels"``: system, engineers only, asks the risk (an open level released lets the boom close);
- ``"set <setting name>"`` (chapter 5.2.4-5.2.8) with the setting's numbers and their ranges
  (``codec.setting_fields``): a write; the risk names the EEPROM wear, and for an assumed selector the
  flag ``selector_verified`` says the engineer verified it on this unit, a statement the risk repeats
  for the confirmation (without it, the adapter refuses a selector not verified before);
- ``"write parameter"`` (:func:`devices.commands.param_write` on :data:`devices.mo64.params.PARAMS`): one named
  setting (a time, one configuration flag, one relay mode...) checked by the model and written by read-modify-write;
  it asks what the model names (a flag that switches a safety function off, by its name) and, for an assumed
  selector, that it is verified on this unit. The page, restore and the batch write through it;
- a ``"set ..."`` command or raw telegram whose value switches a safety flag off asks the same question, naming it;
- ``"change monitoring"`` (on = 1 or 0): a write of the EEPROM;
- releasing and taking back the TCP connection: writes (another client gets the barrier);
- reading the error memory: a read.
"""

from __future__ import annotations

from devices.commands import Arg, Command, param_write, read_parameters
from devices.params import Accepted
from devices.mo64 import codec
from devices.mo64 import params as model
from devices.mo64.adapter import COMMAND_NAMES, OPERATIONS, Mo64Adapter
from devices.mo64.settings import SETTING_WRITES, Mo64Settings
from devices.mo64.control import AREA_CLEAR_RISK, EEPROM_RISK, OPEN_LEVEL_RISK, meaning, operation
from devices.sendpolicy import Verdict
from devices.message import Message, N_, joined

TITLE = "MO 64"
check_can = check_modbus = transmit_forms = None  # hooks of devices/sendpolicy.py this type has none of
__all__ = ["AREA_CLEAR_RISK", "OPEN_LEVEL_RISK", "EEPROM_RISK", "check_telegram"]
CLEAR_LEVELS_RISK = Message(N_("Deactivates every level this tool set in the barrier (levels set by another master or at the "
                               "barrier are not touched). An open level released lets the boom close (page 33): check that "
                               "nobody stands under it (the area is clear)."))


def selector_risk(setting: codec.Setting) -> str:
    return Message(N_("The selector 0x{telegram:02X} 0x{selector:02X} of {name} is an assumption ({assumed}); the manual's "
                      "summary does not name it, and a wrong selector writes another EEPROM setting. Confirm only if you "
                      "verified on this unit that it is {setting}."), telegram=setting.telegram, selector=setting.selector,
                   name=Message(setting.name), assumed=setting.assumed, setting=Message(setting.name))


def _setting_risk(setting: codec.Setting):
    def risk(args) -> str:
        parts = [selector_risk(setting)] if setting.assumed and args.get("selector_verified") else []
        try:  # a flag this value switches off is named (devices/mo64/params.py), whatever the path
            number = model.setting_int(setting.key, codec.setting_from_fields(
                setting.key, [args[name] for name, _, _ in codec.setting_fields(setting.key)]))
            parts = model.safety_questions(setting.key, number) + parts
        except (KeyError, codec.CodecError):
            pass  # out of range: refused by the argument check
        return joined(parts + ([EEPROM_RISK] if setting.eeprom else []), " ")
    return risk


def operation_name(cmd: codec.Command, fn: codec.Function) -> str:
    """The declared name of an operating command, e.g. "open pulse" (also its audit action)."""
    return f"{COMMAND_NAMES[cmd]} {fn.name.lower()}"


def setting_name(key: str) -> str:
    return f"set {codec.SETTINGS[key].name}"


def _operation(cmd: codec.Command, fn: codec.Function) -> Command:
    what = operation(cmd, fn)  # the motion rule's own reading (devices/mo64/control.py)
    if what.kind == "stop":
        return Command(operation_name(cmd, fn), "stop", run=OPERATIONS[cmd, fn], session=True)
    return Command(operation_name(cmd, fn), what.kind, run=OPERATIONS[cmd, fn], session=True, risk=what.risk)


def check_telegram(telegram: bytes) -> Verdict:
    """The verdict on a raw telegram to an MO 64 (type and payload, unframed): the declared command it amounts
    to, its kind and its risk (asked for each telegram), or why it is never sent (a telegram the barrier sends,
    a short command, an unknown setting selector)."""
    what = meaning(telegram)
    return Verdict(refused=what.refused, confirm=(what.risk,) if what.risk else (), name=what.name, kind=what.kind)


def _setting(key: str) -> Command:
    setting = codec.SETTINGS[key]
    return Command(setting_name(key), "write", run=SETTING_WRITES[key], session=True,
                   args=tuple(Arg(name, low, high, unit=setting.unit) for name, low, high in codec.setting_fields(key)),
                   flags=("selector_verified",) if setting.assumed else (), risk=_setting_risk(setting))


def _write_verdict(accepted: Accepted) -> tuple[str, str]:
    """The declared write of one parameter: what the model asks (a safety flag switched off, named) and, for an
    assumed selector, that it is verified on this unit. The EEPROM wear is said on the page and in restore."""
    param = accepted.param
    if not param.setting_key:
        return Message(N_("{name} is read only: no setting telegram is named for it (chapter 5.2)"), name=param.name), ""
    parts = [accepted.risk] + ([model.selector_risk(param)] if param.selector_assumed else [])
    return "", joined([p for p in parts if p], " ")


# the gate passes the page's session: its EEPROM writes are counted for it (Mo64Settings.write_param_in)
WRITE_PARAM = param_write(model.PARAMS, Mo64Settings.write_param_in, _write_verdict, session=True)

COMMANDS = (
    WRITE_PARAM,
    *(_operation(cmd, fn) for cmd in (codec.Command.OPEN, codec.Command.CLOSE, codec.Command.REVERSE)
      for fn in codec.Function),
    Command("clear levels", "system", run=Mo64Adapter.clear_levels_asked, session=True, risk=CLEAR_LEVELS_RISK),
    *(_setting(key) for key in codec.SETTINGS if key != "change_monitoring"),
    Command("change monitoring", "write", run=Mo64Adapter.set_change_monitoring, session=True, args=(Arg("on", 0, 1),),
            risk=EEPROM_RISK),
    Command("release the connection", "write", run=Mo64Adapter.release, session=True),
    Command("take the connection back", "write", run=Mo64Adapter.resume, session=True),
    Command("read error memory", "read", run=Mo64Adapter.read_error_memory),
    read_parameters(Mo64Settings.backup_read),
)
