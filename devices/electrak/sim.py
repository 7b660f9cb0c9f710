"""Electrak HD twin: N actuators on one CAN bus that answer as the document says.

Each actuator sends its status telegram every 100 ms and answers every service request
for itself, from its own parameter set (so the answers can disagree, go missing or err).
Motion follows the control telegram: toward the target at the commanded speed, ramped up
over the soft-start time and slowed over the soft-stop distance, no faster than the load
allows (then Saturated is set). Current rises with a simulated load and trips the overload
flag above the limit (held longer than 40 ms, not during start-up). Every actuator checks
the control telegram against its own model, gearing and stroke (parameter flag). A voltage
or temperature fault lets a running motion go on for 10 s and refuses new ones until it is
gone. A load that moves a standing rod raises Backdrive. Message timeout, too-few-devices,
override/reset, passwords, error answers, both save forms and a bit rate that applies at
power-up are simulated; an active manual control line makes the network send 0x06 itself.
"""

from __future__ import annotations

import asyncio
import math
import time
from dataclasses import dataclass, field

from devices import simserver
from devices.electrak import codec
from devices.electrak.params import BITRATE_SPECIFIER, PARAMS, TIMEOUT_SPECIFIER, length_of, password_of
from devices.simcontrols import NP_, SimAction, SimControls, SimParam

TICK_S = 0.01
STARTUP_S = 0.15  # the current limit does not apply while the motor starts (inrush)
OVERLOAD_HOLD_S = 0.04
NO_LOAD_A = {"MD12": 1.2, "HD24": 0.8, "HD48": 0.5}
CALIBRATED_FRACTION = 0.85  # the calibrated limit: a little above the rated load
SPEED_LOSS_AT_LIMIT = 0.5  # top speed lost at the calibrated current (the twin's motor curve)
BACKDRIVE_DETECT_MM = 0.5  # uncommanded rod travel that raises Backdrive
PARAMETER, OVERLOAD, VOLTAGE, TEMPERATURE, BACKDRIVE, TIMEOUT, SEVERE, TOO_FEW = (1 << b for b in range(8))
BLOCKING = PARAMETER | OVERLOAD | TIMEOUT | SEVERE | TOO_FEW  # "no motion while set" on any device


def factory_values() -> dict[int, int]:
    return {0x01: 300, 0x02: 50, BITRATE_SPECIFIER: codec.bitrate_code(codec.DEFAULT_BITRATE), TIMEOUT_SPECIFIER: 250, 0x08: 0}


@dataclass
class ServiceValues:
    values: dict[int, int] = field(default_factory=factory_values)
    saved: dict[int, int] = field(default_factory=factory_values)
    unlocked: set[int] = field(default_factory=set)  # passwords written
    saves: int = 0


@dataclass
class ActuatorTwin:
    actuator: codec.Actuator
    position_mm: float = 0.0
    speed_mm_s: float = 0.0
    current_a: float = 0.0
    motion: int = 0
    errors: int = 0
    load_a: float = 0.0  # extra motor current from the simulated load
    backdrive_mm_s: float = 0.0  # a static load that moves the rod while it stands (+ out, - in)
    present: bool = True
    voltage_fault: bool = False
    temperature_fault: bool = False
    moving_since: float | None = None
    over_since: float | None = None
    fault_direction: int = 0  # direction of motion when overload/severe fault tripped
    hold_mm: float | None = None  # where the rod stopped (backdrive reference)
    service: ServiceValues = field(default_factory=ServiceValues)
    bitrate: int = codec.DEFAULT_BITRATE  # the bit rate it runs at (a new one applies at power-up)
    save_lengths: set[int] = field(default_factory=lambda: {4})  # strict: the parameter table's length
    service_silent: bool = False  # fault injection: no service answers
    service_error: int | None = None  # fault injection: every service answer is this error
    service_stuck: set[int] = field(default_factory=set)  # fault injection: confirms writes, keeps the value

    def __post_init__(self) -> None:
        self.limits = codec.Limits.of_one(self.actuator)

    @property
    def calibrated_limit_a(self) -> float:
        return codec.CURRENT_LIMIT_A[self.actuator.model] * CALIBRATED_FRACTION

    def answer(self, message: codec.ServiceMessage) -> codec.ServiceMessage | None:
        """This actuator's answer to one service request (None: it stays silent)."""

        def error(code: int) -> codec.ServiceMessage:
            return codec.ServiceMessage(codec.ServiceType.ERROR_RESPONSE, message.specifier, message.length, code)

        def confirm(value: int) -> codec.ServiceMessage:
            return codec.ServiceMessage(codec.ServiceType.WRITE_CONFIRMATION, message.specifier, message.length, value)

        if self.service_silent:
            return None
        if self.service_error is not None:
            return error(self.service_error)
        s = self.service
        if message.type not in (codec.ServiceType.READ_REQUEST, codec.ServiceType.WRITE_REQUEST):
            return error(codec.ERROR_WRONG_ID)
        if message.specifier == codec.PASSWORD_SPECIFIER:
            if message.type != codec.ServiceType.WRITE_REQUEST:
                return error(codec.ERROR_PERMISSION)
            if message.length != 4:
                return error(codec.ERROR_WRONG_SIZE)
            if message.payload not in {password_of(p) for p in PARAMS}:
                return error(codec.ERROR_NOT_FOUND)  # OBJECT_NOT_FOUND/INCORRECT_PASSWORD
            s.unlocked.add(message.payload)
            return confirm(message.payload)
        if message.specifier == codec.SAVE_SPECIFIER:
            if message.type != codec.ServiceType.WRITE_REQUEST:
                return error(codec.ERROR_PERMISSION)
            if message.length not in self.save_lengths:
                return error(codec.ERROR_WRONG_SIZE)
            s.saved = dict(s.values)
            s.saves += 1
            return confirm(0)
        param = PARAMS.get("service", message.specifier)
        if param is None:
            return error(codec.ERROR_NOT_FOUND)
        if message.length != length_of(param):
            return error(codec.ERROR_WRONG_SIZE)
        if password_of(param) not in s.unlocked:
            return error(codec.ERROR_PERMISSION)
        if message.type == codec.ServiceType.READ_REQUEST:
            return codec.ServiceMessage(codec.ServiceType.READ_RESPONSE, message.specifier, message.length, s.values[message.specifier])
        value = message.value
        if param.enum is not None and value not in param.enum:
            return error(codec.ERROR_WRONG_SIZE)
        if message.specifier not in self.service_stuck:
            s.values[message.specifier] = value  # a new bit rate applies at power-up (params.BITRATE_AT_POWER_UP)
        return confirm(value)

    def power_cycle(self) -> None:
        self.service.values = dict(self.service.saved)
        self.service.unlocked.clear()
        self.bitrate = codec.BITRATES[self.service.values[BITRATE_SPECIFIER]]
        self.errors = 0
        self.motion = 0
        self.speed_mm_s = 0.0
        self.moving_since = self.over_since = None


class ElectrakNetworkTwin:
    """The physics and the protocol state of one Electrak network."""

    def __init__(self, actuators: list[codec.Actuator], name: str = "electrak", bus_bitrate: int = codec.DEFAULT_BITRATE):
        self.name = name
        self.bus_bitrate = bus_bitrate
        self.actuators = [ActuatorTwin(a, bitrate=bus_bitrate) for a in actuators]
        for a in self.actuators:
            a.service.values[BITRATE_SPECIFIER] = a.service.saved[BITRATE_SPECIFIER] = codec.bitrate_code(bus_bitrate)
        self.expected = len(actuators)
        self.control: codec.ControlFrame | None = None
        self.last_control = -math.inf
        self.control_gap = math.inf  # time between the last two control telegrams
        self.manual_line = 0  # +1 extend / -1 retract: a control line is active, the network sends 0x06
        self.env_fault_since: float | None = None
        self.motion_request: float | None = None  # target of the motion that runs (None: none)
        self.motion_started: float | None = None

    @property
    def service(self) -> ServiceValues:
        """The first actuator's parameters (as the page shows them; each actuator has its own)."""
        return self.actuators[0].service

    # -- demo controls ----------------------------------------------------------------------
    def set_load(self, load_a: float, index: int | None = None) -> None:
        for i, a in enumerate(self.actuators):
            if index is None or i == index:
                a.load_a = max(0.0, load_a)

    def set_backdrive(self, speed_mm_s: float, index: int | None = None) -> None:
        for i, a in enumerate(self.actuators):
            if index is None or i == index:
                a.backdrive_mm_s = speed_mm_s

    def set_manual_line(self, direction: int) -> None:
        """Activate a manual control line (+1 out, -1 in, 0 off): the actuators send 0x06 themselves."""
        self.manual_line = (direction > 0) - (direction < 0)

    def manual_control(self) -> codec.ControlFrame | None:
        """The control telegram the network sends while a manual line is active."""
        if not self.manual_line:
            return None
        limits = codec.Limits.of([a.actuator for a in self.actuators])
        speed = self.service.values[0x08] / 10 or limits.speed_max  # "Geschwindigkeit" lowers the manual speed
        target = limits.stroke_mm if self.manual_line > 0 else 0.0
        return codec.ControlFrame(target, 0.0, min(max(speed, limits.speed_min), limits.speed_max), enable=True)

    def set_voltage_fault(self, on: bool) -> None:
        """A supply voltage fault on every actuator (or its end)."""
        for a in self.actuators:
            a.voltage_fault = on

    def set_temperature_fault(self, on: bool) -> None:
        """A temperature fault on the first actuator (or its end)."""
        self.actuators[0].temperature_fault = on

    def disagree(self, on: bool) -> None:
        """The last actuator's soft start time differs from the first's (reads of it fail, as they should)."""
        self.actuators[-1].service.values[0x01] = self.actuators[0].service.values[0x01] + (100 if on else 0)

    def disagrees(self) -> bool:
        return self.actuators[-1].service.values[0x01] != self.actuators[0].service.values[0x01]

    def controls(self) -> SimControls:
        """What an engineer may do to this network in simulation (shown by pages/simcontrols.py, through the gate)."""

        def connected(i: int) -> SimAction:
            return SimAction(f"actuator {i + 1} connected", f"actuator {i + 1} connected",
                             lambda on: self.restore(i) if on else self.remove(i),
                             state=lambda: self.actuators[i].present, testid=f"connected-{i + 1}")

        actions = [
            SimAction(NP_("simulation", "extra load"), "Set load", lambda amps: self.set_load(amps), icon="fitness_center",
                      testid="load", params=(SimParam(NP_("simulation", "amps"), "extra load [A]", 0, 0, 25),)),
            SimAction(NP_("simulation", "static load"), "Set static load", lambda speed: self.set_backdrive(speed),
                      icon="south_east", testid="static-load",
                      params=(SimParam(NP_("simulation", "speed"), "rod load [mm/s]", 0, -5, 5),)),
            *(connected(i) for i in range(len(self.actuators))),
            SimAction(NP_("simulation", "supply voltage fault"), "Supply voltage fault", self.set_voltage_fault,
                      state=lambda: any(a.voltage_fault for a in self.actuators), testid="voltage-fault"),
            SimAction(NP_("simulation", "temperature fault"), "Temperature fault", self.set_temperature_fault,
                      state=lambda: self.actuators[0].temperature_fault, testid="temperature-fault"),
            SimAction(NP_("simulation", "manual control line"), "Set manual control line",
                      lambda direction: self.set_manual_line(direction), icon="settings_remote", testid="manual-line",
                      params=(SimParam(NP_("simulation", "direction"), "1 out, -1 in, 0 off", 0, -1, 1),)),
        ]
        if len(self.actuators) > 1:
            actions.append(SimAction(NP_("simulation", "last actuator disagrees"), "last actuator disagrees", self.disagree,
                                     state=self.disagrees, testid="disagree"))
        actions.append(SimAction(NP_("simulation", "power cycle"), "Power-cycle actuators", self.power_cycle,
                                 icon="power_settings_new", testid="power-cycle"))
        return SimControls("Simulated actuators (demo)", tuple(actions),
                           note="Load raises the motor current (above the limit: overload); a rod load moves a standing "
                                "rod (Backdrive; negative pushes it in); an active manual control line makes the network send 0x06 "
                                "itself; the disagreeing actuator's soft start time differs, so reads of it fail.")

    def remove(self, index: int) -> None:
        self.actuators[index].present = False

    def restore(self, index: int) -> None:
        self.actuators[index].present = True

    def power_cycle(self) -> None:
        for a in self.actuators:
            a.power_cycle()
        self.expected = len(self.present)
        self.motion_request = self.motion_started = None

    @property
    def present(self) -> list[ActuatorTwin]:
        """The actuators on this bus: connected and at the bus's bit rate."""
        return [a for a in self.actuators if a.present and a.bitrate == self.bus_bitrate]

    # -- protocol --------------------------------------------------------------------------
    def on_control(self, frame: codec.ControlFrame, now: float) -> None:
        self.control_gap = now - self.last_control
        self.control = frame
        self.last_control = now
        if frame.override:
            self.expected = len(self.present)  # override/reset: count the devices anew

    def on_service(self, message: codec.ServiceMessage) -> list[codec.ServiceMessage]:
        """The answers of the networked actuators to one service request, one each."""
        return [answer for a in self.present if (answer := a.answer(message)) is not None]

    # -- physics ----------------------------------------------------------------------------
    def step(self, dt: float, now: float) -> None:
        present = self.present
        c = self.control
        too_few = len(present) < self.expected
        for a in present:
            timeout_s = a.service.values[TIMEOUT_SPECIFIER] / 1000
            # set after the timeout without a control telegram; cleared only once they come within it
            timed_out = now - self.last_control > timeout_s or self.control_gap > timeout_s
            param_error = c is not None and bool(a.limits.check(c.position_mm, c.current_a, c.speed_mm_s))
            a.errors &= ~(PARAMETER | TIMEOUT | TOO_FEW | VOLTAGE | TEMPERATURE)
            a.errors |= (PARAMETER if param_error else 0) | (TIMEOUT if timed_out else 0) | (TOO_FEW if too_few else 0)
            a.errors |= (VOLTAGE if a.voltage_fault else 0) | (TEMPERATURE if a.temperature_fault else 0)
        enabled = c is not None and c.enable and not c.override
        request = c.position_mm if enabled else None
        if request != self.motion_request:  # a new motion request (or none)
            self.motion_request, self.motion_started = request, None
        env_fault = any(a.errors & (VOLTAGE | TEMPERATURE) for a in present)
        if not env_fault:
            self.env_fault_since = None
        elif self.env_fault_since is None:
            self.env_fault_since = now
        env_block = env_fault and not (
            self.motion_started is not None and self.motion_started < self.env_fault_since  # it ran before the fault
            and now - self.env_fault_since < codec.ENV_FAULT_RUN_ON_S
        )
        if env_block:
            self.motion_started = None  # it ended: when the fault is gone, the request starts anew
        moved = False
        for a in present:
            moved |= self._move(a, dt, now, c, env_block)
        if moved and self.motion_started is None:
            self.motion_started = now
        elif not moved and not any(a.moving_since for a in present):
            self.motion_started = None

    def at_rest(self) -> bool:
        """Nothing for :meth:`step` to move: no rod runs, coasts or is pushed, no current decays, no motion is
        requested or ordered by a manual line (the status frames still go out every STATUS_PERIOD_S)."""
        c = self.control
        if self.motion_started is not None or self.env_fault_since is not None or self.manual_control() is not None:
            return False
        for a in self.present:
            if a.moving_since is not None or a.speed_mm_s or a.backdrive_mm_s or a.current_a > 0.005:
                return False
            if c is not None and c.enable and not c.override and abs(c.position_mm - a.position_mm) > 0.05:
                return False
        return True

    def _blocked(self) -> bool:
        return any(a.errors & BLOCKING for a in self.present)

    def _move(self, a: ActuatorTwin, dt: float, now: float, c: codec.ControlFrame | None, env_block: bool) -> bool:
        enabled = c is not None and c.enable and not c.override
        if not enabled and c is not None:
            a.errors &= ~(OVERLOAD | SEVERE)  # dropping the enable bit clears overload and severe fault
        direction = 0
        if enabled and c is not None:
            delta = c.position_mm - a.position_mm
            direction = (delta > 0.05) - (delta < -0.05)
            if a.errors & (OVERLOAD | SEVERE) and direction and direction != a.fault_direction:
                a.errors &= ~(OVERLOAD | SEVERE)  # moving the other way clears them
        if not enabled or env_block or self._blocked() or direction == 0 or c is None:
            a.speed_mm_s = 0.0  # dynamic braking: the actuators stop at once
            a.moving_since = None
            a.over_since = None
            a.motion = 0
            a.current_a += (0.0 - a.current_a) * min(1.0, dt * 30)
            self._hold(a, dt)
            return False
        a.errors &= ~BACKDRIVE  # assumption: cleared by the next commanded motion (codec.ERROR_FLAGS)
        a.hold_mm = None
        low, high = codec.SPEED_RANGE_MM_S[a.actuator.gearing]
        top = high * max(0.2, 1.0 - SPEED_LOSS_AT_LIMIT * a.load_a / a.calibrated_limit_a)  # what supply and load allow
        target_speed = min(c.speed_mm_s, top)
        if a.moving_since is None:
            a.moving_since = now
        soft_start_s = a.service.values[0x01] / 1000
        ramp = 1.0 if soft_start_s <= 0 else min(1.0, (now - a.moving_since) / soft_start_s)
        remaining = abs(c.position_mm - a.position_mm)
        soft_stop_mm = a.service.values[0x02] / 10
        slow = 1.0 if soft_stop_mm <= 0 else min(1.0, max(0.15, remaining / soft_stop_mm))
        a.speed_mm_s = max(0.5, target_speed * ramp * slow)
        step = min(remaining, a.speed_mm_s * dt)
        a.position_mm = min(max(a.position_mm + direction * step, 0.0), a.actuator.stroke_mm)
        a.motion = 1 if direction > 0 else 2
        if c.speed_mm_s > top and ramp >= 1.0 and slow >= 1.0:
            a.motion |= 1 << 2  # Saturated: at the highest speed the supply and the load allow
        startup = now - a.moving_since < STARTUP_S
        running_a = NO_LOAD_A[a.actuator.model] + a.load_a
        target_a = running_a * (2.0 if startup else 1.0)
        a.current_a += (target_a - a.current_a) * min(1.0, dt * 40)
        limit = c.current_a if c.current_a > 0 else a.calibrated_limit_a
        if not startup and a.current_a > limit:
            a.over_since = a.over_since or now
            if now - a.over_since > OVERLOAD_HOLD_S:
                a.errors |= OVERLOAD
                a.fault_direction = direction
                a.speed_mm_s = 0.0
                a.motion = 0
        else:
            a.over_since = None
        return True

    def _hold(self, a: ActuatorTwin, dt: float) -> None:
        """A standing rod: a strong static load (or vibration) may still move it."""
        if a.hold_mm is None:
            a.hold_mm = a.position_mm
        if a.backdrive_mm_s:
            a.position_mm = min(max(a.position_mm + a.backdrive_mm_s * dt, 0.0), a.actuator.stroke_mm)
            a.speed_mm_s = abs(a.backdrive_mm_s) if 0.0 < a.position_mm < a.actuator.stroke_mm else 0.0
        if abs(a.position_mm - a.hold_mm) > BACKDRIVE_DETECT_MM:
            a.errors |= BACKDRIVE

    def status(self, a: ActuatorTwin) -> codec.StatusFrame:
        return codec.StatusFrame(
            round(a.position_mm, 1), round(max(a.current_a, 0.0), 1), round(a.speed_mm_s, 1), a.motion, a.errors,
        )


class ElectrakSim:
    """The twins of every Electrak network (one per plant device) of one CAN bus."""

    def __init__(self, bus, devices, open_can):
        self.bus_config = bus
        self.bitrate = bus.options.get("bitrate", codec.DEFAULT_BITRATE)
        self.twins: dict[str, ElectrakNetworkTwin] = {}
        for dev in devices:
            actuators = [codec.Actuator(a["model"], a["gearing"], float(a["stroke_mm"])) for a in dev.options["actuators"]]
            self.twins[dev.name] = ElectrakNetworkTwin(actuators, dev.name, bus_bitrate=self.bitrate)
        options = {k: v for k, v in bus.options.items() if k != "simulate"}
        self.can = open_can(f"{bus.name} (simulated actuators)", options)
        self.can.subscribe(False, codec.CONTROL_ID, self.on_control)
        self.can.subscribe(False, codec.SERVICE_REQUEST_ID, self.on_service)
        self._next_status = time.monotonic() + codec.STATUS_PERIOD_S
        # steps every TICK_S while a rod moves, else only when the status frames are due (or a telegram comes)
        self.ticker = simserver.Ticker(self._step, TICK_S, self._rest)
        self._task: asyncio.Task | None = None

    def on_control(self, msg) -> None:
        try:
            frame = codec.ControlFrame.decode(bytes(msg.data))
        except codec.CodecError:
            return
        self.ticker.wake()  # a control telegram may start a motion: stepped up to now, then at TICK_S
        for twin in self.twins.values():
            if twin.present:
                twin.on_control(frame, time.monotonic())

    def on_service(self, msg) -> None:
        try:
            request = codec.ServiceMessage.decode(bytes(msg.data))
        except codec.CodecError:
            return
        self.ticker.wake()
        for twin in self.twins.values():
            for answer in twin.on_service(request):  # every networked device answers for itself
                self.can.send(codec.SERVICE_RESPONSE_ID, answer.encode())

    async def start(self) -> None:
        await self.can.start()
        self._next_status = time.monotonic() + codec.STATUS_PERIOD_S
        self.ticker.start(f"sim {self.bus_config.name} electrak")
        self._task = self.ticker.task

    def _rest(self, now: float) -> float:
        """0 while a rod moves; else until the next status frames are due (simserver.Ticker)."""
        if not all(twin.at_rest() for twin in self.twins.values()):
            return 0.0
        return max(0.0, self._next_status - now) + 0.001

    def _step(self, dt: float, now: float) -> None:
        for twin in self.twins.values():
            twin.step(dt, now)
        if now >= self._next_status:
            self._next_status += codec.STATUS_PERIOD_S
            if now > self._next_status:
                self._next_status = now + codec.STATUS_PERIOD_S
            for twin in self.twins.values():
                manual = twin.manual_control() if twin.present else None
                if manual is not None:  # the actuator with the active line sends the control telegram
                    self.can.send(codec.CONTROL_ID, manual.encode())
                    twin.on_control(manual, now)
                for a in twin.present:
                    self.can.send(codec.STATUS_ID, twin.status(a).encode())

    async def stop(self) -> None:
        self.ticker.stop()
        self._task = None
        await self.can.stop()
