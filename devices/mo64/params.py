"""The MO 64's settings as a declared parameter model (document 003, chapters 5.1 and 5.2).

Pure: no I/O. The barrier keeps its settings in the EEPROM as whole telegram values (a 16-bit time,
the four 16-bit configuration words konfig0 .. konfig3 in one 64-bit setting, the six relay modes in
one 48-bit setting, chapter 5.2.4-5.2.8). Each :class:`Mo64Param` is one named piece of such a value:

- ``space`` is the setting's key in :data:`devices.mo64.codec.SETTINGS` (or, for a value no setting
  telegram writes, the name of the answer it is read from), ``address`` the bit offset of the piece in
  the value read low byte first (the document names every field ``_lo`` before ``_hi``): konfig2 bit 11
  is ``config_flags:43``, multi3 is ``multi_relays:16``;
- ``query`` is the query index whose answer carries it (chapter 5.2.2, table 21), ``width`` its bits;
- ``assumed`` says why a selector or a bit position is an assumption (the page summary does not print
  it); an assumed selector is written only once the engineer confirmed it is verified on the unit.

A write of one piece is a read-modify-write of its setting: the setting is read from the unit, the
piece replaced, the whole value written (syn, EEPROM, ack) and read back (devices/mo64/settings.py);
bits the summary does not name keep what the unit holds.

Flags that switch a safety function off (Kraftüberwachung "ohne", LS-Test off, the loop and light-barrier
modes "Stopp") carry a confirmation that names the function, asked on every path (page, restore, batch,
the raw telegram of a bus tool: :func:`safety_questions`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from devices.message import Message, N_
from devices.mo64 import codec
from devices.params import Access, Field, Param, ParamMap


@dataclass(frozen=True)
class Mo64Param(Param):
    """One named piece of an MO 64 setting: ``width`` bits at bit ``address`` of the value of answer ``query``.

    :param setting: the key of the setting telegram that writes it (``codec.SETTINGS``); "" when no setting
        telegram is named for it (read only)
    :param names: what known values mean, shown beside the number without limiting what may be written
        (the summary names only some relay modes)
    :param assumed: why its selector or bit position is an assumption ("" when the document prints it)
    """

    query: int = 0
    width: int = 16
    setting_key: str = ""
    names: Mapping[int, str] | None = None
    assumed: str = ""

    @property
    def bits(self) -> int:
        return self.width

    @property
    def writable(self) -> bool:
        # one telegram carries the whole value, however many 16-bit words it spans
        return self.access is Access.RW and not self.never_write

    @property
    def answer_type(self) -> int:
        return self.query + codec.QUERY_ANSWER_OFFSET  # SPEC-NOTES "Replies": index n answered by type n + 5

    @property
    def mask(self) -> int:
        return (1 << self.width) - 1

    @property
    def selector_assumed(self) -> bool:
        """The setting's selector is an assumption (codec ``Setting.assumed``): verified on the unit first."""
        return bool(self.setting_key) and bool(codec.SETTINGS[self.setting_key].assumed)

    def display(self, raw: int) -> str:
        if self.names is not None and self.enum is None:
            value = int(self.decode(raw))
            name = self.names.get(value)
            return f"{name} ({value})" if name else f"mode {value} (not named in the summary)"
        if self.scale != 1:
            return f"{self.decode(raw):g} {self.unit}"  # 12.5 s, 10 s (not 10.0 s)
        return super().display(raw)


CONFIG = "config_flags"
MULTI = "multi_relays"
KONFIG_BITS = 16  # chapter 5.1.24: four 16-bit parameters konfig0 .. konfig3
# chapter 5.1.24, table 15 / 16 print no bit numbers for these: the fields follow the printed 9, 8 in the printed
# order, each as wide as its printed choices need (two choices one bit, three two bits) - SPEC-NOTES "MO 64"
ASSUMED_POSITION = Message(N_("bit position not printed in the summary: packed after the printed bits in the printed "
                               "order, as wide as its printed choices need"))

KRAFT_RISK = Message(N_("Kraftüberwachung (force monitoring) = ohne switches the force monitoring off: the boom no longer "
                        "stops or reverses when it meets a person or a vehicle. Confirm only where another protection "
                        "covers the closing edge."))
LS_TEST_RISK = Message(N_("LS-Test off switches the light-barrier test off: a failed light barrier is no longer found before "
                          "the boom closes, and the boom may close onto a person it does not see."))
LOOP_SAFETY_RISK = Message(N_("Induktionsschleifen-Sichern-Modus = Stopp weakens the loop safety mode: a vehicle on the "
                              "safety loop only stops the closing boom above it, the boom no longer opens again."))
LS_MODE_RISK = Message(N_("Lichtschranken-Modus = Stopp weakens the light barrier's reaction: an interrupted light barrier "
                          "only stops the closing boom above the person, it no longer opens again."))
BLINK = Message(N_("2-bit field; the summary names the lamp and the event, not what each value does"))


def _time(name: str, key: str, query: int, description: str) -> Mo64Param:
    setting = codec.SETTINGS[key]
    return Mo64Param(name, key, 0, Access.RW, unit="s", scale=codec.TIME_STEP_S, minimum=0,
                     maximum=round(codec.TIME_MAX * codec.TIME_STEP_S, 2), description=description,
                     query=query, width=16, setting_key=key, assumed=setting.assumed or "")


def _konfig(word: int, shift: int, name: str, description: str, *, width: int = 2, enum=None, assumed: str = "",
            confirm: str = "", confirm_values: tuple[int, ...] = ()) -> Mo64Param:
    where = (Message(N_("konfig{word} bits {high}, {low}"), word=word, high=shift + width - 1, low=shift) if width > 1
             else Message(N_("konfig{word} bit {bit}"), word=word, bit=shift))
    if assumed:
        described = Message(N_("{description} ({where}, assumed; chapter 5.1.24)"), description=description, where=where)
    else:
        described = Message(N_("{description} ({where}; chapter 5.1.24)"), description=description, where=where)
    return Mo64Param(name, CONFIG, KONFIG_BITS * word + shift, Access.RW, enum=enum, confirm=confirm,
                     confirm_values=confirm_values, description=described,
                     query=codec.Q_CONFIG_FLAGS, width=width, setting_key=CONFIG, assumed=assumed)


ON_OFF = {0: "aus", 1: "ein"}
STOP_OPEN = {0: "Stopp und öffnen", 1: "Stopp"}

PARAMS = ParamMap([
    # -- times (chapter 5.1.13-5.1.15, 5.2.4.1) ----------------------------------------------------------------
    _time("t_offen", "t_open", codec.Q_T_OPEN,
          Message(N_("Open time (Offenhaltezeit) in multiples of 10 ms; 0 switches automatic closing off (chapter "
                     "5.2.4.1)."))),
    _time("Pre-warning before opening", "t_prewarn_open", codec.Q_T_PREWARN_OPEN,
          Message(N_("Pre-warning time before the boom opens, in multiples of 10 ms (answer 0x0E; setting selector 0x04 "
                     "0x01 assumed)."))),
    _time("Pre-warning before closing", "t_prewarn_close", codec.Q_T_PREWARN_CLOSE,
          Message(N_("Pre-warning time before the boom closes, in multiples of 10 ms (answer 0x0F; setting selector 0x04 "
                     "0x02 assumed)."))),
    # -- change monitoring (chapter 5.1.9, 5.2.4.5) and, below, the status mask (5.1.8, 5.2.6.1) ----------------------------------
    Mo64Param("Change monitoring", "change_monitoring", 0, Access.RW,
              fields=tuple(Field(f.name, f.shift) for f in codec.CHANGE_MONITORING.fields),
              description=Message(N_("Flaggen: which telegrams the barrier sends by itself on a change over TCP "
                                     "(chapter 5.1.9; bit 0 barrier status, 1 service counter, 2 maintenance counter, 3 "
                                     "gate state, 4 error memory, 5 vehicle counter, 6 barrier position, 7 motor status, "
                                     "8 loop debug).")),
              query=codec.Q_CHANGE_MONITORING, width=16, setting_key="change_monitoring", maximum=0x01FF),
    # -- maintenance interval, vehicle counter (chapter 5.1.26, 5.2.5) -----------------------------------------------
    Mo64Param("Maintenance interval", "maintenance_interval", 0, Access.RW, words=2,
              description=Message(N_("Openings until maintenance is due (SERVICE). Setting selector 0x05 0x01 and the "
                                     "32-bit width are assumed (not in the summary).")),
              query=codec.Q_MAINTENANCE_INTERVAL, width=32, setting_key="maintenance_interval",
              assumed=codec.SETTINGS["maintenance_interval"].assumed or ""),
    Mo64Param("Vehicle counter", "vehicle_counter", 0, Access.RW, words=2, signed=True, device_updates=True,
              description=Message(N_("Signed 32-bit counter of the vehicles the direction logic counts; RAM only, 0 "
                                     "after power-up (chapter 5.2.5). Counted by the barrier: never part of a set, never "
                                     "drift.")),
              query=codec.Q_VEHICLE_COUNTER, width=32, setting_key="vehicle_counter",
              assumed=codec.SETTINGS["vehicle_counter"].assumed or ""),
    Mo64Param("Status mask", "status_mask", 0, Access.RW, words=3,
              fields=tuple(Field(f.name, f.shift) for f in codec.STATUS_BITS.fields),
              description=Message(N_("Maske0 .. Maske4: the barrier-status bits whose change is reported over TCP "
                                     "(chapter 5.2.6.1; factory setting 0, page 18). Bit n is status bit n (Status0 bit "
                                     "0 = bit 0).")),
              query=codec.Q_STATUS_MASK, width=40, setting_key="status_mask"),
    # -- multi relays (chapter 5.1.25, 5.2.7.1) -------------------------------------------------------------------
    *(Mo64Param(f"multi{n}", MULTI, 8 * (n - 1), Access.RW, maximum=255,
                description=Message(N_("Operating mode of multi relay {n} (chapter 5.1.25): 0 the relay is "
                                       "deactivated, 1 fault (Störung: on while an error flag is set); the other modes "
                                       "(loop occupied, loop free, pulses) are named in the summary without their "
                                       "numbers."), n=n),
                query=codec.Q_MULTI_RELAYS, width=8, setting_key=MULTI, names=codec.MULTI_MODE_NAMES)
      for n in range(1, 7)),
    # -- configuration flags (chapter 5.1.24, tables 13-16; setting 0x08 0x00, chapter 5.2.8.1) ----------------------
    _konfig(0, 0, "RtApl in Endlage blinken", Message(N_("Red light blinks in the end position; {blink}"), blink=BLINK)),
    _konfig(0, 2, "RtApl bei Vorwarnung vor dem Öffnen blinken", Message(N_("Red light blinks at the pre-warning before opening; {blink}"), blink=BLINK)),
    _konfig(1, 0, "GnApl bei Vorwarnung vor dem Öffnen blinken", Message(N_("Green light blinks at the pre-warning before opening; {blink}"), blink=BLINK)),
    _konfig(1, 2, "GnApl bei Vorwarnung vor dem Schließen blinken", Message(N_("Green light blinks at the pre-warning before closing; {blink}"), blink=BLINK)),
    _konfig(1, 4, "GnApl beim Öffnen blinken", Message(N_("Green light blinks while the boom opens; {blink}"), blink=BLINK)),
    _konfig(1, 6, "GnApl beim Schließen blinken", Message(N_("Green light blinks while the boom closes; {blink}"), blink=BLINK)),
    _konfig(1, 8, "GnApl bei Zwischenstopp blinken", Message(N_("Green light blinks at an intermediate stop; {blink}"), blink=BLINK)),
    _konfig(1, 10, "GnApl in Endlage AUF blinken", Message(N_("Green light blinks in the end position open; {blink}"), blink=BLINK),
            assumed=Message(N_("printed after bits 9, 8 without its own numbers: taken as bits 11, 10"))),
    _konfig(2, 6, "Warnlicht in Endlage ZU blinken", Message(N_("Warning light blinks in the end position closed; {blink}"), blink=BLINK),
            assumed=Message(N_("printed directly before bits 9, 8 without its own numbers: taken as bits 7, 6"))),
    _konfig(2, 8, "Warnlicht in Endlage AUF blinken", Message(N_("Warning light blinks in the end position open; {blink}"), blink=BLINK)),
    _konfig(2, 10, "BT-Kombi-Auswahl", Message(N_("Which input the BT combination uses: BTA3 or BTZ1B")), width=1,
            enum={0: "BTA3", 1: "BTZ1B"}, assumed=ASSUMED_POSITION),
    _konfig(2, 11, "Kraftüberwachung", Message(N_("Force monitoring: ohne (off), Stopp und öffnen (stop and open "
                                                  "again), Stopp (stop); 'ohne' asks first, naming it")), width=2,
            enum={0: "ohne", 1: "Stopp und öffnen", 2: "Stopp"}, assumed=ASSUMED_POSITION,
            confirm=KRAFT_RISK, confirm_values=(0,)),
    _konfig(2, 13, "Lichtschranken-Modus", Message(N_("What an interrupted light barrier does to a closing boom: "
                                                      "Stopp und öffnen or Stopp; 'Stopp' asks first, naming it")), width=1, enum=STOP_OPEN, assumed=ASSUMED_POSITION,
            confirm=LS_MODE_RISK, confirm_values=(1,)),
    _konfig(2, 14, "Lichtschranken-Schließautomatik", Message(N_("The boom closes by itself once the light barrier is "
                                                                 "free again")), width=1, enum=ON_OFF, assumed=ASSUMED_POSITION),
    _konfig(3, 0, "LS-Test", Message(N_("Light-barrier test before the boom closes; off asks first, naming it")), width=1,
            enum=ON_OFF, assumed=ASSUMED_POSITION, confirm=LS_TEST_RISK, confirm_values=(0,)),
    _konfig(3, 1, "Induktionsschleifen-Sichern-Modus", Message(N_("Loop safety mode: what a vehicle on the safety loop "
                                                                  "does to a closing boom: Stopp und öffnen or Stopp; "
                                                                  "'Stopp' asks first, naming it")), width=1, enum=STOP_OPEN,
            assumed=ASSUMED_POSITION, confirm=LOOP_SAFETY_RISK, confirm_values=(1,)),
    _konfig(3, 2, "Sofort Schließen", Message(N_("The boom closes at once after a vehicle passed (not after the open "
                                                 "time)")),
            width=1, enum=ON_OFF, assumed=ASSUMED_POSITION),
    # -- read only: no setting telegram is named for these (chapter 5.2) ------------------------------------------
    *(Mo64Param(f"schleife_{c.lower()}", "induction_loops", 16 * n, Access.R,
                fields=(Field("eingeschaltet", 0, description=Message(N_("0 loop switched off, 1 switched on (first row "
                                                                         "of 5.1.18)"))),),
                description=Message(N_("Operating mode of induction loop {loop} (chapter 5.1.18, one 16-bit register; "
                                       "bit 0: loop switched off / on). No setting telegram is named for it: read only."),
                                    loop=c),
                query=codec.Q_INDUCTION_LOOPS, width=16)
      for n, c in enumerate("ABC")),
    *(Mo64Param(f"Richtungslogik{n}", "direction_logics", 32 * (n - 1), Access.R, words=2,
                fields=tuple(Field(f.name, f.shift, f.width) for f in codec.DIRECTION_LOGIC.fields),
                description=Message(N_("Direction logic {n} (chapter 5.1.19, table 11, one 32-bit register: bits 2..0 "
                                       "input selection, 19, 18 presence right, 31..20 reserve). No setting telegram is "
                                       "named: read only."), n=n),
                query=codec.Q_DIRECTION_LOGICS, width=32)
      for n in (1, 2)),
    Mo64Param("dec_bt", "dec_bt", 0, Access.R, words=2,
              fields=tuple(Field(f.name, f.shift, f.width) for f in codec.DEC_BT.fields),
              description=Message(N_("Radio code (chapter 5.1.16): bit 31 = a code is stored, A9 .. A1 in bits 17 .. 0 "
                                     "(2 bits each). No setting telegram is named: read only.")),
              query=codec.Q_DEC_BT, width=32),
])

SAFETY = tuple(p for p in PARAMS if p.confirm)  # the flags whose value can switch a safety function off


def value_int(answer_type: int, value: Any) -> int:
    """A decoded answer (or setting) value as one number, low byte first as on the wire."""
    wire = codec.ANSWER_TYPES[answer_type]
    if answer_type == 0x08 and not isinstance(value, Mapping):
        value = {"mask": value, "more": b""}
    return int.from_bytes(wire.encode(value), "little")


def extract(param: Mo64Param, number: int) -> int:
    """The raw value of ``param`` inside a setting's number (:func:`value_int`)."""
    return (int(number) >> param.address) & param.mask


def replace(param: Mo64Param, number: int, raw: int) -> int:
    """``number`` with ``param``'s bits set to ``raw`` (the other bits as they are)."""
    return (int(number) & ~(param.mask << param.address)) | ((int(raw) & param.mask) << param.address)


def setting_value(key: str, number: int) -> Any:
    """The value :func:`codec.encode_setting` takes for setting ``key`` from its number."""
    setting = codec.SETTINGS[key]
    size = codec.SETTING_VALUE_BYTES[setting.telegram]
    value = setting.vtype.decode((int(number) & ((1 << (8 * size)) - 1)).to_bytes(size, "little"))
    if isinstance(value, Mapping):
        return dict(value)
    if isinstance(value, (list, tuple)):
        return list(value)
    return int(value)


def setting_int(key: str, value: Any) -> int:
    """A setting's value (as :func:`codec.encode_setting` takes it) as one number."""
    return int.from_bytes(codec.SETTINGS[key].check(value), "little")


def of_setting(key: str) -> list[Mo64Param]:
    return [p for p in PARAMS if p.setting_key == key]


def of_query(query: int) -> list[Mo64Param]:
    return [p for p in PARAMS if p.query == query]


def safety_questions(key: str, number: int) -> list[str]:
    """The confirmations a value of setting ``key`` asks for the safety flags it switches off (one per flag)."""
    return [p.needs_confirmation(extract(p, number)) for p in SAFETY if p.setting_key == key
            and p.needs_confirmation(extract(p, number))]


def selector_risk(param: Mo64Param) -> str:
    setting = codec.SETTINGS[param.setting_key]
    return Message(N_("The selector 0x{telegram:02X} 0x{selector:02X} of {name} is an assumption ({assumed}); the manual's "
                      "summary does not name it, and a wrong selector writes another EEPROM setting. Confirm only if you "
                      "verified on this unit that it is {setting}."), telegram=setting.telegram, selector=setting.selector,
                   name=param.name, assumed=setting.assumed, setting=Message(setting.name))


__all__ = ["PARAMS", "Mo64Param", "SAFETY", "extract", "replace", "setting_value", "setting_int", "value_int",
           "of_setting", "of_query", "safety_questions", "selector_risk", "KRAFT_RISK", "LS_TEST_RISK",
           "LOOP_SAFETY_RISK", "LS_MODE_RISK"]
