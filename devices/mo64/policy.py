"""What the MO 64 barrier control lets this tool do: its declared commands (see :mod:`devices.commands`).

The MO 64 sits on LogiTed lines (TCP or RS485), where no raw-byte tool of this program sends, so
it declares no frame rules; its commands carry the kinds the gate decides on, and the risks the
gate asks before it runs them (the page asks nothing of its own):

- operating commands (chapter 5.2.1) as ``"<open|close|reverse> <pulse|activate|deactivate>"``:
  motion, asking that the area is clear; deactivating a close or reverse level is a stop (what the
  dead-man rule does), deactivating the open level is motion (it lets the boom close, page 33);
- ``"clear levels"``: system, engineers only, asks the risk (an open level released lets the boom close);
- ``"set <setting name>"`` (chapter 5.2.4-5.2.8) with the setting's numbers and their ranges
  (``codec.setting_fields``): a write; the risk names the EEPROM wear, and for an assumed selector the
  flag ``selector_verified`` says the engineer verified it on this unit, a statement the risk repeats
  for the confirmation (without it, the adapter refuses a selector not verified before);
- ``"change monitoring"`` (on = 1 or 0): a write of the EEPROM;
- releasing and taking back the TCP connection: writes (another client gets the barrier);
- reading the error memory: a read.
"""

from __future__ import annotations

from devices.commands import Arg, Command
from devices.mo64 import codec
from devices.mo64.adapter import COMMAND_NAMES, HELD_LEVELS, operation_method, setting_method

TITLE = "MO 64"

AREA_CLEAR_RISK = "The boom moves: check that nobody stands under it (the area is clear)."
OPEN_LEVEL_RISK = ("Deactivating the open level lets the boom close (page 33): check that nobody stands under it "
                   "(the area is clear).")
CLEAR_LEVELS_RISK = ("Deactivates every level this tool set in the barrier (levels set by another master or at the "
                     "barrier are not touched). An open level released lets the boom close (page 33): check that "
                     "nobody stands under it (the area is clear).")
EEPROM_RISK = ("Every setting write wears the barrier's EEPROM (chapter 4: the number of writes is limited). "
               "Write only what must change.")


def selector_risk(setting: codec.Setting) -> str:
    return (f"The selector 0x{setting.telegram:02X} 0x{setting.selector:02X} of {setting.name} is an assumption "
            f"({setting.assumed}); the manual's summary does not name it, and a wrong selector writes another "
            f"EEPROM setting. Confirm only if you verified on this unit that it is {setting.name}.")


def _setting_risk(setting: codec.Setting):
    def risk(args) -> str:
        parts = [selector_risk(setting)] if setting.assumed and args.get("selector_verified") else []
        return " ".join(parts + ([EEPROM_RISK] if setting.eeprom else []))
    return risk


def operation_name(cmd: codec.Command, fn: codec.Function) -> str:
    """The declared name of an operating command, e.g. "open pulse" (also its audit action)."""
    return f"{COMMAND_NAMES[cmd]} {fn.name.lower()}"


def setting_name(key: str) -> str:
    return f"set {codec.SETTINGS[key].name}"


def _operation(cmd: codec.Command, fn: codec.Function) -> Command:
    if fn is codec.Function.DEACTIVATE and cmd in HELD_LEVELS:
        return Command(operation_name(cmd, fn), "stop", method=operation_method(cmd, fn), session=True)
    risk = OPEN_LEVEL_RISK if fn is codec.Function.DEACTIVATE else AREA_CLEAR_RISK
    return Command(operation_name(cmd, fn), "motion", method=operation_method(cmd, fn), session=True, risk=risk)


def _setting(key: str) -> Command:
    setting = codec.SETTINGS[key]
    return Command(setting_name(key), "write", method=setting_method(key), session=True,
                   args=tuple(Arg(name, low, high, unit=setting.unit) for name, low, high in codec.setting_fields(key)),
                   flags=("selector_verified",) if setting.assumed else (), risk=_setting_risk(setting))


COMMANDS = (
    *(_operation(cmd, fn) for cmd in (codec.Command.OPEN, codec.Command.CLOSE, codec.Command.REVERSE)
      for fn in codec.Function),
    Command("clear levels", "system", method="clear_levels_asked", session=True, risk=CLEAR_LEVELS_RISK),
    *(_setting(key) for key in codec.SETTINGS if key != "change_monitoring"),
    Command("change monitoring", "write", method="set_change_monitoring", session=True, args=(Arg("on", 0, 1),),
            risk=EEPROM_RISK),
    Command("release the connection", "write", method="release", session=True),
    Command("take the connection back", "write", method="resume", session=True),
    Command("read error memory", "read", method="read_error_memory"),
)
