"""The declared parameter model of the Ewellix SCU (document 002, section 4.3 tables 6 and 7, section 7).

Pure: no I/O. The same form as the HD-Lock's registers and the Electrak's service parameters
(:class:`devices.params.ParamMap`), so that backup, restore, the offline project, batch apply, drift and the
replacement assistant work for the SCU through the generic paths in app/.

What is a setting: RT writes the remote data 0x3xxx only (table 3, "Nur data_Ids 3xxx sind erlaubt"); of
them the remote speed of each function (0x3011 .. 0x301A) and the remote position of each actuator
(0x3021 .. 0x3026) are values an engineer chooses. Both are volatile (table 7: "In flüchtigen Registern
gespeichert. Initialisiert nach Reset mit voreingestellten Werten"). The cyclic objects 0x3001 .. 0x3005 are
this tool's own transfer definition, not a setting. Shown with them, read-only: the conversion factors
(0x1011 .. 0x1016), the virtual limits of each actuator (Position_Virtual_Limit_In/Out of UserPositionData
0x2001 .., section 7) and the Safety_ID this tool opens the session with (RO, table 3: a parameter of the
telegram, no data ID).

Keys: ``data:<data ID>`` for a data ID, ``limit_in:<0x200n>`` / ``limit_out:<0x200n>`` for the two fields of
an actuator's UserPositionData, ``session:0`` for the Safety_ID. A raw value is the value's bits as an
unsigned integer (a FLOAT's IEEE bits); the live store keeps it as 16-bit words, high word first
(:meth:`devices.params.Param.split`), like every other model (:attr:`DataParam.addresses` says where).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from devices import values as v
from devices.message import Message, N_
from devices.params import Access, Param, ParamError, ParamMap
from devices.scu import codec
from devices.scu import params as p

DATA = "data"  # a data ID of tables 6 and 7
LIMIT_IN, LIMIT_OUT = "limit_in", "limit_out"  # fields of UserPositionData 0x2001.. (section 7)
SESSION = "session"  # the remote session's own parameters (RO)
SPEED_UNIT = "% or counts/s"  # table 7: relative (%) or absolute (counts/s) speed select, as parametrised
SPEED_MAX = 1000  # table 7: relative 0 .. 100 %, absolute 0 .. 1000 counts/s (the adapter holds the unit's own)
LIMIT_FIELDS = {LIMIT_IN: "Position_Virtual_Limit_In", LIMIT_OUT: "Position_Virtual_Limit_Out"}
VOLATILE = Message(N_("volatile remote data (table 7): the unit keeps it until its next reset, then starts again with "
                      "its configured default"))
# the same as a sentence of its own (a description's last), worded in the catalog as one
_VOLATILE_SENTENCE = Message(N_("Volatile remote data (table 7): the unit keeps it until its next reset, then starts again "
                                "with its configured default"))


@dataclass(frozen=True)
class DataParam(Param):
    """A value of the SCU's data directory: ``address`` is its data ID (for a virtual limit the data ID of the
    UserPositionData that holds it); ``extra["type"]`` names the document's data type."""

    @property
    def data_id(self) -> int:
        return self.address

    @property
    def is_float(self) -> bool:
        return self.extra.get("type") == "FLOAT"

    @property
    def addresses(self) -> tuple[int, ...]:
        """Where the live store keeps the value's 16-bit words (high word first): the first at the data ID, the
        second at the data ID + 0x10000, so that the 32-bit values of consecutive data IDs (0x3021, 0x3022) never
        share a word."""
        return tuple(self.address + 0x10000 * k for k in range(self.words))

    @property
    def writable(self) -> bool:
        # RT carries the whole value in one telegram (table 3), so a 32-bit remote position is one write
        return self.access is Access.RW and not self.never_write

    @property
    def value_type(self) -> v.ValueType:
        # section 3: "Intel Little Endian Format, LS-Byte ... MS-Byte"
        if self.is_float:
            return v.F32LE
        return v.Int(self.bits, self.signed, v.LITTLE)

    def decode(self, raw: int) -> int | float:
        if self.is_float:
            return struct.unpack("<f", int(raw).to_bytes(4, "little"))[0]
        return super().decode(raw)

    def encode(self, value: int | float) -> int:
        if self.is_float:
            return int.from_bytes(struct.pack("<f", float(value)), "little")
        return super().encode(value)

    def display(self, raw: int) -> str:
        if self.is_float:
            value = self.decode(raw)
            return f"{value:g} {self.unit}".strip() if math.isfinite(value) else f"{value} (not a number)"
        return super().display(raw)

    def validate(self, value: int | float | str) -> int:
        if self.is_float:
            raise ParamError(Message(N_("{name} is {access} and cannot be written"), name=self.name,
                                     access=self.access.value))
        return super().validate(value)


def _speed(n: int) -> DataParam:
    return DataParam(
        f"Remote Speed F{n}", DATA, p.speed_id(n), Access.RW, SPEED_UNIT, minimum=0, maximum=SPEED_MAX,
        description=Message(N_("Speed of motion function F{n} when it is started by this tool (RT {data_id}, read back "
                               "with RG; table 7, section 4.6). % (0 .. 100) with speed select relative, the standard "
                               "parametrisation; counts/s (0 .. 1000) with speed select absolute (the plant file's "
                               "speed_select). Default: the function's speed from the unit's configuration. {volatile}."),
                            n=n, data_id=f"0x{p.speed_id(n):04X}", volatile=_VOLATILE_SENTENCE),
        extra={"type": "UINT16", "section": "4.3 table 7, 4.6"})


def _position(n: int) -> DataParam:
    return DataParam(
        f"Remote Position A{n}", DATA, p.remote_position_id(n), Access.RW, "counts", words=2, signed=True,
        minimum=-(2 ** 31), maximum=2 ** 31 - 1,
        description=Message(N_("Target of actuator {n} for 'move to remote position' (RE with para_ID 9), in encoder "
                               "counts (RT {data_id}, read back with RG; table 7, section 4.6). Default: the Memory 1 / "
                               "User 1 position of UserPositionData. {volatile}."),
                            n=n, data_id=f"0x{p.remote_position_id(n):04X}", volatile=_VOLATILE_SENTENCE),
        extra={"type": "INT32", "section": "4.3 table 7, 4.6"})


def _factor(n: int) -> DataParam:
    return DataParam(
        f"Conversion factor A{n}", DATA, 0x1010 + n, Access.RO, "counts/mm", words=2,
        description=Message(N_("Conversion factor of actuator {n} ({data_id}, FLOAT, table 6; no unit in the table, read "
                               "as encoder counts per mm). Part of the unit's configuration: RT cannot write it (table "
                               "3: only data IDs 3xxx)."), n=n, data_id=f"0x{0x1010 + n:04X}"),
        extra={"type": "FLOAT", "section": "4.3 table 6"})


# a whole sentence for each of the two limits (the translator words "in" and "out" with the sentence around them)
_LIMIT_TEXTS = {
    LIMIT_IN: N_("Virtual in limit of actuator {n}: Position_Virtual_Limit_In of UserPositionData {data_id} (struct "
                 "ACTUATOR_POSITIONS, section 7), in encoder counts. Part of the unit's configuration: RT cannot write "
                 "it (table 3: only data IDs 3xxx); the position bars and mm use it as the actuator's end."),
    LIMIT_OUT: N_("Virtual out limit of actuator {n}: Position_Virtual_Limit_Out of UserPositionData {data_id} (struct "
                  "ACTUATOR_POSITIONS, section 7), in encoder counts. Part of the unit's configuration: RT cannot write "
                  "it (table 3: only data IDs 3xxx); the position bars and mm use it as the actuator's end."),
}


def _limit(n: int, space: str) -> DataParam:
    return DataParam(
        f"{LIMIT_FIELDS[space]} A{n}", space, 0x2000 + n, Access.RO, "counts", words=2, signed=True,
        description=Message(_LIMIT_TEXTS[space], n=n, data_id=f"0x{0x2000 + n:04X}"),
        extra={"type": "INT32", "section": "4.3 table 6, 7", "field": LIMIT_FIELDS[space]})


SAFETY_ID = DataParam(
    "Safety_ID", SESSION, 0, Access.RO, enum={int(k): k.name.lower().replace("_", " ") for k in codec.SafetyId},
    description=Message(N_("What the unit does on a communication timeout (0.5 s): 0 stops every motion and starts "
                           "none, 1 stops every motion, 2 stops only the remote motion (firmware V2B3). Sent with every "
                           "RO (table 3); the unit has no data ID to read it back, its RO acknowledgement is the answer. "
                           "Set in the plant file (safety_id), not in the unit.")),
    extra={"type": "UINT8", "section": "4.1 table 3"})

PARAMS = ParamMap([
    *(_speed(n) for n in range(1, p.FUNCTIONS + 1)),
    *(_position(n) for n in range(1, p.ACTUATORS + 1)),
    *(_factor(n) for n in range(1, p.ACTUATORS + 1)),
    *(_limit(n, space) for n in range(1, p.ACTUATORS + 1) for space in (LIMIT_IN, LIMIT_OUT)),
    SAFETY_ID,
])
SETTINGS = [q for q in PARAMS if q.setting]


def params_for(actuators: int) -> list[DataParam]:
    """The parameters of a unit driving ``actuators`` actuators (1 .. 6): every function's remote speed (F1 .. F10
    exist whatever the parametrisation, section 4.4), the per-actuator values of the configured actuators only."""
    out = []
    for q in PARAMS:
        n = actuator_of(q)
        if n is None or n <= actuators:
            out.append(q)
    return out


def actuator_of(param: Param) -> int | None:
    """The actuator 1 .. 6 a parameter belongs to, or None (a function's speed, the Safety_ID)."""
    if param.space in LIMIT_FIELDS:
        return param.address - 0x2000
    if param.space == DATA:
        return p.item(param.address).actuator
    return None


def params_of(data_id: int) -> list[DataParam]:
    """The parameters whose value an RG answer of ``data_id`` (a leaf, not a group) carries."""
    return _BY_DATA_ID.get(data_id, [])


def raw_of(param: DataParam, value) -> int:
    """The raw value of ``param`` in the decoded value of its data ID (a UserPositionData struct for a limit)."""
    if param.space in LIMIT_FIELDS:
        value = value[LIMIT_FIELDS[param.space]]
    return param.encode(value)


_BY_DATA_ID: dict[int, list[DataParam]] = {}
for _q in PARAMS:
    if _q.space != SESSION:
        _BY_DATA_ID.setdefault(_q.address, []).append(_q)

__all__ = ["DATA", "LIMIT_IN", "LIMIT_OUT", "SESSION", "SPEED_UNIT", "SPEED_MAX", "VOLATILE", "DataParam", "SAFETY_ID",
           "PARAMS", "SETTINGS", "params_for", "actuator_of", "params_of", "raw_of"]
