"""MO 64 twin: one simulated Bauer barrier control, its gate and its answers (served by devices/mo64/sim.py).

Written from document 003 (page summaries) and SPEC-NOTES "Bauer MO 64"; the wire format is the
codec's (devices/mo64/codec.py), the behaviour is the document's, as strict as the barrier could be:

* operating commands (chapter 5.2.1): open, close, reverse as a pulse; activate / deactivate set
  and clear a level register. Activating gives an edge only when the level was 0; an active open
  level (BUS_BA = 1, page 33) prevents closing until it is deactivated; an active close level
  prevents opening by command (safety reversal still opens). ack for a valid command and function,
  nak otherwise;
* gate motion with the pre-warning times (0x0E, 0x0F) before opening and closing, a travel time,
  the open time (0x0D; 0 = automatic closing off, chapter 5.2.4.1), position in % (-1 while unknown
  after power-up, chapter 5.1.29), gate state 0x0C;
* safety: an interrupted light barrier (LS) or an occupied loop reverses a closing boom and holds
  it open; a fault (F_ereignis) stops the motor where it is;
* settings (chapter 5.2.4-5.2.8): busy while the motor runs, else syn, the EEPROM write, then ack;
  nak for an unknown selector or a value out of range; every EEPROM write is counted per setting
  (chapter 4: "Schreibzugriff auf das EEPROM"). The vehicle counter is RAM only and answered ack;
* queries (table 21): 0x00-0x1A answered with telegram type index + 5, nak for 0x1B-0x1E and
  anything else; the error memory by level (ASSUMED index byte, see codec) or all ten levels;
* change monitoring (chapter 5.1.9, 5.2.4.5): over TCP only, telegrams sent unsolicited when a
  watched value changes (the barrier status only for the bits set in the status mask, 5.2.6.1);
* error memory (chapter 5.1.23): every change of the error flags is stored with the operating hours
  in level 0, older levels shift down;
* short commands (0x03) are answered nak: their codes are not in the summary (codec ASSUMPTIONS).

Demo controls on :class:`Mo64Twin`: :meth:`~Mo64Twin.drive_vehicle`, :meth:`~Mo64Twin.break_light_barrier`,
:meth:`~Mo64Twin.interrupt_at_next_close` (a person walking through as the boom closes),
:meth:`~Mo64Twin.occupy_loop`, :meth:`~Mo64Twin.raise_fault`, :meth:`~Mo64Twin.clear_fault`, :meth:`~Mo64Twin.power_up`;
fault injection and the strict modes of a real unit in :attr:`~Mo64Twin.strict` (:class:`Mo64Strict`: a light
barrier that never reports, assumed setting selectors it naks, a slow EEPROM write between syn and ack, queries
refused or answered late); :attr:`~Mo64Twin.setting_writes` counts EEPROM writes per setting.
"""

from __future__ import annotations

import logging
import math
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from devices.mo64 import codec
from devices.simcontrols import NP_, SimAction, SimControls, SimParam
from devices.mo64.codec import Command, Function, GateState, Reply, RequestType

log = logging.getLogger(__name__)

SIM_LOG_LIMIT = 1000  # what the twin keeps of its own traffic for the tests (it runs for hours in the demo)
TRAVEL_S = 2.5  # closed -> open; a twin value, the document names no travel time
EEPROM_WRITE_S = 0.08  # between syn and ack (a twin value: long enough that an ack outlives a token passed at syn)
DEFAULT_T_OPEN = 1000  # 10 ms units: 10 s
DEFAULT_T_PREWARN = 50  # 10 ms units: 0.5 s
DEFAULT_MAINTENANCE_INTERVAL = 100_000
START_OPERATING_HOURS = 1234
PROGRAM_VERSION = 0x0412
DEVICE_CODE = 5  # chapter 5.1.5: 0x0005 = MO 64-V4
VEHICLE_WAIT_OPEN_S = 15.0
INTERRUPT_AT_PCT = 60.0  # interrupt_at_next_close: the person steps into the beam once the boom is down to here
# the loops' toggles by name (the audit's words; the catalog's, context simulation, each named whole: a loop is a letter)
LOOP_OCCUPIED = {"A": NP_("simulation", "loop A occupied"), "B": NP_("simulation", "loop B occupied"),
                 "C": NP_("simulation", "loop C occupied")}
LOOP_TOGGLED = {"A": NP_("simulation", "toggle loop-A"), "B": NP_("simulation", "toggle loop-B"),
                "C": NP_("simulation", "toggle loop-C")}

_STATUS = {f.name: f.shift for f in codec.STATUS_BITS.fields}
_MOTOR_RUNS = (GateState.OPENING, GateState.CLOSING)
_MOVING = (GateState.OPENING, GateState.CLOSING, GateState.PREWARN_OPEN, GateState.PREWARN_CLOSE)  # rest() is 0
# change-monitoring bit (chapter 5.1.9, SPEC-NOTES) -> telegram type sent on change
_MONITORED = {0: 0x07, 1: 0x0A, 2: 0x0B, 3: 0x0C, 4: 0x17, 5: 0x1C, 6: 0x1D}  # 7, 8: layouts unknown


@dataclass
class Mo64Strict:
    """What a real unit may do that the tool must cope with: strict modes and injected faults, set as the twin
    is made (the plant file's options) or while it runs.

    :param refuse_queries: optional queries it naks (an RS485-only unit has no MAC, 0x10; a unit may refuse
        error-memory levels, 0x12)
    :param query_form: the query form it takes (table 21 prints "0x02 Auswahl index": "document" takes only that
        three-byte form, "short" only 02 Auswahl, "both" either)
    :param late: queries it answers late (index -> delay in s)
    :param refuse_selectors: setting keys whose selector it does not take (an assumed selector that is wrong on
        it: nak, nothing stored)
    :param eeprom_write_s: how long its EEPROM write takes between syn and ack (a real unit may take far longer
        than this twin's default; the tool waits up to SYN_ACK_TIMEOUT_S)
    :param light_barrier_dead: fault injection: the light barrier never reports (LS stays 0, nothing reverses)
    """

    refuse_queries: set[int] = field(default_factory=set)
    query_form: str = "both"
    late: dict[int, float] = field(default_factory=dict)
    refuse_selectors: set[str] = field(default_factory=set)
    eeprom_write_s: float = EEPROM_WRITE_S
    light_barrier_dead: bool = False

    def __post_init__(self) -> None:
        if self.query_form not in ("both", "document", "short"):
            raise ValueError(f"query_form {self.query_form!r}: both, document or short")
        unknown = self.refuse_selectors - set(codec.SETTINGS)
        if unknown:
            raise ValueError(f"refuse_selectors {sorted(unknown)}: not settings of the MO 64 ({', '.join(codec.SETTINGS)})")


@dataclass(frozen=True)
class Mo64Identity:
    """What names the unit (chapter 5.1.5, 5.1.6, 5.1.20, 5.1.21) and its operating hours at the twin's start."""

    serial_number: int
    device_code: int = DEVICE_CODE
    program_version: int = PROGRAM_VERSION
    operating_hours_start: int = START_OPERATING_HOURS

    @property
    def mac(self) -> bytes:
        n = self.serial_number
        return bytes((0x00, 0x0A, 0x64, (n >> 16) & 0xFF, (n >> 8) & 0xFF, n & 0xFF))


@dataclass
class Mo64Configuration:
    """The loop, direction-logic, radio-code and password registers and the loop-adjust counters as the unit
    answers them (chapter 5.1.16-5.1.31)."""

    induction_loops: tuple[int, int, int] = (0x0001, 0x0001, 0x0000)
    direction_logics: tuple[int, int] = (0, 0)
    dec_bt: int = 0
    password: int = 0
    loop_adjust: list[int] = field(default_factory=lambda: [3, 3, 0])


@dataclass
class Mo64Tally:
    """What the twin counts of its answers, for the tests and the demo."""

    naks: int = 0
    busy_answers: int = 0
    sent_unsolicited: int = 0


class Mo64Twin:
    """One barrier: gate, loops, light barrier, settings, counters, error memory.

    :meth:`handle` takes one decoded request frame and returns the telegrams (type + payload) to
    send, each with the delay before it; :meth:`step` advances the gate and sends change telegrams
    to :attr:`listeners` (the TCP server subscribes; a slave on RS485 never sends on its own).
    """

    def __init__(self, name: str = "mo64", address: int | None = None, serial_number: int = 6400001,
                 travel_s: float = TRAVEL_S, position_known: bool = True, refuse_queries: Iterable[int] = (),
                 query_form: str = "both", late: Mapping[int, float] | None = None,
                 refuse_selectors: Iterable[str] = (), eeprom_write_s: float | None = None):
        self.name = name
        self.address = address
        self.travel_s = float(travel_s)
        self.clock = 0.0
        self.strict = Mo64Strict(set(refuse_queries), query_form, dict(late or {}), set(refuse_selectors),
                                 EEPROM_WRITE_S if eeprom_write_s is None else float(eeprom_write_s))
        self.identity = Mo64Identity(serial_number)
        # settings (EEPROM): factory values; status mask 0 (page 18: "Maske0 bis Maske7 = 0")
        self.settings: dict[str, Any] = {
            "t_open": DEFAULT_T_OPEN, "t_prewarn_open": DEFAULT_T_PREWARN, "t_prewarn_close": DEFAULT_T_PREWARN,
            "change_monitoring": 0, "maintenance_interval": DEFAULT_MAINTENANCE_INTERVAL, "status_mask": 0,
            "multi_relays": (1, 0, 0, 0, 0, 0),
            # factory-like flags (the summary prints no factory values): Kraftüberwachung "Stopp und öffnen"
            # (konfig2 bits 12, 11 = 1) and LS-Test on (konfig3 bit 0), as devices/mo64/params.py places them
            "config_flags": {"konfig0": 0, "konfig1": 0, "konfig2": 1 << 11, "konfig3": 1},
        }
        self.configuration = Mo64Configuration()
        # counters
        self.service_counter = 0
        self.maintenance_counter = 0
        self.vehicle_counter = 0  # RAM only (chapter 5.2.5)
        # gate
        self.gate = GateState.CLOSED
        self.position = 0.0 if position_known else None
        self.open_end_pct = 100.0  # where the open limit switch stops the boom (a unit may report 99 %)
        self._timer = 0.0  # time left in a pre-warning, or of the open time
        self.levels = {c: False for c in Command}
        # inputs, safety, faults
        self.light_barrier = False  # the beam is interrupted
        self._interrupt_next_close = False  # a person walks through the beam as the boom next closes
        self.loops = {"A": False, "B": False, "C": False}
        self.error_flags = 0
        self.error_memory: list[tuple[int, int]] = [(0, 0)] * codec.ERROR_MEMORY_LEVELS
        self._vehicle: list[tuple[str, float]] | None = None
        self._vehicle_wait = 0.0
        # bookkeeping for tests and the demo
        self.setting_writes: dict[str, int] = {}
        self.requests = 0
        self.tally = Mo64Tally()
        self.commands: deque[tuple[str, str]] = deque(maxlen=SIM_LOG_LIMIT)
        self.listeners: list[Callable[[bytes], None]] = []
        self._last_seen: dict[int, bytes] = {}
        self._last_status = self.status_word()

    # -- derived values ------------------------------------------------------------------------------
    @property
    def eeprom_writes(self) -> int:
        return sum(self.setting_writes.values())

    @property
    def motor_runs(self) -> bool:
        return self.gate in _MOTOR_RUNS

    @property
    def operating_hours(self) -> int:
        return self.identity.operating_hours_start + int(self.clock // 3600)

    @property
    def position_pct(self) -> int:
        return codec.POSITION_UNKNOWN if self.position is None else int(round(self.position))

    @property
    def light_barrier_reports(self) -> bool:
        """LS as the control sees it: interrupted, and the light barrier working."""
        return self.light_barrier and not self.strict.light_barrier_dead

    @property
    def obstructed(self) -> bool:
        return self.light_barrier_reports or any(self.loops.values())

    def status_word(self) -> int:
        """The 40 status bits (chapter 5.1.7), Status0 in the low byte."""
        bits = {"LS": self.light_barrier_reports, "F_ereignis": bool(self.error_flags),
                "loop A occupied": self.loops["A"], "loop B occupied": self.loops["B"],
                "loop C occupied": self.loops["C"],
                "SERVICE": 0 < self.settings["maintenance_interval"] <= self.maintenance_counter}
        word = sum(1 << _STATUS[name] for name, on in bits.items() if on)
        for n, mode in enumerate(self.settings["multi_relays"], 1):
            if mode == 1 and self.error_flags:  # chapter 5.1.25: "Störung": on while an error flag is set
                word |= 1 << _STATUS[f"multi relay {n}"]
        return word

    # -- demo controls -------------------------------------------------------------------------------
    def drive_vehicle(self) -> None:
        """A vehicle drives onto loop A (presence opens the barrier), passes the light barrier and
        loop B, and leaves; the vehicle counter counts it."""
        self._vehicle = [("arrive", 0.0), ("wait open", VEHICLE_WAIT_OPEN_S), ("under boom", 0.4),
                         ("on loop B", 0.6), ("gone", 0.0)]
        self._vehicle_wait = 0.0
        self.loops["A"] = True
        self._edge(Command.OPEN, internal=True)

    def break_light_barrier(self, broken: bool = True) -> None:
        self.light_barrier = broken
        if not broken:
            self._interrupt_next_close = False

    def interrupt_at_next_close(self) -> None:
        """A person stands ready at the light barrier and interrupts it once the boom closes (until freed)."""
        self._interrupt_next_close = True

    def toggle_light_barrier(self) -> None:
        """What a checkout asks a person at the light barrier to do: free it when it is interrupted (or about to
        be), else interrupt it as the boom next closes."""
        if self.light_barrier or self._interrupt_next_close:
            self.break_light_barrier(False)
        else:
            self.interrupt_at_next_close()

    def occupy_loop(self, loop: str, occupied: bool = True) -> None:
        """A vehicle (or a test mass) stands on loop ``loop`` (A, B or C); its occupied bit follows (5.1.7)."""
        self.loops[loop] = occupied

    def raise_fault(self, flags: int = 0x0001) -> None:
        """Set error flags (chapter 5.1.23): the motor stops where it is, the error memory records it."""
        self._set_error_flags(self.error_flags | flags)
        if self.motor_runs:
            self.gate = GateState.INTERMEDIATE

    def clear_fault(self, flags: int = 0xFFFFFFFF) -> None:
        self._set_error_flags(self.error_flags & ~flags)

    def power_up(self) -> None:
        """Mains back: position unknown (-1, chapter 5.1.29) until an end position, vehicle counter 0."""
        self.position = None
        self.vehicle_counter = 0
        self.gate = GateState.INTERMEDIATE
        self.levels = {c: False for c in Command}

    def controls(self) -> SimControls:
        """What an engineer may do to this barrier in simulation (shown by pages/simcontrols.py)."""
        return SimControls("Simulated barrier (demo)", (
            SimAction(NP_("simulation", "drive a vehicle"), "Drive a vehicle through", self.drive_vehicle,
                      icon="directions_car", testid="vehicle"),
            SimAction(NP_("simulation", "light barrier interrupted"), "Light barrier interrupted", self.break_light_barrier,
                      state=lambda: self.light_barrier, testid="light-barrier"),
            SimAction(NP_("simulation", "toggle LS"), "Light barrier: interrupt at the next close / free",
                      self.toggle_light_barrier, testid="toggle-ls"),
            *(SimAction(LOOP_OCCUPIED[x], f"Loop {x} occupied", lambda on, x=x: self.occupy_loop(x, on),
                        state=lambda x=x: self.loops[x], testid=f"loop-{x.lower()}") for x in "ABC"),
            *(SimAction(LOOP_TOGGLED[x], f"Loop {x}: occupy / free", lambda x=x: self.occupy_loop(x, not self.loops[x]),
                        testid=f"toggle-loop-{x.lower()}") for x in "ABC"),
            SimAction(NP_("simulation", "light barrier never reports"), "Light barrier never reports (broken)",
                      lambda on: setattr(self.strict, "light_barrier_dead", on), state=lambda: self.strict.light_barrier_dead,
                      testid="light-barrier-dead"),
            SimAction(NP_("simulation", "raise fault"), "Raise fault", self.raise_fault, icon="error", testid="raise-fault",
                      params=(SimParam(NP_("simulation", "flags"), "error flags", 0x0001, 1, 0xFFFFFFFF, hex=True),)),
            SimAction(NP_("simulation", "clear faults"), "Clear faults", self.clear_fault, testid="clear-faults"),
            SimAction(NP_("simulation", "mains back"), "Mains back (power up)", self.power_up, icon="power",
                      testid="power-up"),
        ), note="A vehicle opens the barrier on loop A and passes the light barrier; a fault stops the motor "
                "and is recorded in the error memory; after mains the position is unknown until an end position.")

    def _set_error_flags(self, flags: int) -> None:
        if flags == self.error_flags:
            return
        self.error_flags = flags
        self.error_memory = [(flags, self.operating_hours), *self.error_memory[:-1]]  # newest in level 0

    # -- gate ----------------------------------------------------------------------------------------
    def _start_open(self) -> None:
        if self.gate in (GateState.OPEN, GateState.OPENING, GateState.PREWARN_OPEN):
            if self.gate == GateState.OPEN:
                self._timer = self._t_open_s()
            return
        if self.error_flags:
            return
        if self.gate == GateState.CLOSING:
            self.gate = GateState.OPENING  # a closing boom reverses at once
            return
        self.gate = GateState.PREWARN_OPEN
        self._timer = self.settings["t_prewarn_open"] * codec.TIME_STEP_S

    def _start_close(self) -> None:
        if self.gate in (GateState.CLOSED, GateState.CLOSING, GateState.PREWARN_CLOSE):
            return
        if self.error_flags or self.levels[Command.OPEN] or self.obstructed:
            return  # an active open level prevents closing (page 33); nothing closes onto a vehicle
        self.gate = GateState.PREWARN_CLOSE
        self._timer = self.settings["t_prewarn_close"] * codec.TIME_STEP_S

    def _edge(self, command: Command, internal: bool = False) -> None:
        if command == Command.OPEN:
            if not internal and self.levels[Command.CLOSE] and not self.levels[Command.OPEN]:
                return  # an active close level prevents opening by command
            self._start_open()
        elif command == Command.CLOSE:
            self._start_close()
        elif self.gate in (GateState.OPENING, GateState.PREWARN_OPEN, GateState.OPEN):
            self._start_close()
        else:
            self._start_open()

    def _t_open_s(self) -> float:
        return self.settings["t_open"] * codec.TIME_STEP_S

    def step(self, dt: float) -> None:
        """Advance by ``dt`` seconds and send what changed to the listeners."""
        self.clock += dt
        self._step_vehicle(dt)
        if self._interrupt_next_close and self.gate == GateState.CLOSING and (self.position or 0.0) <= INTERRUPT_AT_PCT:
            self._interrupt_next_close = False
            self.light_barrier = True  # held until freed (break_light_barrier(False))
        if self.gate in (GateState.CLOSING, GateState.PREWARN_CLOSE) and self.obstructed:
            self.gate = GateState.OPENING if self.gate == GateState.CLOSING else GateState.OPEN
            self._timer = self._t_open_s()  # light barrier or loop: reverse and hold open
        speed = 100.0 / self.travel_s
        if self.gate in (GateState.PREWARN_OPEN, GateState.PREWARN_CLOSE):
            self._timer -= dt
            if self._timer <= 0:
                self.gate = GateState.OPENING if self.gate == GateState.PREWARN_OPEN else GateState.CLOSING
        elif self.gate == GateState.OPENING:
            self.position = min(self.open_end_pct, (50.0 if self.position is None else self.position) + speed * dt)
            if self.position >= self.open_end_pct:
                self.gate = GateState.OPEN
                self._timer = self._t_open_s()
                self.service_counter += 1
                self.maintenance_counter += 1
        elif self.gate == GateState.CLOSING:
            self.position = max(0.0, (50.0 if self.position is None else self.position) - speed * dt)
            if self.position <= 0.0:
                self.gate = GateState.CLOSED
        elif self.gate == GateState.OPEN:
            if self.obstructed or self.levels[Command.OPEN]:
                self._timer = self._t_open_s()
            elif self.levels[Command.CLOSE]:
                self._start_close()
            elif self.settings["t_open"]:
                self._timer -= dt
                if self._timer <= 0:
                    self._start_close()
        self._notify()

    def rest(self) -> float:
        """How long :meth:`step` has nothing to do (simserver.Ticker): 0 while the gate moves, warns, is held
        open or a vehicle passes; the open time left when it closes by itself; else unbounded."""
        if self._vehicle or self.gate in _MOVING:
            return 0.0
        if self.gate == GateState.OPEN:
            if self.obstructed or self.levels[Command.OPEN] or self.levels[Command.CLOSE]:
                return 0.0
            if self.settings["t_open"]:
                return max(0.0, self._timer)
        return math.inf

    def _step_vehicle(self, dt: float) -> None:
        if not self._vehicle:
            return
        phase, left = self._vehicle[0]
        if phase == "arrive":
            self._vehicle.pop(0)
        elif phase == "wait open":
            self._vehicle_wait += dt
            if self.gate == GateState.OPEN:
                self._vehicle.pop(0)
                self.light_barrier = self.loops["B"] = True
            elif self._vehicle_wait > left:
                self.loops["A"] = False  # the driver gave up
                self._vehicle = None
        elif left > dt:
            self._vehicle[0] = (phase, left - dt)
        else:
            self._vehicle.pop(0)
            if phase == "under boom":
                self.loops["A"] = self.light_barrier = False
            elif phase == "on loop B":
                self.loops["B"] = False
                self.vehicle_counter += 1
                self._vehicle = None

    # -- change monitoring ---------------------------------------------------------------------------
    def _notify(self) -> None:
        status = self.status_word()
        changed_status = (status ^ self._last_status) & int(self.settings["status_mask"])
        self._last_status = status
        flags = int(self.settings["change_monitoring"])
        for bit, answer_type in _MONITORED.items():
            payload = self.answer_payload(answer_type)
            before = self._last_seen.get(answer_type)
            self._last_seen[answer_type] = payload
            if not flags >> bit & 1 or not self.listeners:
                continue
            if answer_type == 0x07:
                if not changed_status:
                    continue
            elif before is None or before == payload:
                continue
            self._send_unsolicited(bytes((answer_type,)) + payload)

    def _send_unsolicited(self, telegram: bytes) -> None:
        self.tally.sent_unsolicited += 1
        for listener in list(self.listeners):
            try:
                listener(telegram)
            except (OSError, RuntimeError):  # a closed connection (or its ended event loop) must not stop the twin
                log.exception("%s: change telegram not sent", self.name)

    # -- answers -------------------------------------------------------------------------------------
    def answer_payload(self, answer_type: int, level: int | None = None) -> bytes:
        return self.answer(answer_type, level)[1:]

    def answer(self, answer_type: int, level: int | None = None) -> bytes:
        """Telegram ``answer_type`` (0x05..0x1F) with the current value."""
        s, config = self.settings, self.configuration
        if answer_type == 0x17:
            if level is not None:
                flags, hours = self.error_memory[level]
                return codec.encode_answer(0x17, {"index": level, "flags": flags, "timestamp_h": hours})
        values = {
            0x05: self.identity.device_code, 0x06: self.identity.program_version,
            0x07: {"status": self.status_word(), "more": b""},
            0x08: {"mask": int(s["status_mask"]), "more": b""},
            0x09: int(s["change_monitoring"]), 0x0A: self.service_counter, 0x0B: self.maintenance_counter,
            0x0C: int(self.gate), 0x0D: s["t_open"], 0x0E: s["t_prewarn_open"], 0x0F: s["t_prewarn_close"],
            0x10: config.dec_bt, 0x11: bytes(2), 0x12: config.induction_loops, 0x13: config.direction_logics,
            0x14: self.identity.serial_number, 0x15: self.identity.mac, 0x16: self.operating_hours,
            0x17: tuple({"flags": f, "timestamp_h": t} for f, t in self.error_memory),
            0x18: s["config_flags"], 0x19: tuple(s["multi_relays"]), 0x1A: s["maintenance_interval"],
            0x1B: bytes(6), 0x1C: self.vehicle_counter, 0x1D: self.position_pct, 0x1E: config.password,
            0x1F: tuple(config.loop_adjust),
        }
        return codec.encode_answer(answer_type, values[answer_type])

    def handle(self, frame: codec.Frame) -> list[tuple[float, bytes]]:
        """The telegrams (type + payload) answering one request frame, each after its delay in s."""
        self.requests += 1
        try:
            request = codec.decode_request(frame)
        except codec.InvalidRequest as exc:
            return self._nak(str(exc))
        except codec.CodecError as exc:
            return self._nak(str(exc))
        if request.kind is RequestType.QUERY:
            three = len(request.payload) == 2
            strict = self.strict
            if (strict.query_form == "document" and not three) or (
                    strict.query_form == "short" and three and request.query != codec.Q_ERROR_MEMORY):
                return self._nak(f"query form {request.payload.hex(' ')} not taken by this unit ({strict.query_form})")
            if request.query in strict.refuse_queries:
                return self._nak(f"query 0x{request.query:02X} not available on this unit")
            level = request.level if request.query == codec.Q_ERROR_MEMORY else None
            return [(self.strict.late.get(request.query, 0.0), self.answer(request.query + codec.QUERY_ANSWER_OFFSET, level))]
        if request.kind is RequestType.COMMAND:
            return [(0.0, self._command(request.command, request.function))]
        if request.kind is RequestType.SHORT_COMMAND:
            return self._nak(f"short command 0x{request.code:02X}: no code is known")
        return self._setting(request)

    def _nak(self, why: str) -> list[tuple[float, bytes]]:
        self.tally.naks += 1
        log.debug("%s: nak (%s)", self.name, why)
        return [(0.0, bytes((Reply.NAK,)))]

    def _command(self, command: Command, function: Function) -> bytes:
        self.commands.append((command.name.lower(), function.name.lower()))
        if function == Function.PULSE:
            self._edge(command)
        elif function == Function.ACTIVATE:
            was = self.levels[command]
            self.levels[command] = True
            if not was:
                self._edge(command)  # table 19: an edge only when the level register was 0
        else:
            self.levels[command] = False
            if command == Command.OPEN and self.gate == GateState.OPEN:
                self._timer = self._t_open_s()
        return bytes((Reply.ACK,))

    def _setting(self, request: codec.Request) -> list[tuple[float, bytes]]:
        setting = request.setting
        if setting is None or setting.key in self.strict.refuse_selectors:
            return self._nak(f"setting 0x{request.kind:02X} selector 0x{request.selector:02X} unknown")
        if not setting.eeprom:  # the vehicle counter: RAM only, answered ack (chapter 5.2.5)
            self.vehicle_counter = int(request.value)
            return [(0.0, bytes((Reply.ACK,)))]
        if self.motor_runs:
            self.tally.busy_answers += 1
            return [(0.0, bytes((Reply.BUSY,)))]  # chapter 5.2.4: "tele_busy, wenn der Motor läuft"
        value = request.value
        if setting.key == "status_mask":
            value = int(value)
        elif setting.key == "change_monitoring":
            value = int(value)
        elif setting.key == "config_flags":
            value = {k: int(w) for k, w in value.items()}
        elif setting.key == "multi_relays":
            value = tuple(value)
        self.settings[setting.key] = value
        self.setting_writes[setting.key] = self.setting_writes.get(setting.key, 0) + 1
        return [(0.0, bytes((Reply.SYN,))), (self.strict.eeprom_write_s, bytes((Reply.ACK,)))]
