"""The Electrak HD network's safety rules, without I/O: the control telegram 0x06 this tool wants on the bus.

Built on the shared control-session core (:mod:`devices.control`): who controls the network, the lease
of what runs, the dead-man rule. This module adds what is the Electrak's own (document "CAN-Steuerung"):

- the control telegram 0x06 (target, current limit, speed, enable, override/reset) is sent every 100 ms
  while a page holds control; :meth:`ElectrakControl.telegram` is what the periodic sender carries at a
  given time: once the lease is not valid, only the stop form (enable and override cleared);
- Go, Stop, jog (hold-to-run) and its release, override/reset; a stop is never refused, by anyone;
- override/reset is never sent without a confirmation that names its risk: it resets the number of
  devices the actuators expect ("Fehler-Flags" bit 7), so one actuator of a pair may then move alone.
  The bit is a pulse: it is cleared by itself after :data:`OVERRIDE_PULSE_S`;
- Go and jog are refused while fewer actuators are heard than configured; after an override/reset that
  counted fewer than configured, motion stops as soon as fewer are heard again;
- another sender of 0x06 on the bus (a PLC, an actuator whose manual control line is active): control is
  released at once and never taken while it sends (this tool never fights it);
- a page that disconnects stops motion at once (control stays until it is gone for good).

Events in (methods), actions out (lists of the dataclasses below and of :mod:`devices.control`'s
:class:`Report` and :class:`ControlChanged`); every method takes ``now``, monotonic seconds of the
caller's clock. No I/O (tests/safety/test_control_layering.py); the adapter (devices/electrak/adapter.py)
carries the actions out on python-can's periodic sender.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, replace

from devices.control import LEASE_S, ControlChanged, ControlSession, Decision, LeaseChange, Report, Stop
from devices.electrak import codec
from devices.message import N_, Message

OVERRIDE_PULSE_S = 0.3  # three control periods carry the override/reset bit, then it is cleared by itself
# (its lease, LEASE_S, is not renewed: a program that stalls meanwhile stops sending it 0.35 s after the confirmation)
FOREIGN_SENDER = Message(N_("a PLC, or an actuator whose manual control line is active"))

OVERRIDE_RISK = Message(N_(
    "Override/reset resets the number of actuators the network expects to the ones it hears now (document, "
    "'Fehler-Flags' bit 7 'zu wenige Geräte'). With an actuator missing, the 'Too few devices' lock is gone and "
    "one actuator of a pair may then move alone and twist or drop the load. It also holds motion while set. "
    "Send it only when every actuator is connected, or when the missing one is meant to stay off the network."
))
RELEASED = Message(N_("released"))  # control released (the page's Release)
TAKEN_OVER = Message(N_("taken over by another page: the page that held it had disconnected"))
OVERRIDE_UNCONFIRMED = ("override/reset needs a confirmation naming its risk (it resets the number of actuators the "
                        "network expects): confirm it on the Electrak page, or pass the confirmation")


# -- actions ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Send:
    """Send the control telegram 0x06 once, now (no periodic sender runs, e.g. the last one of a release)."""

    frame: codec.ControlFrame


@dataclass(frozen=True, slots=True)
class StartPeriodic:
    """Start sending ``frame`` every 100 ms (only its stop form while the lease is not valid)."""

    frame: codec.ControlFrame


@dataclass(frozen=True, slots=True)
class ModifyPeriodic:
    """The periodic sender carries ``frame`` from now on; ``send_now``: send it once at once as well."""

    frame: codec.ControlFrame
    send_now: bool = True


@dataclass(frozen=True, slots=True)
class StopPeriodic:
    """Stop the periodic sender."""


@dataclass(frozen=True, slots=True)
class CommandChanged:
    """The control telegram this tool wants changed (the adapter publishes it)."""

    frame: codec.ControlFrame


def stop_form(frame: codec.ControlFrame) -> codec.ControlFrame:
    """The control telegram with enable and override cleared, the rest kept."""
    return replace(frame, enable=False, override=False) if frame.enable or frame.override else frame


def stop_form_bytes(data: bytes) -> bytes:
    """The same on the wire: byte 7 bits 0 (enable) and 1 (override/reset) cleared."""
    return bytes(data[:7]) + bytes([data[7] & ~(codec.ENABLE | codec.OVERRIDE)]) if len(data) == 8 else bytes(data)


def is_stop(data: bytes) -> bool:
    """A control telegram that stops: 8 bytes with enable and override/reset both cleared."""
    return len(data) == 8 and not data[7] & (codec.ENABLE | codec.OVERRIDE)


class ElectrakControl:
    """Control of one Electrak network: the telegram 0x06 it wants, under the shared session core.

    :param limits: what every actuator of the network accepts (model, gearing, stroke)
    :param configured: the number of actuators the plant file configures
    """

    def __init__(self, limits: codec.Limits, configured: int, lease_s: float = LEASE_S):
        self.session = ControlSession(lease_s)
        self.limits = limits
        self.configured = configured
        self.heard: int | None = None  # actuators heard (status telegrams per 100 ms); None: not known yet
        self.command = codec.ControlFrame(0.0, 0.0, limits.speed_min, enable=False)
        self.sending = False  # the periodic sender runs
        self.listening_since: float | None = None  # since when a 0x06 of another node would have been heard
        self.foreign_at: float | None = None  # the last 0x06 of another node
        self.override_until: float | None = None  # the override/reset pulse ends then
        self.count_reset_to: int | None = None  # an override/reset made the network expect this many (< configured)

    # -- queries -----------------------------------------------------------------------------------------
    @property
    def holder(self):
        return self.session.holder

    def holders(self) -> set[str]:
        return self.session.holders()

    def telegram(self, now: float) -> codec.ControlFrame:
        """What the periodic sender carries at ``now``: the command, or its stop form once the lease is not valid."""
        c = self.command
        if (c.enable or c.override) and not self.session.lease.valid(now):
            return stop_form(c)
        return c

    def foreign_sender(self, now: float) -> bool:
        return self.foreign_at is not None and now - self.foreign_at <= codec.LISTEN_S

    def listen_remaining(self, now: float) -> float:
        """How much longer to listen for another sender of 0x06 before control may be taken."""
        if self.listening_since is None:
            return codec.LISTEN_S
        return max(0.0, codec.LISTEN_S - (now - self.listening_since))

    def too_few(self) -> str:
        """Why motion may not start for the number of actuators heard, or ""."""
        heard = self.heard
        if heard is None or heard >= self.configured:
            return ""
        said = (f"only {heard} of the {self.configured} configured actuators are heard (status telegrams per 100 ms)")
        if self.count_reset_to is not None:
            return (f"{said}, and Override/reset has made the network expect only the ones it heard then, so one actuator "
                    "of a pair would move alone. Reconnect the missing actuator (check its wiring and power) until all "
                    f"{self.configured} are heard, then press Override/reset again so that the network expects all of them")
        return (f"{said}: one actuator of a pair would move alone. Reconnect the missing actuator (check its wiring and "
                "power) until all are heard, or correct the plant file if the network really has fewer")

    # -- the bus -----------------------------------------------------------------------------------------
    def bus_opened(self, now: float) -> None:
        """The bus was (re)opened: frames of another sender would be heard from now on."""
        self.listening_since = now

    def foreign_control(self, now: float) -> list:
        """A control telegram 0x06 from another node: whoever holds control here releases it at once."""
        self.foreign_at = now
        if self.session.holder is None:
            return []
        return self._release(Message(N_("lost: another sender of the control telegram 0x06 is on the bus ({who}); this "
                                        "tool stopped sending so as not to fight it"), who=FOREIGN_SENDER),
                             now, level="error")

    def actuators_heard(self, heard: int, now: float) -> list:
        """The number of actuators heard changed. After an override/reset that counted fewer than configured, the
        network's own 'Too few devices' lock is gone: motion stops here as soon as fewer are heard again."""
        self.heard = heard
        if heard >= self.configured or self.count_reset_to is None or not self.command.enable:
            return []
        return self._stop_motion(now, "error", Message(N_(
            "motion stopped: only {heard} of the {configured} actuators are heard and Override/reset has turned off the "
            "network's own 'Too few devices' lock. Reconnect the missing actuator, then press Override/reset again"),
            heard=heard, configured=self.configured))

    # -- operator events ---------------------------------------------------------------------------------
    def take(self, session: str, user: str, now: float, wall: float) -> Decision:
        """Control for ``session`` (after listening :meth:`listen_remaining` for another sender of 0x06)."""
        h = self.session.holder
        if h is not None and h.session == session:
            return Decision()
        if self.foreign_sender(now):
            return Decision(Message(N_("control telegrams 0x06 from another sender are on the bus ({who}): taking control "
                                       "would fight it. Stop that sender (or release the control line) and try again."),
                                    who=FOREIGN_SENDER))
        if self.listen_remaining(now) > 0:
            return Decision(Message(N_("listening for another sender of 0x06 for {seconds:g} s first: try again in a moment"),
                                    seconds=codec.LISTEN_S))
        actions: list = []
        if h is not None and h.disconnected is not None:  # taken over from a page that disconnected
            actions += self._release(TAKEN_OVER, now)
        decision = self.session.take(session, user, now, wall)
        if not decision.ok:
            return decision
        c = stop_form(self.command)
        self.command, self.sending = c, True
        actions += [*decision.actions, StartPeriodic(c), CommandChanged(c),
                    Report("info", Message(N_("{user} took control (no other sender of 0x06 heard for {seconds:g} s); "
                                              "control telegrams every 100 ms"), user=user, seconds=codec.LISTEN_S))]
        return Decision(actions=tuple(actions))

    def release(self, session: str, reason: str, now: float) -> list:
        """The holder gives control back (``session`` "": whoever holds it)."""
        h = self.session.holder
        if h is None or (session and h.session != session):
            return []
        return self._release(reason, now)

    def set_target(self, session: str, position_mm: float, speed_mm_s: float, current_a: float, now: float) -> Decision:
        """New target, speed and current limit (checked against every actuator's range); enable stays as it is."""
        d = self.session.check_holder(session)
        if not d.ok:
            return d
        problems = self.limits.check(position_mm, current_a, speed_mm_s)
        if problems:
            return Decision("; ".join(problems))
        before = self.tick(now)  # a lapse not yet seen is seen first: a new target never restarts what it stopped
        return Decision(actions=tuple(before + self._command(
            codec.ControlFrame(position_mm, current_a, speed_mm_s, enable=self.command.enable), now)))

    def go(self, session: str, now: float) -> Decision:
        """Set enable: the actuators move to the target set before."""
        d = self._may_move(session)
        if not d.ok:
            return d
        c = self.command
        problems = self.limits.check(c.position_mm, c.current_a, c.speed_mm_s)
        if problems:
            return Decision("; ".join(problems))
        actions = self.tick(now)  # a lapse not yet seen is reported first; this press starts anew
        actions += self._command(codec.ControlFrame(c.position_mm, c.current_a, c.speed_mm_s, enable=True), now)
        actions.append(Report("info", Message(N_("go: target {position:g} mm at {speed:g} mm/s, limit {current:g} A"),
                                              position=c.position_mm, speed=c.speed_mm_s, current=c.current_a)))
        return Decision(actions=tuple(actions))

    def jog(self, session: str, direction: int, speed_mm_s: float | None, now: float,
            position_mm: float | None = None) -> Decision:
        """Hold-to-run toward an end (+1 out, -1 in); 0 ends it where the actuators are (``position_mm``)."""
        if direction == 0:
            d = self.session.check_holder(session)
            if not d.ok:
                return d
            c = self.command
            target = c.position_mm if position_mm is None else round(position_mm, 1)
            return Decision(actions=tuple(self._command(codec.ControlFrame(target, c.current_a, c.speed_mm_s), now)))
        d = self._may_move(session)
        if not d.ok:
            return d
        c = self.command
        speed = speed_mm_s or c.speed_mm_s
        target = self.limits.stroke_mm if direction > 0 else 0.0
        problems = self.limits.check(target, c.current_a, speed)
        if problems:
            return Decision("; ".join(problems))
        before = self.tick(now)  # a lapse not yet seen is reported first; this press starts anew
        return Decision(actions=tuple(before + self._command(codec.ControlFrame(target, c.current_a, speed, enable=True),
                                                             now)))

    def jog_release(self, session: str, now: float, position_mm: float | None = None) -> list:
        """A jog button released: the jog of ``session`` ends (nothing when it does not jog)."""
        if not self.session.controls(session) or not self.command.enable:
            return []
        return list(self.jog(session, 0, None, now, position_mm).actions)

    def stop(self, session: str | None, now: float) -> list:
        """Clear enable and override (anyone may stop, never refused); it leaves at once."""
        c = stop_form(self.command)
        self.override_until = None
        actions = self._command(c, now, send_now=False)
        actions.append(ModifyPeriodic(c) if self.sending else Send(c))
        actions.append(Report("info", Message(N_("stop: enable cleared"))))
        return actions

    def override(self, session: str, active: bool, now: float, *, confirmed: bool = False) -> Decision:
        """The override/reset bit, as a pulse of :data:`OVERRIDE_PULSE_S` (holds motion, resets the expected number
        of actuators). Setting it needs ``confirmed``: the operator confirmed :data:`OVERRIDE_RISK`."""
        d = self.session.check_holder(session)
        if not d.ok:
            return d
        c = self.command
        if not active:
            self.override_until = None
            return Decision(actions=tuple(self._command(codec.ControlFrame(c.position_mm, c.current_a, c.speed_mm_s), now)))
        if not confirmed:
            return Decision(OVERRIDE_UNCONFIRMED)
        heard = self.heard
        self.count_reset_to = heard if heard is not None and heard < self.configured else None
        self.override_until = now + OVERRIDE_PULSE_S
        actions = self._command(codec.ControlFrame(c.position_mm, c.current_a, c.speed_mm_s, override=True), now)
        if self.count_reset_to is not None:
            actions.append(Report("warning", Message(N_(
                "override/reset sent (confirmed); the network now expects the {heard} actuator(s) it hears, not the "
                "{configured} configured: Go and jog are refused until all are heard"), heard=heard, configured=self.configured)))
        else:
            actions.append(Report("info", Message(N_("override/reset sent (confirmed)"))))
        return Decision(actions=tuple(actions))

    # -- the page's life ---------------------------------------------------------------------------------
    def disconnected(self, session: str, reason: str, now: float) -> list:
        """The page of ``session`` lost its connection: motion stops now; control stays until it is gone."""
        actions = self.session.disconnected(session, reason, now)
        if not any(isinstance(a, Stop) for a in actions):
            return actions
        user = self.session.holder.user
        return self._stop_motion(now, "warning", Message(N_("motion stopped: {reason} ({user}); enable cleared"),
                                                         reason=reason, user=user))

    def back(self, session: str) -> list:
        return self.session.back(session)

    def lost(self, session: str, reason: str, now: float) -> list:
        """The browser of ``session`` went away or froze: stop at once and release its control."""
        if not self.session.controls(session):
            return []
        return self._release(Message(N_("released: {reason}"), reason=reason), now)

    # -- time ----------------------------------------------------------------------------------------------
    def beat(self, alive: Collection[str] | Mapping[str, float], now: float) -> list:
        """The dead-man supervisor (every 50 ms): the sessions whose pages confirmed they are alive; a mapping gives
        each one's last beat (monotonic), from which the lease then counts: a page that froze just before this
        program stalled keeps nothing moving past that beat + the lease."""
        actions = self.tick(now)
        c = self.command
        if c.override and not c.enable:  # the override pulse is never renewed: it ends by itself, or its lease lapses
            return actions
        h = self.session.holder
        beat_at = alive.get(h.session) if isinstance(alive, Mapping) and h is not None else None
        if beat_at is not None and self.session.running:
            lease = self.session.lease
            at = min(now, max(beat_at, lease.renewed_at or beat_at))  # a press since is a sign of life too
            if h.disconnected is None and lease.valid(now) and lease.renew(at):
                actions.append(LeaseChange("renew", at))
            return actions + self._carry(self.session.tick(now), now)
        renewed = self.session.lease.renewed_at
        base = self.session.beat(alive, now)
        actions += self._carry(base, now)
        if self.session.running and self.session.lease.renewed_at != renewed:
            actions.append(LeaseChange("renew", now))
        return actions

    def tick(self, now: float) -> list:
        """Time passes: the override pulse ends; a lease past its time lapses (which stops)."""
        actions: list = []
        if self.override_until is not None and now >= self.override_until:
            self.override_until = None
            c = self.command
            if c.override:
                actions += self._command(replace(c, override=False), now)
        actions += self._carry(self.session.tick(now), now)
        return actions

    # -- inside --------------------------------------------------------------------------------------------
    def _may_move(self, session: str) -> Decision:
        d = self.session.check_holder(session)
        if not d.ok:
            return d
        reason = self.too_few()
        return Decision(f"refused: {reason}") if reason else Decision()

    def _command(self, frame: codec.ControlFrame, now: float, *, send_now: bool = True) -> list:
        """The telegram wanted is now ``frame``: the lease follows what runs, the sender carries it."""
        actions: list = []
        runs = frame.enable or frame.override
        if runs and self.session.holder is not None:
            self.session.started(now)  # a press of the holder's page just now: it is alive
            actions.append(LeaseChange("grant", now))
        elif not runs and self.session.running:
            self.session.idle()
            actions.append(LeaseChange("revoke"))
        if not runs:
            self.override_until = None
        self.command = frame
        if self.sending and send_now:
            actions.append(ModifyPeriodic(frame))
        actions.append(CommandChanged(frame))
        return actions

    def _stop_motion(self, now: float, level: str, text: str) -> list:
        c = self.command
        if not (c.enable or c.override):
            return []
        return [*self._command(stop_form(c), now, send_now=self.sending), Report(level, text)]

    def _carry(self, base: list, now: float) -> list:
        """The shared core's actions in the family's terms: its Stop clears enable and override."""
        out: list = []
        lapse = False
        for action in base:
            if lapse and isinstance(action, Report):  # the lapse in the Electrak's words (below)
                continue
            if isinstance(action, Stop):
                lapse = action.lapse
                c = self.command
                if c.enable or c.override:
                    self.command = stop_form(c)
                    self.override_until = None
                    if self.sending:
                        out.append(ModifyPeriodic(self.command))
                    out.append(CommandChanged(self.command))
                out.append(LeaseChange("revoke"))
                if lapse:
                    lease = self.session.lease
                    renewed = lease.renewed_at
                    stalled_ms = (now - renewed) * 1000 if renewed is not None else lease.valid_s * 1000
                    out.append(Report("error", Message(N_(
                        "motion stopped: this program stalled ({stalled:.0f} ms without renewing the motion's lease, limit "
                        "{limit:.0f} ms); the control telegram's sender cleared enable by itself. The browser was not at "
                        "fault: press again to move"), stalled=stalled_ms, limit=lease.valid_s * 1000)))
            else:
                out.append(action)
        return out

    def _release(self, reason: str, now: float, level: str = "warning") -> list:
        """Stop the keep-alive, send the stop form once more, give control back."""
        user = self.session.holder.user if self.session.holder is not None else "nobody"
        self.session.idle()
        self.session.holder = None
        c = stop_form(self.command)
        self.command, self.override_until = c, None
        actions: list = []
        if self.sending:
            actions.append(StopPeriodic())
            self.sending = False
        actions += [LeaseChange("revoke"), Send(c), CommandChanged(c), ControlChanged(None),
                    Report(level, Message(N_("control {reason} ({user}): enable cleared, control telegrams stopped"),
                                          reason=reason, user=user))]
        return actions
