"""An Electrak HD network on a shared CAN bus: status, control with keep-alive, service parameters."""

from __future__ import annotations

import asyncio
import functools
import itertools
import time
from collections import deque
from dataclasses import dataclass, replace

from devices.adapter import BackupDefaults
from devices import errors
from devices.control import ControlChanged, LeaseChange, Report
from devices.control import Holder as CoreHolder
from devices.electrak import codec, control
from devices.electrak.params import BITRATE_SPECIFIER, PARAMS, SERVICE, length_of, password_of, refusal
from devices.decoding import decoded
from devices.lease import Lease
from devices.live import DeviceState, Holder, Point, session_tag
from devices.message import Message, N_, joined, message_of
from devices.params import Accepted, Param, ParamError, backup_entry
from devices.transport import CanTransport

NETWORK_IDS = frozenset((codec.CONTROL_ID, codec.STATUS_ID, codec.SERVICE_REQUEST_ID, codec.SERVICE_RESPONSE_ID))
SERVICE_TIMEOUT_S = 0.3  # bound for the answers of every actuator to one service telegram
EXTRA_ANSWER_S = 0.02  # after the last expected answer: does an unexpected one follow?

# -- the facts this adapter publishes (DeviceState.publish / fact): what the page, the API and MQTT read.
# Records (frozen dataclasses below, and the codec's Actuator, Limits and ControlFrame) where a fact is more
# than a number or a word.
P_POSITION = "Position"  # mean of the actuators heard [mm]; raw: each status telegram's word (0.1 mm)
P_CURRENT = "Current"  # highest of the actuators heard [A]; raw: each telegram's word (0.1 A)
P_SPEED = "Speed"  # mean of the actuators heard [mm/s]; raw: each telegram's word (0.1 mm/s)
P_MOTION = "Motion flags"  # the motion flags of every actuator heard, or-ed; each flag also by its own name
P_ERRORS = "Error flags"  # the error flags of every actuator heard, or-ed; each flag also by its own name
P_HEARD = "Devices heard"  # status telegrams per 100 ms
P_CONFIGURED = "Devices configured"
P_STROKE = "Stroke"  # shortest configured stroke [mm]
P_ACTUATORS = "Actuators"  # tuple of codec.Actuator: model, gearing, stroke of each configured actuator
P_LIMITS = "Limits"  # codec.Limits: what every actuator of the network accepts
P_TARGET = "Target position"  # what this tool sends in the control telegram 0x06 (commanded: does not age)
P_TARGET_SPEED = "Target speed"
P_CURRENT_LIMIT = "Current limit"
P_ENABLE = "Enable"
P_OVERRIDE = "Override"
P_TELEGRAM = "Control telegram"  # codec.ControlFrame this tool sends; text: the bytes and their meaning
P_DRIVE_TARGET = "Drive target"  # the position the actuators are driven to: only while enable is sent, else None
P_CONTROLLED_BY = "Controlled by"  # the holder's user name (the tile's line), None: nobody
P_CONTROL = "Control"  # Holder: who sends the control telegram (a browser session by its tag), None: nobody
P_IDLE = "Idle"  # nobody sends the control telegram 0x06: Message timeout is the actuators' normal state
P_FOREIGN = "Foreign control sender"  # ForeignSender: the last control telegram 0x06 of another node, None: none
P_SATURATED = "Saturated warning"  # "" or the warning: Saturated stayed on too long
P_SERVICE_LAST = "Last service telegram"  # ServiceReport of the last service exchange
P_SERVICE_ANSWERS = "Service answers"  # answers to the last service telegram
# a service telegram in words (``read 0x0A``), the kind of request and its specifier
SERVICE_KINDS = {codec.ServiceType.READ_REQUEST: N_("read 0x{specifier:02X}"),
                 codec.ServiceType.WRITE_REQUEST: N_("write 0x{specifier:02X}")}
P_SERVICE_REPORTS = "Service reports"  # tuple of ServiceReport: the last exchange of each parameter
P_BITRATE_CHANGE = "Bit rate change"  # BitrateChange: a bit rate written (and saved), None: none
P_SAVE_FORM = "Save form"  # the form of save (0xF0) the network accepted last, None: not saved yet
P_BUS_BITRATE = "Bus bit rate"  # the bit rate of the CAN bus the network is on [bit/s]
SERIES = (P_POSITION, P_CURRENT, P_SPEED, P_DRIVE_TARGET)  # the history (and the chart), by point name


stop_form = control.stop_form_bytes  # the control telegram 0x06 with enable and override cleared, the rest kept


def telegram_text(c: codec.ControlFrame, sent: str) -> Message:
    """The control telegram 0x06 this tool sends, its bytes and what they mean (target, speed, current, flags)."""
    fields = {"bytes": sent, "position": float(c.position_mm), "speed": float(c.speed_mm_s), "current": float(c.current_a),
              "enable": Message(N_("enable")) if c.enable else Message(N_("no enable"))}
    if c.override:
        return Message(N_("0x006: {bytes} (target {position:g} mm, {speed:g} mm/s, {current:g} A, {enable}, override)"),
                       **fields)
    return Message(N_("0x006: {bytes} (target {position:g} mm, {speed:g} mm/s, {current:g} A, {enable})"), **fields)


class CommandError(errors.CommandError):
    """A command that did not take effect; the message says what to do."""


class ControlBusy(CommandError, errors.ControlBusy):
    """Another session holds control."""


class ForeignControl(CommandError):
    """Another node of the bus sends the control telegram 0x06."""


FOREIGN_SENDER = control.FOREIGN_SENDER
TIMEOUT_FLAG = 1 << 5  # error flags byte 7 bit 5: Message timeout


@dataclass(frozen=True, slots=True)
class ForeignSender:
    """Control telegrams 0x06 heard from another node: how many, the last one's time and meaning."""

    frames: int
    time: float
    text: str


@dataclass(frozen=True, slots=True)
class ServiceReport:
    """One service exchange with every actuator: what was asked, each answer in words, what was wrong."""

    what: str
    time: float
    answers: tuple[str, ...]
    expected: int
    problems: tuple[str, ...]
    ok: bool
    key: str | None = None  # the parameter's key, None for a password or save telegram


@dataclass(frozen=True, slots=True)
class BitrateChange:
    """A new bit rate written and read back from every actuator; ``saved``: when it was saved (None: not yet)."""

    raw: int
    written: float
    saved: float | None = None


def _refuse_as_the_document(param: Param, value) -> None:
    """:raises CommandError: the document refuses ``value`` for ``param`` (:func:`refusal`)"""
    reason = refusal(param, value)
    if reason:
        raise CommandError(reason)


class ElectrakAdapter(BackupDefaults):
    """The network of actuators of one plant device (status frames cannot be told apart)."""

    params = PARAMS
    transport = "can"

    @property
    def command(self) -> codec.ControlFrame:
        """The control telegram 0x06 this tool wants on the bus (the core's)."""
        return self.core.command

    @property
    def controller(self) -> CoreHolder | None:
        """Who controls the network (session, user, since, disconnected), None: nobody."""
        return self.core.holder

    def __init__(self, config, state: DeviceState, bus: CanTransport):
        self.config = config
        self.state = state
        self.bus = bus
        self.actuators = [codec.Actuator(a["model"], a["gearing"], float(a["stroke_mm"])) for a in config.options["actuators"]]
        self.limits = codec.Limits.of(self.actuators)
        self.state.params = PARAMS
        self.state.stale_after = 1.0  # status every 100 ms
        self.recent: list[codec.StatusFrame] = []  # the newest status telegram of each actuator heard
        self.heard = 0
        self._reports: dict[str, ServiceReport] = {}
        self.core = control.ElectrakControl(self.limits, len(self.actuators))  # the safety rules, without I/O
        self.lease = Lease()  # the periodic sender's: follows the core's lease (grant, renew, revoke)
        self.frames: deque[tuple[float, codec.StatusFrame]] = deque(maxlen=200)
        self._last_sample = 0.0
        self._status_data: bytes | None = None  # the last status telegram's bytes, and its decoding
        self._status_frame: codec.StatusFrame | None = None
        self._status_key: tuple | None = None  # what the status points were last worked out from, and their contents
        self._status_contents: dict[str, tuple] = {}
        self._pending: codec.ServiceMessage | None = None  # the service request whose answers are collected
        self._answers: list[codec.ServiceMessage] = []
        self._all_answered: asyncio.Event | None = None
        self._service_lock = asyncio.Lock()
        self._listening_reconnects = -1  # the bus's open count the core's listening window belongs to
        self._saturated_since: float | None = None
        self._foreign: ForeignSender | None = None
        self._saturated_warning = ""
        bus.subscribe(False, codec.STATUS_ID, self.on_status)
        bus.subscribe(False, codec.SERVICE_RESPONSE_ID, self.on_service)
        bus.subscribe(False, codec.CONTROL_ID, self.on_control)
        self.key = f"electrak control {config.name}"
        self.state.registers_periodic = False  # service parameters are read on demand
        state.fact(P_CONFIGURED, len(self.actuators))
        state.fact(P_STROKE, self.limits.stroke_mm, "mm", text="shortest configured stroke")
        state.fact(P_ACTUATORS, tuple(self.actuators),
                   text="; ".join(f"{a.model} {a.gearing} {a.stroke_mm:g} mm stroke" for a in self.actuators))
        limits = self.limits
        state.fact(P_LIMITS, limits, text=f"0..{limits.stroke_mm:g} mm, {limits.speed_min:g}..{limits.speed_max:g} mm/s, "
                                          f"0..{limits.current_a:g} A (0 = calibrated limit)")
        state.fact(P_BUS_BITRATE, int(bus.options.get("bitrate", codec.DEFAULT_BITRATE)), "bit/s")
        state.fact(P_FOREIGN, None, text="none heard")
        state.fact(P_SATURATED, "")
        state.fact(P_SERVICE_LAST, None, text="none yet")
        state.fact(P_SERVICE_REPORTS, ())
        state.fact(P_BITRATE_CHANGE, None, text="none")
        state.fact(P_SAVE_FORM, None, text="not saved yet")
        self._publish_command()

    # -- bus monitor ---------------------------------------------------------------------------
    def owns_frame(self, arbitration_id: int, is_extended: bool, data: bytes) -> bool:
        """Bus monitor: every frame of the network (control 0x06, status 0x07, service 0x0A/0x0B, internal
        0x600-0x6FF; standard IDs, "Das Netzwerk im Überblick"). Frames cannot be told apart by actuator."""
        return not is_extended and (arbitration_id in NETWORK_IDS or arbitration_id in codec.INTERNAL_IDS)

    # -- status ----------------------------------------------------------------------------
    def on_status(self, msg) -> None:
        """A status telegram 0x07 (every actuator sends one every 100 ms): the network's live points, one change
        for the readers (O(1): a telegram like the one before is not decoded or worded again)."""
        data = bytes(msg.data)
        if data == self._status_data:
            frame = self._status_frame
        else:
            frame = decoded(self.state, codec.StatusFrame.decode, data, "status telegram")
            if frame is None:
                return
            self._status_data, self._status_frame = data, frame
        now = time.time()
        frames = self.frames
        frames.append((now, frame))
        while now - frames[0][0] > 1.0:  # the last second's telegrams (oldest first)
            frames.popleft()
        self.state.counters.responses += 1
        heard = len(frames) / 10  # frames per 100 ms = devices heard
        # the newest telegram of each device: the last `heard` frames (they cannot be told apart)
        count = max(1, round(heard))
        recent = [f for _, f in itertools.islice(reversed(frames), count)]
        recent.reverse()
        if round(heard) != self.heard or self.core.heard is None:
            self.heard = round(heard)
            self._carry(self.core.actuators_heard(self.heard, time.monotonic()))
        self.recent = recent
        motion = errors = 0
        for f in recent:
            motion |= f.motion
            errors |= f.errors
        self._watch_saturated(motion & 0x04, time.monotonic())
        idle = self.idle()
        sample = None
        if now - self._last_sample >= 0.09:
            self._last_sample = now
            sample = functools.partial(self.state.sample_of, SERIES)
        self.state.publish_telegram(now, self._status_points(tuple(recent), motion, errors, idle, now), None, sample)
        self.state.fact(P_IDLE, idle)  # a foreign sender's window ends with time: looked at with every status

    def _status_points(self, recent: tuple[codec.StatusFrame, ...], motion: int, errors: int, idle: bool,
                       now: float) -> dict[str, Point]:
        """The live points of the network at ``now``: averages (the frames cannot be told apart), raw words per
        frame, flags by name. What they say is worked out once for the same telegrams (an idle network sends
        the same ones ten times a second); only their time is new."""
        key = (recent, self.heard, motion, errors, idle)
        if key != self._status_key:
            self._status_key, self._status_contents = key, self._status_contents_of(recent, motion, errors, idle)
        make = Point._make
        return {name: make((value, unit, now, raw, text, True, None))
                for name, (value, unit, raw, text) in self._status_contents.items()}

    def _status_contents_of(self, recent: tuple[codec.StatusFrame, ...], motion: int, errors: int,
                            idle: bool) -> dict[str, tuple]:
        """name -> (value, unit, raw, text) of every status point."""
        out: dict[str, tuple] = {}
        if recent:
            n = len(recent)
            out[P_POSITION] = (round(sum(f.position_mm for f in recent) / n, 1), "mm",
                               [round(f.position_mm * 10) for f in recent], "mean of the actuators heard")
            out[P_CURRENT] = (max(f.current_a for f in recent), "A", [round(f.current_a * 10) for f in recent],
                              "highest of the actuators heard")
            out[P_SPEED] = (round(sum(f.speed_mm_s for f in recent) / n, 1), "mm/s",
                            [round(f.speed_mm_s * 10) for f in recent], "mean of the actuators heard")
        out[P_MOTION] = (motion, "", motion,
                         ", ".join(name for bit, (name, _) in codec.MOTION_FLAGS.items() if motion >> bit & 1) or "none")
        text = ", ".join(name for bit, (name, _, _) in codec.ERROR_FLAGS.items() if errors >> bit & 1) or "none"
        if errors & TIMEOUT_FLAG and idle:
            text += " (expected while idle: nobody sends the control telegram 0x06)"
        out[P_ERRORS] = (errors, "", errors, text)
        for bit, (name, _) in codec.MOTION_FLAGS.items():
            out[name] = (bool(motion >> bit & 1), "", motion >> bit & 1, None)
        for bit, (name, *_) in codec.ERROR_FLAGS.items():
            out[name] = (bool(errors >> bit & 1), "", errors >> bit & 1, None)
        out[P_HEARD] = (self.heard, "", None, f"status telegrams per 100 ms, {len(self.actuators)} configured")
        return out

    def idle(self) -> bool:
        """Nobody sends the control telegram 0x06 (this tool holds no control, no other sender heard):
        the actuators' Message timeout is then their normal idle state, not a fault."""
        return self.controller is None and not self.foreign_sender()

    def target_mm(self) -> float | None:
        """The position the actuators are driven to: only while this tool sends enable (None otherwise,
        a gap in the chart, not a target nobody is going to)."""
        c = self.command
        return c.position_mm if self.controller is not None and c.enable and not c.override else None

    def _publish_command(self) -> None:
        """What this tool sends in the control telegram 0x06 (commanded, so it does not age)."""
        c, publish, fact = self.command, self.state.publish, self.state.fact
        publish(P_TARGET, c.position_mm, "mm", periodic=False)
        publish(P_TARGET_SPEED, c.speed_mm_s, "mm/s", periodic=False)
        publish(P_CURRENT_LIMIT, c.current_a, "A", periodic=False, text="calibrated default" if not c.current_a else None)
        publish(P_ENABLE, c.enable, periodic=False)
        publish(P_OVERRIDE, c.override, periodic=False)
        publish(P_CONTROLLED_BY, self.controller.user if self.controller else None, periodic=False,
                text=None if self.controller else "nobody")
        holder = self.controller
        fact(P_CONTROL, None if holder is None else Holder(holder.user, session_tag(holder.session), holder.since),
             text="nobody" if holder is None else
             f"{holder.user} since {time.strftime('%H:%M:%S', time.localtime(holder.since))}")
        try:
            sent = c.encode().hex(" ").upper()
        except codec.CodecError as exc:  # never sent (the limits refuse it first): said, not raised
            sent = Message(N_("not encodable: {error}"), error=message_of(exc))
        fact(P_TELEGRAM, c, text=telegram_text(c, sent))
        target = self.target_mm()
        fact(P_DRIVE_TARGET, target, "mm", text="not driven" if target is None else None)
        fact(P_IDLE, self.idle())

    def _watch_saturated(self, saturated: int, now: float) -> None:
        """The document asks that Saturated does not stay set when driven over CAN ("Bewegungs-Flags")."""
        if not saturated:
            self._saturated_since = None
            self._saturated_warning = ""
            self.state.fact(P_SATURATED, "")
            return
        if self._saturated_since is None:
            self._saturated_since = now
        if now - self._saturated_since >= codec.SATURATED_WARN_S and not self._saturated_warning:
            self._saturated_warning = Message(N_(
                "Saturated has stayed on for more than {seconds:g} s: an actuator runs at the highest speed "
                "its supply and load allow and the network cannot keep synchronised. Lower the speed (or the load)."),
                seconds=float(codec.SATURATED_WARN_S))
            self.state.fact(P_SATURATED, self._saturated_warning)
            self.state.event("warning", self._saturated_warning)

    async def poll(self) -> None:
        """Service parameters are read on demand; the status arrives by itself."""
        if self.state.age is not None and self.state.age > self.state.stale_after * 3 and self.state.online:
            self.state.mark_offline(Message(N_("no status telegram for more than 3 s: check the bus and the actuators' "
                                               "power")))

    # -- control: the core (devices/electrak/control.py) decides, this shell carries it out ----------------
    def _carry(self, actions) -> None:
        """Carry out the control core's actions on the bus, the lease of the periodic sender and the store."""
        publish = False
        for action in actions:
            kind = type(action)
            if kind is control.Send:
                self.bus.send(codec.CONTROL_ID, action.frame.encode(), False)
            elif kind is control.ModifyPeriodic:
                self.bus.modify_periodic(self.key, action.frame.encode(), send_now=action.send_now)
            elif kind is control.StartPeriodic:
                # on python-can's cyclic task: its clock does not depend on the event loop; without a valid
                # lease only the stop form leaves (enable and override cleared)
                self.bus.start_periodic(self.key, codec.CONTROL_PERIOD_S, codec.CONTROL_ID, action.frame.encode(), False,
                                        lease=self.lease, stop_form=stop_form, on_lapse=self._lapsed)
            elif kind is control.StopPeriodic:
                self.bus.stop_cyclic(self.key)
            elif kind is LeaseChange:
                if action.what == "grant":
                    self.lease.grant(action.at)
                elif action.what == "renew":
                    self.lease.renew(action.at)
                else:
                    self.lease.revoke()
            elif kind is Report:
                self.state.event(action.level, action.text)
            elif kind in (control.CommandChanged, ControlChanged):
                publish = True
        if publish:
            self._publish_command()
        if self.core.override_until is not None:  # the override/reset pulse ends by itself
            self._wake(self.core.override_until)

    def _wake(self, at: float) -> None:
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:  # no loop (a test without one): the supervisor's next beat ends it
            return
        loop.call_later(max(0.0, at - time.monotonic()) + 0.005, self._tick)

    def _tick(self) -> None:
        self._carry(self.core.tick(time.monotonic()))

    def _decided(self, decision) -> None:
        """Carry out a granted request; a refused one raises with the core's reason."""
        if not decision.ok:
            raise (ControlBusy if decision.busy else CommandError)(decision.refused)
        self._carry(decision.actions)

    def _control_frame(self):
        return codec.CONTROL_ID, self.command.encode(), False

    def on_control(self, msg) -> None:
        """A control telegram 0x06 from another node: a PLC, or an actuator with an active control line."""
        if not msg.is_rx:  # our own frame, handed back by the interface
            return
        now = time.monotonic()
        frames = self._foreign.frames if self._foreign is not None else 0
        try:
            text = codec.describe_frame(codec.CONTROL_ID, False, bytes(msg.data), {(False, codec.STATUS_ID)})
        except ValueError:  # a codec error: malformed data is shown as its bytes, never stops the bus
            text = bytes(msg.data).hex(" ")
        self._foreign = ForeignSender(frames + 1, time.time(), text or "")
        actions = self.core.foreign_control(now)  # whoever holds control here releases it: never fight it
        self.state.fact(P_FOREIGN, self._foreign, text=f"{self._foreign.text} · {self._foreign.frames} frames")
        self.state.fact(P_IDLE, self.idle())
        self._carry(actions)

    def foreign_sender(self, now: float | None = None) -> bool:
        """Was a control telegram from another node heard within the listening window?"""
        return self.core.foreign_sender(time.monotonic() if now is None else now)

    async def take_control(self, session: str, user: str) -> None:
        """Listen for another sender of 0x06 first; then send the control telegram every 100 ms (enable cleared)."""
        h = self.controller
        if h is not None and h.session == session:
            return
        if h is not None and h.disconnected is None:
            raise ControlBusy(f"{h.user} holds control since {time.strftime('%H:%M:%S', time.localtime(h.since))}")
        if not self.bus.state.connected:
            raise CommandError(f"CAN bus {self.bus.name} is not open: {self.bus.state.last_error or 'not connected'}")
        if self._listening_reconnects != self.bus.state.reconnects:  # (re)opened since: listen from now on
            self._listening_reconnects = self.bus.state.reconnects
            self.core.bus_opened(time.monotonic())
        wait = self.core.listen_remaining(time.monotonic())
        while wait > 0:  # (the loop may wake a timer up to its clock resolution early)
            await asyncio.sleep(wait)
            wait = self.core.listen_remaining(time.monotonic())
        now = time.monotonic()
        decision = self.core.take(session, user, now, time.time())
        if not decision.ok and self.core.foreign_sender(now):
            raise ForeignControl(decision.refused)
        self._decided(decision)

    def release_control(self, session: str, reason: str = control.RELEASED) -> bool:
        """Drop the enable bit, send it once more and stop the keep-alive."""
        actions = self.core.release(session, reason, time.monotonic())
        self._carry(actions)
        return bool(actions)

    # -- the dead-man rule (app.worker) -------------------------------------------------------
    def renew_leases(self, alive) -> None:
        """The worker's supervisor, every 50 ms: the controlling session is alive, motion may go on (``alive``: a set
        of sessions, or a mapping of each to its page's last beat on the monotonic clock, from which the lease counts)."""
        self._carry(self.core.beat(alive, time.monotonic()))

    def _lapsed(self, lapsed_at: float) -> None:
        """The lease ran out (the program stalled): the sender has sent the stop form by itself since."""
        self._carry(self.core.tick(max(time.monotonic(), lapsed_at)))

    def holders(self) -> set[str]:
        """The session that keeps motion running: control held and enable (or override) set."""
        return self.core.holders()

    def session_back(self, session: str) -> None:
        """The page of ``session`` confirms it is alive again after its connection dropped: its control is its own again."""
        self._carry(self.core.back(session))

    def session_stop(self, session: str, reason: str) -> None:
        """The page of ``session`` disconnected: motion stops at once (enable cleared, sent now); control, which
        moves nothing by itself, stays until the page is gone for good (:meth:`session_lost`)."""
        self._carry(self.core.disconnected(session, reason, time.monotonic()))

    def session_lost(self, session: str, reason: str) -> None:
        """The browser of ``session`` went away or froze: stop at once and release its control."""
        self._carry(self.core.lost(session, reason, time.monotonic()))

    def set_command(self, session: str, position_mm: float, speed_mm_s: float, current_a: float) -> None:
        """New target, speed and current limit (validated); keeps the enable bit as it is."""
        self._decided(self.core.set_target(session, position_mm, speed_mm_s, current_a, time.monotonic()))

    def go(self, session: str) -> None:
        """Enable: the actuators move to the target set before (refused while fewer actuators are heard than configured)."""
        self._decided(self.core.go(session, time.monotonic()))

    def stop(self, session: str | None = None) -> None:
        """Clear the enable bit (anyone may stop); the telegram leaves at once, not at the next period."""
        self._carry(self.core.stop(session, time.monotonic()))

    def jog(self, session: str, direction: int, speed_mm_s: float | None = None) -> None:
        """Hold-to-run: move toward an end while held (direction +1 out, -1 in); 0 stops."""
        self._decided(self.core.jog(session, direction, speed_mm_s, time.monotonic(), self.position_mm()))

    def jog_stop(self, session: str) -> None:
        """A jog button released: the jog of ``session`` ends where the actuators are (nothing when it does not jog)."""
        self._carry(self.core.jog_release(session, time.monotonic(), self.position_mm()))

    def override(self, session: str, active: bool, *, confirmed: bool = False) -> None:
        """Override/reset bit (a pulse of three control periods): holds motion and resets the expected number of
        devices. Setting it needs ``confirmed`` (the risk of :data:`devices.electrak.control.OVERRIDE_RISK`)."""
        self._decided(self.core.override(session, active, time.monotonic(), confirmed=confirmed))

    def position_mm(self) -> float | None:
        recent = self.recent
        return sum(f.position_mm for f in recent) / len(recent) if recent else None

    # -- service parameters ----------------------------------------------------------------------
    def on_service(self, msg) -> None:
        answer = decoded(self.state, codec.ServiceMessage.decode, bytes(msg.data), "service answer")
        if answer is None:
            return
        request = self._pending
        if request is None or not codec.belongs_to(request, answer):
            return  # late, or not ours: the next exchange must not take it
        self._answers.append(answer)
        if len(self._answers) >= len(self.actuators) and self._all_answered is not None:
            self._all_answered.set()

    async def _exchange(self, request: codec.ServiceMessage) -> list[codec.ServiceMessage]:
        """Send one service telegram and collect the answers of every actuator (bounded)."""
        self._pending, self._answers, self._all_answered = request, [], asyncio.Event()
        self.state.counters.requests += 1
        try:
            if not self.bus.send(codec.SERVICE_REQUEST_ID, request.encode(), False):
                raise CommandError(f"CAN bus {self.bus.name} did not take the frame: {self.bus.state.last_error or 'bus not open'}")
            try:
                await asyncio.wait_for(self._all_answered.wait(), SERVICE_TIMEOUT_S)
                await asyncio.sleep(EXTRA_ANSWER_S)  # one more than configured?
            except asyncio.TimeoutError:
                self.state.counters.timeouts += 1
            return list(self._answers)
        finally:
            self._pending, self._all_answered = None, None

    async def _service(self, request: codec.ServiceMessage, what: str = "", key: str | None = None) -> list[codec.ServiceMessage]:
        """One service telegram that every configured actuator must answer as asked (reads: alike)."""
        return self._check(request, await self._exchange(request), what, key)

    def _check(self, request, answers: list[codec.ServiceMessage], what: str, key: str | None) -> list[codec.ServiceMessage]:
        problems = codec.answer_problems(request, answers, len(self.actuators))
        self._report(request, answers, problems, what, key)
        if problems:
            if any(a.type == codec.ServiceType.ERROR_RESPONSE for a in answers):
                self.state.counters.exceptions += 1
            raise CommandError(f"{what or f'0x{request.specifier:02X}'}: " + "; ".join(problems))
        return answers

    def _report(self, request, answers, problems, what: str, key: str | None) -> None:
        kind = SERVICE_KINDS.get(request.type, N_("type 0x{type:02X} 0x{specifier:02X}"))
        asked = Message(kind, type=request.type, specifier=request.specifier)
        report = ServiceReport(Message("{asked} ({what})", asked=asked, what=what) if what else asked, time.time(),
                               tuple(codec.describe_answer(a) for a in answers), len(self.actuators), tuple(problems),
                               not problems, key)
        answered = joined([codec.numbered(n, a) for n, a in enumerate(report.answers, 1)], "; ") or Message(N_("no answer"))
        self.state.fact(P_SERVICE_ANSWERS, len(answers))
        self.state.fact(P_SERVICE_LAST, report, text=Message("{what}: {answered}{problems}", what=report.what, answered=answered,
                                                             problems="" if report.ok else Message(
                                                                 " - {problems}", problems=joined(list(report.problems), "; "))))
        if key is not None:
            self._reports[key] = report
            self.state.fact(P_SERVICE_REPORTS, tuple(self._reports.values()))

    async def _unlock(self, param: Param) -> None:
        await self._service(codec.password_request(password_of(param)), Message(N_("password for {name}"), name=param.name))

    async def _read(self, param: Param) -> int:
        answers = await self._service(codec.read_request(param.address, length_of(param)), param.name, param.key)
        return answers[0].value

    async def read_param(self, param: Param) -> int:
        """Every actuator's value; fails unless all answer and agree."""
        async with self._service_lock:
            await self._unlock(param)
            try:
                value = await self._read(param)
            except CommandError:
                self.state.registers.pop((SERVICE, param.address), None)  # no single value to show
                raise
        self.state.update_registers(SERVICE, param.address, [value])
        return value

    async def read_all(self) -> dict[str, int]:
        return {p.name: await self.read_param(p) for p in PARAMS}

    async def write_param(self, param: Param, value, *, confirmed: bool = False) -> int:
        """An entry for ``param``, checked by the parameter model, written by :meth:`write_accepted`."""
        _refuse_as_the_document(param, value)
        try:
            accepted = param.accept(value)
        except ParamError as exc:
            raise CommandError(str(exc)) from None
        return await self.write_accepted(accepted, confirmed=confirmed)

    async def write_accepted(self, accepted: Accepted, *, confirmed: bool = False) -> int:
        """Password, write, read back from every actuator (document "Passwort", "Beispiel einer Parameter-Änderung")
        of a value the parameter model accepted; the document's own refusals (:func:`refusal`) still apply."""
        param = accepted.param
        _refuse_as_the_document(param, accepted.value)
        try:
            raw = accepted.cleared(confirmed)
        except ParamError as exc:
            raise CommandError(str(exc)) from None
        async with self._service_lock:
            await self._unlock(param)
            request = codec.write_request(param.address, length_of(param), raw)
            answers = await self._exchange(request)
            if any(a.type == codec.ServiceType.WRITE_CONFIRMATION for a in answers):
                self.state.unsaved.add(param.key)  # at least one actuator took it: lost at power-off unless saved
            self._check(request, answers, param.name, param.key)
            try:
                back = await self._read(param)
            except CommandError as exc:
                self.state.registers.pop((SERVICE, param.address), None)
                self.state.counters.write_errors += 1
                raise CommandError(f"{param.name}: read back after writing {param.display(raw)} failed: {exc}") from None
        self.state.update_registers(SERVICE, param.address, [back])
        if back != raw:
            self.state.counters.write_errors += 1
            raise CommandError(f"{param.name}: read back {param.display(back)} instead of {param.display(raw)}")
        if param.address == BITRATE_SPECIFIER:
            self._publish_bitrate_change(BitrateChange(raw, time.time()))
            self.state.event("warning", Message(N_("bit rate {value} written and read back from every actuator: save it, "
                                                   "switch the bus, restart the actuators"), value=param.display(raw)))
        else:
            self.state.event("info", Message(N_("{name} = {value} written and read back from {n} actuator(s) (not yet "
                                                "saved)"), name=param.name, value=param.display(raw), n=len(self.actuators)))
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

    async def save_step(self) -> str:
        return f"save parameters (0xF0), {await self.save_parameters()}"

    async def save_parameters(self) -> str:
        """Save (0xF0) in the table's form, once more in the example's on WRONG_SIZE (codec.SAVE_LENGTHS);
        returns the form the network accepted."""
        first, second = codec.SAVE_LENGTHS
        expected = len(self.actuators)
        async with self._service_lock:
            request = codec.save_request(first)
            answers = await self._exchange(request)
            refused = sum(1 for a in answers if a.error_code == codec.ERROR_WRONG_SIZE)
            accepted = {first: expected - refused}
            if refused and len(answers) == expected and all(
                a.type == codec.ServiceType.WRITE_CONFIRMATION or a.error_code == codec.ERROR_WRONG_SIZE for a in answers
            ):
                self._report(request, answers, [], f"save, {codec.SAVE_FORMS[first]}: {refused} WRONG_SIZE", None)
                request = codec.save_request(second)
                answers = await self._exchange(request)
                taken = sum(1 for a in answers if a.type == codec.ServiceType.WRITE_CONFIRMATION)
                accepted[second] = taken
                # those that saved in the first form may refuse the second; the others must all take it
                fits = taken == refused and len(answers) == expected and all(
                    a.type == codec.ServiceType.WRITE_CONFIRMATION or a.error_code == codec.ERROR_WRONG_SIZE for a in answers
                )
                problems = [] if fits else codec.answer_problems(request, answers, expected) + [
                    f"{taken} of the {refused} actuators that refused the {codec.SAVE_FORMS[first]} took the {codec.SAVE_FORMS[second]}"
                ]
            else:
                problems = codec.answer_problems(request, answers, expected)
            self._report(request, answers, problems, f"save, {codec.SAVE_FORMS[request.length]}", None)
            if problems:
                raise CommandError("save parameters (0xF0): " + "; ".join(problems) + ". The changes may not be saved on every actuator: save again.")
        forms = {length: n for length, n in accepted.items() if n}
        if len(forms) == 1:
            form = codec.SAVE_FORMS[next(iter(forms))]
            said = Message(form)  # the form's words are marked by the Electrak service page (SAVE_FORM_WORDS)
        else:
            form = " and ".join(f"{codec.SAVE_FORMS[length]} by {n} actuator{'s' if n > 1 else ''}" for length, n in forms.items())
            parts = [Message(N_("{form} by {n} actuators") if n > 1 else N_("{form} by {n} actuator"),
                             form=Message(codec.SAVE_FORMS[length]), n=n) for length, n in forms.items()]
            said = (Message(N_("{first} and {second}"), first=parts[0], second=parts[1]) if len(parts) == 2
                    else joined(parts, " and "))
        self.state.fact(P_SAVE_FORM, form)
        change = self.bitrate_change
        if change is not None and PARAMS.get(SERVICE, BITRATE_SPECIFIER).key in self.state.unsaved:
            self._publish_bitrate_change(replace(change, saved=time.time()))
        self.state.unsaved.clear()
        self.state.event("info", Message(N_("parameters saved (0xF0); the network accepted the {form}"), form=said))
        return form

    @property
    def bitrate_change(self) -> BitrateChange | None:
        point = self.state.points.get(P_BITRATE_CHANGE)
        return None if point is None else point.value

    def _publish_bitrate_change(self, change: BitrateChange) -> None:
        name = PARAMS.get(SERVICE, BITRATE_SPECIFIER).display(change.raw)
        self.state.fact(P_BITRATE_CHANGE, change, text=f"{name} written" + (", saved" if change.saved else ", not saved"))
