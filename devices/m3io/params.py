"""The settings of a CAN-M3IO module as a parameter model (document "CAN-M3IO", Dok-Rev. 3.8).

Pure: no I/O. What the module keeps and this tool may set:

- the 15 customer-data records (section 7.2.4.2.3/4, addressed mode only): 6 bytes each, read in
  area 3 and written in area 4; a record written with fewer bytes is padded with 0xFF, an unwritten
  one reads FF FF FF FF FF FF. Its value is the bytes as hex text ("01 02 0a ff ff ff"), its raw
  value those 6 bytes as one number, first byte highest;
- P2 (section 4.3, 7.2.4): the HMR's three-phase output SSR1-3 loaded on two phases only. The module
  does not keep it (lost at any reset): this tool keeps it in the plant file (``p2 = true``) and
  sends it; in addressed mode it is written in area 1 index 15 too and read back in area 2 index 15.

Read-only, shown with them: the addressing that SW1 sets (section 5.8) and, in addressed mode, the
module's serial number, product code, software version and dynamic configuration (area 2).

Raw values wider than a register word are kept in the live store as words in slots ``address``,
``address + 100``, ... of their space (:attr:`ModuleParam.addresses`), first word highest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from devices import values
from devices.m3io import codec
from devices.message import Message, N_
from devices.params import Access, Field, Param, ParamError, ParamMap

CUSTOMER = "customer"  # area 3 read / area 4 write, index 1..15 (7.2.4.2.3/4)
CONFIG = "config"  # area 2 read, index 1, 2, 3, 15 (7.2.4.2.2)
CFG = "cfg"  # the Sync cfg byte (7.2.4), by bit: 7 = P2
ADDRESSING = "sw1"  # the DIP switch SW1 (5.8): read from the plant file, shown
SLOT = 100  # a wide raw value's words are kept at address, address + SLOT, ...
RECORD_BYTES = 6
P2_BIT = 7

P2_OPTION = "p2"  # the plant file's device option that keeps P2 across a restart (the module forgets it)
P2_NAMES = {0: "three-phase load", 1: "two-phase load (P2)"}
P2_RISK = Message(N_("P2 on: the module then reports a load fault on SSR1-3 unless exactly two of the three phases carry "
                     "a load (section 4.3): a three-phase load that lost one phase (a blown fuse, a broken wire) is no "
                     "longer switched off as a fault. Set it only for a load wired on two phases."))


@dataclass(frozen=True)
class ModuleParam(Param):
    """A value of ``size`` bytes (not a 16-bit register): a customer-data record, an area 2 value, a cfg bit."""

    size: int = 1  # bytes on the wire

    @property
    def bits(self) -> int:
        return 8 * self.size

    @property
    def addresses(self) -> range:
        return range(self.address, self.address + SLOT * self.words, SLOT)

    @property
    def writable(self) -> bool:
        return self.access is Access.RW and not self.never_write

    @property
    def value_type(self) -> values.ValueType:
        if self.space == CUSTOMER:
            return values.Bytes(RECORD_BYTES)
        if self.enum is not None:
            return values.Enum(values.Int(self.bits, False, values.LITTLE), self.enum)
        return values.Int(self.bits, False, values.LITTLE)

    def display(self, raw: int) -> str:
        if self.space == CONFIG and self.address == codec.CONFIG_SERIAL:
            return f"{raw:08d}"  # eight digits with leading zeros (7.2.4.2.2)
        if self.space == CONFIG and self.address == codec.CONFIG_VERSION:
            return f"{codec.decode_version(raw)} (assumed decoding: 0x{raw:04X})"
        if self.space == CONFIG and self.address == codec.CONFIG_PRODUCT:
            return f"0x{raw:04X} {codec.product_name(raw)}"
        if self.space == CONFIG and self.address == codec.CONFIG_DYNAMIC:
            return f"0x{raw:02X} (P2 {int(bool(raw & codec.P2))})"
        if self.space == ADDRESSING:
            return describe_sw1(raw)
        return super().display(raw)


@dataclass(frozen=True)
class RecordParam(ModuleParam):
    """A customer-data record: 6 bytes, shown and entered as hex text (7.2.4.2.3/4)."""

    size: int = RECORD_BYTES
    words: int = 3
    text_value: bool = True  # its value is text (hex bytes), not a number: restore and projects take it as such
    allowed_text: str = Message(N_("1 to 6 bytes as hex, e.g. 01 02 0a (padded with ff to 6 bytes)"))

    def decode(self, raw: int) -> str:
        return record_text(raw)

    def encode(self, value) -> int:
        return record_raw(parse_record(value, self.name))

    def display(self, raw: int) -> str:
        return record_text(raw)

    def validate(self, value) -> int:
        """Hex text or bytes (1 to 6 of them; fewer are padded with 0xFF as the module does), or the raw number."""
        if not self.writable:
            raise ParamError(Message(N_("{name} is {access} and cannot be written"), name=self.name,
                                     access=self.access.value))
        if isinstance(value, int) and not isinstance(value, bool):
            if not 0 <= value < 1 << 48:
                raise ParamError(Message(N_("{name}: {value} does not fit 6 bytes"), name=self.name, value=value))
            return value
        return record_raw(parse_record(value, self.name))

    def limits(self) -> tuple[float, float]:
        return 0, (1 << 48) - 1


def parse_record(value, name: str = "customer record") -> bytes:
    """A record as entered -> its 6 stored bytes (0xFF-padded, 7.2.4.2.4).

    :raises ParamError: not hex bytes, none, or more than 6
    """
    if isinstance(value, bytes | bytearray):
        payload = bytes(value)
    elif isinstance(value, str):
        text = value.strip().replace(":", " ").replace(",", " ")
        compact = "".join(text.split())
        if compact.lower().startswith("0x"):
            compact = compact[2:]
        try:
            payload = bytes.fromhex(text) if " " in text else bytes.fromhex(compact)
        except ValueError:
            raise ParamError(Message(N_("{name}: {value!r} is not bytes as hex, e.g. 01 02 0a"), name=name,
                                     value=value)) from None
    else:
        raise ParamError(Message(N_("{name}: {value!r} is not bytes as hex"), name=name, value=value))
    if not payload:
        raise ParamError(Message(N_("{name}: no bytes given (at least 1, at most {count}; ff ff ff ff ff ff is an "
                                    "empty record)"), name=name, count=RECORD_BYTES))
    if len(payload) > RECORD_BYTES:
        raise ParamError(Message(N_("{name}: a customer record holds {count} bytes, {given} given"), name=name,
                                 count=RECORD_BYTES, given=len(payload)))
    return codec.pad6(payload)


def record_raw(payload: bytes) -> int:
    return int.from_bytes(codec.pad6(payload), "big")


def record_bytes(raw: int) -> bytes:
    return int(raw).to_bytes(RECORD_BYTES, "big")


def record_text(raw: int) -> str:
    return record_bytes(raw).hex(" ")


def describe_sw1(sw1: int) -> str:
    """What SW1 sets, in words (5.8): ``0xCA: addressed mode, module address 10, 500 kbit/s, DigOut 0x20A``."""
    ids = codec.derive_ids(sw1)
    if ids.addressed:
        table = "S7 on" if sw1 & 0x40 else "S7 off"
        return (f"0x{sw1:02X}: addressed mode, module address {sw1 & 0x0F}, {ids.bitrate // 1000} kbit/s, "
                f"function IDs of {table}, DigOut 0x{ids.dig_out:03X}")
    return f"0x{sw1:02X}: offset {sw1 & 0x7F} (base 0x3A0 + 5 x offset), 500 kbit/s, DigOut 0x{ids.dig_out:03X}"


def _record(index: int) -> RecordParam:
    return RecordParam(
        f"Customer data {index}", CUSTOMER, index, Access.RW,
        description=Message(N_("Customer-data record {index}: 6 bytes the module stores (area 3 reads it, area 4 writes "
                               "it, section 7.2.4.2.3/4; addressed mode only). Fewer bytes are padded with ff; an "
                               "unwritten record reads ff ff ff ff ff ff. Every write is read back from the module's "
                               "answer."), index=index),
    )


def _words(size: int) -> int:
    return math.ceil(size / 2)


PARAMS = ParamMap([
    *(_record(i) for i in codec.CUSTOMER_RECORDS),
    ModuleParam("P2", CFG, P2_BIT, Access.RW, enum=P2_NAMES, default=0, confirm=P2_RISK, confirm_values=(1,),
                description=Message(N_("HMR only: the three-phase output SSR1-3 is loaded on two phases only (Sync cfg "
                                       "bit 7, section 4.3 and 7.2.4; firmware 17.0 and later). The module forgets it "
                                       "at any reset: this tool keeps it in the plant file (p2 = true) and sends it "
                                       "with every DigOut period; in addressed mode it is also written in area 1 "
                                       "index 15 and read back in area 2 index 15."))),
    ModuleParam("Serial number", CONFIG, codec.CONFIG_SERIAL, Access.RO, size=4, words=_words(4),
                description=Message(N_("Area 2 index 1 (7.2.4.2.2): 32 bits, shown with 8 digits. Addressed mode "
                                       "only."))),
    ModuleParam("Product code", CONFIG, codec.CONFIG_PRODUCT, Access.RO, size=2, words=1,
                description=Message(N_("Area 2 index 2 (7.2.4.2.2): the device; 0x3000 HM01, 0x3009 KM01, 0x300A HMR01 "
                                       "(from 08.11.2013). Checked against the plant file's variant. Addressed mode "
                                       "only."))),
    ModuleParam("Software version", CONFIG, codec.CONFIG_VERSION, Access.RO, size=2, words=1,
                # the assumption is worded in the catalog where app/device_words.py marks it (M3IO_ASSUMPTIONS)
                description=Message(N_("Area 2 index 3 (7.2.4.2.2); {assumption}. Addressed mode only."),
                                    assumption=Message(codec.VERSION_ASSUMPTION))),
    ModuleParam("Dynamic configuration", CONFIG, codec.CONFIG_DYNAMIC, Access.RO, size=1, words=1,
                fields=(Field("P2", P2_BIT, description=Message(N_("two-phase load"))),), device_updates=True,
                description=Message(N_("Area 2 index 15 (7.2.4.2.2): the cfg byte the module holds now (bit 7 P2); 0 "
                                       "after any reset until this tool sends P2 again. Addressed mode only."))),
    ModuleParam("SW1", ADDRESSING, 0, Access.R,
                description=Message(N_("The DIP switch SW1 (section 5.8) as the plant file gives it: S8 off, base 0x3A0 "
                                       "+ 5 x S7..S1 at 500 kbit/s; S8 on, addressed mode: S7 the function-ID table, S6 "
                                       "1 Mbit/s, S4..S1 the module address. Set on the module itself, never over the "
                                       "bus."))),
])

P2_PARAM = PARAMS.get(CFG, P2_BIT)
SW1_PARAM = PARAMS.get(ADDRESSING, 0)
CONFIG_PARAMS = tuple(PARAMS.space(CONFIG))
RECORD_PARAMS = tuple(PARAMS.space(CUSTOMER))


def record_param(index: int) -> RecordParam:
    param = PARAMS.get(CUSTOMER, index)
    if param is None:
        raise ParamError(Message(N_("customer record {index} is outside 1..15"), index=index))
    return param
