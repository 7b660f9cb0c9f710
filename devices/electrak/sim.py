"""Electrak HD twin: N actuators on one CAN bus that answer as the document says.

Each actuator sends its status telegram every 100 ms. Motion follows the control
telegram: toward the target at the commanded speed within the gearing's range,
ramped up over the soft-start time and slowed over the soft-stop distance. Current
rises with a simulated load and trips the overload flag above the limit (held longer
than 40 ms, not during start-up). Message timeout, parameter range, too-few-devices
and the service parameters with passwords, error responses and save are simulated.
"""

from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass, field

from devices.electrak import codec
from devices.electrak.params import PARAMS, length_of, password_of

TICK_S = 0.01
STARTUP_S = 0.15  # the current limit does not apply while the motor starts (inrush)
OVERLOAD_HOLD_S = 0.04
NO_LOAD_A = {"MD12": 1.2, "HD24": 0.8, "HD48": 0.5}
CALIBRATED_FRACTION = 0.85  # the calibrated limit: a little above the rated load


@dataclass
class ActuatorTwin:
    actuator: codec.Actuator
    position_mm: float = 0.0
    speed_mm_s: float = 0.0
    current_a: float = 0.0
    motion: int = 0
    errors: int = 0
    load_a: float = 0.0  # extra motor current from the simulated load
    present: bool = True
    voltage_fault: bool = False
    temperature_fault: bool = False
    moving_since: float | None = None
    over_since: float | None = None
    fault_direction: int = 0  # direction of motion when overload/severe fault tripped

    @property
    def calibrated_limit_a(self) -> float:
        return codec.CURRENT_LIMIT_A[self.actuator.model] * CALIBRATED_FRACTION


@dataclass
class ServiceValues:
    values: dict[int, int] = field(default_factory=lambda: {0x01: 300, 0x02: 50, 0x04: 2, 0x06: 250, 0x08: 0})
    saved: dict[int, int] = field(default_factory=dict)
    unlocked: set[int] = field(default_factory=set)  # passwords written
    saves: int = 0


class ElectrakNetworkTwin:
    """The physics and the protocol state of one Electrak network."""

    def __init__(self, actuators: list[codec.Actuator], name: str = "electrak"):
        self.name = name
        self.actuators = [ActuatorTwin(a) for a in actuators]
        self.expected = len(actuators)
        self.service = ServiceValues()
        self.service.saved = dict(self.service.values)
        self.control: codec.ControlFrame | None = None
        self.last_control = 0.0
        self.can_bitrate = codec.DEFAULT_BITRATE
        self.limits = codec.Limits.of(actuators)

    # -- demo controls ----------------------------------------------------------------------
    def set_load(self, load_a: float, index: int | None = None) -> None:
        for i, a in enumerate(self.actuators):
            if index is None or i == index:
                a.load_a = max(0.0, load_a)

    def remove(self, index: int) -> None:
        self.actuators[index].present = False

    def restore(self, index: int) -> None:
        self.actuators[index].present = True

    @property
    def present(self) -> list[ActuatorTwin]:
        return [a for a in self.actuators if a.present]

    # -- protocol --------------------------------------------------------------------------
    def on_control(self, frame: codec.ControlFrame, now: float) -> None:
        self.control = frame
        self.last_control = now
        if frame.override:
            self.expected = len(self.present)  # override/reset: count the devices anew

    def on_service(self, message: codec.ServiceMessage) -> codec.ServiceMessage:
        """The answer of an actuator to one service request."""

        def error(code: int) -> codec.ServiceMessage:
            return codec.ServiceMessage(codec.ServiceType.ERROR_RESPONSE, message.specifier, message.length, code)

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
            return codec.ServiceMessage(codec.ServiceType.WRITE_CONFIRMATION, message.specifier, 4, message.payload)
        if message.specifier == codec.SAVE_SPECIFIER:
            if message.type != codec.ServiceType.WRITE_REQUEST:
                return error(codec.ERROR_PERMISSION)
            s.saved = dict(s.values)
            s.saves += 1
            return codec.ServiceMessage(codec.ServiceType.WRITE_CONFIRMATION, message.specifier, message.length, 0)
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
        s.values[message.specifier] = value
        if message.specifier == 0x04:
            self.can_bitrate = codec.BITRATES[value]
        return codec.ServiceMessage(codec.ServiceType.WRITE_CONFIRMATION, message.specifier, message.length, value)

    def power_cycle(self) -> None:
        self.service.values = dict(self.service.saved)
        self.service.unlocked.clear()
        self.can_bitrate = codec.BITRATES[self.service.values[0x04]]

    # -- physics ----------------------------------------------------------------------------
    def step(self, dt: float, now: float) -> None:
        present = self.present
        timeout_s = self.service.values[0x06] / 1000
        timed_out = now - self.last_control > timeout_s
        c = self.control
        param_error = c is not None and bool(self.limits.check(c.position_mm, c.current_a, c.speed_mm_s))
        too_few = len(present) < self.expected
        for a in present:
            a.errors &= ~(1 << 0 | 1 << 5 | 1 << 7 | 1 << 2 | 1 << 3)
            a.errors |= (1 << 0 if param_error else 0) | (1 << 5 if timed_out else 0) | (1 << 7 if too_few else 0)
            a.errors |= (1 << 2 if a.voltage_fault else 0) | (1 << 3 if a.temperature_fault else 0)
        blocking = any(a.errors & 0b1110_0011 for a in present)  # parameter, overload, timeout, severe, too few
        for a in present:
            self._move(a, dt, now, c, blocking)

    def _move(self, a: ActuatorTwin, dt: float, now: float, c: codec.ControlFrame | None, blocking: bool) -> None:
        enabled = c is not None and c.enable and not c.override
        if not enabled and c is not None:
            a.errors &= ~(1 << 1 | 1 << 6)  # dropping the enable bit clears overload and severe fault
        direction = 0
        if enabled and c is not None:
            delta = c.position_mm - a.position_mm
            direction = (delta > 0.05) - (delta < -0.05)
            if a.errors & (1 << 1 | 1 << 6) and direction and direction != a.fault_direction:
                a.errors &= ~(1 << 1 | 1 << 6)  # moving the other way clears them
                blocking = any(x.errors & 0b1110_0011 for x in self.present)
        if not enabled or blocking or direction == 0 or c is None:
            a.speed_mm_s = 0.0  # dynamic braking: the actuators stop at once
            a.moving_since = None
            a.over_since = None
            a.motion = 0
            a.current_a += (0.0 - a.current_a) * min(1.0, dt * 30)
            return
        low, high = codec.SPEED_RANGE_MM_S[a.actuator.gearing]
        target_speed = min(max(c.speed_mm_s, low), high)
        if a.moving_since is None:
            a.moving_since = now
        soft_start_s = self.service.values[0x01] / 1000
        ramp = 1.0 if soft_start_s <= 0 else min(1.0, (now - a.moving_since) / soft_start_s)
        remaining = abs(c.position_mm - a.position_mm)
        soft_stop_mm = self.service.values[0x02] / 10
        slow = 1.0 if soft_stop_mm <= 0 else min(1.0, max(0.15, remaining / soft_stop_mm))
        a.speed_mm_s = max(0.5, target_speed * ramp * slow)
        step = min(remaining, a.speed_mm_s * dt)
        a.position_mm = min(max(a.position_mm + direction * step, 0.0), a.actuator.stroke_mm)
        a.motion = 1 if direction > 0 else 2
        if self.present and a.speed_mm_s >= high * 0.99 and a.load_a > 0:
            a.motion |= 1 << 2  # saturated under load at top speed
        startup = now - a.moving_since < STARTUP_S
        running_a = NO_LOAD_A[a.actuator.model] + a.load_a
        target_a = running_a * (2.0 if startup else 1.0)
        a.current_a += (target_a - a.current_a) * min(1.0, dt * 40)
        limit = c.current_a if c.current_a > 0 else a.calibrated_limit_a
        if not startup and a.current_a > limit:
            a.over_since = a.over_since or now
            if now - a.over_since > OVERLOAD_HOLD_S:
                a.errors |= 1 << 1
                a.fault_direction = direction
                a.speed_mm_s = 0.0
                a.motion = 0
        else:
            a.over_since = None

    def status(self, a: ActuatorTwin) -> codec.StatusFrame:
        return codec.StatusFrame(
            round(a.position_mm, 1), round(max(a.current_a, 0.0), 1), round(a.speed_mm_s, 1), a.motion, a.errors,
        )


class ElectrakSim:
    """The twins of every Electrak network (one per plant device) of one CAN bus."""

    def __init__(self, bus, devices):
        from app.can_bus import CanBus, CanBusState

        self.bus_config = bus
        self.bitrate = bus.options.get("bitrate", codec.DEFAULT_BITRATE)
        self.twins: dict[str, ElectrakNetworkTwin] = {}
        for dev in devices:
            actuators = [codec.Actuator(a["model"], a["gearing"], float(a["stroke_mm"])) for a in dev.options["actuators"]]
            twin = ElectrakNetworkTwin(actuators, dev.name)
            twin.can_bitrate = self.bitrate
            self.twins[dev.name] = twin
        options = {k: v for k, v in bus.options.items() if k != "simulate"}
        self.can = CanBus(f"{bus.name} (simulated actuators)", options, CanBusState(bus.name, "can", ""))
        self.can.subscribe(False, codec.CONTROL_ID, self.on_control)
        self.can.subscribe(False, codec.SERVICE_REQUEST_ID, self.on_service)
        self._task: asyncio.Task | None = None

    def _active(self) -> list[ElectrakNetworkTwin]:
        return [t for t in self.twins.values() if t.can_bitrate == self.bitrate]

    def on_control(self, msg) -> None:
        try:
            frame = codec.ControlFrame.decode(bytes(msg.data))
        except codec.CodecError:
            return
        for twin in self._active():
            twin.on_control(frame, time.monotonic())

    def on_service(self, msg) -> None:
        try:
            request = codec.ServiceMessage.decode(bytes(msg.data))
        except codec.CodecError:
            return
        for twin in self._active():
            answer = twin.on_service(request)
            for _actuator in twin.present:  # every networked device answers
                self.can.send(codec.SERVICE_RESPONSE_ID, answer.encode())

    async def start(self) -> None:
        await self.can.start()
        self._task = asyncio.create_task(self._run(), name=f"sim {self.bus_config.name} electrak")

    async def _run(self) -> None:
        last = time.monotonic()
        next_status = last + codec.STATUS_PERIOD_S
        while True:
            await asyncio.sleep(TICK_S)
            now = time.monotonic()
            for twin in self.twins.values():
                twin.step(now - last, now)
            last = now
            if now >= next_status:
                next_status += codec.STATUS_PERIOD_S
                if now > next_status:
                    next_status = now + codec.STATUS_PERIOD_S
                for twin in self._active():
                    for a in twin.present:
                        self.can.send(codec.STATUS_ID, twin.status(a).encode())

    async def stop(self) -> None:
        if self._task:
            self._task.cancel()
            self._task = None
        await self.can.stop()
