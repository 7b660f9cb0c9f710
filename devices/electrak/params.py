"""Service parameters of the Electrak HD SY2 (document "Konfigurierbare Parameter").

``address`` is the command specifier; ``extra["password"]`` the password that has to be
written to specifier 0xFF before the parameter can be read or written; ``extra["length"]``
its size in bytes.
"""

from __future__ import annotations

from dataclasses import dataclass

from devices import values
from devices.electrak import codec
from devices.message import Message, N_
from devices.params import Access, Param, ParamMap

SERVICE = "service"

BITRATE_NAMES = {code: f"{rate // 1_000_000} Mbit/s" if rate >= 1_000_000 else f"{rate // 1000} kbit/s" for code, rate in codec.BITRATES.items()}
PASSWORD_A = 0xE5F6A7B8  # soft start, soft stop
PASSWORD_B = 0x9A8B7C6D  # bit rate, timeout
PASSWORD_C = 0x6B7C8D9A  # speed
BITRATE_SPECIFIER = 0x04
TIMEOUT_SPECIFIER = 0x06

# Assumption: "Baudrate" does not say when a new bit rate takes effect; like every parameter it
# is lost at power-off unless saved ("Parameter speichern"), so it is read back and saved on the
# old bit rate and takes effect when the actuators are powered up again.
BITRATE_AT_POWER_UP = True

BITRATE_WARNING = Message(N_(
    "The actuators keep the old bit rate until they are powered up again: write it, read it back from every actuator, "
    "save it (0xF0), then set the bus's bitrate in the plant file, restart commission and power-cycle the actuators. "
    "Every device on this bus must be switched alike, or it leaves the bus."
))

# "CAN-Steuerung": the control telegram comes every 100 ms; a timeout that is not well above that
# period (its jitter on a loaded machine reaches tens of ms) sets the message-timeout flag
# ("Fehler-Flags" bit 5) between telegrams and stops the actuators. 100 ms measured: the flag set in
# 48 of 79 samples. The floor is the period plus the same again for jitter.
CONTROL_PERIOD_MS = 100
TIMEOUT_MIN_MS = 2 * CONTROL_PERIOD_MS
TIMEOUT_DEFAULT_MS = 250
# the timeout is how long motion outlives this tool when it stops sending: at most a second, and
# anything above the default is confirmed (65535 ms let an actuator run on for a minute)
TIMEOUT_MAX_MS = 1000
TIMEOUT_REFUSAL = Message(
    N_("below {minimum} ms, twice the control period of {period} ms: the control telegram comes every {period} ms with "
       "jitter, so the message-timeout flag would be set between telegrams and the actuators would stop"),
    minimum=TIMEOUT_MIN_MS, period=CONTROL_PERIOD_MS)
TIMEOUT_WARNING = Message(
    N_("Above the default {default} ms the actuators keep moving for that long after this tool (or a controller) stops "
       "sending, e.g. when the program hangs or the cable is pulled."), default=TIMEOUT_DEFAULT_MS)


@dataclass(frozen=True)
class ServiceParam(Param):
    """A service parameter: ``extra["length"]`` bytes in the telegram's payload, not a Modbus register."""

    @property
    def value_type(self) -> values.ValueType:
        # "Service-Telegramm": payload bytes 4 (LSB) .. 7 (MSB), the parameter's "Länge" bytes of it
        base = values.Int(8 * length_of(self), False, values.LITTLE)
        if self.scale != 1:
            return values.Scaled(base, self.scale, self.unit)
        if self.enum is not None:
            return values.Enum(base, self.enum)
        return base


def _param(name, specifier, password, length, unit="", scale=1.0, description="", **kw) -> Param:
    return ServiceParam(
        name, SERVICE, specifier, Access.RW, unit=unit, scale=scale, description=description,
        extra={"password": f"0x{password:08X}", "length": str(length)}, **kw,
    )


PARAMS = ParamMap([
    _param("Soft start time", 0x01, PASSWORD_A, 2, "ms", minimum=0, maximum=65535,
           description=Message(N_("Time in milliseconds the actuator takes to reach full speed: adjusts the soft "
                                  "start."))),
    _param("Soft stop distance", 0x02, PASSWORD_A, 2, "mm", 0.1, minimum=0, maximum=6553.5,
           description=Message(N_("Distance to the target (0.1 mm units) from which the actuator starts to slow down: "
                                  "adjusts the soft stop."))),
    _param("Bit rate", BITRATE_SPECIFIER, PASSWORD_B, 1, enum=BITRATE_NAMES, confirm=BITRATE_WARNING,
           description=Message(N_("CAN bit rate of the actuator (default 500 kbit/s)."))),
    _param("Timeout", TIMEOUT_SPECIFIER, PASSWORD_B, 2, "ms", minimum=TIMEOUT_MIN_MS, maximum=TIMEOUT_MAX_MS,
           confirm=TIMEOUT_WARNING, confirm_values=tuple(range(TIMEOUT_DEFAULT_MS + 1, TIMEOUT_MAX_MS + 1)),
           description=Message(N_("Time in milliseconds without a control telegram after which the actuators set the "
                                  "message-timeout flag and stop: how long motion outlives this tool when it stops "
                                  "sending (default {default} ms, {minimum} .. {maximum} ms: above the {period} ms control "
                                  "period with its jitter; above the default asks first)."),
                               default=TIMEOUT_DEFAULT_MS, minimum=TIMEOUT_MIN_MS, maximum=TIMEOUT_MAX_MS,
                               period=CONTROL_PERIOD_MS)),
    _param("Speed", 0x08, PASSWORD_C, 2, "mm/s", 0.1, minimum=0, maximum=6553.5,
           description=Message(N_("Target speed of the device in 0.1 mm/s units; lowers the speed when driven through "
                                  "the manual lines."))),
])


def password_of(param: Param) -> int:
    return int(param.extra["password"], 16)


def length_of(param: Param) -> int:
    return int(param.extra["length"])


def refusal(param: Param, value) -> str:
    """Why ``value`` must not be written to ``param`` beyond its range (a Message, the parameter by the model's
    name), or ``""``."""
    if param.address != TIMEOUT_SPECIFIER:
        return ""
    try:
        number = float(value)
    except (TypeError, ValueError):
        return ""
    if number >= TIMEOUT_MIN_MS:
        return ""
    return Message(N_("{name} {value} ms is {refusal}"), name=param.name, value=f"{number:g}", refusal=TIMEOUT_REFUSAL)
