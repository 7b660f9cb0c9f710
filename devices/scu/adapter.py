"""An Ewellix SCU on a point-to-point RS232 line: remote session, live data, functions, data directory.

Document 002, sections 4 to 7. The worker calls :meth:`ScuAdapter.poll` every ``poll_period``
(200 ms): it opens the remote session (RO with the Safety_ID, then RC), defines a cyclic object
(RT of 0x3001) so that each RC keep-alive brings positions and status back in one transaction,
and falls back to RG reads when the unit refuses the definition. Commands from the page (RE, RS,
RT with RG read-back, RA, RG of any data ID) go through the same line; every RE is followed by
its RS (section 4.6), also under the worker's dead-man rule (:meth:`holders`,
:meth:`session_lost`).

The RC keep-alive leaves from the serial line's own thread (devices/scu/keepalive.py), on a
clock no page work can delay, under a lease (devices/lease.py) the worker's dead-man supervisor
renews while a function runs. Once that lease has lapsed (the event loop stalled, or the
controlling browser is gone) the thread sends RS to every running function by itself (never RS 19:
the emergency stop stays on) and then withholds RC, so the unit's own watchdog ends remote mode and
stops every drive (section 5) even if an RS was lost.

The adapter composes its parts, each with its own state: :class:`~devices.scu.link.ScuLink` (requests and answers),
:class:`~devices.scu.opening.ScuOpening` (the remote session), :class:`~devices.scu.keepalive.RcKeepAlive`,
:class:`~devices.scu.livedata.ScuLiveData` (live points) and :class:`~devices.scu.functions.ScuFunctions` (RE, RS,
the emergency stop); the parameter model is :class:`~devices.scu.settings.ScuSettings`.
"""

from __future__ import annotations

import time
from typing import Any

from devices.adapter import BackupDefaults
from devices import values as v
from devices.control import RELEASED, ControlChanged, Report
from devices.lease import Lease
from devices.live import DeviceState, Holder, session_tag
from devices.message import Message, N_, message_of
from devices.scu import codec
from devices.scu import params as p
from devices.scu.facts import (  # noqa: F401 - the published names, also read from here by older callers
    CommandError, ControlBusy, ActuatorScale, FunctionMap, P_ACTUATORS, P_CONFIGURATION, P_CONTROL, P_CONTROLLED_BY, P_CRC_RETRIES, P_CYCLIC, P_ESTOP, P_FIRMWARE, P_FUNCTIONS, P_LINE, P_RC_GAP, P_RC_PERIOD, P_REFUSAL, P_RESYNCS, P_RS_PENDING, P_RUNNING, P_SAFETY_ID, P_SCALES, P_SERIAL, P_SESSION, P_SESSION_REASON, P_SINGLE_IDS, P_SKIPPED, P_SPEED, P_WATCH, Refusal, SerialLine, SpeedRange, chart_points, describe_answer, actuator_scales, answer_length, header_offset, value_text, jsonable as _jsonable)
from devices.scu.functions import ScuFunctions
from devices.scu.link import ScuLink
from devices.scu.opening import CYCLIC_READ_IDS, PROBE_ID, WATCH_RG, WATCH_SESSION, ScuOpening  # noqa: F401 - read from here
from devices.scu.keepalive import RC_KEY, RcKeepAlive
from devices.scu.livedata import ERROR_BIT_GROUPS, ROTATING_IDS, ScuLiveData  # noqa: F401 - ERROR_BIT_GROUPS: read from here
from devices.scu.model import PARAMS
from devices.params import Accepted
from devices.scu.settings import RESTORE_NOTE, ScuSettings
from devices.scu.control import (ESTOP, NOT_HELD, OpenSession, Outcome, ScuControl, SendEstop, SendRS,
                                 WithholdRC)
from devices.transport import SerialLineError

# RS refused with CSE ("the unit did not execute the telegram", section 4.2) or unanswered is sent again, at
# most this many times in all; the function stays held (RS pending, retried every poll) until an RS is acknowledged.
# How the unit is watched while nobody holds control (section 4.1 lists RG among the remote-only commands;
# a unit that answers RG outside remote mode is watched without a session, so its own watchdog is never
# kept alive for nobody).
# Emergency stop (function 19) is not released by the dead-man rule: RS would end the emergency stop,
# the unsafe direction. It is released only by an explicit "release emergency stop" (section 4.4, F20).
REMOTE_SPEED_MAX = 1000  # table 7: relative 0 .. 100 %, absolute 0 .. 1000 counts/s
# Table 7 / section 4.6: the remote speed is in % (0 .. 100) with "speed select relative", the standard
# parametrisation, or in counts/s (0 .. 1000) with "speed select absolute"; the plant file says which.
SPEED_LIMITS = {"relative": (100, "%"), "absolute": (REMOTE_SPEED_MAX, "counts/s")}
SERVICE_IDS = (0x0001, 0x0002, 0x0060, 0x0070, 0x0080, 0x0090, 0x00B0, 0x00C0, 0x00C1, 0x1010)

class ScuAdapter(BackupDefaults):
    """One SCU on a serial line (``type = "scu"`` on a ``type = "serial"`` bus)."""

    params = PARAMS
    transport = "serial"
    backup_available = True
    restore_wear = RESTORE_NOTE  # nothing to save: the remote data are volatile (table 7)
    keepalive_period_s = codec.KEEP_ALIVE_PERIOD_S  # RC interleaved into long operations after this gap

    def __init__(self, config, state: DeviceState, line):
        self.config = config
        self.state = state
        self.line = line
        options = config.options
        self.safety_id = codec.SafetyId(options.get("safety_id", codec.DEFAULT_SAFETY_ID))
        self.scales = actuator_scales(options)
        state.params = PARAMS
        self.settings = ScuSettings(self)  # the parameter model on this line (devices/scu/settings.py)
        self.speed_select = options.get("speed_select", "relative")
        self.speed_max, self.speed_unit = SPEED_LIMITS[self.speed_select]
        # Which actuators each function F1..F10 drives: the unit's parametrisation (section 4.4), which the
        # RS232 interface cannot read. The plant file names it (functions = { F1 = [1, 2] }); without it the
        # SCP11 assignment of section 5 (F(n) drives actuator n) is assumed and said to be assumed.
        configured = options.get("functions")
        self.functions_assumed = not configured
        self.function_actuators: dict[int, list[int]] = (
            {int(k.lstrip("Ff")) - 1: list(x) for k, x in configured.items()} if configured
            else {n - 1: [n] for n in range(1, len(self.scales) + 1)})
        self.baudrate = line.options.get("baudrate", codec.DEFAULT_BAUDRATE) if line is not None else codec.DEFAULT_BAUDRATE
        self.port = line.options.get("port", "") if line is not None else ""
        # the safety state and its rules (devices/scu/control.py): session, control, running functions, owed RS,
        # the emergency stop, RC withheld; this adapter carries its actions out on the line
        self.core = ScuControl(lease=Lease())
        self.link = ScuLink(self)  # requests and answers on the line (devices/scu/link.py)
        self.opening = ScuOpening(self)  # opening the remote session (devices/scu/opening.py)
        self.rc = RcKeepAlive(self)  # the RC keep-alive on the line's own thread (devices/scu/keepalive.py)
        self.live = ScuLiveData(self)  # the live points (devices/scu/livedata.py)
        self.functions = ScuFunctions(self)  # RE, RS, the emergency stop (devices/scu/functions.py)
        self.cyclic: p.CyclicDefinition | None = None
        self.cyclic_note = ""
        self.watch: str | None = None  # WATCH_RG or WATCH_SESSION once the first RG outside a session told
        self.single_ids: set[int] = set()  # groups this unit refused: read member by member (remembered)
        self.cyclic_refused = False  # the unit refused the cyclic object (definition or RC with it)
        state.stale_after = 2.0
        state.registers_periodic = False
        self.publish_session()
        state.fact(P_ACTUATORS, len(self.scales))
        state.fact(P_SAFETY_ID, int(self.safety_id), text=codec.SAFETY_MODES[self.safety_id])
        state.fact(P_LINE, SerialLine(self.port, self.baudrate), text=f"{self.port} at {self.baudrate} baud 8N1")
        state.fact(P_SPEED, SpeedRange(self.speed_select, self.speed_max, self.speed_unit),
                   text=f"0 .. {self.speed_max} {self.speed_unit} ({self.speed_select})")
        state.fact(P_FUNCTIONS, FunctionMap(tuple((fn, tuple(acts)) for fn, acts in sorted(self.function_actuators.items())),
                                            self.functions_assumed))
        serial = options.get("serial")
        state.fact(P_SERIAL, None if serial in (None, "") else str(serial),
                   text=None if serial not in (None, "") else "not in the plant file (no data ID for it, section 4.3)")
        state.fact(P_CONTROLLED_BY, None, text="nobody")
        self._publish_control()
        self.publish_scales()
        self.sync_held()
        self.publish_estop()
        self.link.publish_counts()
        state.fact(P_CYCLIC, self.cyclic_note)
        state.fact(P_REFUSAL, None, text="none")
        state.fact(P_SINGLE_IDS, ())

    # -- the core's state, as the rest of the program reads it ------------------------------------------
    @property
    def session(self) -> str:
        """closed, opening, open, lost or released."""
        return self.core.phase

    @property
    def session_reason(self) -> str:
        return self.core.reason

    @property
    def controller(self):
        """The holder of control (``session``, ``user``, ``since``), or None."""
        return self.core.control.holder

    @property
    def running(self) -> dict[int, str]:
        """fnc_ID -> session that sent its RE, until its RS is acknowledged."""
        return self.core.running

    @property
    def rs_pending(self) -> dict[int, str]:
        """Functions whose RS was not acknowledged: held, sent again."""
        return self.core.rs_pending

    @property
    def estop(self) -> bool:
        """The emergency stop is on (pressed, not yet released by RS 19)."""
        return self.core.estop is not None

    @property
    def lease(self) -> Lease:
        return self.core.control.lease

    # -- carrying the core's actions out ----------------------------------------------------------------
    async def carry_out(self, actions) -> None:
        """Do what the core asks, in order; what an answer leads to comes before the rest."""
        todo = list(actions)
        while todo:
            action = todo.pop(0)
            if isinstance(action, SendRS):
                todo[:0] = await self._rs_action(action)
            elif isinstance(action, SendEstop):
                todo[:0] = self.core.estop_answered(await self._estop_request(action.why), time.monotonic())
                self.publish_estop()
            elif isinstance(action, OpenSession):
                await self.open_session(forced=action.forced)
            else:
                self.apply(action)
        self.sync_held()
        self.sync_phase()

    def apply(self, action) -> None:
        """The actions without I/O of the line: reports, control, withholding RC."""
        if isinstance(action, Report):
            if action.text.startswith("STOP FAILED"):
                self.state.error(action.text)
            self.state.event(action.level, action.text)
        elif isinstance(action, ControlChanged):
            c = action.holder
            self.state.fact(P_CONTROLLED_BY, None if c is None else c.user, text="nobody" if c is None else None)
            self._publish_control()
        elif isinstance(action, WithholdRC):
            with self.rc.guard:
                self.rc.withheld = True
            self.sync_phase()

    def sync_phase(self) -> None:
        """The session's phase as the core has it: published, and RC armed only while it is open."""
        with self.rc.guard:
            armed = self.rc.armed
        if self.core.phase == "open" and not armed:
            self.rc.arm()
        elif self.core.phase != "open" and armed:
            self.rc.disarm()
        self.publish_session()

    @staticmethod
    def outcome(exc: BaseException | None) -> Outcome:
        if exc is None:
            return Outcome.ACK
        if isinstance(exc, codec.CommandRefused):
            return Outcome.of_status(exc.code)
        return Outcome.LOST

    async def _estop_request(self, why: str) -> Outcome:
        try:
            await self.link.request(codec.encode_re(codec.Function.EMERGENCY_STOP), f"RE F20 emergency stop ({why})",
                                keepalive=False)
        except (SerialLineError, codec.CodecError) as exc:
            return self.outcome(exc)
        return Outcome.ACK

    async def _rs_action(self, action: SendRS) -> list:
        """One RS as the core asks (its form and attempt); returns what the core makes of the answer."""
        label = codec.FUNCTIONS[codec.Function(action.fn)].label
        frame = codec.encode_rs(action.fn, -1, -1) if action.three_bytes else codec.encode_rs(action.fn)
        exc: BaseException | None = None
        try:
            await self.link.request(frame, f"RS {label} ({action.why})" + (f", attempt {action.attempt}" if action.attempt > 1 else "")
                                + (" (three-byte form)" if action.three_bytes else ""), keepalive=False)
        except (SerialLineError, codec.CodecError) as e:
            exc = e
        outcome = self.outcome(exc)
        # An acknowledged RS may end the lease (nothing held any more: devices/control.py idle()). The line's thread
        # must see that end and the held functions change as one: between the two it saw F1 held and no lease, a
        # lapse that never was (withheld RC, a stopped session)
        with self.rc.guard:
            follow = self.core.rs_answered(action, outcome, time.monotonic())
            self.rc.held = self.core.held
        if action.fn == ESTOP:
            self.publish_estop()
        return follow

    # -- the line -------------------------------------------------------------------------------

    @property
    def crc_retries(self) -> int:
        """Answers with a bad CRC, sent again."""
        return self.link.crc_retries

    def rc_gaps(self) -> list[float]:
        """Seconds between the acknowledged RCs kept (the last 50)."""
        return self.rc.gaps()

    @property
    def rc_times(self):
        """When the last 50 acknowledged RCs were sent (monotonic)."""
        return self.rc.times

    @rc_times.setter
    def rc_times(self, times) -> None:
        self.rc.times = times

    @property
    def rc_on_line_thread(self) -> bool:
        """False: RC from the poll on the loop, also on a line with a thread of its own (a scripted conversation)."""
        return self.rc.wanted

    @rc_on_line_thread.setter
    def rc_on_line_thread(self, wanted: bool) -> None:
        self.rc.wanted = wanted

    # -- the session -------------------------------------------------------------------------------
    def publish_session(self) -> None:
        self.state.fact(P_SESSION, self.session,
                        text=self.session + (f": {self.session_reason}" if self.session_reason else ""))
        self.state.fact(P_SESSION_REASON, self.session_reason)
        self.state.fact(P_WATCH, self.watch, text=self.watch_text())

    def _publish_control(self) -> None:
        c = self.controller
        self.state.fact(P_CONTROL, None if c is None else Holder(c.user, session_tag(c.session), c.since),
                        text="nobody" if c is None else f"{c.user} since {time.strftime('%H:%M:%S', time.localtime(c.since))}")

    def publish_scales(self) -> None:
        self.state.fact(P_SCALES, tuple(self.scales))

    def publish_cyclic(self) -> None:
        self.state.fact(P_CYCLIC, self.cyclic_note)

    def watch_text(self) -> str:
        if self.watch == WATCH_RG:
            return Message(N_("watching with RG outside a remote session: the unit answers RG without remote mode; the "
                              "session (RO, RC) is opened only while someone holds control or a function runs"))
        if self.watch == WATCH_SESSION:
            return Message(N_("the remote session is open for reading only: the unit refuses RG outside remote mode "
                              "(section 4.1); no RE is sent unless a page holds control"))
        return Message(N_("not known yet: the first RG outside a session tells"))

    def set_session(self, session: str, reason: str = "") -> None:
        self.core.phase, self.core.reason = session, reason
        self.publish_session()
        if session == "open":
            self.rc.arm()
        else:
            self.rc.disarm()

    # -- the RC keep-alive on the line's own thread, under a lease (issue 28) ------------------------------

    def sync_held(self) -> None:
        """The functions the lease covers follow ``running``; nothing held: the lease ends without a lapse."""
        with self.rc.guard:
            self.rc.held = self.core.held
            if not self.rc.held:
                self.lease.revoke()
        names = lambda fns: ", ".join(codec.FUNCTIONS[codec.Function(f)].label for f in fns) or "none"  # noqa: E731
        self.state.fact(P_RUNNING, tuple(sorted(self.running)), text=names(sorted(self.running)))
        self.state.fact(P_RS_PENDING, tuple(sorted(self.rs_pending)), text=names(sorted(self.rs_pending)))

    def renew_leases(self, alive: set[str]) -> None:
        """The worker's supervisor, every 50 ms: a session that runs a function is alive, it may go on."""
        with self.rc.guard:
            held = self.rc.held
        if held and {s for fn, s in list(self.running.items()) if fn in held} & alive:
            self.lease.renew()

    def lost(self, reason: str) -> None:
        for action in self.core.lost(reason, time.monotonic()):
            self.apply(action)
        self.sync_phase()

    def _needs_session(self) -> bool:
        """A remote session is needed: the unit refuses RG without one, someone drives, a stop is owed, F20 is on, or a
        setting is being written (RT, devices/scu/settings.py)."""
        return self.core.needs_session(self.watch == WATCH_SESSION) or self.settings.writing > 0

    async def open_session(self, forced: bool = False) -> None:
        """RO with the Safety_ID, RC, the emergency stop and owed RS again, the cyclic object (devices/scu/opening.py).

        :param forced: for the emergency stop: whatever the backoff or an earlier RA (never while RC is withheld)
        """
        await self.opening.open(forced)

    async def send_rc(self) -> codec.Answer:
        """One RC from the loop (with the cyclic object when it is defined)."""
        return await self.opening.send_rc()

    async def poll(self) -> None:
        """One cycle: learn how the unit is watched; open the session when needed (with backoff), close it when
        nobody needs it (watching with RG); RC (with the cyclic data) and the live reads."""
        if self.session == "released":
            return
        if self.watch is None:
            if time.monotonic() < self.core.next_open:
                return
            try:
                await self.opening.probe()
            except (SerialLineError, codec.CodecError, v.DecodeError) as exc:
                self.core.open_failed(Message(N_("no answer to the first RG: {error}"), error=message_of(exc)), time.monotonic(),
                                      answered_before=False)
                return
        if self._needs_session() and self.session != "open":
            if self.core.may_open(time.monotonic()):
                return  # backoff, released, or RC withheld until the unit's watchdog has tripped
            await self.open_session()
            return
        if not self._needs_session() and self.session == "open" and self.watch == WATCH_RG:
            await self.opening.end("nobody holds control: watching with RG outside a remote session")
        try:
            if self.session == "open":
                if not self.rc.threaded():
                    await self.send_rc()  # else the line's own thread sends it (RcKeepAlive.tick)
                for fn in sorted(self.rs_pending):
                    await self.send_rs(fn, self.rs_pending[fn])
            live = [] if self.cyclic is not None else list(CYCLIC_READ_IDS)
            live += self.live.rg_on_loop
            self.live.rg_on_loop = []
            data_id = ROTATING_IDS[self.live.rotate % len(ROTATING_IDS)]
            self.live.rotate += 1
            by_thread = self._rg_by_thread(data_id)
            with self.rc.guard:
                if not by_thread or len(self.rc.thread_rgs) >= 3:  # the line's thread does not read them now: here
                    if by_thread:
                        self.rc.rgs_taken_over += len(self.rc.thread_rgs)
                    live += self.rc.thread_rgs
                    self.rc.thread_rgs.clear()
                if by_thread:
                    self.rc.thread_rgs.append(data_id)  # read right after the next RC, in the same wake-up (_rc_tick)
                else:
                    live.append(data_id)
            for data_id in live:
                await self._read_live(data_id)
        except codec.CommandRefused as exc:
            if exc.code == codec.Status.PE and self.session != "open" and self.watch == WATCH_RG:
                self.watch = WATCH_SESSION  # it answered RG once (perhaps still in an old remote mode): no more
                self.publish_session()
        except (SerialLineError, codec.CodecError, v.DecodeError) as exc:
            self.state.error(f"poll: {exc}", log=False)
        self.live.publish_period()

    def _rg_by_thread(self, data_id: int) -> bool:
        """Whether the line's thread reads ``data_id`` after its next RC: a single read while the session is open with
        the cyclic object and the thread sends RC, nothing runs and no RS is owed."""
        return (self.session == "open" and self.cyclic is not None and self.rc.threaded() and self.line.cyclic_running(RC_KEY)
                and not self.running and not self.rs_pending and self.opening.ids_of(data_id) == [data_id])

    async def _read_live(self, data_id: int) -> None:
        """RG of a data ID, or of the members of a group the unit refused; one refused read never ends the poll."""
        for read_id in self.opening.ids_of(data_id):
            try:
                answer = await self.link.request(codec.encode_rg(read_id), f"RG 0x{read_id:04X}",
                                             quiet=read_id == data_id and p.DIRECTORY.get(read_id) is not None
                                             and p.DIRECTORY[read_id].is_group)
            except codec.CommandRefused as exc:
                if exc.code == codec.Status.PE:
                    raise
                if exc.code == codec.Status.CSE:
                    continue  # line noise (section 4.2): read again in its turn, nothing remembered
                entry = p.DIRECTORY.get(read_id)
                if read_id == data_id and entry is not None and entry.is_group and data_id not in self.single_ids:
                    self.single_ids.add(data_id)  # remembered for this unit: its members one by one from now on
                    self.state.fact(P_SINGLE_IDS, tuple(sorted(f"0x{g:04X}" for g in self.single_ids)))
                    self.state.event("warning", Message(N_("the unit refused the group read {data_id} ({status}): its data "
                                                           "IDs are read one by one"), data_id=f"0x{data_id:04X}",
                                                        status=exc.info.name))
                    await self._read_live(data_id)
                continue
            self.live.publish_read(read_id, answer)

    # -- live points ----------------------------------------------------------------------------------

    # -- control ------------------------------------------------------------------------------------
    async def take_control(self, session: str, user: str) -> None:
        """One browser session at a time drives the unit (the remote session is opened for it by the next poll)."""
        decision = self.core.control.take(session, user, time.monotonic(), time.time())
        if decision.busy:
            c = self.controller
            raise ControlBusy(f"{c.user} holds control since {time.strftime('%H:%M:%S', time.localtime(c.since))}")
        for action in decision.actions:
            self.apply(action)

    def controls(self, session: str) -> bool:
        """Whether ``session`` holds control of the unit (the gate's check for commands that need control)."""
        return self.core.control.controls(session)

    def check_holder(self, session: str) -> None:
        decision = self.core.control.check_holder(session)
        if not decision.ok:
            raise (ControlBusy if decision.busy else CommandError)(decision.refused)

    def check_open(self) -> None:
        if self.session != "open":
            raise CommandError(f"the remote session is {self.session}"
                               + (f" ({self.session_reason})" if self.session_reason else "")
                               + ": everything except RO/RA needs remote mode (section 4.1)")

    async def ensure_open(self) -> None:
        """Open the remote session now when it is needed and closed (watching with RG, or lost with backoff past)."""
        if self.session in ("open", "released"):
            return
        if not self.core.may_open(time.monotonic()):
            await self.open_session()

    async def release_control(self, session: str, reason: str = RELEASED) -> bool:
        if self.controller is None or (session and self.controller.session != session):
            return False
        holder = self.controller.session
        await self.functions.stop_held(holder, reason)
        self.core.control.running = False  # what it ran has had its RS (an RS not acknowledged stays owed)
        for action in self.core.control.release(holder, reason):
            self.apply(action)
        return True

    def holders(self) -> set[str]:
        """Sessions whose RE (motion, buzzer, outputs, LEDs) has not yet been followed by an acknowledged RS."""
        return self.core.holders()

    # -- the unit's functions: RE, RS, the emergency stop (devices/scu/functions.py) ---------------------
    def session_lost(self, session: str, reason: str) -> None:
        """The browser of ``session`` went away or froze: RS at once for everything it runs, release control."""
        self.functions.session_lost(session, reason)

    async def stopped(self) -> None:
        """Wait for the RS frames that :meth:`session_lost` has sent off (tests, shutdown)."""
        await self.functions.stopped()

    async def run_function(self, session: str, function: int, motion: int = -1, ramp: int = -1,
                           requested_at: float | None = None) -> str:
        """RE of a function (F1..F10 with motion and ramp; buzzer, outputs, LEDs with -1, -1)."""
        return await self.functions.run_function(session, function, motion, ramp, requested_at)

    async def stop(self, session: str | None = None, function: int | None = None) -> list[str]:
        """RS to ``function``, or to every function run (anyone may stop)."""
        return await self.functions.stop(session, function)

    async def jog(self, session: str, function: int, direction: int, ramp: int = -1,
                  requested_at: float | None = None) -> str:
        """Hold-to-run: +1 out, -1 in while held; 0 (release) sends RS."""
        return await self.functions.jog(session, function, direction, ramp, requested_at)

    async def jog_stop(self, session: str, function: int) -> str:
        """Release of a jog button: RS after the press's RE (the declared stop ``jog stop (RS)``)."""
        return await self.functions.jog_stop(session, function)

    async def emergency_stop(self, session: str | None = None, user: str | None = None) -> str:
        """RE of function 19: never refused (devices/scu/functions.py)."""
        return await self.functions.emergency_stop(session, user)

    async def withhold_rc(self, session: str) -> str:
        """The watchdog test (section 5): RC withheld on purpose."""
        return await self.functions.withhold_rc(session)

    async def release_emergency_stop(self, session: str) -> str:
        """RS 19: the only way the emergency stop is released."""
        return await self.functions.release_emergency_stop(session)

    async def send_rs(self, fn: int, why: str) -> bool:
        """RS of ``fn`` after any RE of it still on the line (never before it); True once acknowledged."""
        return await self.functions.send_rs(fn, why)

    def actuators_of(self, function: int) -> list[int]:
        """The actuators function ``function`` (fnc_ID 0..9) drives, as configured (or assumed, SCP11)."""
        return list(self.function_actuators.get(int(function), []))

    def functions_text(self, function: int) -> str:
        acts = self.actuators_of(function)
        return (", ".join(f"A{a}" for a in acts) if acts else "no actuator") + (
            " (assumed: SCP11, section 5; set functions in the plant file)" if self.functions_assumed else "")

    def estop_text(self) -> str:
        """The emergency stop in words: on or off, who pressed it and when, what the unit said."""
        e = self.core.estop
        if e is None:
            return "off"
        unit = (Message(N_("confirmed by the unit")) if e.confirmed else
                Message(N_("not confirmed by the unit ({refusal})"), refusal=e.refusal) if e.refusal else
                Message(N_("not yet confirmed by the unit")))
        return Message(N_("ON since {time}, pressed by {who}; {unit}; released only by its release (RS 19)"),
                       time=time.strftime('%H:%M:%S', time.localtime(e.at)), who=e.who, unit=unit)

    def publish_estop(self) -> None:
        self.state.fact(P_ESTOP, self.estop, text=self.estop_text())

    async def write_read_back(self, data_id: int, value: Any, what: str) -> Any:
        await self.link.request(p.rt_frame(data_id, value), f"RT 0x{data_id:04X} {what} = {value}")
        answer = await self.link.request(codec.encode_rg(data_id), f"RG 0x{data_id:04X} {what} (read-back)")
        back = p.rg_value(data_id, answer)
        self._publish_remote(data_id, back)
        if back != value:
            self.state.counters.write_errors += 1
            raise CommandError(f"{what}: wrote {value}, read back {back}")
        return back

    def _publish_remote(self, data_id: int, value: Any) -> None:
        entry = p.item(data_id)
        self.settings.note(data_id, value)
        if entry.function is not None:
            self.state.publish(f"F{entry.function} remote speed", value, "% or counts/s", periodic=False)
        elif entry.actuator is not None:
            mm = self.scales[entry.actuator - 1].mm(value) if entry.actuator <= len(self.scales) else None
            self.state.publish(f"A{entry.actuator} remote position", value, "counts", periodic=False,
                               text=f"{value} counts" + (f" = {mm:g} mm" if mm is not None else ""))

    async def set_remote_speed(self, session: str, function: int, speed: int) -> int:
        """RT 0x3011.. (F1..F10) and RG read-back; % or counts/s per the unit's configuration (table 7)."""
        self.check_holder(session)
        await self.ensure_open()
        self.check_open()
        if isinstance(speed, bool) or not isinstance(speed, int) or not 0 <= speed <= self.speed_max:
            raise CommandError(f"remote speed: 0..{self.speed_max} {self.speed_unit} (the unit's speed select is "
                               f"{self.speed_select}, table 7), a whole number")
        return await self.write_read_back(p.speed_id(function), speed, f"remote speed F{function}")

    async def set_remote_position(self, session: str, actuator: int, *, counts: int | None = None,
                                  mm: float | None = None) -> int:
        """RT 0x3021.. in counts (or mm through the actuator's conversion) and RG read-back."""
        self.check_holder(session)
        await self.ensure_open()
        self.check_open()
        if not 1 <= actuator <= len(self.scales):
            raise CommandError(f"actuator {actuator} is not configured (1..{len(self.scales)})")
        if counts is None:
            if mm is None:
                raise CommandError("give the remote position in counts or mm")
            counts = self.scales[actuator - 1].counts(float(mm))
        if not -(2 ** 31) <= int(counts) < 2 ** 31:
            raise CommandError("remote position must fit INT32")
        return await self.write_read_back(p.remote_position_id(actuator), int(counts), f"remote position A{actuator}")

    async def set_remote_target(self, session: str, actuator: int, value: float, mm: bool = False) -> int:
        """The declared ``set remote position``: ``value`` in mm (``mm``) or counts."""
        if mm:
            return await self.set_remote_position(session, actuator, mm=float(value))
        if float(value) != int(value):
            raise CommandError("remote position in counts: a whole number")
        return await self.set_remote_position(session, actuator, counts=int(value))

    async def release_scu(self, session: str | None = None) -> str:
        """RS to every running function, then RA: the hand switch has the unit back; no reopening until asked.

        An RA without an acknowledgement still releases the unit: RC stops with it, so the unit's watchdog ends
        remote mode within 500 ms (section 5). The result says which, and the event says the same.
        """
        for fn in [f for f in self.running if f not in NOT_HELD]:
            await self.send_rs(fn, Message(N_("release of the SCU")))
        how = Message(N_("released (RA acknowledged): normal mode, the hand switch has the unit"))
        try:
            await self.link.request(codec.encode_ra(), "RA release the SCU", keepalive=False)
        except (SerialLineError, codec.CodecError) as exc:
            how = Message(N_("released without an acknowledged RA ({error}): RC has stopped, so the unit's watchdog ends "
                             "remote mode within 500 ms (section 5) and the hand switch has the unit then"),
                          error=message_of(exc))
        finally:
            self.cyclic = None
            self.core.released()
            self.sync_phase()
        self.state.event("info" if how.startswith("released (RA") else "warning",
                         Message("SCU {how}", how=how))  # a template without words: not marked (docs/i18n.md)
        return how

    async def reopen(self, session: str | None = None) -> str:
        """Open the remote session again (after a release, or by hand after a loss): the line is resynchronised first."""
        await self.link.resync()
        self.core.reopen_asked()
        why_not = self.core.may_open(time.monotonic())
        if why_not and self.session != "open":
            raise CommandError(f"not opened now: {why_not}")
        await self.open_session()
        return self.session

    # -- data directory -------------------------------------------------------------------------------
    async def read_data(self, data_id: int) -> dict:
        """RG of one data ID or group ID: decoded value, text and the raw bytes."""
        if self.watch != WATCH_RG:
            await self.ensure_open()
            self.check_open()
        entry = p.item(data_id)
        answer = await self.link.request(codec.encode_rg(data_id), f"RG 0x{data_id:04X} {entry.name}")
        result = {"data_id": data_id, "key": entry.key, "name": entry.name, "type": entry.type_name, "unit": entry.unit,
                  "comment": entry.comment, "raw": answer.data.hex(" ").upper(), "value": None, "text": "", "error": ""}
        try:
            value = p.decode_data(data_id, answer.data)
        except (v.DecodeError, ValueError) as exc:
            result["error"] = Message(N_("cannot decode {n} bytes as {type}: {error}"), n=len(answer.data),
                                      type=entry.type_name, error=str(exc))
            return result
        result["value"] = value
        result["text"] = value_text(data_id, value)
        self.live.publish_ids({data_id: value})
        return result

    # -- parameter model: backup, restore, project, batch, drift (devices/scu/settings.py) -------------------
    async def backup_read(self, progress=None) -> list[dict]:
        return await self.settings.backup_read(progress)

    def backup_identity(self) -> dict:
        return self.settings.identity()

    async def read_param(self, param) -> int:
        return await self.settings.read_param(param)

    async def write_param(self, param, value, *, confirmed: bool = False) -> int:
        return await self.settings.write(param, value, confirmed=confirmed)

    async def write_accepted(self, accepted: Accepted, *, confirmed: bool = False) -> int:
        return await self.settings.write_accepted(accepted, confirmed=confirmed)

    async def save_step(self) -> None:
        return None  # remote data are volatile (table 7): there is nothing to save them with
