"""Service parameters of the Electrak HD SY2 (document "Konfigurierbare Parameter").

``address`` is the command specifier; ``extra["password"]`` the password that has to be
written to specifier 0xFF before the parameter can be read or written; ``extra["length"]``
its size in bytes.
"""

from __future__ import annotations

from devices.params import Access, Param, ParamMap

SERVICE = "service"

BITRATE_NAMES = {0: "1 Mbit/s", 2: "500 kbit/s", 3: "250 kbit/s", 4: "125 kbit/s"}
PASSWORD_A = 0xE5F6A7B8  # soft start, soft stop
PASSWORD_B = 0x9A8B7C6D  # bit rate, timeout
PASSWORD_C = 0x6B7C8D9A  # speed

BITRATE_WARNING = (
    "After the change the actuators leave this bus: they answer only once the bus itself runs at the new bit rate "
    "(change bitrate in the plant file and restart). Every actuator of the network must be switched alike."
)


def _param(name, specifier, password, length, unit="", scale=1.0, description="", **kw) -> Param:
    return Param(
        name, SERVICE, specifier, Access.RW, unit=unit, scale=scale, description=description,
        extra={"password": f"0x{password:08X}", "length": str(length)}, **kw,
    )


PARAMS = ParamMap([
    _param("Soft start time", 0x01, PASSWORD_A, 2, "ms", minimum=0, maximum=65535,
           description="Time in milliseconds the actuator takes to reach full speed: adjusts the soft start."),
    _param("Soft stop distance", 0x02, PASSWORD_A, 2, "mm", 0.1, minimum=0, maximum=6553.5,
           description="Distance to the target (0.1 mm units) from which the actuator starts to slow down: adjusts the soft stop."),
    _param("Bit rate", 0x04, PASSWORD_B, 1, enum=BITRATE_NAMES, confirm=BITRATE_WARNING,
           description="CAN bit rate of the actuator (default 500 kbit/s)."),
    _param("Timeout", 0x06, PASSWORD_B, 2, "ms", minimum=1, maximum=65535,
           description="Time in milliseconds without a control telegram after which the actuator sets the message-timeout flag."),
    _param("Speed", 0x08, PASSWORD_C, 2, "mm/s", 0.1, minimum=0, maximum=6553.5,
           description="Target speed of the device in 0.1 mm/s units; lowers the speed when driven through the manual lines."),
])


def password_of(param: Param) -> int:
    return int(param.extra["password"], 16)


def length_of(param: Param) -> int:
    return int(param.extra["length"])
