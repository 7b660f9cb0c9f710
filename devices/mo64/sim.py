"""MO 64 twin: simulated Bauer barrier controls on LogiTed TCP and on an RS485 line.

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
fault injection :attr:`~Mo64Twin.light_barrier_dead` (a light barrier that never reports: no LS, no reversal);
:attr:`~Mo64Twin.setting_writes` counts EEPROM writes per setting; strict modes of a real unit:
:attr:`~Mo64Twin.refuse_selectors` (assumed setting selectors it naks) and :attr:`~Mo64Twin.eeprom_write_s`
(a slow EEPROM write between syn and ack).

Servers: :class:`Mo64TcpSim` (one barrier, one client at a time, chapter 3) and :class:`Mo64Rs485Sim`
(several barriers by bus address, and with ``shared = true`` a second master passing the token,
chapter 2.6, which records how long the tool held it).
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from devices import simserver
from devices.mo64 import codec
from devices.simcontrols import SimAction, SimControls, SimParam
from devices.mo64.codec import Command, Function, GateState, Reply, RequestType

log = logging.getLogger(__name__)

TICK_S = 0.02
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
TOKEN_HOLD_S = 0.05  # how long the second master keeps the token each round
TOKEN_LOST_S = 1.0  # the second master takes the token back when the tool did not pass it by then

_STATUS = {f.name: f.shift for f in codec.STATUS_BITS.fields}
_MOTOR_RUNS = (GateState.OPENING, GateState.CLOSING)
# change-monitoring bit (chapter 5.1.9, SPEC-NOTES) -> telegram type sent on change
_MONITORED = {0: 0x07, 1: 0x0A, 2: 0x0B, 3: 0x0C, 4: 0x17, 5: 0x1C, 6: 0x1D}  # 7, 8: layouts unknown


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
        # strict modes a real unit may have: optional queries it naks (an RS485-only unit has no MAC,
        # 0x10; a unit may refuse error-memory levels, 0x12), the query form it takes (table 21 prints
        # "0x02 Auswahl index": "document" takes only that three-byte form, "short" only 02 Auswahl,
        # "both" either), and queries it answers late (index -> delay in s)
        self.refuse_queries = set(refuse_queries)
        if query_form not in ("both", "document", "short"):
            raise ValueError(f"query_form {query_form!r}: both, document or short")
        self.query_form = query_form
        self.late = dict(late or {})
        # strict modes for the settings: setting keys whose selector this unit does not take (an assumed selector
        # that is wrong on it: nak, nothing stored), and how long its EEPROM write takes between syn and ack
        # (a real unit may take far longer than this twin's default; the tool waits up to SYN_ACK_TIMEOUT_S)
        unknown = set(refuse_selectors) - set(codec.SETTINGS)
        if unknown:
            raise ValueError(f"refuse_selectors {sorted(unknown)}: not settings of the MO 64 ({', '.join(codec.SETTINGS)})")
        self.refuse_selectors = set(refuse_selectors)
        self.eeprom_write_s = EEPROM_WRITE_S if eeprom_write_s is None else float(eeprom_write_s)
        # identity (chapter 5.1.5, 5.1.6, 5.1.20, 5.1.21)
        self.device_code = DEVICE_CODE
        self.program_version = PROGRAM_VERSION
        self.serial_number = serial_number
        self.mac = bytes((0x00, 0x0A, 0x64, (serial_number >> 16) & 0xFF, (serial_number >> 8) & 0xFF,
                          serial_number & 0xFF))
        self.operating_hours_start = START_OPERATING_HOURS
        # settings (EEPROM): factory values; status mask 0 (page 18: "Maske0 bis Maske7 = 0")
        self.settings: dict[str, Any] = {
            "t_open": DEFAULT_T_OPEN, "t_prewarn_open": DEFAULT_T_PREWARN, "t_prewarn_close": DEFAULT_T_PREWARN,
            "change_monitoring": 0, "maintenance_interval": DEFAULT_MAINTENANCE_INTERVAL, "status_mask": 0,
            "multi_relays": (1, 0, 0, 0, 0, 0),
            # factory-like flags (the summary prints no factory values): Kraftüberwachung "Stopp und öffnen"
            # (konfig2 bits 12, 11 = 1) and LS-Test on (konfig3 bit 0), as devices/mo64/params.py places them
            "config_flags": {"konfig0": 0, "konfig1": 0, "konfig2": 1 << 11, "konfig3": 1},
        }
        self.induction_loops = (0x0001, 0x0001, 0x0000)
        self.direction_logics = (0, 0)
        self.dec_bt = 0
        self.password = 0
        self.loop_adjust = [3, 3, 0]
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
        self.light_barrier_dead = False  # fault injection: the light barrier never reports (LS stays 0, nothing reverses)
        self._interrupt_next_close = False  # a person walks through the beam as the boom next closes
        self.loops = {"A": False, "B": False, "C": False}
        self.error_flags = 0
        self.error_memory: list[tuple[int, int]] = [(0, 0)] * codec.ERROR_MEMORY_LEVELS
        self._vehicle: list[tuple[str, float]] | None = None
        self._vehicle_wait = 0.0
        # bookkeeping for tests and the demo
        self.setting_writes: dict[str, int] = {}
        self.requests = 0
        self.naks = 0
        self.busy_answers = 0
        self.commands: deque[tuple[str, str]] = deque(maxlen=SIM_LOG_LIMIT)
        self.listeners: list[Callable[[bytes], None]] = []
        self.sent_unsolicited = 0
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
        return self.operating_hours_start + int(self.clock // 3600)

    @property
    def position_pct(self) -> int:
        return codec.POSITION_UNKNOWN if self.position is None else int(round(self.position))

    @property
    def light_barrier_reports(self) -> bool:
        """LS as the control sees it: interrupted, and the light barrier working."""
        return self.light_barrier and not self.light_barrier_dead

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
            SimAction("drive a vehicle", "Drive a vehicle through", self.drive_vehicle, icon="directions_car",
                      testid="vehicle"),
            SimAction("light barrier interrupted", "Light barrier interrupted", self.break_light_barrier,
                      state=lambda: self.light_barrier, testid="light-barrier"),
            SimAction("toggle LS", "Light barrier: interrupt at the next close / free", self.toggle_light_barrier,
                      testid="toggle-ls"),
            *(SimAction(f"loop {x} occupied", f"Loop {x} occupied", lambda on, x=x: self.occupy_loop(x, on),
                        state=lambda x=x: self.loops[x], testid=f"loop-{x.lower()}") for x in "ABC"),
            *(SimAction(f"toggle loop-{x}", f"Loop {x}: occupy / free", lambda x=x: self.occupy_loop(x, not self.loops[x]),
                        testid=f"toggle-loop-{x.lower()}") for x in "ABC"),
            SimAction("light barrier never reports", "Light barrier never reports (broken)",
                      lambda on: setattr(self, "light_barrier_dead", on), state=lambda: self.light_barrier_dead,
                      testid="light-barrier-dead"),
            SimAction("raise fault", "Raise fault", self.raise_fault, icon="error", testid="raise-fault",
                      params=(SimParam("flags", "error flags", 0x0001, 1, 0xFFFFFFFF, hex=True),)),
            SimAction("clear faults", "Clear faults", self.clear_fault, testid="clear-faults"),
            SimAction("mains back", "Mains back (power up)", self.power_up, icon="power", testid="power-up"),
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
        self.sent_unsolicited += 1
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
        s = self.settings
        if answer_type == 0x17:
            if level is not None:
                flags, hours = self.error_memory[level]
                return codec.encode_answer(0x17, {"index": level, "flags": flags, "timestamp_h": hours})
        values = {
            0x05: self.device_code, 0x06: self.program_version,
            0x07: {"status": self.status_word(), "more": b""},
            0x08: {"mask": int(s["status_mask"]), "more": b""},
            0x09: int(s["change_monitoring"]), 0x0A: self.service_counter, 0x0B: self.maintenance_counter,
            0x0C: int(self.gate), 0x0D: s["t_open"], 0x0E: s["t_prewarn_open"], 0x0F: s["t_prewarn_close"],
            0x10: self.dec_bt, 0x11: bytes(2), 0x12: self.induction_loops, 0x13: self.direction_logics,
            0x14: self.serial_number, 0x15: self.mac, 0x16: self.operating_hours,
            0x17: tuple({"flags": f, "timestamp_h": t} for f, t in self.error_memory),
            0x18: s["config_flags"], 0x19: tuple(s["multi_relays"]), 0x1A: s["maintenance_interval"],
            0x1B: bytes(6), 0x1C: self.vehicle_counter, 0x1D: self.position_pct, 0x1E: self.password,
            0x1F: tuple(self.loop_adjust),
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
            if (self.query_form == "document" and not three) or (
                    self.query_form == "short" and three and request.query != codec.Q_ERROR_MEMORY):
                return self._nak(f"query form {request.payload.hex(' ')} not taken by this unit ({self.query_form})")
            if request.query in self.refuse_queries:
                return self._nak(f"query 0x{request.query:02X} not available on this unit")
            level = request.level if request.query == codec.Q_ERROR_MEMORY else None
            return [(self.late.get(request.query, 0.0), self.answer(request.query + codec.QUERY_ANSWER_OFFSET, level))]
        if request.kind is RequestType.COMMAND:
            return [(0.0, self._command(request.command, request.function))]
        if request.kind is RequestType.SHORT_COMMAND:
            return self._nak(f"short command 0x{request.code:02X}: no code is known")
        return self._setting(request)

    def _nak(self, why: str) -> list[tuple[float, bytes]]:
        self.naks += 1
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
        if setting is None or setting.key in self.refuse_selectors:
            return self._nak(f"setting 0x{request.kind:02X} selector 0x{request.selector:02X} unknown")
        if not setting.eeprom:  # the vehicle counter: RAM only, answered ack (chapter 5.2.5)
            self.vehicle_counter = int(request.value)
            return [(0.0, bytes((Reply.ACK,)))]
        if self.motor_runs:
            self.busy_answers += 1
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
        return [(0.0, bytes((Reply.SYN,))), (self.eeprom_write_s, bytes((Reply.ACK,)))]


# -- servers -----------------------------------------------------------------------------------------
def _twin_for(dev: Any, address: int | None = None) -> Mo64Twin:
    opts = dev.options
    return Mo64Twin(dev.name, address, int(opts.get("serial_number", 6400000 + (address or 1))),
                    float(opts.get("travel_s", TRAVEL_S)), refuse_queries=opts.get("refuse_queries", ()),
                    query_form=opts.get("query_form", "both"), refuse_selectors=opts.get("refuse_selectors", ()),
                    eeprom_write_s=opts.get("eeprom_write_s"))


_MOVING = (GateState.OPENING, GateState.CLOSING, GateState.PREWARN_OPEN, GateState.PREWARN_CLOSE)


def _ticker(twins: list[Mo64Twin]) -> simserver.Ticker:
    def step(dt_s: float, now: float) -> None:
        for twin in twins:
            twin.step(dt_s)

    def rest(now: float) -> float:
        return min(twin.rest() for twin in twins) if twins else math.inf

    return simserver.Ticker(step, TICK_S, rest)  # slow while no gate moves; a telegram wakes it (wake())


class Mo64TcpSim:
    """One MO 64 with the TCP module on the bus's host and port (chapter 3).

    The barrier serves one client at a time: a second client is closed at once while the first is
    connected (counted in :attr:`refused`).
    """

    def __init__(self, bus, devices):
        if len(devices) != 1:
            raise ValueError(f"LogiTed TCP bus {bus.name}: one MO 64 per connection ({len(devices)} configured)")
        dev = devices[0]
        self.bus = bus
        self.twin = _twin_for(dev)
        self.twins: dict[str, Mo64Twin] = {dev.name: self.twin}
        self.host = bus.options.get("host", "127.0.0.1")
        self.port = int(bus.options.get("port", codec.TCP_PORT))
        # chapter 3: the next client connects after the first one closed
        self.endpoint = simserver.TwinServer(f"the simulated MO 64 {bus.name}", self._serve, simserver.REFUSE)
        self._ticker = _ticker([self.twin])
        self.garbage = 0

    @property
    def connections(self) -> int:
        return self.endpoint.connections

    @property
    def refused(self) -> int:
        return self.endpoint.refused

    async def start(self) -> None:
        await self.endpoint.start(self.host, self.port)
        self._ticker.start(f"sim {self.bus.name}")

    def _push(self, telegram: bytes) -> None:
        for writer in self.endpoint.clients:
            if not writer.is_closing():
                writer.write(codec.encode_frame(telegram))

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        async def answer(item) -> None:
            if isinstance(item, codec.FrameError):
                self.garbage += 1
                return  # a telegram with a bad checksum is not answered
            self._ticker.wake()  # a command may move the gate: stepped up to now, then at TICK_S
            for delay, telegram in self.twin.handle(item):
                if delay:
                    await asyncio.sleep(delay)
                writer.write(codec.encode_frame(telegram))
                await writer.drain()

        self.twin.listeners.append(self._push)
        try:
            await simserver.serve_telegrams(reader, codec.FrameSplitter(codec.TCP), answer)
        finally:
            if self._push in self.twin.listeners:
                self.twin.listeners.remove(self._push)

    async def stop(self) -> None:
        self._ticker.stop()
        await self.endpoint.stop()


@dataclass
class TokenHold:
    """One time the tool held the token: from the token to it until its token onward."""

    given: float
    passed: float | None = None

    @property
    def held_s(self) -> float | None:
        return None if self.passed is None else self.passed - self.given


class Mo64Rs485Sim:
    """An RS485 line (38400 8N1) served on the TCP port of the bus's ``socket://`` URL.

    Several barriers, each answering only telegrams addressed to it (device option ``address``) and
    never a token telegram (chapter 2.6). Every frame on the line reaches every connected client
    (a bus). With ``shared = true`` a second master at ``next_master`` holds the token at start,
    passes it to the tool's ``master_address``, sometimes queries a barrier itself while it holds
    the token, and records each of the tool's holds in :attr:`holds` (the limit is 200 ms,
    chapter 2.6.1); telegrams the tool sends while it does not hold the token are counted in
    :attr:`sent_without_token`.
    """

    def __init__(self, bus, devices):
        self.bus = bus
        opts = bus.options
        self.master_address = int(opts.get("master_address", codec.RS485_LAYOUT.master_address))
        self.shared = bool(opts.get("shared", False))
        self.next_master = int(opts.get("next_master", self.master_address + 1))
        self.by_address: dict[int, Mo64Twin] = {}
        self.twins: dict[str, Mo64Twin] = {}
        for n, dev in enumerate(devices):
            address = int(dev.options.get("address", 0x10 + n))
            if address in self.by_address or address in (self.master_address, self.next_master):
                raise ValueError(f"RS485 bus {bus.name}: address {address} of {dev.name} is taken")
            twin = _twin_for(dev, address)
            self.by_address[address] = twin
            self.twins[dev.name] = twin
        self.endpoint = simserver.TwinServer(f"the simulated RS485 line {bus.name}", self._serve, simserver.SHARE)
        self._ticker = _ticker(list(self.by_address.values()))
        self._master_task: asyncio.Task | None = None
        self.tool_has_token = not self.shared
        self.holds: deque[TokenHold] = deque(maxlen=SIM_LOG_LIMIT)  # the demo plant runs for hours: bounded
        self.token_lost = 0
        self.sent_without_token = 0
        self.own_queries = 0
        self.own_answers: deque[bytes] = deque(maxlen=SIM_LOG_LIMIT)
        self.unaddressed = 0
        self.garbage = 0
        self.collisions = 0  # answers a barrier sent in another master's turn (see _answer)
        self._answering: set[asyncio.Task] = set()
        self._token_back = asyncio.Event()

    async def start(self) -> None:
        await self.endpoint.start(*simserver.host_port(self.bus.options["port"], "a simulated RS485 line"))
        self._ticker.start(f"sim {self.bus.name}")
        if self.shared:
            self._master_task = asyncio.create_task(self._second_master(), name=f"sim {self.bus.name} master")

    async def _put(self, raw: bytes, source: asyncio.StreamWriter | None = None) -> None:
        """Bytes on the line: every client but the one that sent them hears them."""
        for writer in list(self.endpoint.clients):
            if writer is source or writer.is_closing():
                continue
            writer.write(raw)
            try:
                await writer.drain()
            except ConnectionError:
                pass

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        async def on_line(item) -> None:
            if isinstance(item, codec.FrameError):
                self.garbage += 1
                return
            await self._put(item.raw, writer)
            await self._frame_from_client(item)

        await simserver.serve_telegrams(reader, codec.FrameSplitter(codec.RS485), on_line)

    async def _frame_from_client(self, frame: codec.Frame) -> None:
        if frame.is_token:
            if self.shared and frame.da == self.next_master and self.tool_has_token:
                self.tool_has_token = False
                if self.holds and self.holds[-1].passed is None:
                    self.holds[-1].passed = time.monotonic()
                self._token_back.set()
            return  # a slave ignores token telegrams (chapter 2.6)
        if not self.tool_has_token:
            self.sent_without_token += 1
        await self._to_barrier(frame)

    async def _to_barrier(self, frame: codec.Frame) -> None:
        twin = self.by_address.get(frame.da)
        if twin is None:
            self.unaddressed += 1
            return  # nobody answers a telegram addressed to nobody
        # the barrier answers on its own time while the line goes on (a token passed meanwhile is heard)
        self._ticker.wake()  # a command may move the gate: stepped up to now, then at TICK_S
        task = asyncio.create_task(self._answer(twin, frame, twin.handle(frame)))
        self._answering.add(task)
        task.add_done_callback(self._answering.discard)

    async def _answer(self, twin: Mo64Twin, frame: codec.Frame, answers: list[tuple[float, bytes]]) -> None:
        for delay, telegram in answers:
            await asyncio.sleep(delay or 0.002)
            raw = codec.encode_frame(telegram, codec.RS485, da=frame.sa, sa=twin.address)
            if self.shared and frame.sa == self.master_address and not self.tool_has_token:
                # the other master holds the token and may send at any moment of its turn: a slave's
                # answer in that turn collides with it (two stations at once); everyone hears garbage
                self.collisions += 1
                raw = raw[:-2] + bytes((raw[-2] ^ 0xFF, raw[-1] ^ 0xFF))
            await self._put(raw)

    async def _second_master(self) -> None:
        rounds = 0
        try:
            while True:
                await asyncio.sleep(TOKEN_HOLD_S)
                rounds += 1
                if rounds % 3 == 0 and self.by_address and self.endpoint.clients:
                    address = sorted(self.by_address)[(rounds // 3) % len(self.by_address)]
                    request = codec.encode_frame(codec.encode_query(codec.Q_GATE_STATE), codec.RS485,
                                                 da=address, sa=self.next_master)
                    self.own_queries += 1
                    await self._put(request)
                    self._ticker.wake()
                    answers = self.by_address[address].handle(codec.decode_frame(request, codec.RS485))
                    for delay, telegram in answers:
                        await asyncio.sleep(delay or 0.002)
                        raw = codec.encode_frame(telegram, codec.RS485, da=self.next_master, sa=address)
                        self.own_answers.append(raw)
                        await self._put(raw)
                if not self.endpoint.clients:
                    continue  # nobody to pass the token to
                self._token_back.clear()
                self.tool_has_token = True
                self.holds.append(TokenHold(time.monotonic()))
                await self._put(codec.encode_token(self.master_address, sa=self.next_master))
                try:
                    await asyncio.wait_for(self._token_back.wait(), TOKEN_LOST_S)
                except TimeoutError:
                    self.token_lost += 1  # the token is regenerated by the second master
                    self.tool_has_token = False
        except asyncio.CancelledError:
            pass

    @property
    def hold_times_s(self) -> list[float]:
        """How long the tool held the token each time it passed it on."""
        return [h.held_s for h in self.holds if h.held_s is not None]

    async def stop(self) -> None:
        self._ticker.stop()
        for task in list(self._answering):
            task.cancel()
        if self._master_task:
            self._master_task.cancel()
            self._master_task = None
        await self.endpoint.stop()


__all__ = ["Mo64Twin", "Mo64TcpSim", "Mo64Rs485Sim", "TokenHold"]
