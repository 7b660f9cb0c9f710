"""CAN-M3IO I/O module (KM, HM, HMR): IDs from SW1, DigOut/DigIn, temperatures with SSR
status bits, SYNC and addressed data. Pure: no I/O. Sections refer to the M3IO document.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from devices import errors
from devices.message import Message, N_, Word


class CodecError(errors.CodecError):
    """A frame or value that cannot be encoded or decoded."""


class Variant(str, Enum):
    KM = "KM"  # no power part: no SSR, no Pt100 (section 4.1)
    HM = "HM"  # six single SSR outputs (4.2)
    HMR = "HMR"  # SSR1-3 one three-phase output (4.3)


WATCHDOG_S = 2.0  # section 7.1
DIGOUT_PERIOD_S = 0.1  # while controlled: the 2 s watchdog (7.1) with room, and a lapsed lease stops outputs within 0.5 s
TEMP_PERIOD_S = 0.5  # section 7.2.2
DIGIN_MIN_INTERVAL_S = 0.010  # section 7.2.1


# -- identifiers (section 5.8) ----------------------------------------------------------------


@dataclass(frozen=True)
class CanIds:
    dig_out: int
    dig_in: int
    temp14: int
    temp56: int
    sync: int
    mdata: int | None  # addressed mode only
    bitrate: int
    addressed: bool

    def by_name(self) -> dict[str, int]:
        names = {"DigOut": self.dig_out, "DigIn": self.dig_in, "Temp1-4": self.temp14, "Temp5-6": self.temp56, "Sync": self.sync}
        if self.mdata is not None:
            names["MData"] = self.mdata
        return names


# section 5.8.2: function IDs by S7 (ON, OFF)
FUNCTION_IDS = {
    True: {"dig_out": 0x200, "dig_in": 0x180, "temp14": 0x380, "temp56": 0x480, "sync": 0x240, "mdata": 0x1C0},
    False: {"dig_out": 0x180, "dig_in": 0x200, "temp14": 0x380, "temp56": 0x400, "sync": 0x680, "mdata": 0x700},
}


def derive_ids(sw1: int) -> CanIds:
    """CAN IDs and bit rate from DIP switch SW1 (S8 = bit 7 ... S1 = bit 0)."""
    if not 0 <= sw1 <= 0xFF:
        raise CodecError(f"SW1 {sw1} is not an 8-bit switch value")
    if not sw1 & 0x80:  # 5.8.1: 500 kbit/s, base 0x3A0 + 5 * (S7..S1)
        base = 0x3A0 + 5 * (sw1 & 0x7F)
        return CanIds(base, base + 1, base + 2, base + 3, base + 4, None, 500_000, False)
    table = FUNCTION_IDS[bool(sw1 & 0x40)]  # S7
    address = sw1 & 0x0F  # S4..S1
    bitrate = 1_000_000 if sw1 & 0x20 else 500_000  # S6
    return CanIds(*(table[k] + address for k in ("dig_out", "dig_in", "temp14", "temp56", "sync", "mdata")), bitrate, True)


# -- outputs (section 7.2.1) -------------------------------------------------------------------

REQ = 0x80  # obsolete DigIn request bit (since V16.0 DigIn always answers)
OUTPUT_BITS: dict[Variant, dict[str, int]] = {
    Variant.HM: {"LED": 0, "SSR1": 1, "SSR2": 2, "SSR3": 3, "SSR4": 4, "SSR5": 5, "SSR6": 6},
    Variant.HMR: {"LED": 0, "SSR1-3": 1, "SSR4": 2, "SSR5": 3, "SSR6": 4},
    Variant.KM: {"LED": 0},
}


def encode_dig_out(variant: Variant, outputs: dict[str, bool]) -> bytes:
    bits = OUTPUT_BITS[variant]
    unknown = set(outputs) - set(bits)
    if unknown:
        raise CodecError(f"{variant.value} has no output {', '.join(sorted(unknown))}")
    value = 0
    for name, on in outputs.items():
        if on:
            value |= 1 << bits[name]
    return bytes([value])


def decode_dig_out(variant: Variant, data: bytes) -> dict[str, bool]:
    if len(data) != 1:
        raise CodecError(f"DigOut has 1 byte, got {len(data)}")
    return {name: bool(data[0] >> bit & 1) for name, bit in OUTPUT_BITS[variant].items()}


def decode_dig_in(data: bytes) -> dict[str, bool]:
    """E1..E6 in bits 0-5 (bits 6-7 read 1)."""
    if len(data) != 1:
        raise CodecError(f"DigIn has 1 byte, got {len(data)}")
    return {f"E{i + 1}": bool(data[0] >> i & 1) for i in range(6)}


def encode_dig_in(inputs: dict[str, bool]) -> bytes:
    return bytes([0xC0 | sum(1 << i for i in range(6) if inputs.get(f"E{i + 1}"))])


# -- temperatures and SSR status (sections 7.2.2, 7.2.3) ---------------------------------------

TEMP_MIN_RAW, TEMP_MAX_RAW = 0, 2000


@dataclass(frozen=True)
class TempWord:
    """One temperature word: 12-bit two's complement value (bits 0-11, bit 11 = vz), sb, Last, Triac, Si."""

    raw: int

    @property
    def value_raw(self) -> int:
        v = self.raw & 0x0FFF
        return v - 0x1000 if v & 0x0800 else v

    @property
    def celsius(self) -> float:
        return self.value_raw / 10

    @property
    def in_range(self) -> bool:
        """Readings below 0 or above 200.0 C mean "out of measuring range" (7.2.2)."""
        return TEMP_MIN_RAW <= self.value_raw <= TEMP_MAX_RAW

    @property
    def vz(self) -> bool:
        return bool(self.raw & 0x0800)

    @property
    def sb(self) -> bool:
        return bool(self.raw & 0x1000)

    @property
    def load(self) -> bool:
        return bool(self.raw & 0x2000)

    @property
    def triac(self) -> bool:
        return bool(self.raw & 0x4000)

    @property
    def fuse(self) -> bool:
        return bool(self.raw & 0x8000)

    @classmethod
    def make(cls, tenths: int, load: bool, triac: bool, fuse: bool, addressed: bool) -> TempWord:
        if not -0x800 <= tenths <= 0x7FF:
            raise CodecError(f"temperature {tenths / 10} C does not fit 12 bits")
        value = tenths & 0x0FFF
        vz = bool(value & 0x0800)
        sb = True if addressed else vz  # 7.2.3: sb = 1 in addressed mode, = vz otherwise
        return cls(value | sb << 12 | load << 13 | triac << 14 | fuse << 15)

    def text(self) -> str:
        return f"{self.celsius:.1f} °C" if self.in_range else f"out of range ({self.celsius:.1f})"


def decode_temps(data: bytes, expected: int) -> list[TempWord]:
    if len(data) != 2 * expected:
        raise CodecError(f"temperature frame needs {2 * expected} bytes, got {len(data)}")
    return [TempWord(int.from_bytes(data[i:i + 2], "little")) for i in range(0, len(data), 2)]


def encode_temps(words: list[TempWord]) -> bytes:
    return b"".join(w.raw.to_bytes(2, "little") for w in words)


# section 5.5: channel -> (fuse, rating HMR, rating HM)
FUSES = {1: ("SI3", "16 A", "10 A"), 2: ("SI4", "16 A", "10 A"), 3: ("SI5", "16 A", "10 A"),
         4: ("SI6", "10 A", "10 A"), 5: ("SI7", "10 A", "10 A"), 6: ("SI8", "10 A", "10 A")}


def fuse_advice(variant: Variant, channel: int) -> str:
    fuse, hmr, hm = FUSES[channel]
    return f"replace fuse {fuse} ({hmr if variant is Variant.HMR else hm}, fast-acting 5x20 mm)"


NO_LOAD_TEXT = "none (no load, no supply, or a triac with a permanent short circuit)"  # Last = 0 (7.2.3)


@dataclass
class ChannelMonitor:
    """Evaluation of Last/Si/Triac of one SSR as section 7.2.3 asks.

    With no load (Last = 0) fuse and triac say nothing ("unknown"). After the first
    switch-on all three bits read 1: remember it, since a blown fuse can take Last to 0
    too. A blown fuse (Si = 0) stays in the module until its 24 V are cut, so the module
    reporting Si = 1 with a load again means it was reset: the fault is cleared then, and
    :attr:`cleared` says so for the one update that cleared it.
    """

    seen_ok: bool = False
    fuse_blown: bool = False
    load: str = "unknown"
    fuse: str = "unknown"
    triac: str = "unknown"
    cleared: str | None = None

    def update(self, word: TempWord, switched_on: bool) -> None:
        self.cleared = None
        if self.fuse_blown and word.fuse and word.load:
            # 7.2.3: only cutting the 24 V resets Si = 0 in the module, so it was reset: follow it
            self.fuse_blown = self.seen_ok = False
            self.cleared = Message(N_("the module was reset (24 V cut) and reports its fuse ok with a load again (Si = 1, "
                                      "Last = 1)"))
        if switched_on and word.load and word.fuse and word.triac:
            self.seen_ok = True
        if not word.fuse and (word.load or self.seen_ok):
            self.fuse_blown = True  # latched as in the module, which keeps Si = 0 until 24 V are cut
        self.load = "present" if word.load else NO_LOAD_TEXT
        if self.fuse_blown:
            self.fuse = "blown"
        elif word.load:
            self.fuse = "ok"
        else:
            self.fuse = "unknown"
        if not word.load or self.fuse_blown:
            self.triac = "unknown"
        elif switched_on:
            self.triac = "ok" if word.triac else "defective"
        else:
            self.triac = "not checked (off)"


# -- SYNC and addressed data (section 7.2.4) ------------------------------------------------------

P2 = 0x80  # cfg bit 7: HMR three-phase output loaded on two phases only


def encode_sync_cfg(two_phase: bool) -> bytes:
    return bytes([P2 if two_phase else 0])


def cfg_with_dig_out(two_phase: bool) -> bytes | None:
    """The Sync cfg to send (before) every DigOut, or None when the default (0) will do.

    7.2.4: cfg is not stored and is lost at any reset; a reset shorter than one DigOut period
    shows nothing on the bus, so P2 is repeated every DigOut period rather than after a silence.
    """
    return encode_sync_cfg(True) if two_phase else None


AREA_WRITE_CONFIG, AREA_READ_CONFIG, AREA_READ_CUSTOMER, AREA_WRITE_CUSTOMER, AREA_LOAD_DATA = 1, 2, 3, 4, 5
CONFIG_SERIAL, CONFIG_PRODUCT, CONFIG_VERSION, CONFIG_DYNAMIC = 1, 2, 3, 15
CUSTOMER_RECORDS = range(1, 16)
PRODUCT_CODES = {
    0x0000: "MIO", 0x1000: "New KKD01", 0x2000: "KKD01", 0x2001: "KKD02", 0x2002: "ABB KKD01", 0x2003: "ABB KKD02",
    0x3000: "HM01", 0x3001: "KM01 (until 07.11.2013)", 0x3002: "HMR01 (until 07.11.2013)",
    0x3009: "KM01 (from 08.11.2013)", 0x300A: "HMR01 (from 08.11.2013)",
}


# 7.2.4.2.2 and 5.6: the product codes that are CAN-M3IO variants (the others are other modules)
PRODUCT_VARIANTS = {0x3000: Variant.HM, 0x3001: Variant.KM, 0x3002: Variant.HMR, 0x3009: Variant.KM, 0x300A: Variant.HMR}


def encode_u16(value: int) -> bytes:
    """A 2-byte value in a payload, low byte first: 0x1234 -> 34 12 (7.2.4.2)."""
    if not 0 <= value <= 0xFFFF:
        raise CodecError(f"{value} does not fit 16 bits")
    return value.to_bytes(2, "little")


# The one place where the software version's decoding is stated: the document gives index 3 of area 2 as
# "SW version" (7.2.4.2.2) without its format. Read as high byte . low byte (0x1201 -> "18.1"), which the
# documents' firmware numbers (V16.0 in 7.2.1) fit; an assumption, and shown as one wherever it is shown.
VERSION_ASSUMPTION = "the document names the SW version word without its format; read as high byte . low byte (0x1201 = 18.1)"


def decode_version(raw: int) -> str:
    """Area 2 index 3 (SW version) as assumed (:data:`VERSION_ASSUMPTION`): ``0x1201`` -> ``"18.1"``."""
    return f"{raw >> 8}.{raw & 0xFF}"


def decode_u16(payload: bytes) -> int:
    if len(payload) < 2:
        raise CodecError(f"a 16-bit value needs 2 bytes, got {len(payload)}")
    return int.from_bytes(payload[:2], "little")


def encode_sync_request(area: int, index: int, payload: bytes = b"") -> bytes:
    if len(payload) > 6:
        raise CodecError(f"addressed data carries up to 6 bytes, got {len(payload)}")
    return bytes([area, index]) + payload


def pad6(payload: bytes) -> bytes:
    """MData and stored records are 0xFF-padded to 6 bytes (7.2.4.2)."""
    return (payload + b"\xff" * 6)[:6]


@dataclass(frozen=True)
class MData:
    area: int
    index: int
    payload: bytes  # always 6 bytes

    @classmethod
    def decode(cls, data: bytes) -> MData:
        if len(data) != 8:
            raise CodecError(f"MData has 8 bytes, got {len(data)}")
        return cls(data[0], data[1], bytes(data[2:8]))

    def encode(self) -> bytes:
        return bytes([self.area, self.index]) + pad6(self.payload)


def encode_serial(serial: int) -> bytes:
    """Serial number as uint32 LE: 00033852 -> 0x843C (7.2.4.2.2)."""
    if not 0 <= serial <= 99_999_999:
        raise CodecError(f"serial number {serial} has more than 8 digits")
    return serial.to_bytes(4, "little")


def decode_serial(payload: bytes) -> str:
    return f"{int.from_bytes(payload[:4], 'little'):08d}"


P_PRODUCT = "Product"  # the live point of the product's name (devices/m3io/adapter.py), the catalogs' context of the names


def product_name(code: int) -> str:
    """The product's name (7.2.4.2.2), a word of the point ``Product`` that pages word in the document's words ("HMR01 ab
    08.11.2013"); the English as before."""
    name = PRODUCT_CODES.get(code)
    return f"unknown product 0x{code:04X}" if name is None else Word(name, P_PRODUCT)


def product_variant(code: int) -> Variant | None:
    return PRODUCT_VARIANTS.get(code)


@dataclass(frozen=True)
class VariantCheck:
    """The plant file's variant against the module's product code."""

    state: str  # "ok", "mismatch", "unchecked" (not read yet), "not possible" (simple mode)
    text: str  # a :class:`~devices.message.Message`, worded in the reader's language where it is shown
    may_switch: bool  # outputs may be switched on


def check_variant(variant: Variant, addressed: bool, code: int | None) -> VariantCheck:
    """HM and HMR put different SSRs on the same DigOut bits (7.2.1): in addressed mode, outputs
    are switched on only once the product code (7.2.4.2.2) matched the plant file's variant."""
    if not addressed:
        return VariantCheck(
            "not possible",
            Message(N_("The variant cannot be checked: with SW1 switch 8 off the module does not report its product code. "
                       'Make sure the module is the variant the plant file names (variant = "{variant}"): '
                       "HM and HMR switch different SSRs with the same DigOut bits."), variant=variant.value),
            True,
        )
    if code is None:
        return VariantCheck("unchecked", Message(N_("The product code has not been read yet: outputs stay off until it "
                                                    "matches the plant file.")), False)
    reported = product_variant(code)
    name = Message("0x{code} {product}", code=f"{code:04X}", product=product_name(code))
    if reported is variant:
        return VariantCheck("ok", Message(N_("The module reports {name}: variant {variant} as in the plant file."),
                                          name=name, variant=variant.value), True)
    if reported is None:
        return VariantCheck(
            "mismatch",
            Message(N_('The module reports {name}, which is no CAN-M3IO (KM, HM, HMR), but the plant file says variant = '
                       '"{variant}": check that SW1 addresses the right module; outputs are refused.'),
                    name=name, variant=variant.value),
            False,
        )
    return VariantCheck(
        "mismatch",
        Message(N_('The module reports {name}, i.e. variant {reported}, but the plant file says variant = "{variant}": '
                   'change it to variant = "{reported}" in the plant file (or fit the right module); outputs are refused.'),
                name=name, reported=reported.value, variant=variant.value),
        False,
    )


def temp_input(variant: Variant, word_number: int) -> int:
    """The Pt100 input a temperature word carries: HMR t1-t3 all carry TEMP1 (7.2.2), else TEMP<n>."""
    return 1 if variant is Variant.HMR and word_number <= 3 else word_number


def describe_temp(variant: Variant, word_number: int, word: TempWord) -> str:
    """One temperature word for the bus monitor: the reading (or "out of range", 7.2.2) and the
    status bits of SSR<n> named as section 7.2.3 names them; with Last = 0, Si and Triac mean nothing."""
    temp = f"TEMP{temp_input(variant, word_number)}"
    reading = Message(_READING if word.in_range else _OUT_OF_RANGE, temp=temp, value=word.celsius)
    status = _STATUS[(bool(word.fuse), bool(word.triac))] if word.load else _NO_LOAD
    return Message("{reading} · SSR{n} {status}", reading=reading, n=word_number, status=status)


# the bus monitor's words of a temperature word (7.2.2, 7.2.3: Si, Triac, Last), Messages the page words
_READING = "{temp} {value:.1f} °C"
_OUT_OF_RANGE = N_("{temp} out of range ({value:.1f} °C)")
_NO_LOAD = Message(N_("no load: fuse, triac unknown"))
_LOAD = N_("load, fuse {fuse}, triac {triac}")
_FUSE = {True: Message(N_("ok")), False: Message(N_("blown"))}
_TRIAC = {True: Message(N_("ok")), False: Message(N_("not conducting"))}
_STATUS = {(fuse, triac): Message(_LOAD, fuse=_FUSE[fuse], triac=_TRIAC[triac]) for fuse in (True, False)
           for triac in (True, False)}  # made once: the monitor words every temperature frame


SYNC_AREAS = {  # the DBC's value table too (devices/m3io/dbc.py): plain texts, worded where the monitor shows them
    AREA_WRITE_CONFIG: N_("write config"), AREA_READ_CONFIG: N_("read config"), AREA_READ_CUSTOMER: N_("read customer data"),
    AREA_WRITE_CUSTOMER: N_("write customer data"), AREA_LOAD_DATA: N_("load data"),
}
CONFIG_NAMES = {CONFIG_SERIAL: N_("serial number"), CONFIG_PRODUCT: N_("product code"), CONFIG_VERSION: N_("SW version"),
                CONFIG_DYNAMIC: N_("dyn. configuration")}


def _record_name(area: int, index: int) -> str:
    """``read config serial number``, ``load data SSR3``, ``write customer data 7`` (7.2.4.2), a :class:`Message`."""
    name = Message(SYNC_AREAS[area]) if area in SYNC_AREAS else Message(N_("area {area}"), area=area)
    if area in (AREA_WRITE_CONFIG, AREA_READ_CONFIG):
        item = Message(CONFIG_NAMES[index]) if index in CONFIG_NAMES else Message(N_("index {index}"), index=index)
        return Message("{name} {item}", name=name, item=item)
    if area == AREA_LOAD_DATA:
        return Message("{name} SSR{index}", name=name, index=index)
    return Message("{name} {index}", name=name, index=index)


_CFG = {True: N_("cfg 0x{cfg:02X} (P2 {p2}: two-phase load)"), False: N_("cfg 0x{cfg:02X} (P2 {p2}: three-phase load)")}


def _describe_cfg(cfg: int) -> str:
    return Message(_CFG[bool(cfg & P2)], cfg=cfg, p2=int(bool(cfg & P2)))


def describe_mdata(variant: Variant, m: MData) -> str:
    """An addressed-data answer with its value decoded (7.2.4.2.x), else its bytes."""
    name = _record_name(m.area, m.index)
    if m.area == AREA_READ_CONFIG and m.index == CONFIG_SERIAL:
        value = decode_serial(m.payload)
    elif m.area == AREA_READ_CONFIG and m.index == CONFIG_PRODUCT:
        code = decode_u16(m.payload)
        value = Message("0x{code:04X} {product}", code=code, product=product_name(code))
    elif m.area == AREA_READ_CONFIG and m.index == CONFIG_VERSION:
        value = str(decode_u16(m.payload))
    elif m.area in (AREA_WRITE_CONFIG, AREA_READ_CONFIG) and m.index == CONFIG_DYNAMIC:
        value = _describe_cfg(m.payload[0])
    elif m.area == AREA_LOAD_DATA and 1 <= m.index <= 6:
        value = describe_temp(variant, m.index, TempWord(decode_u16(m.payload)))
    else:
        value = m.payload.hex(" ")
    return Message("{name}: {value}", name=name, value=value)


_TEMPS = {n: "M3IO " + "; ".join("{t%d}" % i for i in range(n)) for n in range(7)}
_ALL_OFF = Message(N_("all off"))
_NO_INPUT = Message(N_("no input"))


def describe_frame_for(ids: CanIds, variant: Variant, arbitration_id: int, data: bytes) -> str | None:
    """Bus monitor: the meaning of a frame on one module's IDs, with the document's names, else None."""
    try:
        if arbitration_id == ids.dig_out:
            on = [k for k, v in decode_dig_out(variant, data).items() if v]
            return Message("M3IO DigOut: {outputs}", outputs=", ".join(on) if on else _ALL_OFF)
        if arbitration_id == ids.dig_in:
            on = [k for k, v in decode_dig_in(data).items() if v]
            return Message("M3IO DigIn: {inputs}", inputs=", ".join(on) if on else _NO_INPUT)
        if arbitration_id in (ids.temp14, ids.temp56):
            words = decode_temps(data, 4 if arbitration_id == ids.temp14 else 2)
            first = 1 if arbitration_id == ids.temp14 else 5
            temps = {f"t{i}": describe_temp(variant, first + i, w) for i, w in enumerate(words)}  # one Message per frame
            return Message(_TEMPS[len(temps)], **temps)
        if arbitration_id == ids.sync:
            if len(data) <= 1:
                return Message("M3IO Sync {cfg}", cfg=_describe_cfg(data[0])) if data else "M3IO Sync"
            if ids.addressed:
                if len(data) > 2:
                    return Message(N_("M3IO Sync {record} data {bytes}"), record=_record_name(data[0], data[1]),
                                   bytes=bytes(data[2:]).hex(" "))
                return Message("M3IO Sync {record}", record=_record_name(data[0], data[1]))
            return f"M3IO Sync {bytes(data).hex(' ')}"
        if ids.mdata is not None and arbitration_id == ids.mdata:
            return Message("M3IO MData {text}", text=describe_mdata(variant, MData.decode(data)))
    except CodecError as exc:
        return Message(N_("M3IO, malformed: {error}"), error=str(exc))
    return None
