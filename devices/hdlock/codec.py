"""HD-Lock 102000.X: pure conversions of register values and system commands.

No I/O here. Section numbers refer to the HD-Lock document
(``shared/seeds/000_b07d13a7b38b34b0.txt``).
"""

from __future__ import annotations

import struct
from collections.abc import Mapping
from dataclasses import dataclass
from enum import IntEnum
from functools import lru_cache

from devices import errors
from devices.message import N_, Message, Word
from devices.hdlock.params import PARAMS
from devices.hdlock.tables import LOCK_REQUEST_SOURCE

# LockStatus bits (holding 1000, section 3.2.1; bit 4 repeats "LockRequest", see SPEC-NOTES)
LOCK_REQUEST = 1 << 0
PROXIMITY_IN_PLACE = 1 << 1
DOOR_IN_POSITION = 1 << 2
PROXIMITY_OVERRANGE = 1 << 3
LOCK_REQUEST_BIT4 = 1 << 4
FORCE_ACTIVE = 1 << 7
SOURCE_DOOR_IGNORED = 0x80  # LockRequestSource 0x80-0x87: the bolt moves whatever the door (section 3.2.2 b)
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
REG_FW_UPDATE = 32770  # FwUpdateCommandRegister: never written by this tool
REG_DEVICE_ADDRESS = 103  # DeviceAddress, changed only by command 3 (sections 3.2, 4.3)
REG_LOCK_REQUEST_SOURCE = 4  # section 6.5.1: the source the lock uses is holding 4; 1002 is a register of its own
REG_LOCK_REQUEST_SOURCE_SETTING = 1002  # section 3.2.2: the setting, values as holding 4
# section 6.6.1.1: of LockRequestSource only the low byte is kept (the high byte is 0 after a reset) and the lock
# acts on it (0x80-0x87: the door is ignored): a value is judged as the lock stores it, never as the whole word
LOW_BYTE_REGISTERS = frozenset({REG_LOCK_REQUEST_SOURCE, REG_LOCK_REQUEST_SOURCE_SETTING})


def stored_value(address: int, word: int) -> int:
    """The value holding ``address`` keeps of a written 16-bit ``word`` (:data:`LOW_BYTE_REGISTERS`: the low byte)."""
    return word & 0xFF if address in LOW_BYTE_REGISTERS else word & 0xFFFF


class SystemCommand(IntEnum):
    """Command IDs written to holding 2003 (section 4)."""

    SAVE_SETTINGS = 1
    RESTORE_SETTINGS = 2
    SET_MODBUS_ADDRESS = 3


MODBUS_BROADCAST = 0  # section 5.6: the lock answers address 0 (one lock on the line)
MODBUS_BROADCAST_SET_ADDRESS = 255  # section 4.3: Set Modbus Address to every lock on the line at once, no answer
MODBUS_ADDRESS_MIN = 1
MODBUS_ADDRESS_MAX = 254  # section 5.2: 248..254 supported besides the standard 1..247
ADDRESS_COMMAND_ANSWERED = False  # section 4.3 does not say the lock answers the write of 2003 at its old address
BROADCAST_TURNAROUND_S = 0.1  # Modbus over Serial Line 2.4.1: after a broadcast the master waits 100-200 ms
ADDRESS_SETTLE_S = 0.1  # section 4.3 gives no time for taking a new address: wait this long before looking for it


class CodecError(errors.CodecError):
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


def broadcast_takers(mask: int, expected: int, statuses: Mapping[str, int | None]) -> tuple[list[str], list[str]]:
    """Known locks that would take a broadcast address by their last LockStatus (section 4.3).

    :param statuses: lock name -> last LockStatus read, or None when not known
    :returns: (names whose status meets the condition, names whose status is unknown)
    """
    takers = [name for name, status in statuses.items() if status is not None and set_address_accepted(mask, expected, status)]
    unknown = [name for name, status in statuses.items() if status is None]
    return takers, unknown


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


# -- CAN protocol (section 6) -------------------------------------------------------------


def pack_le(value: int, length: int) -> bytes:
    """An unsigned value as ``length`` bytes, least significant first (section 6.2)."""
    if not 0 <= value < 1 << (8 * length):
        raise CodecError(f"{value} does not fit {length} unsigned byte{'s' if length != 1 else ''}")
    return value.to_bytes(length, "little")


def unpack_le(data: bytes) -> int:
    """Bytes least significant first -> unsigned value (section 6.2)."""
    return int.from_bytes(data, "little")


CAN_COMMAND = 0x700
CAN_SET_DEVICE_ADDRESS = 0x701
CAN_READ_INPUT = 0x702
CAN_READ_HOLDING = 0x703
CAN_WRITE_HOLDING = 0x704
CAN_SILENT_WRITE_HOLDING = 0x705
CAN_FWU_ERASE = 0x706  # never sent by this tool
CAN_FWU_WRITE = 0x707  # never sent by this tool
CAN_REQUEST_IDS = range(0x700, 0x708)
CAN_REQUEST_NAMES = {
    CAN_COMMAND: "Command",
    CAN_SET_DEVICE_ADDRESS: "Set Device Address",
    CAN_READ_INPUT: "Read Input-Register",
    CAN_READ_HOLDING: "Read Holding-Register",
    CAN_WRITE_HOLDING: "Write Holding-Register",
    CAN_SILENT_WRITE_HOLDING: "Silent Write Holding-Register",
    CAN_FWU_ERASE: "FWU erase sector",
    CAN_FWU_WRITE: "FWU write flash",
}
EXTENDED_FLAG = 0x80000000  # section 6.3: MSB marks an extended device ID
CAN_BROADCAST = 0  # section 6.4: standard format, target 0
STD_ID_MAX = 0x7FF
EXT_ID_MAX = 0x1FFFFFFF


class CanCommand(IntEnum):
    """Byte 4-5 of a 0x700 Command frame (section 6.6.1)."""

    SET_LOCK_REQUEST_SOURCE = 0
    SET_CAN_BAUDRATE = 1
    FIRMWARE_UPDATE_ENTER = 2  # never sent by this tool
    BOOTLOADER_UPDATE_ENTER = 3  # never sent by this tool
    UPDATE_LEAVE = 4  # never sent by this tool


FIVE_BYTE_COMMANDS = {CanCommand.FIRMWARE_UPDATE_ENTER, CanCommand.BOOTLOADER_UPDATE_ENTER, CanCommand.UPDATE_LEAVE}
SENDABLE_COMMANDS = {CanCommand.SET_LOCK_REQUEST_SOURCE, CanCommand.SET_CAN_BAUDRATE}

# section 6.6.1.2: value -> (bit/s, max. line length)
CAN_BITRATES: dict[int, tuple[int, str]] = {
    0: (5_000, "10,000 m"),
    1: (10_000, "5,000 m"),
    2: (20_000, "2,500 m"),
    3: (33_300, ""),
    4: (50_000, "1,000 m"),
    5: (83_300, ""),
    6: (100_000, ""),
    7: (125_000, "500 m"),
    8: (250_000, "250 m (default)"),
    9: (500_000, "100 m"),
    10: (800_000, ""),
    11: (1_000_000, "25 m"),
}
CAN_DEFAULT_BITRATE = 250_000


@dataclass(frozen=True)
class CanFrame:
    """A CAN frame as the codec sees it (no python-can types here)."""

    arbitration_id: int
    data: bytes
    is_extended_id: bool = False


@dataclass(frozen=True)
class DeviceId:
    """A lock's device ID; the CAN ID it answers under (section 6.3)."""

    value: int
    extended: bool

    @classmethod
    def make(cls, value: int, extended: bool | None = None) -> DeviceId:
        """IDs above 0x7FF are extended automatically (section 6.6.2)."""
        if not 0 <= value <= EXT_ID_MAX:
            raise CodecError(f"device ID {value:#x} does not fit 29 bits")
        ext = value > STD_ID_MAX if extended is None else extended or value > STD_ID_MAX
        return cls(value, ext)

    @classmethod
    def from_u32(cls, raw: int) -> DeviceId:
        """Bytes 0-3 of a request: bit 31 set = extended (section 6.3)."""
        value = raw & ~EXTENDED_FLAG & 0xFFFFFFFF
        return cls.make(value, bool(raw & EXTENDED_FLAG))

    def to_u32(self) -> int:
        return self.value | (EXTENDED_FLAG if self.extended else 0)

    def __str__(self) -> str:
        return f"{self.value} ({'ext' if self.extended else 'std'} 0x{self.value:X})"


BROADCAST_ID = DeviceId(CAN_BROADCAST, False)


def _request(can_id: int, target: DeviceId, payload: bytes) -> CanFrame:
    return CanFrame(can_id, pack_le(target.to_u32(), 4) + payload, False)


def encode_can_command(target: DeviceId, command: CanCommand, value: int) -> CanFrame:
    """0x700 Command: bytes 4-5 command, 6-7 parameter, little-endian (section 6.6.1)."""
    if command not in SENDABLE_COMMANDS:
        raise CodecError(f"{command.name} is a firmware-update command and is never sent")
    if command is CanCommand.SET_CAN_BAUDRATE and value not in CAN_BITRATES:
        raise CodecError(f"bit-rate value {value} is not in the table of section 6.6.1.2 (0..11)")
    if not 0 <= value <= 0xFFFF:
        raise CodecError(f"command parameter {value} is not a 16-bit value")
    return _request(CAN_COMMAND, target, pack_le(int(command), 2) + pack_le(value, 2))


def encode_set_device_address(target: DeviceId, new: DeviceId) -> CanFrame:
    """0x701 Set Device Address: bytes 4-7 the new ID with the extended flag (section 6.6.2)."""
    if new.value == CAN_BROADCAST:
        raise CodecError("device ID 0 is the broadcast address")
    return _request(CAN_SET_DEVICE_ADDRESS, target, pack_le(new.to_u32(), 4))


def encode_read(target: DeviceId, space: str, address: int, count: int = 1) -> CanFrame:
    """0x702 / 0x703: read ``count`` registers from ``address``; one answer frame each."""
    if not 0 <= address <= 0xFFFF or not 1 <= count <= 0xFFFF:
        raise CodecError(f"register range {address}+{count} is not valid")
    can_id = CAN_READ_INPUT if space == "input" else CAN_READ_HOLDING
    return _request(can_id, target, pack_le(address, 2) + pack_le(count, 2))


def encode_write(target: DeviceId, address: int, value: int, silent: bool = False) -> CanFrame:
    """0x704 / 0x705: bytes 6-7 carry the value (one register per frame, SPEC-NOTES)."""
    if not 0 <= address <= 0xFFFF or not 0 <= value <= 0xFFFF:
        raise CodecError(f"write {address}={value} is not a 16-bit register write")
    if address == REG_FW_UPDATE:
        raise CodecError("FwUpdateCommandRegister (32770) is never written")
    can_id = CAN_SILENT_WRITE_HOLDING if silent else CAN_WRITE_HOLDING
    return _request(can_id, target, pack_le(address, 2) + pack_le(value, 2))



@dataclass(frozen=True)
class CanRequest:
    """A decoded request frame 0x700-0x707 (for the twin and the bus monitor)."""

    kind: int
    target: DeviceId
    a: int  # address / command / new ID low word
    b: int  # count / value / parameter / new ID high word

    @property
    def new_id(self) -> DeviceId:
        return DeviceId.from_u32(self.a | self.b << 16)


def decode_request(frame: CanFrame) -> CanRequest:
    if frame.is_extended_id or frame.arbitration_id not in CAN_REQUEST_IDS:
        raise CodecError(f"0x{frame.arbitration_id:X} is not an HD-Lock request ID")
    # 6.6.1: the firmware-update commands 2-4 are 5 bytes long (decoded to name and refuse them)
    five_byte = frame.arbitration_id == CAN_COMMAND and len(frame.data) == 5 and frame.data[4] in FIVE_BYTE_COMMANDS
    if len(frame.data) < 6 and not five_byte:
        raise CodecError(f"request 0x{frame.arbitration_id:X} too short ({len(frame.data)} bytes)")
    if len(frame.data) > 8:  # section 6.2: a CAN frame carries [1...8] data bytes
        raise CodecError(f"request 0x{frame.arbitration_id:X} has {len(frame.data)} bytes, a CAN frame at most 8")
    data = frame.data + bytes(8 - len(frame.data))
    target = DeviceId.from_u32(unpack_le(data[0:4]))
    return CanRequest(frame.arbitration_id, target, unpack_le(data[4:6]), unpack_le(data[6:8]))


@dataclass(frozen=True, slots=True)
class StatusFrame:
    """Periodic status (section 6.5.1); proximity/source split per SPEC-NOTES."""

    status: int
    motor_pos: int
    proximity: int
    lock_request_source: int

    @property
    def bits(self) -> dict[str, bool]:
        return lock_status_bits(self.status)


@dataclass(frozen=True, slots=True)
class FwuStatusFrame:
    """Firmware-update status (section 6.5.2)."""

    flashing: bool
    application: bool  # True: firmware is updated, False: boot loader


@dataclass(frozen=True, slots=True)
class RegisterAnswer:
    """One register in answer to a read or write (sections 6.5.3, 6.5.4)."""

    space: str
    address: int
    value: int


LockFrame = StatusFrame | FwuStatusFrame | RegisterAnswer


_WORDS3 = struct.Struct("<HHH")  # three 16-bit words, least significant byte first (section 6.2)
_WORDS2 = struct.Struct("<HH")


def decode_lock_frame(data: bytes) -> LockFrame:
    """A frame sent by a lock under its device ID, identified by bytes 0-1 (every status frame of a
    lock on the bus comes here: one unpack, no intermediate objects)."""
    if len(data) < 2:
        raise CodecError(f"lock frame too short ({len(data)} bytes)")
    b0, b1 = data[0], data[1]
    if b0 == 0 and b1 == 0:
        if len(data) < 8:
            raise CodecError(f"status frame needs 8 bytes, got {len(data)}")
        status, pos, word = _WORDS3.unpack_from(data, 2)
        if status & FORCE_ACTIVE and word >= SOURCE_DOOR_IGNORED:
            # 6.5.1 adds a source of 0x80-0x87 (ForceActive set) to proximity << 6: 0x80 is 2 << 6 (SPEC-NOTES)
            word -= SOURCE_DOOR_IGNORED
            return StatusFrame(status, pos, word >> 6, SOURCE_DOOR_IGNORED | word & 0x3F)
        return StatusFrame(status, pos, word >> 6, word & 0x3F)
    if b0 == 1 and b1 == 0:
        if len(data) < 6:
            raise CodecError(f"FWU status frame needs 6 bytes, got {len(data)}")
        flashing, application = _WORDS2.unpack_from(data, 2)
        return FwuStatusFrame(bool(flashing), bool(application))
    if b1 == 1 and b0 in (0, 1):
        if len(data) < 6:
            raise CodecError(f"register answer needs 6 bytes, got {len(data)}")
        address, value = _WORDS2.unpack_from(data, 2)
        return RegisterAnswer("input" if b0 == 0 else "holding", address, value)
    raise CodecError(f"unknown lock frame type {data[0]:02X} {data[1]:02X}")


def encode_status(frame: StatusFrame) -> bytes:
    # as the lock builds it (6.5.1): the whole source added, 0x80-0x87 included
    word = ((frame.proximity << 6) + (frame.lock_request_source & 0xFF)) & 0xFFFF
    return bytes([0, 0]) + b"".join(pack_le(v, 2) for v in (frame.status & 0xFFFF, frame.motor_pos & 0xFFFF, word))


def encode_fwu_status(frame: FwuStatusFrame) -> bytes:
    return bytes([1, 0]) + pack_le(int(frame.flashing), 2) + pack_le(int(frame.application), 2)


def encode_register_answer(answer: RegisterAnswer) -> bytes:
    return bytes([0 if answer.space == "input" else 1, 1]) + pack_le(answer.address, 2) + pack_le(answer.value, 2)


def looks_like_status(data: bytes) -> bool:
    """True for an 8-byte frame starting 00 00: a lock's periodic status (discovery)."""
    return len(data) == 8 and data[0] == 0 and data[1] == 0


def describe_request(frame: CanFrame) -> str:
    """Human text of a request frame for the bus monitor (a :class:`Message`: the page words it; the request names
    are the document's, section 6.6)."""
    try:
        req = decode_request(frame)
    except CodecError as exc:
        return Message(N_("HD-Lock request, malformed: {error}"), error=str(exc))
    target = Message(N_("broadcast")) if req.target.value == CAN_BROADCAST else Message(N_("lock {id}"), id=str(req.target))
    name = CAN_REQUEST_NAMES[req.kind]
    if req.kind == CAN_COMMAND:
        try:
            command = CanCommand(req.a).name
        except ValueError:
            command = Message(N_("command {number}"), number=req.a)
        detail = Message(N_("{command} value {value}"), command=command, value=req.b)
        if req.a in FIVE_BYTE_COMMANDS:
            detail = Message(N_("{command} (firmware update, section 6.6.1: never sent by this tool)"), command=command)
        if req.a == CanCommand.SET_LOCK_REQUEST_SOURCE:
            source = LOCK_REQUEST_SOURCE.get(req.b)
            detail = Message("{detail} ({source})", detail=detail,
                             source=Word(source, "LockRequestSource") if source else Message(N_("undefined")))
        if req.a == CanCommand.SET_CAN_BAUDRATE and req.b in CAN_BITRATES:
            detail = Message("{detail} ({kbit} kbit/s)", detail=detail, kbit=CAN_BITRATES[req.b][0] // 1000)
    elif req.kind == CAN_SET_DEVICE_ADDRESS:
        try:
            detail = Message(N_("new ID {id}"), id=str(req.new_id))
        except CodecError as exc:  # section 6.4: a device ID has at most 29 bits
            return Message(N_("HD-Lock request, malformed: {error}"), error=str(exc))
    elif req.kind in (CAN_READ_INPUT, CAN_READ_HOLDING):
        param = PARAMS.get("input" if req.kind == CAN_READ_INPUT else "holding", req.a)
        detail = (Message(N_("{address} {name} count {count}"), address=req.a, name=param.label or param.name, count=req.b)
                  if param else Message(N_("{address} count {count}"), address=req.a, count=req.b))
    elif req.kind in (CAN_WRITE_HOLDING, CAN_SILENT_WRITE_HOLDING):
        detail = Message(N_("register {address} {value} (0x{raw:04X})"), address=req.a,
                         value=describe_register("holding", req.a, req.b), raw=req.b & 0xFFFF)
    else:
        detail = Message(N_("firmware update"))
    return Message("{name} -> {target}: {detail}", name=name, target=target, detail=detail)


@lru_cache(maxsize=1024)
def _status_names(status: int) -> str:
    """The set bits of a LockStatus word by name, ``-`` for none (discovery words every status-like frame of
    an unknown ID: a flood repeats few status words)."""
    return ", ".join(name for name, on in lock_status_bits(status).items() if on) or "-"


# the words of a lock's frames (a Message each: the page words it, the codec looks nothing up)
_STATUS = N_("Status 0x{status:04X} [{bits}] motorPos {motor_pos} proximity {proximity} source {code}")
_STATUS_SOURCE = N_("Status 0x{status:04X} [{bits}] motorPos {motor_pos} proximity {proximity} source {code} {source}")
_REGISTER_ANSWER = {"input": N_("Input register {address} {value} (0x{raw:04X})"),
                    "holding": N_("Holding register {address} {value} (0x{raw:04X})")}
_FWU_STATUS = {True: N_("FWU status: flashing, {program}"), False: N_("FWU status: idle, {program}")}
_PROGRAM = {True: Message(N_("application")), False: Message(N_("boot loader"))}


def describe_lock_frame(data: bytes) -> str:
    """A frame a lock sends under its device ID in words (a :class:`Message`), its register and bit names as the
    document prints them."""
    try:
        frame = decode_lock_frame(data)
    except CodecError as exc:
        return Message(N_("HD-Lock frame, malformed: {error}"), error=str(exc))
    if isinstance(frame, StatusFrame):
        source = LOCK_REQUEST_SOURCE.get(frame.lock_request_source)  # 6 bits: 0x0n and 0x8n share a name (SPEC-NOTES)
        if source:
            return Message(_STATUS_SOURCE, status=frame.status, bits=_status_names(frame.status), motor_pos=frame.motor_pos,
                           proximity=frame.proximity, code=frame.lock_request_source, source=Word(source, "LockRequestSource"))
        return Message(_STATUS, status=frame.status, bits=_status_names(frame.status), motor_pos=frame.motor_pos,
                       proximity=frame.proximity, code=frame.lock_request_source)
    if isinstance(frame, FwuStatusFrame):
        return Message(_FWU_STATUS[frame.flashing], program=_PROGRAM[frame.application])
    template = _REGISTER_ANSWER.get(frame.space)
    if template is None:  # decode_lock_frame knows two spaces only
        return f"{frame.space.title()} register {frame.address} {describe_register(frame.space, frame.address, frame.value)} (0x{frame.value:04X})"
    return Message(template, address=frame.address, value=describe_register(frame.space, frame.address, frame.value),
                   raw=frame.value)


def describe_register(space: str, address: int, raw: int) -> str:
    """One register as ``Name = value`` through the register map: signed, scaled, enum and bit names.

    Words of a multi-word value (input 104/105, section 3.1) are named as such; a register the map
    does not list is shown as its number.
    """
    param = PARAMS.get(space, address)
    if param is None:
        owner = next((p for p in PARAMS.space(space) if address in p.addresses), None)
        if owner is None:
            return Message(N_("(not in the register map) = {value}"), value=raw & 0xFFFF)
        word = N_("{name} (high word) = {value}") if address == owner.address else N_("{name} (low word) = {value}")  # SPEC-NOTES: 104 high, 105 low
        return Message(word, name=owner.label or owner.name, value=raw & 0xFFFF)
    name = param.label or param.name
    if param.words > 1:
        return Message(N_("{name} (high word) = {value}"), name=name, value=raw & 0xFFFF)
    return f"{name} = {param.display(raw & 0xFFFF)}"


def describe_frame(arbitration_id: int, is_extended: bool, data: bytes, lock_ids: set[tuple[bool, int]]) -> str | None:
    """Bus monitor: the meaning of a frame this device type owns, else None."""
    if not is_extended and arbitration_id in CAN_REQUEST_IDS:
        return Message("HD-Lock {text}", text=describe_request(CanFrame(arbitration_id, data, False)))
    if (is_extended, arbitration_id) in lock_ids:
        return Message("HD-Lock {text}", text=describe_lock_frame(data))
    return None


STATUS_PERIOD_S = 1.0  # section 6.5: a lock sends its status "alle 1000 ms"
STATUS_PERIOD_TOLERANCE = 0.3  # section 6.5 gives no tolerance: 0.7-1.3 s between two status frames counts as "about 1 s"
DISCOVERY_FRAMES = 3  # section 6.5.1 (status repeated every 1 s): three in a row at that period before a lock is listed
DISCOVERY_EVIDENCE = {"period_s": STATUS_PERIOD_S, "tolerance": STATUS_PERIOD_TOLERANCE, "frames": DISCOVERY_FRAMES,
                      "text": "status frames"}


def discovered(arbitration_id: int, is_extended: bool, data: bytes) -> dict | None:
    """One frame of an unknown ID that has the form of a lock's periodic status (section 6.5.1).

    One frame is not enough: the entry carries the evidence a lock must show before it is
    listed (``DISCOVERY_FRAMES`` such frames ``STATUS_PERIOD_S`` apart); which IDs other device
    types occupy is the worker's business (``DeviceType.can_fixed_ids``).
    """
    if not looks_like_status(data) or (not is_extended and arbitration_id in CAN_REQUEST_IDS):
        return None
    if arbitration_id == CAN_BROADCAST or arbitration_id > (EXT_ID_MAX if is_extended else STD_ID_MAX):
        return None  # section 6.4: device ID 0 is the broadcast target, never a lock's own ID
    status = decode_lock_frame(data)
    return {
        "type": "hdlock", "device_id": arbitration_id, "extended": is_extended, "summary": describe_lock_frame(data), "status": status,
        "evidence": DISCOVERY_EVIDENCE,
    }
