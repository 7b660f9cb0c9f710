"""HD-Lock 102000.X: pure conversions of register values and system commands.

No I/O here. Section numbers refer to the HD-Lock document
(``shared/seeds/000_b07d13a7b38b34b0.txt``).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

# LockStatus bits (holding 1000, section 3.2.1; bit 4 repeats "LockRequest", see SPEC-NOTES)
LOCK_REQUEST = 1 << 0
PROXIMITY_IN_PLACE = 1 << 1
DOOR_IN_POSITION = 1 << 2
PROXIMITY_OVERRANGE = 1 << 3
LOCK_REQUEST_BIT4 = 1 << 4
FORCE_ACTIVE = 1 << 7
BOLT_LOCKED = 1 << 8
BOLT_UNLOCKED = 1 << 9
BOLT_MOVING_OUT = 1 << 10
BOLT_MOVING_IN = 1 << 11

LOCK_STATUS_NAMES = {
    0: "LockRequest",
    1: "ProximityInPlace",
    2: "DoorInPosition",
    3: "ProximityOverrange",
    4: "LockRequest (bit 4)",
    7: "ForceActive",
    8: "BoltLocked",
    9: "BoltUnlocked",
    10: "BoltMovingOut",
    11: "BoltMovingIn",
}

# System command registers (section 4)
REG_PARAM0 = 2000
REG_PARAM1 = 2001
REG_PARAM2 = 2002
REG_COMMAND = 2003


class SystemCommand(IntEnum):
    """Command IDs written to holding 2003 (section 4)."""

    SAVE_SETTINGS = 1
    RESTORE_SETTINGS = 2
    SET_MODBUS_ADDRESS = 3


MODBUS_BROADCAST = 0  # section 5.6: the lock answers address 0 (one lock on the line)
MODBUS_ADDRESS_MIN = 1
MODBUS_ADDRESS_MAX = 254  # section 5.2: 248..254 supported besides the standard 1..247


class CodecError(ValueError):
    """A value that cannot be encoded or a frame that cannot be decoded."""


def to_signed16(raw: int) -> int:
    """Two's complement of a 16-bit register (section 3.2.7): 65506 -> -30."""
    raw &= 0xFFFF
    return raw - 0x10000 if raw & 0x8000 else raw


def from_signed16(value: int) -> int:
    """Signed value -> 16-bit register: -30 -> 65506."""
    if not -0x8000 <= value <= 0x7FFF:
        raise CodecError(f"{value} does not fit a signed 16-bit register")
    return value & 0xFFFF


def serial_number(high_word: int, low_word: int) -> int:
    """Input registers 104 (high) and 105 (low) -> serial number (section 3.1)."""
    return ((high_word & 0xFFFF) << 16) | (low_word & 0xFFFF)


def lock_status_bits(status: int) -> dict[str, bool]:
    """LockStatus word -> {bit name: set} for every defined bit."""
    return {name: bool(status >> bit & 1) for bit, name in LOCK_STATUS_NAMES.items()}


def set_address_condition(mask: int, expected: int, lock_status: int) -> int:
    """Result of ``(P1 & LockStatus) ^ P2`` (section 4.3); 0 means the lock takes the address."""
    return ((mask & lock_status) ^ expected) & 0xFFFF


def set_address_accepted(mask: int, expected: int, lock_status: int) -> bool:
    return set_address_condition(mask, expected, lock_status) == 0


@dataclass(frozen=True)
class CommandWrites:
    """The register writes of one system command, in the order they must be sent."""

    writes: tuple[tuple[int, int], ...]


def encode_system_command(command: SystemCommand, p0: int = 0, p1: int = 0, p2: int = 0) -> CommandWrites:
    """Parameters first (2000-2002), the command ID last (2003), as section 4 requires."""
    for value in (p0, p1, p2):
        if not 0 <= value <= 0xFFFF:
            raise CodecError(f"command parameter {value} is not a 16-bit value")
    if command is SystemCommand.SET_MODBUS_ADDRESS and not MODBUS_ADDRESS_MIN <= p0 <= MODBUS_ADDRESS_MAX:
        raise CodecError(f"new Modbus address {p0} is outside {MODBUS_ADDRESS_MIN}..{MODBUS_ADDRESS_MAX}")
    return CommandWrites(((REG_PARAM0, p0), (REG_PARAM1, p1), (REG_PARAM2, p2), (REG_COMMAND, int(command))))
