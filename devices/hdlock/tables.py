"""Value tables and bit fields of the BSS HD-Lock register map (the vendor document, section 3).

The words each register's values stand for, the fields of its bit words and the warnings some values carry;
:mod:`devices.hdlock.params` builds the register map from them. Pure data.
"""

from __future__ import annotations

from devices.message import Message, N_
from devices.params import Field

# -- value tables -----------------------------------------------------------------------

LOCK_STATE: dict[int, str] = {
    0: "Unlocked (bolt retracted)",
    1: "Locked (bolt extended)",
}

LOCK_REQUEST: dict[int, str] = {
    0: "Inactive",
    1: "Active",
}

MOTOR_STATE_IR3: dict[int, str] = {
    0: "Inactive",
    1: "Extending",
    2: "Retracting",
    3: "Braking",
}

DOOR_STATE: dict[int, str] = {
    0: "Undefined",
    1: "Door open",
    2: "Door closing",
    3: "Door closed",
}

STATE_MACHINE_STATE: dict[int, str] = {
    0: "Start",
    1: "Referencing",
    2: "Unlocked",
    3: "Locking",
    4: "Locked",
    5: "Unlocking",
    6: "Error locked",
    7: "Error locking",
    8: "Error locking pause short",
    9: "Error locking pause long",
    10: "Error locking waiting",
    11: "Error unlocked",
    12: "Error unlocking",
}

# Input 11 and holding 3003: int16, -1/0/1 (sections 3.1 and 3.2.5).
DIRECTION: dict[int, str] = {
    -1: "Always right-hinged",
    0: "Automatic",
    1: "Always left-hinged",
}

# Input 15, bits 4-5 (System Clock Source).
SYSCLK_SOURCE: dict[int, str] = {
    0: "HSI",
    1: "HSE",
    2: "PLL",
}

MOTOR_STATE_IR53: dict[int, str] = {
    -1: "Inactive",
    0: "Forward",
    1: "Backward",
    2: "Braked",
    3: "Last state",
    4: "Active",
}

# Assumption: section 3.1 lists these names for input 54 without numbers; they are
# numbered 0.. in printed order until a device on the bench proves otherwise.
MOTOR_RESULT: dict[int, str] = {
    0: "None",
    1: "AtPos",
    2: "MinSpeed",
    3: "Timeout",
    4: "userStop",
    5: "OutStageDisabled",
    6: "Currentlimit",
}

ZERO_POSITION_WHEN_UNLOCKED: dict[int, str] = {
    0: "No",
    1: "Yes",
}

# Section 3.2.2. 0x00-0x07: the bolt extends when condition 1 holds AND the door is
# closed; 0x80-0x87: same condition 1, the door condition is always true (ignored).
_IRS_NAMES = (
    "IrsNever",
    "IrsAlways",
    "IrsOverrange",
    "IrsLine",
    "IrsNotLine",
    "IrsToggleOnLineEdge",
    "IrsToggleOnLinePEdge",
    "IrsToggleOnLineNEdge",
)
LOCK_REQUEST_SOURCE: dict[int, str] = {
    **{value: name for value, name in enumerate(_IRS_NAMES)},
    **{0x80 | value: f"{name} (door ignored)" for value, name in enumerate(_IRS_NAMES)},
}

# Section 3.2.4 (value 9 is printed as "-": not assigned).
OUTPUT_FUNCTION: dict[int, str] = {
    0: "Always off",
    1: "Always on",
    2: "Door closed",
    3: "Door open",
    4: "Bolt extended",
    5: "Bolt retracted",
    6: "Lock request",
    7: "No lock request",
    8: "Blink ~1 Hz",
    10: "Hall sensors overdriven",
}

REMOVE_MAGNET: dict[int, str] = {
    0: "Off (secure)",
    1: "Retract when magnet removed",
}

PARITY: dict[int, str] = {
    0: "None",
    1: "Odd",
    2: "Even",
}

STOP_BITS: dict[int, str] = {
    0: "0.5",
    1: "1",
    2: "2.5",
    3: "2",
}

BAUDRATES: tuple[int, ...] = (300, 1200, 4800, 9600, 14400, 19200, 38400, 56000, 57600)

# -- bit fields ---------------------------------------------------------------------------

# Section 3.2.1; bits 5, 6, 12-15 unused; bit 4 is printed as a second "LockRequest"
# and shown as "LockRequest (bit 4)" (SPEC-NOTES).
LOCK_STATUS_BITS: tuple[Field, ...] = (
    Field("LockRequest", 0, description=Message(N_("Active when a lock request is active."))),
    Field("ProximityInPlace", 1, description=Message(N_("Active when the strike plate (door) is in position."))),
    Field(
        "DoorInPosition",
        2,
        description=Message(N_("Active when the strike plate (door) is in position, after the disturbance delay.")),
    ),
    Field(
        "ProximityOverrange",
        3,
        description=Message(N_("Active when both hall sensors are overdriven (strong magnet at the sensors).")),
    ),
    Field(
        "LockRequest (bit 4)",
        4,
        description=Message(N_(
            "Printed a second time as 'LockRequest' in the bit table of section 3.2.1; "
            "meaning not described separately."
        )),
    ),
    Field(
        "ForceActive",
        7,
        description=Message(N_("Active when the bolt is driven independently of the strike plate (door).")),
    ),
    Field("BoltLocked", 8, description=Message(N_("Active when the bolt is fully extended."))),
    Field("BoltUnlocked", 9, description=Message(N_("Active when the bolt is fully retracted."))),
    Field("BoltMovingOut", 10, description=Message(N_("Active while the bolt is extending."))),
    Field("BoltMovingIn", 11, description=Message(N_("Active while the bolt is retracting."))),
)

HALL_FIELDS: tuple[Field, ...] = (
    Field("H1", 8, 8, description=Message(N_("8-bit analogue value of hall sensor 1 (high byte)."))),
    Field("H2", 0, 8, description=Message(N_("8-bit analogue value of hall sensor 2 (low byte)."))),
)

SYSTEM_CORE_CLOCK_CONFIG_FIELDS: tuple[Field, ...] = (
    Field("HSI ready", 0, description=Message(N_("Internal oscillator (HSI) ready."))),
    Field("HSE ready", 1, description=Message(N_("External oscillator (HSE) ready."))),
    Field("PLL ready", 2, description=Message(N_("Phase-locked loop (PLL) ready."))),
    Field("HSE active", 3, description=Message(N_("0 = internal oscillator (HSI) active, 1 = external (HSE) active."))),
    Field("SysClkSource", 4, 2, description=Message(N_("System clock source: 0 = HSI, 1 = HSE, 2 = PLL."))),
)

# section 3.2.2: with 0x80-0x87 condition 2 (door closed) is always met: the bolt moves by condition 1 alone
DOOR_IGNORED_SOURCES = tuple(range(0x80, 0x88))
DOOR_IGNORED_WARNING = Message(N_(
    "With LockRequestSource 0x80-0x87 the lock ignores the door (section 3.2.2, condition 2 always met): "
    "the bolt extends by its condition alone, also while the door is open, and can strike the door or its frame."
))
REMOVE_MAGNET_WARNING = Message(N_(
    "Security risk: with SettingsRemoveMagnet = 1 the bolt retracts as soon as the magnetic "
    "field of the strike plate weakens, even while locking is requested. The lock can then be "
    "unlocked from outside by manipulating the magnetic field (section 3.2.6). "
    "Write 1 only if this behaviour is explicitly required."
))
