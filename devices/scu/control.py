"""The SCU's safety rules as a state machine without I/O (document 002, sections 4.1, 4.6, 5; tables 3, 8).

What it decides, from events (operator commands, answers, refusals, losses, time) alone:

- the remote session: closed, opening, open, lost, released (RA), and when it may be opened again;
- the RC keep-alive: sent while the session is open, **withheld** once a stop was refused or not
  answered, so that the unit's own watchdog ends remote mode and stops every drive (section 5:
  "Fällt die Kommunikation mit RC aus, stoppt die Steuereinheit alle in Bewegung befindlichen
  Antriebe"); no reopening until RC has been withheld longer than the watchdog's 500 ms;
- which functions run (RE sent, RS not acknowledged) and for whom, the RS owed to each (section 4.6:
  every RE is followed by an RS), RS sent again on CSE or no answer, in the three-byte form of table 3
  after a PCE to the two-byte form;
- the emergency stop (function 19, F20): never refused, whatever the session's state; the running
  functions get their RS whatever the unit answers to RE 19; switched on again after every reopening;
  released only by its explicit release (RS 19);
- control and the lease of what runs (the shared :class:`devices.control.ControlSession`).

The adapter (:mod:`devices.scu.adapter`) carries the actions out on the serial line. No I/O here, no
clock: every method takes ``now`` (monotonic seconds) from its caller.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from devices.control import ControlSession, Decision, Report, Stop, dead_man
from devices.message import Message, N_
from devices.scu import codec

WITHHOLD_S = codec.WATCHDOG_S + 0.3  # RC withheld this long: the unit's 500 ms watchdog has tripped, with margin
REOPEN_BACKOFF_S = (0.2, 0.5, 1.0, 2.0, 5.0)
RS_ATTEMPTS = 3
ESTOP = int(codec.Function.EMERGENCY_STOP)
LEASE_LAPSED = N_("the lease of the running functions lapsed")  # RC withheld for it (section 5's watchdog stops the drives)
EMERGENCY_STOP = Message(N_("emergency stop"))  # why RE 19 and the RS of the running functions are sent
NOT_HELD = frozenset({ESTOP})  # the emergency stop runs under no lease: nothing ends it but its release
MOTION = frozenset(int(f) for f in codec.MOTION_FUNCTIONS)
PHASES = ("closed", "opening", "open", "lost", "released")


class Outcome(Enum):
    """How the unit answered a request."""

    ACK = "ack"
    CSE = "CSE"  # checksum error: line noise, not executed (section 4.2): send again
    PDE = "PDE"
    PCE = "PCE"  # parameter count: the unit expects the request's other form (table 3)
    ICE = "ICE"
    PE = "PE"  # not possible in the unit's present mode (remote mode gone)
    LOST = "lost"  # no answer, or an answer that could not be read

    @classmethod
    def of_status(cls, status: int) -> "Outcome":
        return {0x06: cls.ACK, 0x80: cls.CSE, 0x81: cls.PDE, 0x82: cls.PCE, 0x83: cls.ICE, 0x84: cls.PE}.get(
            int(status), cls.PDE)


# -- actions --------------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class SendRS:
    fn: int
    why: str
    attempt: int = 1
    three_bytes: bool = False  # RS fnc_ID para_ID[0] para_ID[1] (table 3 lists P2 and P3 as function parameters)


@dataclass(frozen=True, slots=True)
class SendEstop:
    """RE 19: the emergency stop (F20), on the unit."""

    why: str


@dataclass(frozen=True, slots=True)
class OpenSession:
    """Open the remote session now: RO, RC, then the core's :meth:`ScuControl.opened` actions."""

    why: str
    forced: bool = False  # for the emergency stop: whatever the backoff or an earlier RA


@dataclass(frozen=True, slots=True)
class WithholdRC:
    """Send no RC from now on: the unit's watchdog ends remote mode and stops every drive within 500 ms."""

    reason: str


@dataclass(frozen=True, slots=True)
class Estop:
    who: str  # the user who pressed it (or the session tag)
    at: float  # wall-clock time it was pressed
    confirmed: bool = False  # the unit acknowledged RE 19 (since the last opening)
    refusal: str = ""  # what the unit answered instead, if it did not acknowledge


def label(fn: int) -> str:
    return codec.FUNCTIONS[codec.Function(fn)].label


def labels(fns) -> str:
    return ", ".join(label(f) for f in sorted(fns)) or "none"


class ScuControl:
    """The safety state of one SCU and the rules that change it."""

    def __init__(self, lease=None):
        """:param lease: the lease of what runs (pure ``LeaseState`` by default; the adapter passes the thread-safe
            ``devices.lease.Lease`` its RC thread asks)"""
        self.control = ControlSession(lease=lease)
        self.phase = "closed"
        self.reason = ""
        self.running: dict[int, str] = {}  # fnc_ID -> session that sent its RE (RS not yet acknowledged)
        self.rs_pending: dict[int, str] = {}  # fnc_ID -> why its RS was sent and not acknowledged
        self.estop: Estop | None = None
        self.withheld_since: float | None = None  # RC withheld since (monotonic); None: RC goes out while open
        self.withheld_reason = ""
        self.failures = 0
        self.next_open = 0.0
        self.rs_three_bytes = False  # the unit answered PCE to the two-byte RS: three bytes from now on
        self.ro_two_bytes = False  # the unit answered PCE to the one-byte RO: two bytes from now on
        self.stop_failures = 0

    # -- queries ------------------------------------------------------------------------------------------
    @property
    def held(self) -> frozenset[int]:
        """Running functions the lease covers (never the emergency stop)."""
        return frozenset(fn for fn in self.running if fn not in NOT_HELD)

    def holders(self) -> set[str]:
        return {s for fn, s in self.running.items() if fn not in NOT_HELD}

    def rc_allowed(self, now: float) -> bool:
        """Whether an RC may go out now: the session is open and no failed stop made the tool withhold it."""
        return self.phase == "open" and self.withheld_since is None

    def watchdog_owed(self, now: float) -> bool:
        """RC is withheld and the unit's watchdog may not have tripped yet."""
        return self.withheld_since is not None and now - self.withheld_since < WITHHOLD_S

    def may_open(self, now: float, forced: bool = False) -> str:
        """Why the session may not be opened now ("" = it may)."""
        if self.phase == "open":
            return Message(N_("the session is open"))
        if self.watchdog_owed(now):
            return Message(N_("RC is withheld ({reason}) until the unit's watchdog has stopped every drive ({ms:.0f} ms)"),
                           reason=self.withheld_reason, ms=WITHHOLD_S * 1000)
        if forced:
            return ""
        if self.phase == "released":
            return Message(N_("released to the hand switch (RA): open the session again to drive it"))
        if now < self.next_open:
            return Message(N_("reopening in {seconds:.1f} s (backoff)"), seconds=self.next_open - now)
        return ""

    def needs_session(self, watched_in_session: bool) -> bool:
        """A remote session is needed: the unit is read only in one, someone drives, a stop is owed, or F20 is on."""
        return (watched_in_session or self.control.holder is not None or bool(self.running) or bool(self.rs_pending)
                or self.estop is not None)

    # -- the session ----------------------------------------------------------------------------------------
    def opening(self) -> None:
        self.phase, self.reason = "opening", ""

    def ro_refused(self, outcome: Outcome) -> bool:
        """RO answered with an error: True when the other form of table 3 (Safety_ID and para_ID[0]) is worth a try."""
        if outcome == Outcome.PCE and not self.ro_two_bytes:
            self.ro_two_bytes = True
            return True
        return False

    def opened(self, now: float) -> list:
        """RO and RC were acknowledged: the session is open. Before anything else: F20 again when it is on, and
        the RS owed to every function that ran (section 4.6), whatever the cyclic object's definition does."""
        self.phase, self.reason = "open", ""
        self.failures = 0
        self.withheld_since, self.withheld_reason = None, ""
        actions: list = []
        if self.estop is not None:
            self.estop = Estop(self.estop.who, self.estop.at)  # to be confirmed again by this session
            actions.append(SendEstop(Message(N_("kept on after reopening"))))
        for fn in sorted((set(self.running) | set(self.rs_pending)) - NOT_HELD):
            actions.append(SendRS(fn, self.rs_pending.get(fn) or Message(N_("after the lost session")),
                                  three_bytes=self.rs_three_bytes))
        return actions

    def open_failed(self, reason: str, now: float, answered_before: bool) -> None:
        self.phase, self.reason = ("lost" if answered_before else "closed"), reason
        self._backoff(now)

    def lost(self, reason: str, now: float) -> list:
        """The session ended without RA (watchdog, PE, no answer): reopened with backoff."""
        if self.phase != "open":
            return []
        self.phase, self.reason = "lost", reason
        self._unconfirm_estop()
        self._backoff(now)
        return [Report("error", Message(N_("remote session lost: {reason}; reopening with backoff"), reason=reason))]

    def _unconfirm_estop(self) -> None:
        """Remote mode ended: whether F20 is still on in the unit is not known until the session is open again."""
        if self.estop is not None and self.estop.confirmed:
            self.estop = Estop(self.estop.who, self.estop.at, confirmed=False, refusal=Message(N_("remote mode ended")))

    def closed(self, reason: str) -> None:
        """Nobody needs the session (watching with RG): RA sent."""
        self.phase, self.reason = "closed", reason

    def released(self) -> None:
        """RA by the operator: the hand switch has the unit; no reopening until asked (the emergency stop stays on)."""
        self.phase, self.reason = "released", Message(N_("released to the hand switch (RA); open the session again to drive it"))

    def reopen_asked(self) -> None:
        if self.phase != "open":
            self.phase, self.reason = "closed", ""
        self.next_open = 0.0

    def _backoff(self, now: float) -> None:
        self.failures += 1
        self.next_open = now + REOPEN_BACKOFF_S[min(self.failures - 1, len(REOPEN_BACKOFF_S) - 1)]

    def withhold(self, reason: str, now: float) -> list:
        """Withhold RC: the unit's watchdog stops every drive (section 5). The session counts as lost from now on,
        and it is not opened again before the watchdog has tripped."""
        if self.withheld_since is None:
            self.withheld_since, self.withheld_reason = now, reason
        was_open = self.phase == "open"
        self.phase, self.reason = "lost", Message(N_("RC withheld: {reason}"), reason=reason)
        self._unconfirm_estop()
        if was_open:
            self._backoff(now)
        self.next_open = max(self.next_open, self.withheld_since + WITHHOLD_S)
        return [WithholdRC(reason)]

    # -- functions ----------------------------------------------------------------------------------------------
    def check_run(self, session: str, fn: int) -> Decision:
        """May ``session`` start function ``fn`` now? (The session is opened first by the caller if needed.)"""
        decision = self.control.check_holder(session)
        if not decision.ok:
            return decision
        if self.estop is not None and fn in MOTION:
            return Decision("the emergency stop (function 19) is on: release it first (RS 19, by the person who set it)")
        if fn in self.rs_pending:
            return Decision(f"the RS of {label(fn)} is not acknowledged yet: no new RE until it is")
        if self.withheld_since is not None:
            return Decision(f"RC is withheld after a stop that was not acknowledged ({self.withheld_reason}): "
                            "no RE until the session is open again and every RS is acknowledged")
        return Decision()

    def re_sent(self, session: str, fn: int, now: float) -> None:
        """The RE of ``fn`` goes out now: it runs until an acknowledged RS, whatever its answer."""
        self.running[fn] = session
        if fn not in NOT_HELD:
            self.control.started(now)

    def re_answered(self, fn: int, outcome: Outcome) -> list:
        """The RE's answer: anything but ACK is followed by its RS at once (a lost answer may have been executed)."""
        if outcome == Outcome.ACK:
            return []
        return [SendRS(fn, Message(N_("RE not confirmed")), three_bytes=self.rs_three_bytes)]

    def stop_targets(self, fn: int | None, started: set[int]) -> list[int]:
        """What a Stop sends RS to: ``fn``, or every function that runs, ran this session or owes an RS (F1 at least)."""
        if fn is not None:
            return [int(fn)]
        return sorted(((set(self.running) | set(started) | set(self.rs_pending)) - NOT_HELD) or {int(codec.Function.F1)})

    def rs_answered(self, action: SendRS, outcome: Outcome, now: float) -> list:
        """An RS's answer: done, sent again (CSE, no answer; PCE once in the three-byte form), or a failed stop,
        which withholds RC so that the unit's own watchdog stops it (section 5)."""
        fn = action.fn
        if outcome == Outcome.ACK:
            self.running.pop(fn, None)
            self.rs_pending.pop(fn, None)
            if fn == ESTOP:
                self.estop = None
            self._held_changed()
            return []
        if outcome == Outcome.PCE and not action.three_bytes:
            self.rs_three_bytes = True
            return [SendRS(fn, action.why, action.attempt, three_bytes=True)]
        if outcome in (Outcome.CSE, Outcome.LOST) and action.attempt < RS_ATTEMPTS and self.phase == "open":
            return [SendRS(fn, action.why, action.attempt + 1, three_bytes=action.three_bytes)]
        # not acknowledged: refused (PDE, PCE in both forms, ICE, PE), or CSE / no answer RS_ATTEMPTS times
        if fn == ESTOP:
            # the release was not acknowledged: it stays on here, and RE 19 goes out again so that the unit (which may
            # have executed the RS whose answer was lost) is in the same state as the tool says
            if self.estop is not None:
                self.estop = Estop(self.estop.who, self.estop.at, confirmed=False, refusal=Message(N_("release not acknowledged")))
            return [Report("error", Message(N_("RS 19 ({why}) not acknowledged ({outcome}): the emergency stop stays on; "
                                               "RE 19 is sent again"), why=action.why, outcome=outcome.value)),
                    SendEstop(Message(N_("release not acknowledged")))]
        self.rs_pending[fn] = action.why
        self.running.setdefault(fn, "")
        self.stop_failures += 1
        actions: list = []
        if outcome == Outcome.PE:
            # not possible in the unit's mode: remote mode has ended (its watchdog stopped every remote drive, section 5)
            actions += self.lost(Message(N_("PE to RS {function}: the unit is no longer in remote mode"), function=label(fn)), now)
        if self.estop is not None and self.estop.confirmed:
            reason = Message(N_("RS {function} ({why}) not acknowledged ({outcome}); the emergency stop F20 is on in the "
                                "unit and keeps every drive stopped; RS is sent again"),
                             function=label(fn), why=action.why, outcome=outcome.value)
        else:
            reason = Message(N_("RS {function} ({why}) not acknowledged ({outcome})"),
                             function=label(fn), why=action.why, outcome=outcome.value)
            actions += self.withhold(reason, now)
        actions.append(Report("error", Message(
            N_("STOP FAILED: {reason}. RC is withheld, so the unit's own watchdog ends remote mode and stops every drive "
               "within 500 ms (section 5); the session is opened again after that and the RS sent again. If the actuator "
               "still moves, use the hand switch's stop or cut the supply"), reason=reason)
            if self.withheld_since is not None else Message(N_("STOP FAILED: {reason}. "), reason=reason)))
        return actions

    def _held_changed(self) -> None:
        if not self.held:
            self.control.idle()

    # -- the emergency stop -----------------------------------------------------------------------------------------
    def estop_pressed(self, who: str, now: float, wall: float) -> list:
        """Anyone may press it, in any state of the session: never refused. F20 on the unit (opening the session for
        it if needed, whatever the backoff or an RA), and RS to every running function whatever the unit answers."""
        if self.estop is None:
            self.estop = Estop(who, wall)
        actions: list = [Report("warning", Message(N_("emergency stop (function 19, F20) pressed by {who}"), who=who))]
        if self.phase != "open":
            actions.append(OpenSession(EMERGENCY_STOP, forced=True))  # opened() then sends RE 19 and the RS
            return actions
        actions.append(SendEstop(EMERGENCY_STOP))
        actions += [SendRS(fn, EMERGENCY_STOP, three_bytes=self.rs_three_bytes) for fn in sorted(self.held)]
        return actions

    def estop_unreachable(self, reason: str, now: float) -> list:
        """The session could not be opened for the emergency stop: nothing the tool sends reaches the unit, so
        no RC feeds its watchdog and no remote motion runs; the stop stays on in the tool."""
        return [Report("error", Message(N_("emergency stop: the unit did not answer ({reason}). The tool sends no RC, so "
                                           "the unit's watchdog keeps remote mode off and no remote motion runs; the "
                                           "emergency stop stays on here and is switched on in the unit as soon as it "
                                           "answers. Use the hardware emergency stop if anything moves"), reason=reason))]

    def estop_answered(self, outcome: Outcome, now: float) -> list:
        if self.estop is None:
            return []
        if outcome == Outcome.ACK:
            self.estop = Estop(self.estop.who, self.estop.at, confirmed=True)
            return []
        text = {Outcome.PDE: Message(N_("refused (PDE): F20 exists from firmware V2B1 only (table 8)")),
                Outcome.LOST: Message(N_("not answered"))}.get(outcome, Message(N_("refused ({outcome})"),
                                                                              outcome=outcome.value))
        self.estop = Estop(self.estop.who, self.estop.at, confirmed=False, refusal=text)
        actions: list = self.lost(Message(N_("PE to RE 19: the unit is no longer in remote mode")), now) if outcome == Outcome.PE else []
        actions += [Report("error", Message(N_("RE 19 (emergency stop) {refusal}: the running functions get their RS; the "
                                               "emergency stop stays on in this tool and no motion starts until it is "
                                               "released"), refusal=text))]
        return actions

    def estop_release(self, session: str) -> Decision:
        decision = self.control.check_holder(session)
        if not decision.ok:
            return decision
        if self.estop is None:
            return Decision("the emergency stop is not on")
        return Decision(actions=(SendRS(ESTOP, Message(N_("emergency stop released")), three_bytes=self.rs_three_bytes),))

    # -- control and the dead-man rule -----------------------------------------------------------------------------
    def _stops(self, actions: list, session: str | None) -> list:
        """Turn the shared core's Stop into the RS of what ``session`` (None: anyone) runs."""
        out: list = []
        for a in actions:
            if isinstance(a, Stop):
                out += [SendRS(fn, (Message(N_("lease lapsed")) if a.lapse else a.reason), three_bytes=self.rs_three_bytes)
                        for fn, s in sorted(self.running.items())
                        if fn not in NOT_HELD and (session is None or s == session)]
            else:
                out.append(a)
        return out

    def beat(self, alive: set[str], now: float) -> list:
        """The supervisor: renew the lease while a session that runs something is alive; a lapse sends RS."""
        holders = self.holders()
        if holders and holders & alive:
            self.control.running = True
            if self.control.lease.renew(now):
                return []
        return self.tick(now)

    def tick(self, now: float) -> list:
        if not self.held:
            return []
        lease = self.control.lease
        if not lease.granted:
            lease.grant(now)  # something runs without a lease (an RS owed since a lost session): from now on
        elif lease.lapsed_at is not None:
            return []  # the lapse was dealt with (RC withheld, RS sent); what is still held gets its RS on reopening
        self.control.running = True
        actions = self._stops(self.control.tick(now), None)
        if not actions or (self.estop is not None and self.estop.confirmed):
            return actions  # with F20 on in the unit RC goes on: remote mode keeps the emergency stop in force
        # a lapse means this program or the page stalled: RC is withheld first, so the unit's watchdog stops every
        # drive within 500 ms whatever becomes of the RS that follow
        return self.withhold(Message(LEASE_LAPSED), now) + actions

    def session_lost(self, session: str, reason: str) -> list:
        """The page of ``session`` went away or froze: RS at once for what it runs, and its control released."""
        actions = [SendRS(fn, dead_man(reason), three_bytes=self.rs_three_bytes)
                   for fn, s in sorted(self.running.items()) if s == session and fn not in NOT_HELD]
        if self.control.controls(session):
            running = self.control.running
            self.control.running = False  # the RS above already stop what it runs
            actions += self.control.lost(session, reason)
            self.control.running = running and bool(self.held)
        return actions
