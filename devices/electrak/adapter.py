"""An Electrak HD network on a shared CAN bus: status, control with keep-alive, service parameters."""

from __future__ import annotations

import asyncio
import time
from collections import deque
from dataclasses import dataclass

from app.state import DeviceState
from devices.electrak import codec
from devices.electrak.params import PARAMS, SERVICE, length_of, password_of
from devices.params import Param, ParamError, backup_entry

SERVICE_TIMEOUT_S = 0.3
SERIES = ("Position [mm]", "Current [A]", "Speed [mm/s]", "Target [mm]")


class CommandError(Exception):
    """A command that did not take effect; the message says what to do."""


class ControlBusy(CommandError):
    """Another session holds control."""


@dataclass
class Controller:
    session: str
    user: str
    since: float


class ElectrakAdapter:
    """The network of actuators of one plant device (status frames cannot be told apart)."""

    params = PARAMS
    transport = "can"

    def __init__(self, config, state: DeviceState, bus):
        self.config = config
        self.state = state
        self.bus = bus
        self.actuators = [codec.Actuator(a["model"], a["gearing"], float(a["stroke_mm"])) for a in config.options["actuators"]]
        self.limits = codec.Limits.of(self.actuators)
        self.state.params = PARAMS
        self.state.stale_after = 1.0  # status every 100 ms
        self.state.info.update(configured=len(self.actuators), heard=0, actuators=self.actuators, limits=self.limits)
        self.command = codec.ControlFrame(0.0, 0.0, self.limits.speed_min, enable=False)
        self.controller: Controller | None = None
        self.frames: deque[tuple[float, codec.StatusFrame]] = deque(maxlen=200)
        self._last_sample = 0.0
        self._service_waiters: dict[int, asyncio.Future] = {}
        self._service_answers: dict[int, int] = {}
        self._service_lock = asyncio.Lock()
        bus.subscribe(False, codec.STATUS_ID, self.on_status)
        bus.subscribe(False, codec.SERVICE_RESPONSE_ID, self.on_service)
        self.key = f"electrak control {config.name}"

    # -- status ----------------------------------------------------------------------------
    def on_status(self, msg) -> None:
        try:
            frame = codec.StatusFrame.decode(bytes(msg.data))
        except codec.CodecError as exc:
            self.state.counters.malformed += 1
            self.state.error(f"malformed status telegram: {exc}", log=False)
            return
        now = time.time()
        self.frames.append((now, frame))
        self.state.counters.responses += 1
        self.state.mark_seen(now)
        heard = sum(1 for t, _ in self.frames if now - t <= 1.0) / 10  # frames per 100 ms = devices heard
        # the newest telegram of each device: the last `heard` frames (they cannot be told apart)
        recent = [f for _, f in list(self.frames)[-max(1, round(heard)):]]
        info = self.state.info
        info["heard"] = round(heard)
        info["status"] = recent
        info["motion"] = 0
        info["errors"] = 0
        for f in recent:
            info["motion"] |= f.motion
            info["errors"] |= f.errors
        if now - self._last_sample >= 0.09 and recent:
            self._last_sample = now
            self.state.add_history({
                "Position [mm]": round(sum(f.position_mm for f in recent) / len(recent), 1),
                "Current [A]": max(f.current_a for f in recent),
                "Speed [mm/s]": round(sum(f.speed_mm_s for f in recent) / len(recent), 1),
                "Target [mm]": self.command.position_mm,
            }, now)

    async def poll(self) -> None:
        """Service parameters are read on demand; the status arrives by itself."""
        if self.state.age is not None and self.state.age > self.state.stale_after * 3 and self.state.online:
            self.state.mark_offline("no status telegram for more than 3 s: check the bus and the actuators' power")

    # -- control ---------------------------------------------------------------------------
    def _control_frame(self):
        return codec.CONTROL_ID, self.command.encode(), False

    def take_control(self, session: str, user: str) -> None:
        if self.controller is not None and self.controller.session != session:
            raise ControlBusy(f"{self.controller.user} holds control since {time.strftime('%H:%M:%S', time.localtime(self.controller.since))}")
        if self.controller is None:
            self.controller = Controller(session, user, time.time())
            self.state.info["controlled_by"] = user
            self.command = codec.ControlFrame(self.command.position_mm, self.command.current_a, self.command.speed_mm_s, enable=False)
            self.bus.start_cyclic(self.key, codec.CONTROL_PERIOD_S, self._control_frame)
            self.state.event("info", f"{user} took control; control telegrams every 100 ms")

    def release_control(self, session: str, reason: str = "released") -> bool:
        """Drop the enable bit, send it once more and stop the keep-alive."""
        if self.controller is None or (session and self.controller.session != session):
            return False
        user = self.controller.user
        self.command = codec.ControlFrame(self.command.position_mm, self.command.current_a, self.command.speed_mm_s, enable=False)
        self.bus.stop_cyclic(self.key)
        self.bus.send(*self._control_frame())
        self.controller = None
        self.state.info["controlled_by"] = None
        self.state.event("warning", f"control {reason} ({user}): enable cleared, control telegrams stopped")
        return True

    def _check_holder(self, session: str) -> None:
        if self.controller is None:
            raise CommandError("take control first")
        if self.controller.session != session:
            raise ControlBusy(f"{self.controller.user} holds control")

    def set_command(self, session: str, position_mm: float, speed_mm_s: float, current_a: float) -> None:
        """New target, speed and current limit (validated); keeps the enable bit as it is."""
        self._check_holder(session)
        problems = self.limits.check(position_mm, current_a, speed_mm_s)
        if problems:
            raise CommandError("; ".join(problems))
        self.command = codec.ControlFrame(position_mm, current_a, speed_mm_s, enable=self.command.enable)

    def go(self, session: str) -> None:
        self._check_holder(session)
        c = self.command
        problems = self.limits.check(c.position_mm, c.current_a, c.speed_mm_s)
        if problems:
            raise CommandError("; ".join(problems))
        self.command = codec.ControlFrame(c.position_mm, c.current_a, c.speed_mm_s, enable=True)
        self.state.event("info", f"go: target {c.position_mm:g} mm at {c.speed_mm_s:g} mm/s, limit {c.current_a:g} A")

    def stop(self, session: str | None = None) -> None:
        """Clear the enable bit (anyone may stop)."""
        c = self.command
        self.command = codec.ControlFrame(c.position_mm, c.current_a, c.speed_mm_s, enable=False)
        if self.controller is None:
            self.bus.send(*self._control_frame())
        self.state.event("info", "stop: enable cleared")

    def jog(self, session: str, direction: int, speed_mm_s: float | None = None) -> None:
        """Hold-to-run: move toward an end while held (direction +1 out, -1 in); 0 stops."""
        self._check_holder(session)
        c = self.command
        if direction == 0:
            current = self.position_mm()
            target = c.position_mm if current is None else round(current, 1)
            self.command = codec.ControlFrame(target, c.current_a, c.speed_mm_s, enable=False)
            return
        speed = speed_mm_s or c.speed_mm_s
        target = self.limits.stroke_mm if direction > 0 else 0.0
        problems = self.limits.check(target, c.current_a, speed)
        if problems:
            raise CommandError("; ".join(problems))
        self.command = codec.ControlFrame(target, c.current_a, speed, enable=True)

    def override(self, session: str, active: bool) -> None:
        """Override/reset bit: holds motion and resets the expected number of devices."""
        self._check_holder(session)
        c = self.command
        self.command = codec.ControlFrame(c.position_mm, c.current_a, c.speed_mm_s, enable=False, override=active)

    def position_mm(self) -> float | None:
        recent = self.state.info.get("status") or []
        return sum(f.position_mm for f in recent) / len(recent) if recent else None

    # -- service parameters ----------------------------------------------------------------------
    def on_service(self, msg) -> None:
        try:
            answer = codec.ServiceMessage.decode(bytes(msg.data))
        except codec.CodecError as exc:
            self.state.counters.malformed += 1
            self.state.error(f"malformed service answer: {exc}", log=False)
            return
        self._service_answers[answer.specifier] = self._service_answers.get(answer.specifier, 0) + 1
        future = self._service_waiters.get(answer.specifier)
        if future is not None and not future.done():
            future.set_result(answer)

    async def _service(self, request: codec.ServiceMessage) -> codec.ServiceMessage:
        loop = asyncio.get_running_loop()
        future = loop.create_future()
        self._service_waiters[request.specifier] = future
        self._service_answers[request.specifier] = 0
        self.state.counters.requests += 1
        try:
            if not self.bus.send(codec.SERVICE_REQUEST_ID, request.encode(), False):
                raise CommandError(f"CAN bus {self.bus.name} did not take the frame: {self.bus.state.last_error or 'bus not open'}")
            try:
                answer = await asyncio.wait_for(future, SERVICE_TIMEOUT_S)
            except asyncio.TimeoutError:
                self.state.counters.timeouts += 1
                raise CommandError(f"no service answer to 0x{request.specifier:02X} within {SERVICE_TIMEOUT_S} s") from None
            await asyncio.sleep(0.02)  # the other actuators' answers
        finally:
            self._service_waiters.pop(request.specifier, None)
        count = self._service_answers.get(request.specifier, 0)
        self.state.info["service_answers"] = count
        if answer.type == codec.ServiceType.ERROR_RESPONSE:
            self.state.counters.exceptions += 1
            raise CommandError(f"0x{request.specifier:02X}: {answer.error_name}")
        return answer

    async def _unlock(self, param: Param) -> None:
        await self._service(codec.password_request(password_of(param)))

    async def read_param(self, param: Param) -> int:
        async with self._service_lock:
            await self._unlock(param)
            answer = await self._service(codec.read_request(param.address, length_of(param)))
        self.state.update_registers(SERVICE, param.address, [answer.value])
        return answer.value

    async def read_all(self) -> dict[str, int]:
        return {p.name: await self.read_param(p) for p in PARAMS}

    async def write_param(self, param: Param, value, *, confirmed: bool = False) -> int:
        """Password, write, read back (document "Passwort", "Beispiel einer Parameter-Änderung")."""
        try:
            raw = param.prepare_write(value, confirmed=confirmed)
        except ParamError as exc:
            raise CommandError(str(exc)) from None
        async with self._service_lock:
            await self._unlock(param)
            await self._service(codec.write_request(param.address, length_of(param), raw))
            if param.address == 0x04:  # the actuators left this bus: nothing to read back
                self.state.update_registers(SERVICE, param.address, [raw])
                self.state.unsaved.add(param.key)
                self.state.event("warning", f"bit rate set to {param.display(raw)}: switch the bus too")
                return raw
            back = (await self._service(codec.read_request(param.address, length_of(param)))).value
        self.state.update_registers(SERVICE, param.address, [back])
        if back != raw:
            self.state.counters.write_errors += 1
            raise CommandError(f"{param.name}: read back {param.display(back)} instead of {param.display(raw)}")
        self.state.unsaved.add(param.key)
        self.state.event("info", f"{param.name} = {param.display(raw)} written and read back (not yet saved)")
        return raw

    # -- backup and restore (app/backup.py) --------------------------------------------------
    async def backup_read(self, progress=None) -> list[dict]:
        entries = []
        for n, param in enumerate(PARAMS, 1):
            entries.append(backup_entry(param, await self.read_param(param)))
            if progress:
                progress(n / len(PARAMS.params))
        return entries

    def backup_identity(self) -> dict:
        return {"actuators": [f"{a.model} {a.gearing} {a.stroke_mm:g} mm" for a in self.actuators]}

    async def restore_entry(self, key: str, raw: int) -> int:
        param = PARAMS.by_key.get(key)
        if param is None:
            raise CommandError(f"{key} is not an Electrak service parameter")
        return await self.write_param(param, param.decode(int(raw)), confirmed=True)

    async def save_step(self) -> str:
        await self.save_parameters()
        return "save parameters (0xF0)"

    async def save_parameters(self) -> None:
        async with self._service_lock:
            await self._service(codec.save_request())
        self.state.unsaved.clear()
        self.state.event("info", "parameters saved (0xF0)")
