"""The shared control-session core: who controls a device, the lease of what runs, the dead-man rule.

Sans-I/O in the manner of h11: the core holds state and answers events (an operator takes or
releases control, a page disconnects or comes back, the supervisor's beat, time passing) with
*actions* (stop what runs, say this); it never sends, sleeps or reads a clock. Every method takes
``now``, monotonic seconds from the caller's clock, so a test drives it in virtual time. A family
core (``devices/<type>/control.py``) holds one :class:`ControlSession` and adds its own rules
(keep-alive, stop and its acknowledgement, emergency stop); the adapter carries the actions out.

The rules every family shares:

- one browser session at a time controls a device; another is refused while the holder's page is
  connected, and may take over once it has disconnected;
- what runs (motion, mains outputs) runs under a lease that the dead-man supervisor renews while the
  controlling page is alive; a lease not renewed for ``lease_s`` lapses, and a lapse latches: it
  stops what runs and nothing runs again until an operator starts it anew;
- a page that disconnects stops what it runs at once (it keeps control until it is gone for good);
  a page gone for good stops and releases.

No import of asyncio, threading, sockets or any bus library (tests/safety/test_control_layering.py).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from devices.message import Message, N_

LEASE_S = 0.35  # as devices.lease.LEASE_S: a lease renewed every 50 ms lapses 0.35 s after its last renewal
STOP_DEADLINE_S = 0.5  # what runs stops within this long after the controlling operator is gone (ARCHITECTURE.md, rule 7)
def dead_man(reason: str) -> Message:
    """What stops under the dead-man rule, with its reason, named once: the worker's own reason for a silent page says
    "dead-man: ..." already, a page that went away ("the controlling browser disconnected") gets it here."""
    if str(reason).startswith("dead-man"):
        return reason if isinstance(reason, Message) else Message(reason)
    return Message(N_("dead-man: {reason}"), reason=reason)


RELEASED = Message(N_("released"))  # control given back by its holder ("control released (alice)")


# -- actions ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Stop:
    """Stop everything the session runs (the family knows what that is on its device)."""

    reason: str
    lapse: bool = False  # the lease lapsed (the program or the page stalled): say so loudly


@dataclass(frozen=True, slots=True)
class Report:
    """Say this in the device's events (``level`` info, warning or error)."""

    level: str
    text: str


@dataclass(frozen=True, slots=True)
class LeaseChange:
    """The cyclic sender's own lease (the thread-safe ``devices.lease.Lease`` it reads on its own thread) follows the
    core's: ``grant``, ``renew`` or ``revoke``. ``at``: the time it counts from (for a renewal, the controlling page's
    last sign of life when the supervisor tells it); None: the event's time."""

    what: str
    at: float | None = None


@dataclass(frozen=True, slots=True)
class ControlChanged:
    """The holder changed (``holder`` None: nobody controls the device now)."""

    holder: "Holder | None"


@dataclass(frozen=True, slots=True)
class Holder:
    session: str
    user: str
    since: float  # wall-clock time control was taken (for people)
    disconnected: float | None = None  # monotonic time its page's connection dropped (it may come back)


@dataclass(frozen=True, slots=True)
class Decision:
    """What the core says to a request it may refuse: ``refused`` is the reason ("" = granted)."""

    refused: str = ""
    busy: bool = False  # refused because another session holds control
    actions: tuple = ()

    @property
    def ok(self) -> bool:
        return not self.refused


class LeaseState:
    """A lease in the caller's time: granted, renewed, lapsed (latched) or revoked. Pure."""

    __slots__ = ("valid_s", "until", "lapsed_at", "renewed_at")

    def __init__(self, valid_s: float = LEASE_S):
        self.valid_s = valid_s
        self.until: float | None = None  # None: not granted
        self.lapsed_at: float | None = None
        self.renewed_at: float | None = None

    @property
    def granted(self) -> bool:
        return self.until is not None

    def grant(self, now: float) -> None:
        self.until, self.lapsed_at, self.renewed_at = now + self.valid_s, None, now

    def revoke(self) -> None:
        self.until = self.lapsed_at = None

    def valid(self, now: float) -> bool:
        if self.until is None or self.lapsed_at is not None:
            return False
        if now > self.until:
            self.lapsed_at = self.until
            return False
        return True

    def renew(self, now: float) -> bool:
        if not self.valid(now):
            return False
        self.until, self.renewed_at = now + self.valid_s, now
        return True


class ControlSession:
    """Who controls one device, and the lease of what runs for the holder.

    ``running`` is the family's business: it calls :meth:`started` when something begins to run for the
    holder and :meth:`idle` when nothing runs any more (stopped and acknowledged).
    """

    def __init__(self, lease_s: float = LEASE_S, lease=None):
        """:param lease: the lease object (``LeaseState`` by default; an adapter whose cyclic sender runs on a thread
            of its own passes the thread-safe ``devices.lease.Lease``, which has the same methods)"""
        self.holder: Holder | None = None
        self.lease = LeaseState(lease_s) if lease is None else lease
        self.running = False
        self.lapses = 0

    # -- queries ---------------------------------------------------------------------------------
    def controls(self, session: str) -> bool:
        return self.holder is not None and self.holder.session == session

    def holders(self) -> set[str]:
        """The session that keeps something running (the dead-man supervisor watches it)."""
        return {self.holder.session} if self.holder is not None and self.running else set()

    def check_holder(self, session: str) -> Decision:
        if self.holder is None:
            return Decision("take control first")
        if self.holder.session != session:
            return Decision(f"{self.holder.user} holds control", busy=True)
        return Decision()

    # -- operator events -------------------------------------------------------------------------
    def take(self, session: str, user: str, now: float, wall: float) -> Decision:
        """``session`` asks for control. A holder whose page has disconnected may be taken over."""
        actions: list = []
        h = self.holder
        if h is not None and h.session != session and h.disconnected is not None:
            actions += self._drop(Message(N_("taken over by {user}: the page that held it had disconnected"), user=user))
            h = None
        if h is not None and h.session != session:
            return Decision(f"{h.user} holds control since {_clock(h.since)}", busy=True)
        if h is not None:
            return Decision(actions=tuple(actions))
        self.holder = Holder(session, user, wall)
        actions += [ControlChanged(self.holder), Report("info", Message(N_("{user} took control"), user=user))]
        return Decision(actions=tuple(actions))

    def release(self, session: str, reason: str = RELEASED) -> list:
        """The holder gives control back (``session`` "" : whoever holds it); what runs stops first."""
        if self.holder is None or (session and self.holder.session != session):
            return []
        return self._drop(reason, level="info")

    def disconnected(self, session: str, reason: str, now: float) -> list:
        """The page of ``session`` lost its connection: what it runs stops now; control stays until it is gone."""
        if not self.controls(session):
            return []
        self.holder = replace(self.holder, disconnected=now)
        if not self.running:
            return []
        return [Stop(reason), Report("warning", Message(N_("stopped: {reason} ({user})"), reason=reason, user=self.holder.user))]

    def back(self, session: str) -> list:
        """The page of ``session`` is alive again: its control is its own again (nothing restarts)."""
        if self.controls(session) and self.holder.disconnected is not None:
            self.holder = replace(self.holder, disconnected=None)
        return []

    def lost(self, session: str, reason: str) -> list:
        """The page of ``session`` is gone for good (or froze): stop and release."""
        if not self.controls(session):
            return []
        return self._drop(Message(N_("released: {reason}"), reason=reason))

    # -- what runs, and its lease ---------------------------------------------------------------------
    def started(self, now: float) -> None:
        """Something runs for the holder from now on (a press of its page just now: it is alive)."""
        self.running = True
        self.lease.grant(now)

    def idle(self) -> None:
        """Nothing runs any more: the lease ends without a lapse."""
        self.running = False
        self.lease.revoke()

    def beat(self, alive: set[str], now: float) -> list:
        """The dead-man supervisor: ``alive`` are the sessions whose pages confirmed they are alive."""
        if not self.running or self.holder is None:
            return []
        if self.holder.session in alive and self.holder.disconnected is None and self.lease.renew(now):
            return []
        return self.tick(now)

    def tick(self, now: float) -> list:
        """Time passes: a lease past its time lapses (once), which stops what runs."""
        if not self.running or self.lease.valid(now):
            return []
        self.running = False  # (running without a granted lease would be a family's bug: it stops as well)
        self.lapses += 1
        lapsed_at, renewed_at = self.lease.lapsed_at, self.lease.renewed_at
        late_ms = ((lapsed_at - renewed_at) * 1000 if lapsed_at is not None and renewed_at is not None
                   else self.lease.valid_s * 1000)
        return [Stop(Message(N_("lease lapsed: the controlling page stopped confirming it is alive, or this program "
                                "stalled")), lapse=True),
                Report("error", Message(N_("stopped: the lease of what ran was not renewed for {ms:.0f} ms (this program "
                                           "stalled, or the controlling browser stopped confirming it is alive). Press "
                                           "again to go on"), ms=late_ms))]

    def _drop(self, reason: str, level: str = "warning") -> list:
        user = self.holder.user if self.holder is not None else Message(N_("nobody"))
        actions: list = []
        if self.running:
            actions.append(Stop(reason))
        self.holder = None
        actions += [ControlChanged(None), Report(level, Message(N_("control {reason} ({user})"), reason=reason, user=user))]
        return actions


def _clock(wall: float) -> str:
    """Hours, minutes and seconds of a wall-clock time, in UTC (pure: no local time zone lookup)."""
    seconds = int(wall) % 86400
    return f"{seconds // 3600:02d}:{seconds // 60 % 60:02d}:{seconds % 60:02d} UTC"
