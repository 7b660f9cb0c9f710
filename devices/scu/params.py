"""Data directory of the Ewellix SCU (document 002, section 4.3 tables 6 and 7, section 7).

Pure: no I/O. Every data ID of the tables is a :class:`DataItem` with its typed value
(:mod:`devices.values`), unit, access and the document's comment. Multi-byte values are
little-endian (section 3: "Intel Little Endian Format").

Per-actuator data IDs are the group ID plus the actuator number (0x0011 = position of
actuator 1); reading a group ID returns the block of its members (0x0010 = all six
positions, section 4.6). Remote speeds are per function (0x3011 = F1 .. 0x301A = F10).

Public API: :data:`DIRECTORY` (data ID -> :class:`DataItem`), :func:`item`, :func:`actuator_id`,
:func:`speed_id`, :func:`remote_position_id`, :func:`decode_data` (an RG answer's data),
:func:`encode_data` (RT data), :func:`rg_value`, :class:`CyclicDefinition` (data IDs 0x3001..)
and :data:`ACTUATOR_POSITIONS`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from devices import values as v
from devices.errors import CommissionError
from devices.message import Message, N_, joined
from devices.params import Access
from devices.scu import codec

ACTUATORS = 6  # section 4.6: "Position aller 6 möglichen Antriebe"
FUNCTIONS = 10  # F1 .. F10 (section 4.4)
USERS = 4  # section 7: USER_1 .. USER_4

READ = Access.R
REMOTE_WRITE = Access.RW  # only remote data 0x3xxx, volatile: lost at reset (section 4.3, table 7)


@dataclass(frozen=True)
class DataItem:
    """One entry of the data directory.

    :param data_id: the data index (or group index for a block)
    :param vtype: the value's type; for a group, a :class:`devices.values.Struct` of its members
    :param unit: engineering unit of the decoded value
    :param group: the secondary collection index the item belongs to (0x0010 for 0x0011), or None
    :param actuator: 1..6 for per-actuator items; :param function: 1..10 for per-function items
    :param members: for a group ID, the member data IDs in block order
    :param label: the item in plain English for a commissioning engineer, with the document's own name
        where that helps to find it in the table (``"Hand switch LEDs (LED HS)"``); empty: :attr:`name` is clear
    """

    data_id: int
    name: str
    vtype: v.ValueType
    unit: str = ""
    access: Access = READ
    comment: str = ""
    group: int | None = None
    actuator: int | None = None
    function: int | None = None
    members: tuple[int, ...] = ()
    label: str = ""

    @property
    def title(self) -> str:
        """What to call the item on a screen: its label, else the document's name."""
        return self.label or self.name

    @property
    def is_group(self) -> bool:
        return bool(self.members)

    @property
    def size(self) -> int | None:
        return self.vtype.size

    @property
    def writable(self) -> bool:
        return self.access == REMOTE_WRITE

    @property
    def type_name(self) -> str:
        return self.vtype.name

    @property
    def key(self) -> str:
        return f"0x{self.data_id:04X}"


# -- value types of the tables ----------------------------------------------------------------------
COUNTS = "counts"  # "Einheit: Encoder Flanken (Count)"
POSITION = v.I32LE
CURRENT = v.Scaled(v.U16LE, 0.1, "A")  # "Festkomma 0,1 A", 0 .. 100 A
ANALOGUE = v.Scaled(v.U16LE, 0.01, "V")  # "Auflösung: 0,01 V", 0 .. 6.00 V
BATTERY_VOLTAGE = v.Scaled(v.U16LE, 0.1, "V")  # "Festkomma 0,1 V", 0 .. 40.0 V
# The document names no character set for the info strings; latin-1 decodes every byte, so a
# firmware text never fails to show (section 4.3, 0x0001 / 0x0002).
FIRMWARE_INFO = v.String(31, encoding="latin-1")
CONFIGURATION_INFO = v.String(36, encoding="latin-1")

BINARY_INPUTS = v.Bits(v.U8, (
    *(v.BitField(f"input_{n}", n - 1, description=Message(N_("input {n} (logical level)"), n=n)) for n in range(1, 5)),
    *(v.BitField(f"input_{n}_level", n + 3, description=Message(N_("input {n} (input level)"), n=n)) for n in range(1, 5)),
))
# 0x0081..: "2 B: Linearantriebfehler 1 B: Spitzenstrom erreicht 1 B: Kurzschluss-Detektionen", read in
# wire order (LS byte first, section 3): bits 0..15 actuator errors, 16..23 peak current, 24..31 short circuit.
ACTUATOR_ERRORS = v.Bits(v.U32LE, (
    v.BitField("actuator_errors", 0, 16, description=Message(N_("linear actuator errors"))),
    v.BitField("peak_current", 16, 8, description=Message(N_("peak current reached"))),
    v.BitField("short_circuit", 24, 8, description=Message(N_("short-circuit detections"))),
))
ERROR_CODE = v.Bits(v.U32LE, tuple(
    v.BitField(b.key, b.bit - 1, description=b.cause) for b in codec.ERROR_BITS.values()
))
ACTUATOR_STATUS_2 = v.Bits(v.U8, (
    v.BitField("initialised", 0, description=Message(N_("initialised"))),
    v.BitField("enable_in", 1, description=Message(N_("enable flag, inward direction"))),
    v.BitField("enable_out", 2, description=Message(N_("enable flag, outward direction"))),
))
BATTERY_MAINS = v.Bits(v.U8, (
    v.BitField("mains", 0, description=Message(N_("mains connected"))),
    v.BitField("battery", 1, description=Message(N_("battery connected"))),
    v.BitField("charger_on", 2, description=Message(N_("charge controller on"))),
    v.BitField("charging", 3, description=Message(N_("charging active"))),
))
# 0x0110 names "Binary Output 1" for bit 0 and bit 1: bit 1 is binary output 2 (section 4.3, print error).
BINARY_OUTPUTS = v.Bits(v.U8, (v.BitField("output_1", 0, description=Message(N_("output 1"))),
                               v.BitField("output_2", 1, description=Message(N_("output 2")))))
LED_HS = v.Bits(v.U8, (v.BitField("led_1", 0, description="LED1"), v.BitField("led_2", 1, description="LED2")))
LED_LB = v.Bits(v.U8, tuple(v.BitField(f"led_{n}", n - 1, description=f"LED{n}") for n in range(1, 9)))
BUZZER = v.Bits(v.U8, (v.BitField("buzzer", 0, description=Message(N_("buzzer"))),))
SENSOR_SUPPLY = v.Bits(v.U8, (v.BitField("sensor_supply", 0, description=Message(N_("sensor supply"))),))
# 0x0162 reads "Bit 0: Funktion 0 ... Bit 9: Funktion 10": bit n is fnc_ID n, i.e. F(n+1) (section 4.3 / 4.4).
LOCK_STATUS = v.Bits(v.U16LE, tuple(v.BitField(f"F{n + 1}_locked", n, description=f"F{n + 1}")
                                    for n in range(FUNCTIONS)))
ACTUATOR_STATUS_1 = v.Bits(v.U8, (  # descriptions: table 6, 0x0171 ("signal limit_in_out" is the document's term)
    v.BitField("present", 0, description=Message(N_("actuator present"))),
    v.BitField("limit_in_out", 1, description=Message(N_("limit in/out signal (limit_in_out)"))),
    v.BitField("switch_1", 2, description=Message(N_("switch 1 signal"))),
    v.BitField("switch_2", 3, description=Message(N_("switch 2 signal"))),
    v.BitField("motion", 4, description=Message(N_("motion active"))),
    v.BitField("in_position", 5, description=Message(N_("in position reached"))),
    v.BitField("out_position", 6, description=Message(N_("out position reached"))),
    v.BitField("stroke_recorded", 7, description=Message(N_("stroke recorded"))),
))

_POSITION_NAMES = ("Position_Memory_1", "Position_Memory_2", "Position_Memory_3", "Position_Memory_4",
                   "Position_Intermediate_In", "Position_Intermediate_Out")
ACTUATOR_POSITIONS = v.Struct("ACTUATOR_POSITIONS", (  # section 7: 4 users x 6 INT32, then the virtual limits
    *((f"{name}[USER_{u}]", v.I32LE) for u in range(1, USERS + 1) for name in _POSITION_NAMES),
    ("Position_Virtual_Limit_In", v.I32LE), ("Position_Virtual_Limit_Out", v.I32LE),
))
CYCLIC_OBJECT = v.Array(v.U16LE, 12)  # UINT16[12]; 0xFFFF (-1) = no transfer (table 7)
CYCLIC_SLOTS = 6  # para[0..5] write data IDs, para[6..11] read data IDs (table 7)
NO_DATA_ID = 0xFFFF


def _status1_text() -> str:
    return N_("Bit 0 actuator present, 1 signal limit_in_out, 2 signal switch 1, 3 signal switch 2, 4 motion active, "
              "5 in position reached, 6 out position reached, 7 stroke recorded")


# -- the tables ---------------------------------------------------------------------------------------
_ITEMS: list[DataItem] = [
    DataItem(0x0001, "Firmware info", FIRMWARE_INFO, comment=N_("Name, version, CS; size = 31 B"), group=0x0000),
    DataItem(0x0002, "Configuration info", CONFIGURATION_INFO, comment=N_("Name, version, CS; size = 36 B"),
             group=0x0000),
    DataItem(0x0020, "Actual_State_Binary Inputs 1 ... 4", BINARY_INPUTS,
             comment=N_("Bits 0..3: logical level of inputs 1..4; bits 4..7: input level of inputs 1..4 "
                        "(0 = not active, 1 = active)"), label=N_("Binary inputs 1-4 (Actual_State_Binary Inputs)")),
    DataItem(0x0040, "Actual_State_Keys", v.U32LE, comment=N_("(no comment in the document)"), label="Keys (Actual_State_Keys)"),
    DataItem(0x008F, "Number_Total_Over_Current", v.U32LE, group=0x0080),
    DataItem(0x00BF, "Max_Total_Current", CURRENT, "A", comment=N_("0 ... 1000, fixed point 0.1 A, 0 ... 100 A"),
             group=0x00B0),
    DataItem(0x00C0, "Max_Temp_Rectifer_FET", v.U8, "ADC", comment=N_("ADC value 0 ... 255")),
    DataItem(0x00C1, "Number_Over_Temp_Rectifer_FET", v.U32LE),
    DataItem(0x0100, "Battery Mains", BATTERY_MAINS,
             comment=N_("Bit 0 mains connected, 1 battery connected, 2 charge controller on, 3 charging active"),
             label="Battery and mains"),
    DataItem(0x0110, "Binary Output Status", BINARY_OUTPUTS, comment=N_("Bit 0 binary output 1 on, bit 1 output 2 on"),
             label=N_("Binary outputs")),
    DataItem(0x0120, "LED HS", LED_HS, comment=N_("Bit 0/1: LED1/LED2 of the hand switch on"),
             label=N_("Hand switch LEDs (LED HS)")),  # HS = Handschalter
    DataItem(0x0130, "LED LB", LED_LB, comment=N_("Bit 0..7: LED1..LED8 of the locking box on"),
             label=N_("Locking box LEDs (LED LB)")),  # LB = Lockingbox
    DataItem(0x0140, "Buzzer", BUZZER, comment=N_("Bit 0: buzzer on")),
    DataItem(0x0150, "Sensor Supply", SENSOR_SUPPLY, comment=N_("Bit 0: sensor supply on")),
    DataItem(0x0162, "Lock Status", LOCK_STATUS, comment=N_("Bit n: function n (F(n+1)) locked"),
             label=N_("Locked functions (Lock Status)")),
    DataItem(0x0164, "Battery voltage", BATTERY_VOLTAGE, "V", comment=N_("fixed point 0.1 V, 0 ... 40.0 V")),
    DataItem(0x0165, "Locking Box detected", v.U8, comment=N_("0 ... 2 locking boxes"), label=N_("Locking boxes detected")),
    DataItem(0x0166, "Benutzer", v.U8, comment=N_("user 1 ... 4"), label=N_("Active user (Benutzer)")),  # Benutzer = user
]

_PER_ACTUATOR = [  # (group, name pattern, type, unit, comment)
    (0x0010, "Actual_Position Actuator {n}", POSITION, COUNTS, N_("unit: encoder edges (counts)")),
    (0x0060, "Number_cycle_of_on_of_Relay_in A{n}", v.U32LE, "", N_("switching cycles of the relay 'in'")),
    (0x0070, "Number_cycle_of_on_of_Relay_out A{n}", v.U32LE, "", N_("switching cycles of the relay 'out'")),
    (0x0080, "Number_Actuator error A{n}", ACTUATOR_ERRORS, "",
     N_("error counter: 2 B linear actuator errors, 1 B peak current reached, 1 B short-circuit detections")),
    (0x0090, "Cumulated_Stroke A{n}", v.U32LE, COUNTS, N_("unit: encoder edges")),
    (0x00A0, "Strom A{n}", CURRENT, "A", N_("0 ... 1000, fixed point 0.1 A, 0 ... 100 A")),
    (0x00B0, "Max_Current A{n}", CURRENT, "A", N_("0 ... 1000, fixed point 0.1 A, 0 ... 100 A")),
    (0x00E0, "Actuator status 2 A{n}", ACTUATOR_STATUS_2, "",
     N_("Bit 0 initialised, 1 enable flag inward, 2 enable flag outward, 3..7 unused")),
    (0x00F0, "Speed A{n}", v.U16LE, "% or counts/s",
     N_("speed select relative: %, 0 ... 100 (absolute: encoder edges/s)")),
    (0x0170, "Actuator Status 1 A{n}", ACTUATOR_STATUS_1, "", _status1_text()),
    (0x1010, "Conversion factor A{n}", v.F32LE, "", "FLOAT"),
    (0x2000, "UserPositionData A{n}", ACTUATOR_POSITIONS, COUNTS, N_("struct ACTUATOR_POSITIONS (section 7)")),
]
for _group, _name, _type, _unit, _comment in _PER_ACTUATOR:
    for _n in range(1, ACTUATORS + 1):
        _ITEMS.append(DataItem(_group + _n, _name.format(n=_n), _type, _unit, READ, _comment, _group, _n))
for _n in range(1, 5):
    _ITEMS.append(DataItem(0x0030 + _n, f"Actual_State_Analogue_Input_{_n}", ANALOGUE, "V",
                           comment=N_("0 ... 600, resolution 0.01 V, 0 ... 6.00 V"), group=0x0030))
for _n, _label in enumerate(("last recent", "History 1", "History 2", "History 3", "History 4"), 1):
    _ITEMS.append(DataItem(0x00D0 + _n, f"Error_Code {_n} ({_label})", ERROR_CODE,
                           comment=N_("error code bits, see section 4.5 (Bit n = mask 1 << (n-1))"), group=0x00D0))
for _n in range(1, 6):
    _ITEMS.append(DataItem(0x3000 + _n, f"CyclicObj {_n}", CYCLIC_OBJECT, access=REMOTE_WRITE, group=0x3000,
                           comment=N_("data IDs para[0..5] written with every RC, para[6..11] read back with it; "
                                      "-1 = no transfer; default -1")))
for _n in range(1, FUNCTIONS + 1):
    _ITEMS.append(DataItem(0x3010 + _n, f"Remote Speed F{_n}", v.U16LE, "% or counts/s", REMOTE_WRITE,
                           N_("default: the function's configured speed; relative: %, 0 ... 100; "
                              "absolute: encoder edges/s, 0 ... 1000"), 0x3010, function=_n))
for _n in range(1, ACTUATORS + 1):
    _ITEMS.append(DataItem(0x3020 + _n, f"Remote Position A{_n}", POSITION, COUNTS, REMOTE_WRITE,
                           N_("default: Memory 1 / User 1 position of UserPositionData; unit: encoder edges"),
                           0x3020, _n))

# Group IDs: only 0x0010 is described (section 4.6, all six positions). The other blocks are taken
# to answer their members in ID order the same way (section 4.3: "ganze Blöcke"); a block of another
# length is reported by decode_data as a named error with its raw bytes.
_GROUP_NAMES = {
    0x0000: N_("Firmware and configuration info"), 0x0010: N_("Actual_Position, all actuators"),
    0x0030: N_("Analogue inputs 1 ... 4"), 0x0060: N_("Relay in cycles, all actuators"),
    0x0070: N_("Relay out cycles, all actuators"), 0x0080: N_("Actuator error counters and total over-current"),
    0x0090: N_("Cumulated stroke, all actuators"), 0x00A0: N_("Currents, all actuators"),
    0x00B0: N_("Max currents and max total current"), 0x00D0: N_("Error code and history"),
    0x00E0: N_("Actuator status 2, all actuators"), 0x00F0: N_("Speeds, all actuators"),
    0x0170: N_("Actuator status 1, all actuators"), 0x1010: N_("Conversion factors, all actuators"),
    0x2000: N_("User position data, all actuators"), 0x3000: N_("Cyclic objects 1 ... 5"),
    0x3010: N_("Remote speeds F1 ... F10"), 0x3020: N_("Remote positions, all actuators"),
}
for _group, _name in _GROUP_NAMES.items():
    _members = tuple(sorted(i.data_id for i in _ITEMS if i.group == _group))
    _struct = v.Struct(_name, tuple((f"0x{m:04X}", next(i.vtype for i in _ITEMS if i.data_id == m)) for m in _members))
    _ITEMS.append(DataItem(_group, _name, _struct, comment=N_("group ID: the block of its members in ID order"),
                           members=_members))

DIRECTORY: dict[int, DataItem] = {i.data_id: i for i in sorted(_ITEMS, key=lambda i: i.data_id)}
if len(DIRECTORY) != len(_ITEMS):
    raise RuntimeError("duplicate data ID in the SCU directory")
GROUPS = {g: DIRECTORY[g] for g in _GROUP_NAMES}


class UnknownDataId(CommissionError, KeyError):
    """A data ID that is not in the document's tables."""

    def __init__(self, data_id: int):
        self.data_id = data_id
        super().__init__(f"data ID 0x{data_id:04X} is not in the SCU data directory")


# How the set and clear bits of a bit-field item read (section 4.3, table 6): (set, clear, no bit set).
FLAG_WORDS: dict[int, tuple[str, str, str]] = {
    0x0020: (N_("active"), N_("not active"), N_("no input active")),
    0x0100: ("", "", N_("none")),  # only what is there: "mains connected, battery connected, charge controller on"
    0x0110: (N_("on"), N_("off"), N_("all off")), 0x0120: ("on", "off", "all off"), 0x0130: ("on", "off", "all off"),
    0x0140: ("on", "off", "off"), 0x0150: ("on", "off", "off"),
    0x0162: (N_("locked"), N_("unlocked"), N_("no function locked")),
}
FLAGS_EACH = 4  # up to this many bits each is named with its state; more (or no state words): only the set ones


def flags_text(data_id: int, raw: int) -> str:
    """A bit-field item's value in words: ``"output 1 off, output 2 on"``, ``"LED1, LED3 on"``, ``"all off"``.

    :param raw: the register's value as read (undocumented set bits are named by number)
    :raises KeyError: ``data_id`` is not a bit-field item with :data:`FLAG_WORDS`
    """
    on, off, none = FLAG_WORDS[data_id]
    fields = item(data_id).vtype.fields
    raw = int(raw)
    named = sum(f.mask for f in fields)
    extra = [n for n in range(32) if raw >> n & 1 and not named >> n & 1]
    set_ = [_word(f.description) for f in fields if raw & f.mask]
    if len(fields) <= FLAGS_EACH and on:
        text = joined([_stated(f.description, on if raw & f.mask else off) for f in fields])
    elif set_:
        text = _stated(joined(set_), on) if on else joined(set_)
    else:
        text = Message(none)
    if extra:
        return joined([text, Message(N_("undocumented bits set: {bits}"), bits=", ".join(map(str, extra)))], "; ")
    return text


def _word(text: str) -> Message:
    """A word of table 6 (marked where it is declared) as a :class:`Message`; one that is a Message already as it is."""
    return text if isinstance(text, Message) else Message(text)


def _stated(what: str, state: str) -> Message:
    """A bit's name and its state (``"output 1 off"``), each in the reader's language."""
    return Message("{what} {state}", what=_word(what), state=_word(state))


def user_text(value: int) -> str:
    """0x0166 Benutzer: "User 1 ... 4" (table 6)."""
    if 1 <= value <= USERS:
        return Message(N_("user {n}"), n=value)
    return Message(N_("{value} (not one of user 1 ... {users})"), value=value, users=USERS)


def item(data_id: int) -> DataItem:
    try:
        return DIRECTORY[data_id]
    except KeyError:
        raise UnknownDataId(data_id) from None


def actuator_id(group: int, actuator: int) -> int:
    """Group ID + actuator number: ``actuator_id(0x0010, 1) == 0x0011`` (SPEC-NOTES, section 4.6).

    :param group: a per-actuator group (0x0010, 0x00A0, 0x0170, 0x3020, ...)
    :param actuator: 1 .. 6
    """
    if not 1 <= actuator <= ACTUATORS:
        raise ValueError(f"actuator {actuator} is not 1 .. {ACTUATORS}")
    data_id = group + actuator
    if DIRECTORY.get(data_id) is None or DIRECTORY[data_id].actuator != actuator:
        raise UnknownDataId(data_id)
    return data_id


def speed_id(function: int) -> int:
    """Remote speed of motion function F1..F10: 0x3011 .. 0x301A (table 7)."""
    if not 1 <= function <= FUNCTIONS:
        raise ValueError(f"function F{function} is not F1 .. F{FUNCTIONS}")
    return 0x3010 + function


def remote_position_id(actuator: int) -> int:
    """Remote position of actuator 1..6: 0x3021 .. 0x3026 (table 7)."""
    return actuator_id(0x3020, actuator)


def decode_data(data_id: int, data: bytes) -> Any:
    """The value of an RG answer's data (or an RC read slot).

    Groups decode to ``{member data ID: value}``.

    :raises UnknownDataId: not in the tables (show the raw bytes)
    :raises devices.values.DecodeError: wrong length or bytes (TruncatedError / ExcessDataError)
    """
    entry = item(data_id)
    value = entry.vtype.decode(bytes(data))
    if entry.is_group:
        return {int(k, 16): x for k, x in value.items()}
    return value


def encode_data(data_id: int, value: Any, *, remote_only: bool = True) -> bytes:
    """The bytes of ``value`` for ``data_id`` (RT data, or a twin's RG answer with ``remote_only=False``).

    :param value: for a group, ``{member data ID: value}``
    :raises devices.values.EncodeError: a value the type cannot carry
    :raises PermissionError: a data ID outside remote data 0x3xxx when ``remote_only`` (table 3, RT)
    """
    entry = item(data_id)
    if remote_only and not entry.writable:
        raise PermissionError(f"{entry.key} {entry.name} is read only: RT writes remote data 0x3xxx only")
    if entry.is_group and isinstance(value, Mapping):
        value = {f"0x{k:04X}" if isinstance(k, int) else k: x for k, x in value.items()}
    return entry.vtype.encode(value)


def rg_value(data_id: int, answer: codec.Answer) -> Any:
    """Decode the value of an RG answer (raises :class:`devices.scu.codec.CommandRefused` on an error code)."""
    return decode_data(data_id, answer.raise_for_status().data)


def rt_frame(data_id: int, value: Any) -> bytes:
    """A complete RT request writing ``value`` to remote data ``data_id``."""
    return codec.encode_rt(data_id, encode_data(data_id, value))


# -- cyclic objects (table 7, 0x3001..0x3005; RC table 3) ----------------------------------------------------
@dataclass(frozen=True)
class CyclicDefinition:
    """Data IDs written with every RC (``write_ids``) and read back with it (``read_ids``), up to 6 each.

    :param write_ids: remote data IDs 0x3xxx whose values the RC request carries, in order
    :param read_ids: data IDs whose values the RC answer carries, in order
    """

    write_ids: tuple[int, ...] = ()
    read_ids: tuple[int, ...] = ()

    def __post_init__(self):
        for ids, what in ((self.write_ids, "write"), (self.read_ids, "read")):
            if len(ids) > CYCLIC_SLOTS:
                raise ValueError(f"a cyclic object holds at most {CYCLIC_SLOTS} {what} data IDs")
            for data_id in ids:
                entry = item(data_id)
                if entry.size is None:
                    raise ValueError(f"{entry.key} has no fixed size")
        for data_id in self.write_ids:
            if not item(data_id).writable:
                raise ValueError(f"0x{data_id:04X} cannot be written: only remote data 0x3xxx (table 7)")

    def encode(self) -> bytes:
        """The UINT16[12] value of CyclicObj n, unused slots -1."""
        pad = lambda ids: list(ids) + [NO_DATA_ID] * (CYCLIC_SLOTS - len(ids))  # noqa: E731
        return CYCLIC_OBJECT.encode(pad(self.write_ids) + pad(self.read_ids))

    @classmethod
    def decode(cls, data: bytes) -> CyclicDefinition:
        slots = CYCLIC_OBJECT.decode(data)
        used = lambda ids: tuple(i for i in ids if i != NO_DATA_ID)  # noqa: E731
        return cls(used(slots[:CYCLIC_SLOTS]), used(slots[CYCLIC_SLOTS:]))

    @property
    def write_size(self) -> int:
        return sum(item(i).size for i in self.write_ids)

    @property
    def read_size(self) -> int:
        return sum(item(i).size for i in self.read_ids)

    def encode_write(self, values: Sequence[Any] | Mapping[int, Any]) -> bytes:
        """RC write data: the values of ``write_ids`` in order (a sequence, or a mapping by data ID)."""
        if isinstance(values, Mapping):
            values = [values[i] for i in self.write_ids]
        if len(values) != len(self.write_ids):
            raise v.EncodeError(f"{len(values)} values given, {len(self.write_ids)} needed")
        return b"".join(item(i).vtype.encode(x) for i, x in zip(self.write_ids, values))

    def decode_read(self, data: bytes) -> dict[int, Any]:
        """RC answer data -> ``{data ID: value}`` for ``read_ids``."""
        return self._split(self.read_ids, data)

    def decode_write(self, data: bytes) -> dict[int, Any]:
        """RC request write data -> ``{data ID: value}`` (the twin's side)."""
        return self._split(self.write_ids, data)

    def encode_read(self, values: Mapping[int, Any]) -> bytes:
        """RC answer data from ``{data ID: value}`` (the twin's side)."""
        return b"".join(item(i).vtype.encode(values[i]) for i in self.read_ids)

    @staticmethod
    def _split(ids: Sequence[int], data: bytes) -> dict[int, Any]:
        data = bytes(data)
        need = sum(item(i).size for i in ids)
        if len(data) != need:
            raise (v.TruncatedError(need, len(data)) if len(data) < need else v.ExcessDataError(need, len(data)))
        out, at = {}, 0
        for data_id in ids:
            entry = item(data_id)
            value, at = entry.vtype.decode_from(data, at)
            out[data_id] = {int(k, 16): x for k, x in value.items()} if entry.is_group else value
        return out


def rc_frame(index: int, definition: CyclicDefinition, values: Sequence[Any] | Mapping[int, Any] = ()) -> bytes:
    """A complete RC request for cyclic object ``index`` (0 = 0x3001) with its write data."""
    return codec.encode_rc(index, definition.encode_write(values))


__all__ = [
    "ACTUATORS", "FUNCTIONS", "USERS", "READ", "REMOTE_WRITE", "DataItem", "DIRECTORY", "GROUPS", "UnknownDataId",
    "item", "actuator_id", "speed_id", "remote_position_id", "decode_data", "encode_data", "rg_value", "rt_frame",
    "CyclicDefinition", "rc_frame", "ACTUATOR_POSITIONS", "CYCLIC_OBJECT", "ERROR_CODE", "ACTUATOR_STATUS_1",
    "ACTUATOR_STATUS_2", "ACTUATOR_ERRORS", "BINARY_INPUTS", "BATTERY_MAINS", "LOCK_STATUS", "FLAG_WORDS", "flags_text",
    "user_text",
]
