"""SCU twin: one simulated Ewellix control unit on a point-to-point RS232 line.

The line is a TCP port (the master opens it as a pyserial ``socket://`` URL). Every behaviour
follows document 002, as strict as the unit could be:

* remote session (section 4.1, table 3): RO opens remote mode with a Safety_ID, RA ends it; every
  other command answers PE outside remote mode, and also after RO until the first RC came
  (section 5: "Bevor das erste Kommando ... muss ebenfalls eine Kommunikation mit RC stattgefunden haben");
* the RC watchdog: no RC for 500 ms drops remote mode, stops the motions (all, or with Safety_ID 2
  only the remote ones) and sets error bit 22;
* CSE on a bad checksum, PCE on a wrong count, PDE on a wrong ID or value, ICE on an unknown command;
  silence for bytes that start no telegram and for a telegram cut short (inter-byte limit 1000 ms);
* the data directory (tables 6, 7) read with RG by data ID or group ID, remote data written with RT,
  cyclic objects 0x3001.. exchanged with RC;
* functions (section 4.4): F1..F10 move their actuators (SCP11: F(n) drives actuator n, section 5)
  to In, Out, Mem1..4, Intermediate In/Out or the remote position, with a soft start/stop ramp at the
  remote speed; actuators stop at their end positions; buzzer, binary outputs, LEDs, emergency stop.

Demo controls on :class:`ScuTwin`: :meth:`~ScuTwin.add_load`, :meth:`~ScuTwin.trip_actuator_error`,
:meth:`~ScuTwin.switch_to_battery`, :meth:`~ScuTwin.drop_line`; :attr:`~ScuTwin.re_without_rs` counts
RE commands that ended without their RS (section 4.6: every RE must be stopped with RS).
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from devices import simserver
from devices.scu import codec, params
from devices.scu.actuator_twin import (DEFAULT_COUNTS_PER_MM, DEFAULT_IN_COUNTS, DEFAULT_OUT_COUNTS, IDLE_CURRENT_A,
                                       ActuatorTwin, actuator_configs)
from devices.scu.codec import Function, Motion, Ramp, Status
from devices.simcontrols import NP_, SimAction, SimControls, SimParam

log = logging.getLogger(__name__)

TICK_S = 0.02
MAX_SPEED_COUNTS_S = 600.0  # 100 % remote speed (absolute speed select allows up to 1000 counts/s, table 7)
RAMP_S = 0.4  # soft start/stop: 0 -> 100 % in this time
DEFAULT_REMOTE_SPEED = 100  # "Voreinstellung: Funktionsgeschwindigkeit aus der Konfiguration" (table 7), % here
RUN_CURRENT_A = 1.5  # at 100 % speed without load
PEAK_CURRENT_A = 12.0  # above it the actuator trips (error bits 15..20: peak / over current)
MAINS_VOLTAGE_V = 27.2  # battery voltage while charging
BATTERY_FULL_V = 25.6
FIRMWARE_INFO = "SCU V2B3 twin CS 0000"
CONFIGURATION_INFO = "SCP11 single run twin V1.0 CS 0000"

_ACTUATOR_ERROR_BITS = tuple(codec.ERROR_BITS[14 + n].mask for n in range(1, 7))
# Bits table 10 clears "mit nächster Bewegung": 14 (total current), 15..20 (actuators), 21 (position difference).
# Bit 22 (remote timeout) names no clearing condition: the twin keeps it until the next motion the same
# way, so a master that reopens the session can still read why it was lost (section 4.5, table 10).
_CLEARED_BY_MOTION = codec.CLEARED_BY_NEXT_MOVE


@dataclass
class ScuStrict:
    """Strict modes a real unit may have (document 002 allows each) and injected faults, off by default; set
    before the first byte or while the twin runs (``twin.strict.<name>``)."""

    single_ids_only: bool = False  # groups refused with PDE (the document describes only 0x0010, section 4.6)
    refuse_cyclic_rc: bool = False  # the definition of 0x3001 is taken, RC with index 0..4 answers PDE
    rg_outside_session: bool = False  # True: RG answered without remote mode (section 4.1 says it is not)
    cse_on_rs: int = 0  # the next N RS answer CSE and are not executed (-1: every RS)
    answer_delay_s: float = 0.0  # each answer this late (section 3 allows up to 2000 ms)
    # the document's other readings (SPEC-NOTES) and older firmware
    ro_two_bytes_only: bool = False  # PCE to RO with the Safety_ID alone: RO takes para_ID[0] too (table 3)
    rs_three_bytes_only: bool = False  # PCE to the two-byte RS: RS takes para_ID[0] and para_ID[1] (table 3 text)
    v2b0: bool = False  # firmware before V2B1: no F20 (table 8), RE/RS 19 answered PDE
    rt_cyclic_unanswered: bool = False  # the definition of a cyclic object (RT 0x3001..) gets no answer
    cse_next: dict[str, int] = field(default_factory=dict)  # command -> the next N of it answered CSE (line noise)
    ignores_watchdog: bool = False  # a broken unit: no RC for 500 ms stops nothing (the checkout must see it)
    stray_bytes: int = 0  # the next N answers come with a stray byte in front (a noisy line)
    split_answers: bool = False  # answers come in two pieces with a pause between (inter-byte gap)
    # data IDs the unit's parametrisation does not have (a function or actuator it was not configured with): RG
    # and RT of them, and of a group holding one, answer PDE ("Fehler in den Telegramm-Datenbytes", section 4.2)
    refused_ids: set[int] = field(default_factory=set)
    line_dropped: bool = False  # fault injection: the unit answers nothing


@dataclass
class ScuIo:
    """The unit's supply, inputs and outputs (table 6)."""

    mains: bool = True
    battery_v: float = MAINS_VOLTAGE_V
    binary_inputs: int = 0
    analogue: list[int] = field(default_factory=lambda: [0, 0, 0, 0])
    binary_outputs: int = 0
    led_hs: int = 0
    led_lb: int = 0
    buzzer: bool = False
    sensor_supply: bool = True


@dataclass
class ScuStatistics:
    """The unit's statistics data IDs (table 6): error history and the peaks it keeps."""

    history: list[int] = field(default_factory=lambda: [0, 0, 0, 0])  # 0x00D2 .. 0x00D5
    total_over_current: int = 0
    max_total_current_a: float = 0.0
    max_temp_adc: int = 96
    over_temp_count: int = 0


class ScuTwin:
    """The unit's state and its answers; :meth:`handle` takes one item of a request splitter."""

    def __init__(self, name: str = "scu", actuators: Any = 2, safety_id: int = 1, speed_select: str = "relative"):
        self.name = name
        self.speed_select = speed_select  # table 7: relative 0 .. 100 %, absolute 0 .. 1000 counts/s
        self.configured_safety_id = safety_id
        self.actuators: list[ActuatorTwin] = []
        for n, cfg in enumerate(actuator_configs(actuators), 1):
            lo = int(cfg.get("in_counts", DEFAULT_IN_COUNTS))
            cpm = float(cfg.get("counts_per_mm") or DEFAULT_COUNTS_PER_MM)
            hi = int(cfg.get("out_counts") or (lo + round(float(cfg["stroke_mm"]) * cpm) if cfg.get("stroke_mm")
                                               else DEFAULT_OUT_COUNTS))
            if cfg.get("stroke_mm") and not cfg.get("counts_per_mm"):
                cpm = (hi - lo) / float(cfg["stroke_mm"])
            span = hi - lo
            act = ActuatorTwin(n, lo, hi, cpm, position=float(lo))
            mems = [lo + span * k // 5 for k in (1, 2, 3, 4)]
            for u in range(1, params.USERS + 1):
                for k, name_ in enumerate(("Position_Memory_1", "Position_Memory_2", "Position_Memory_3",
                                           "Position_Memory_4")):
                    act.user_positions[f"{name_}[USER_{u}]"] = mems[k]
                act.user_positions[f"Position_Intermediate_In[USER_{u}]"] = lo + span // 10
                act.user_positions[f"Position_Intermediate_Out[USER_{u}]"] = hi - span // 10
            act.user_positions["Position_Virtual_Limit_In"] = lo
            act.user_positions["Position_Virtual_Limit_Out"] = hi
            self.actuators.append(act)
        self.user = 1
        # remote data (table 7): volatile, defaults after reset
        self.reset_remote_data()
        # session
        self.remote = False
        self.safety_id: int | None = None
        self.rc_seen = False
        self.last_rc = 0.0
        self.session_lost_count = 0
        # I/O and the unit's statistics (data IDs 0x00D0..)
        self.io = ScuIo()
        self.emergency_stop = False
        self.lock_status = 0
        self.error_code = 0
        self.statistics = ScuStatistics()
        self.strict = ScuStrict()
        self.resets = 0
        self.keys = 0  # Actual_State_Keys (0x0040)
        self.function_log: list[tuple[str, int]] = []  # (RE/RS, fnc_ID) in the order executed
        self.function_times: list[float] = []  # monotonic time of each function_log entry
        self.watchdog_trips: list[float] = []
        self.rc_received: deque[float] = deque(maxlen=5000)  # monotonic times of the RCs that fed the watchdog  # monotonic times the RC watchdog ended remote mode
        # counters
        self.open_re: dict[int, float] = {}  # fnc_ID -> time of an RE not yet stopped with RS
        self.re_without_rs = 0
        self.answers = 0
        self.requests: dict[str, int] = {}

    def reset_remote_data(self) -> None:
        """Remote data back to their defaults, as after a reset (table 7: "In flüchtigen Registern gespeichert.
        Initialisiert nach Reset mit voreingestellten Werten")."""
        self.cyclic: list[tuple[int, ...]] = [(params.NO_DATA_ID,) * 12 for _ in codec.CYCLIC_OBJECT_IDS]
        self.remote_speed = [DEFAULT_REMOTE_SPEED] * params.FUNCTIONS
        self.remote_position = [a.user_positions["Position_Memory_1[USER_1]"] for a in self.actuators]

    def reset(self) -> None:
        """A reset of the unit (power cycle): every motion stops, remote mode ends, the remote data are back at
        their defaults (table 7): what a real unit does that a twin kept running would hide."""
        now = time.monotonic()
        for act in self.actuators:
            act.stop()
        if self.remote:
            self._end_session(now, "reset")
        self.emergency_stop = False
        self.reset_remote_data()
        self.resets += 1

    def _refused(self, data_id: int) -> bool:
        entry = params.DIRECTORY.get(data_id)
        members = entry.members if entry is not None and entry.is_group else ()
        return data_id in self.strict.refused_ids or any(m in self.strict.refused_ids for m in members)

    # -- demo controls ----------------------------------------------------------------------------
    def controls(self) -> SimControls:
        """What an engineer may do to this unit in simulation (shown by pages/simcontrols.py, through the gate)."""
        n = len(self.actuators)
        actuator = SimParam(NP_("simulation", "actuator"), "actuator", 1, 1, n)
        return SimControls("Simulated SCU (demo)", (
            SimAction(NP_("simulation", "add load"), "Add load", lambda to, amps: self.add_load(to, amps), icon="fitness_center",
                      testid="add-load", params=(SimParam(NP_("simulation", "to"), "load on actuator", 1, 1, n),
                                                 SimParam(NP_("simulation", "amps"), "load [A]", 3, -20, 20))),
            SimAction(NP_("simulation", "actuator error"), "Trip actuator error", self.trip_actuator_error, icon="error",
                      testid="actuator-error", params=(actuator,)),
            SimAction("on battery", "On battery (mains off)", self.switch_to_battery,
                      state=lambda: not self.io.mains, testid="on-battery"),
            SimAction("line dropped", "Line dropped (no answers)", self.drop_line,
                      state=lambda: self.strict.line_dropped, testid="line-dropped"),
            SimAction(NP_("simulation", "reset"), "Reset the unit", self.reset, icon="restart_alt", testid="reset-unit"),
        ), note="Load raises the current of a moving actuator (above 12 A it trips); an actuator error stops it fast "
                "and sets its error bit; a dropped line ends remote mode within 500 ms; a reset ends remote mode and "
                "sets the remote speeds and positions back to their defaults (volatile, table 7).")

    def add_load(self, actuator: int, amps: float) -> None:
        """Add ``amps`` of load current to actuator 1..6 while it moves (negative removes load)."""
        act = self.actuators[actuator - 1]
        act.load_a = max(0.0, act.load_a + amps)

    def trip_actuator_error(self, actuator: int) -> None:
        """Actuator error (bits 15..20: peak current, sensor monitor, ...): fast stop, counted (table 10)."""
        act = self.actuators[actuator - 1]
        act.errors = min(act.errors + 1, 0xFFFF)
        act.peak_current_count = min(act.peak_current_count + 1, 0xFF)
        self._stop_actuator(act)
        self.raise_error(_ACTUATOR_ERROR_BITS[actuator - 1])

    def switch_to_battery(self, on_battery: bool = True) -> None:
        """Mains off (battery operation) or back on (0x0100 bits 0, 2, 3)."""
        self.io.mains = not on_battery
        if on_battery:
            self.io.battery_v = min(self.io.battery_v, BATTERY_FULL_V)

    def drop_line(self, dropped: bool = True) -> None:
        """Stop answering (a pulled cable or DTR/RTS off): requests are read and ignored."""
        self.strict.line_dropped = dropped

    # -- errors -------------------------------------------------------------------------------------
    def raise_error(self, mask: int) -> None:
        """Set error bits in Error_Code 1; the previous code shifts into the history (0x00D2..0x00D5)."""
        new = self.error_code | mask
        if new == self.error_code:
            return
        if self.error_code:
            self.statistics.history = [self.error_code, *self.statistics.history[:-1]]
        self.error_code = new

    # -- session and motion -------------------------------------------------------------------------
    def _stop_actuator(self, act: ActuatorTwin) -> None:
        act.stop()

    def _end_session(self, now: float, reason: str) -> None:
        self.remote = False
        self.rc_seen = False
        for act in self.actuators:
            if act.moving:
                self._stop_actuator(act)  # the twin has no hand switch: every motion is a remote motion
        self.re_without_rs += len(self.open_re)
        self.open_re.clear()
        self.io.binary_outputs = 0
        self.io.buzzer = False
        log.info("%s: remote mode ended (%s)", self.name, reason)

    def check_watchdog(self, now: float) -> bool:
        """Drop remote mode when RC did not come for 500 ms (section 4.1, table 3); True if it tripped."""
        if self.remote and now - self.last_rc > codec.WATCHDOG_S and not self.strict.ignores_watchdog:
            self.session_lost_count += 1
            self.watchdog_trips.append(now)
            self.raise_error(codec.REMOTE_TIMEOUT_MASK)
            self._end_session(now, "no RC for 500 ms")
            return True
        return False

    def _target(self, act: ActuatorTwin, motion: Motion) -> float | None:
        u = self.user
        pos = act.user_positions
        table = {
            Motion.IN: act.in_counts, Motion.OUT: act.out_counts,
            Motion.MEM1: pos[f"Position_Memory_1[USER_{u}]"], Motion.MEM2: pos[f"Position_Memory_2[USER_{u}]"],
            Motion.MEM3: pos[f"Position_Memory_3[USER_{u}]"], Motion.MEM4: pos[f"Position_Memory_4[USER_{u}]"],
            Motion.INTERMEDIATE_IN: pos[f"Position_Intermediate_In[USER_{u}]"],
            Motion.INTERMEDIATE_OUT: pos[f"Position_Intermediate_Out[USER_{u}]"],
            Motion.REMOTE_POSITION: self.remote_position[act.number - 1],
        }
        if motion not in table:
            return None
        return float(min(max(table[motion], act.in_counts), act.out_counts))  # the end positions bound every move

    def function_actuators(self, function: int) -> list[ActuatorTwin]:
        """SCP11 (section 5): function F(n) drives actuator n alone."""
        return [a for a in self.actuators if a.number == function + 1]

    def _start(self, function: int, motion: Motion, ramp: int) -> int:
        acts = self.function_actuators(function)
        if not acts:
            return Status.PDE  # no actuator is assigned to this function in the configuration
        if self.emergency_stop:
            return Status.PE  # F20 holds every motion: "nicht möglich im aktuellen SCU-Zustand" (table 4.4)
        self.error_code &= ~_CLEARED_BY_MOTION  # "Bit wird mit nächster Bewegung zurückgesetzt" (table 10)
        for act in acts:
            target = self._target(act, motion)
            if target is None:
                continue  # motion 0: undefined direction, no motion (table 9)
            direction = (target > act.position) - (target < act.position)
            if direction == 0:
                continue
            if act.direction != direction:
                if direction > 0:
                    act.relay_out += 1
                else:
                    act.relay_in += 1
                act.speed = 0.0  # a start or a reversal begins from standstill
            act.target, act.direction, act.function, act.motion = target, direction, function, motion
            act.soft = ramp != Ramp.FAST  # -1: the configuration's default, soft here
        return Status.ACK

    def step(self, dt: float, now: float | None = None) -> None:
        """Advance motion, currents and the supply by ``dt`` seconds."""
        if now is not None:
            self.check_watchdog(now)
        accel = MAX_SPEED_COUNTS_S / RAMP_S
        total = 0.0
        for act in self.actuators:
            if not act.moving:
                act.current_a = IDLE_CURRENT_A
                continue
            pct = self.remote_speed[act.function] if act.function is not None else DEFAULT_REMOTE_SPEED
            if self.speed_select == "absolute" and act.function is not None:  # counts/s (table 7)
                v_set = float(min(pct, MAX_SPEED_COUNTS_S))
            else:
                v_set = MAX_SPEED_COUNTS_S * min(pct, 100) / 100.0
            dist = abs(act.target - act.position)
            if act.soft:
                v_new = act.speed + accel * dt if act.speed < v_set else max(act.speed - accel * dt, v_set)
                v_new = min(v_new, v_set, math.sqrt(2 * accel * dist) + accel * dt)  # soft stop before the target
            else:
                v_new = v_set
            act.speed = max(v_new, 0.0)
            travel = act.speed * dt
            if v_set <= 0:
                travel = 0.0
            if travel >= dist:
                travel = dist
                act.position = act.target
                act.cumulated_stroke += travel
                act.stop()  # target or end position reached; the function stays executed until RS
                continue
            act.position += act.direction * travel
            act.cumulated_stroke += travel
            act.current_a = RUN_CURRENT_A * act.speed / MAX_SPEED_COUNTS_S + 0.3 + act.load_a
            act.max_current_a = max(act.max_current_a, act.current_a)
            total += act.current_a
            if act.current_a > PEAK_CURRENT_A:
                self.trip_actuator_error(act.number)
        self.statistics.max_total_current_a = max(self.statistics.max_total_current_a, total)
        if self.io.mains:
            self.io.battery_v += (MAINS_VOLTAGE_V - self.io.battery_v) * min(1.0, dt / 5.0)
        else:
            self.io.battery_v = max(20.0, self.io.battery_v - (0.002 + 0.01 * total) * dt)

    def rest(self, now: float) -> float:
        """How long :meth:`step` has nothing to do (simserver.Ticker): 0 while an actuator moves or the battery
        charges; else until the remote watchdog falls due (if a session is open)."""
        if any(act.moving for act in self.actuators) or (self.io.mains and MAINS_VOLTAGE_V - self.io.battery_v > 0.01):
            return 0.0
        if self.remote:
            # the watchdog is found past its limit as by the ticks every TICK_S: up to one tick late
            return max(0.0, self.last_rc + codec.WATCHDOG_S - now) + TICK_S
        return math.inf

    # -- data directory ----------------------------------------------------------------------------
    def _act(self, n: int) -> ActuatorTwin | None:
        return self.actuators[n - 1] if n <= len(self.actuators) else None

    def value(self, data_id: int) -> Any:
        """The current value of a leaf data ID, in the form its value type encodes."""
        entry = params.item(data_id)
        if entry.is_group:
            return {m: self.value(m) for m in entry.members}
        n = entry.actuator
        if n is not None:
            act = self._act(n)
            group = entry.group
            if group == 0x1010:
                return act.counts_per_mm if act else 0.0
            if group == 0x2000:
                return dict(act.user_positions) if act else {k: 0 for k, _ in params.ACTUATOR_POSITIONS.members}
            if group == 0x3020:
                return self.remote_position[n - 1] if act else 0
            if act is None:
                return 0
            return {
                0x0010: lambda: round(act.position),
                0x0060: lambda: act.relay_in, 0x0070: lambda: act.relay_out,
                0x0080: lambda: act.errors | act.peak_current_count << 16 | act.short_circuit_count << 24,
                0x0090: lambda: round(act.cumulated_stroke),
                0x00A0: lambda: round(act.current_a, 1), 0x00B0: lambda: round(act.max_current_a, 1),
                0x00E0: lambda: act.status_2,
                0x00F0: lambda: round(100 * act.speed / MAX_SPEED_COUNTS_S),
                0x0170: lambda: act.status_1,
            }[group]()
        if entry.function is not None:
            return self.remote_speed[entry.function - 1]
        if 0x3001 <= data_id <= 0x3005:
            return list(self.cyclic[data_id - 0x3001])
        if 0x0031 <= data_id <= 0x0034:
            return self.io.analogue[data_id - 0x0031] / 100
        if 0x00D1 <= data_id <= 0x00D5:
            return [self.error_code, *self.statistics.history][data_id - 0x00D1]
        battery_mains = int(self.io.mains) | 1 << 1 | int(self.io.mains) << 2 | int(self.io.mains and self.io.battery_v < 27.0) << 3
        fixed = {
            0x0001: FIRMWARE_INFO, 0x0002: CONFIGURATION_INFO, 0x0020: self.io.binary_inputs, 0x0040: self.keys,
            0x008F: self.statistics.total_over_current, 0x00BF: round(self.statistics.max_total_current_a, 1), 0x00C0: self.statistics.max_temp_adc,
            0x00C1: self.statistics.over_temp_count, 0x0100: battery_mains, 0x0110: self.io.binary_outputs, 0x0120: self.io.led_hs,
            0x0130: self.io.led_lb, 0x0140: int(self.io.buzzer), 0x0150: int(self.io.sensor_supply),
            0x0162: self.lock_status, 0x0164: round(self.io.battery_v, 1), 0x0165: 0, 0x0166: self.user,
        }
        return fixed[data_id]

    def read(self, data_id: int) -> bytes:
        return params.encode_data(data_id, self.value(data_id), remote_only=False)

    def write(self, data_id: int, data: bytes) -> int:
        """RT / RC write data to remote data ``data_id``; returns the answer code."""
        entry = params.DIRECTORY.get(data_id)
        if entry is None or not entry.writable or self._refused(data_id):
            return Status.PDE  # "Nur data_Ids 3xxx sind erlaubt" (table 3), and only those of table 7
        if len(data) != entry.size:
            return Status.PCE
        value = entry.vtype.decode(data)
        if 0x3001 <= data_id <= 0x3005:
            try:
                definition = params.CyclicDefinition.decode(data)
            except (ValueError, KeyError):
                return Status.PDE  # an unknown data ID, or a write slot outside 0x3xxx (table 7)
            if self.strict.single_ids_only and any(params.item(i).is_group for i in definition.read_ids):
                return Status.PDE
            self.cyclic[data_id - 0x3001] = tuple(value)
        elif entry.function is not None:
            if value > (100 if self.speed_select == "relative" else 1000):
                return Status.PDE  # speed select relative: 0 .. 100 %, absolute: 0 .. 1000 counts/s (table 7)
            self.remote_speed[entry.function - 1] = value
        elif entry.actuator is not None:
            act = self._act(entry.actuator)
            if act is None:
                return Status.PDE  # no such actuator on this unit
            self.remote_position[entry.actuator - 1] = value
            if act and act.moving and act.motion == Motion.REMOTE_POSITION:  # a moving remote target follows
                target = self._target(act, Motion.REMOTE_POSITION)
                direction = (target > act.position) - (target < act.position)
                if direction == act.direction:
                    act.target = target
                else:
                    act.stop()  # behind it now: stop rather than reverse without a new RE
        return Status.ACK

    # -- requests -----------------------------------------------------------------------------------
    def handle(self, item: Any, now: float | None = None) -> bytes | None:
        """The answer to one item of a :class:`devices.scu.codec.FrameSplitter` (requests), or None."""
        now = time.monotonic() if now is None else now
        if self.strict.line_dropped:
            return None
        self.check_watchdog(now)
        if isinstance(item, codec.Request):
            self.requests[item.command.decode()] = self.requests.get(item.command.decode(), 0) + 1
            answer = self._request(item, now)
        elif isinstance(item, codec.ChecksumError):
            answer = _answer(item.raw[:2], Status.CSE)
        elif isinstance(item, (codec.ParameterCountError, codec.ParameterDataError)):
            answer = _answer(item.raw[:2], item.status)
        elif isinstance(item, codec.GarbageError) and len(item.raw) >= 4 and _looks_like_command(item.raw):
            answer = _answer(item.raw[:2], Status.ICE)  # a telegram with an unknown command code (table 4.4)
        else:
            return None  # bytes that start no telegram, or a telegram cut short: nothing to answer
        if answer is not None:
            self.answers += 1
        return answer

    def _request(self, req: codec.Request, now: float) -> bytes:
        cmd = req.command
        if self.strict.cse_next.get(cmd.decode()):
            self.strict.cse_next[cmd.decode()] -= 1
            return _answer(cmd, Status.CSE)  # damaged on the way (section 4.2): not executed
        if cmd == codec.RG and not self.remote and self.strict.rg_outside_session:
            return self._rg(req)
        if cmd == codec.RO:
            if self.strict.ro_two_bytes_only and len(req.params) < 2:
                return _answer(cmd, Status.PCE)
            self.remote, self.safety_id, self.rc_seen, self.last_rc = True, req.safety_id, False, now
            return _answer(cmd, Status.ACK)
        if cmd == codec.RA:
            if self.remote:
                self._end_session(now, "RA")
            return _answer(cmd, Status.ACK)
        if not self.remote:
            return _answer(cmd, Status.PE)  # section 4.1: only while remote mode is open
        if cmd == codec.RC:
            return self._rc(req, now)
        if not self.rc_seen:
            return _answer(cmd, Status.PE)  # section 5: an RC must come before the first command
        if cmd == codec.RG:
            return self._rg(req)
        if cmd == codec.RT:
            if self.strict.rt_cyclic_unanswered and req.data_id in codec.CYCLIC_OBJECT_IDS:
                return None
            return _answer(cmd, self.write(req.data_id, req.data))
        if cmd in (codec.RE, codec.RS) and self.strict.v2b0 and req.function == Function.EMERGENCY_STOP:
            return _answer(cmd, Status.PDE)  # table 8: F20 from firmware V2B1
        if cmd == codec.RE:
            return _answer(cmd, self._execute(req.function, req.para, now))
        if cmd == codec.RS:
            if self.strict.rs_three_bytes_only and len(req.params) < 3:
                return _answer(cmd, Status.PCE)
            if self.strict.cse_on_rs:
                self.strict.cse_on_rs -= 1 if self.strict.cse_on_rs > 0 else 0
                return _answer(cmd, Status.CSE)  # "Fehler in der Telegramm-Checksumme": not executed (section 4.2)
            return _answer(cmd, self._stop(req.function))
        return _answer(cmd, Status.ICE)

    def _rg(self, req: codec.Request) -> bytes:
        entry = params.DIRECTORY.get(req.data_id)
        if entry is None or (self.strict.single_ids_only and entry.is_group) or self._refused(req.data_id):
            return _answer(codec.RG, Status.PDE)
        return codec.encode_answer(codec.RG, Status.ACK, self.read(req.data_id))

    def _rc(self, req: codec.Request, now: float) -> bytes:
        if req.index == -1:
            if req.data:
                return _answer(codec.RC, Status.PCE)
            status, read = Status.ACK, b""
        else:
            if self.strict.refuse_cyclic_rc:
                return _answer(codec.RC, Status.PDE)
            definition = params.CyclicDefinition.decode(params.CYCLIC_OBJECT.encode(self.cyclic[req.index]))
            if len(req.data) != definition.write_size:
                return _answer(codec.RC, Status.PCE)  # the watchdog is not fed by a refused RC
            at = 0
            for data_id in definition.write_ids:
                size = params.item(data_id).size
                status = self.write(data_id, req.data[at:at + size])
                if status != Status.ACK:
                    return _answer(codec.RC, status)
                at += size
            read = b"".join(self.read(i) for i in definition.read_ids)
        self.last_rc, self.rc_seen = now, True
        self.rc_received.append(now)
        return codec.encode_answer(codec.RC, Status.ACK, read)

    def _execute(self, function: int, para: tuple[int, ...], now: float) -> int:
        self.function_log.append(("RE", function))
        self.function_times.append(now)
        fn = Function(function)
        if fn in codec.MOTION_FUNCTIONS:
            status = self._start(function, Motion(para[0]), para[1])
        elif fn == Function.EMERGENCY_STOP:
            self.emergency_stop = True
            for act in self.actuators:
                act.stop()  # fast stop of every actuator
            status = Status.ACK
        else:
            self._switch(fn, True)
            status = Status.ACK
        if status == Status.ACK:
            if function in self.open_re:
                self.re_without_rs += 1  # the previous RE of this function was never stopped
            self.open_re[function] = now
        return status

    def _stop(self, function: int) -> int:
        self.function_log.append(("RS", function))
        self.function_times.append(time.monotonic())
        fn = Function(function)
        if fn in codec.MOTION_FUNCTIONS:
            for act in self.actuators:
                if act.function == function:
                    act.stop()
        elif fn == Function.EMERGENCY_STOP:
            self.emergency_stop = False
        else:
            self._switch(fn, False)
        self.open_re.pop(function, None)
        return Status.ACK

    def _switch(self, fn: Function, on: bool) -> None:
        io = self.io
        if fn == Function.BUZZER:
            io.buzzer = on
        elif fn in (Function.BINARY_OUTPUT_1, Function.BINARY_OUTPUT_2):
            mask = 1 if fn == Function.BINARY_OUTPUT_1 else 2
            io.binary_outputs = io.binary_outputs | mask if on else io.binary_outputs & ~mask
        elif fn in (Function.LED_1, Function.LED_2):
            mask = 1 if fn == Function.LED_1 else 2
            io.led_hs = io.led_hs | mask if on else io.led_hs & ~mask


def _looks_like_command(raw: bytes) -> bool:
    return all(0x41 <= b <= 0x5A for b in raw[:2])


def _answer(command: bytes, status: int) -> bytes:
    """``X Y code C1 C2``; also for command letters the unit does not know (ICE)."""
    body = bytes(command[:2]) + bytes([int(status)])
    return body + codec.crc16(body).to_bytes(2, "little")


class ScuSim:
    """The SCU of one plant-file serial bus, served on the TCP port of its ``socket://`` URL.

    Point to point (section 3, "Netzwerkebene"): one unit per line and one master at a time; a new
    connection replaces the old one. With the bus option ``wire_delay`` each answer waits for the
    wire time of request and answer at the bus's baud rate (8N1).
    """

    def __init__(self, bus, devices):
        if len(devices) != 1:
            raise ValueError(f"serial bus {bus.name}: an SCU line is point to point, one SCU per bus "
                             f"({len(devices)} configured)")
        dev = devices[0]
        self.bus = bus
        self.device = dev
        self.twin = ScuTwin(dev.name, dev.options.get("actuators", 2),
                            int(dev.options.get("safety_id", codec.DEFAULT_SAFETY_ID)),
                            dev.options.get("speed_select", "relative"))
        self.twins: dict[str, ScuTwin] = {dev.name: self.twin}
        self.baudrate = int(bus.options.get("baudrate", codec.DEFAULT_BAUDRATE))
        self.wire_delay = bool(bus.options.get("wire_delay"))
        # point to point: a new master replaces the old one
        self.endpoint = simserver.TwinServer(f"the simulated SCU line {bus.name}", self._serve, simserver.REPLACE)
        # slow while nothing moves; a telegram steps it up to its arrival without the remote watchdog's check,
        # which the telegram (an RC) feeds first, as with a tick after its bytes were read
        self._ticker = simserver.Ticker(self.twin.step, TICK_S, self.twin.rest,
                                        catch_up=lambda dt, now: self.twin.step(dt))
        # the unit's 500 ms RC watchdog counts in the unit's own time: the twin serves its line on a loop of its own
        self._own = simserver.OwnLoop(f"sim {bus.name}")

    @property
    def connections(self) -> int:
        return self.endpoint.connections

    async def start(self) -> None:
        host, port = simserver.host_port(self.bus.options["port"], "a simulated SCU line")

        async def serve() -> None:
            await self.endpoint.start(host, port)
            self._ticker.start(f"sim {self.bus.name}")

        try:
            await self._own.call(serve)
        except OSError:
            self._own.close()
            raise

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        async def answer(item) -> None:
            self._ticker.wake()  # a command may start a motion: stepped up to now, then at TICK_S
            answer = self.twin.handle(item)
            if answer is None:
                return
            if self.wire_delay:
                raw = item.raw
                await asyncio.sleep(codec.wire_time_s(len(raw) + len(answer), self.baudrate))
            twin = self.twin
            if twin.strict.answer_delay_s:
                await asyncio.sleep(twin.strict.answer_delay_s)
            if twin.strict.stray_bytes:
                twin.strict.stray_bytes -= 1
                answer = b"\x00" + answer  # noise on the line: one byte that starts no telegram
            if twin.strict.split_answers:
                cut = max(1, len(answer) // 2)
                writer.write(answer[:cut])
                await writer.drain()
                await asyncio.sleep(0.05)  # well inside the 1000 ms inter-byte limit (section 3)
                answer = answer[cut:]
            writer.write(answer)
            await writer.drain()

        # a telegram cut short (the inter-byte limit passed) is dropped without an answer
        await simserver.serve_telegrams(reader, codec.FrameSplitter(codec.REQUESTS), answer, codec.MAX_INTER_BYTE_S)

    async def stop(self) -> None:
        async def end() -> None:
            self._ticker.stop()
            await self.endpoint.stop()

        if self._own.loop is not None:
            await self._own.call(end)
        self._own.close()


__all__ = ["ScuSim", "ScuTwin", "ActuatorTwin"]
