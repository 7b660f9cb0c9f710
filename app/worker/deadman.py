"""The dead-man supervisor (ARCHITECTURE rule 6): browser sessions, their beats, and the leases.

A session that keeps motion or mains outputs running (it is among the holders' :meth:`holders`)
must confirm it is alive about ten times a second (:meth:`DeadmanSupervisor.heartbeat`); what it
holds is stopped once it has not confirmed for DEADMAN_TIMEOUT_S of this program's live clock
(closed, disconnected, frozen, network lost), within DEADMAN_BOUND_S of its last confirmation, and
a holder that never confirmed at all is stopped DEADMAN_TIMEOUT_S after it was first seen holding.
While it confirms, the supervisor renews the short leases of the senders it keeps running
(devices/lease.py), so a stalled program stops motion too.

A page beats only while it is needed (a page that holds nothing sends nothing; the rule above is the
same for every session, asked or not):

- while its session holds something: the supervisor, seeing a session holding that it has not asked
  yet, asks its page to beat (:attr:`DeadmanSupervisor.ask_beat`, a callback the web layer sets, so this
  package imports no UI), and tells it to stop once it has held nothing for BEAT_RELEASE_S;
- for BEAT_WINDOW_S after any user interaction on the page (pages/frame.py): the command that takes
  control or starts motion comes from an interaction, so the page beats before that command reaches
  the server and the first beat never waits for the server's request;
- after its connection came back (:meth:`DeadmanSupervisor.session_connected`): its first beat gives
  it back what it controlled (``session_back``), as before.

Silence is counted on a clock that runs only while this program runs on time: a supervision tick
credits at most LIVE_CREDIT_S however late it comes, so beats that waited in the socket because the
server was busy are not mistaken for a dead browser (a stalled loop is covered by the leases instead).

What a session holds is asked of the holders: the device adapters and the extra holders (an
engineer's cyclic transmit list, a replay), through the contract of devices/adapter.py.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Callable, Iterable
from typing import Any

from app.worker.loophealth import SUPERVISE_PERIOD_S
from devices.message import Message, N_
from devices.adapter import LeaseRenewer, SessionHolder, SessionResumer, SessionStopper

log = logging.getLogger(__name__)

BEAT_PERIOD_S = 0.1
DEADMAN_TIMEOUT_S = 0.4  # a browser tab starved of CPU on a loaded laptop (another tab loading) sends a beat 300+ ms late
DEADMAN_BOUND_S = 0.5  # the stated bound: timeout + one supervision period (0.45 s) + sending
LIVE_CREDIT_S = 2 * SUPERVISE_PERIOD_S
SILENCE_LIMIT_S = 2.0  # however busy this program was: no sign of life for this long in real time stops the session
BEAT_WINDOW_S = 5.0  # a page beats this long after any user interaction (the take reaches the server while it beats)
BEAT_RELEASE_S = 3.0  # a page asked to beat is told to stop once its session has held nothing this long


_CAPABLE: dict[tuple[type, type], bool] = {}


def _can(holder: Any, protocol: type) -> bool:
    """``isinstance(holder, protocol)`` for a runtime-checkable Protocol, answered once per class: the
    check walks the Protocol's members each time (about 15 us), and the supervisor asks 20 times a second
    for every adapter. The capabilities are methods of the holder's class, so the class decides."""
    key = (type(holder), protocol)
    known = _CAPABLE.get(key)
    if known is None:
        known = _CAPABLE[key] = isinstance(holder, protocol)
    return known


class DeadmanSupervisor:
    """The sessions' signs of life, and what is stopped when one goes silent or away.

    :param holders: returns ``(name, holder)`` of everything a session may keep running, at each call
    """

    def __init__(self, holders: Callable[[], Iterable[tuple[str, Any]]]):
        self._holders = holders
        self.sessions: dict[str, str] = {}  # connected browser sessions -> role
        self.beats: dict[str, float] = {}  # session -> monotonic time of its last sign of life
        self.beats_live: dict[str, float] = {}  # session -> the live clock at its last sign of life
        self.browser_sent: dict[str, float] = {}  # session -> the browser's own time of its last beat (ms)
        self.holding_since: dict[str, float] = {}  # holders that never sent a beat (live clock)
        self.late_beats = 0  # beats that came late because this program was busy, not because the browser was silent
        self.trips: deque[dict] = deque(maxlen=100)  # dead-man trips, newest last
        self.live = 0.0  # seconds this program ran on time (advanced by the supervision tick)
        self.live_at: float | None = None  # monotonic time of the last advance
        # the pages asked to beat: session -> monotonic time it was last seen holding (or asked)
        self.asked: dict[str, float] = {}
        self.dropped: set[str] = set()  # sessions whose connection dropped: asked to beat when it comes back
        # asks the page of a session to beat (True) or to stop (False); set by the web layer (app/web.py)
        self.ask_beat: Callable[[str, bool], None] | None = None

    # -- the live clock --------------------------------------------------------------------------------
    def live_clock(self, now: float) -> float:
        """Seconds this program ran on time up to ``now`` (a stall counts as at most LIVE_CREDIT_S)."""
        if self.live_at is None:
            return self.live
        return self.live + min(max(0.0, now - self.live_at), LIVE_CREDIT_S)

    def start_clock(self, now: float | None = None) -> None:
        self.live_at = time.monotonic() if now is None else now

    def tick(self, now: float) -> bool:
        """One supervision tick at monotonic time ``now``: advance the live clock, apply the rule. Returns whether
        there is anything to supervise (a page connected, something held): else the tick may come more slowly."""
        self.live = self.live_clock(now)
        self.live_at = now
        try:
            return self.supervise(now)
        except Exception:  # the supervisor itself must never end
            log.exception("dead-man supervision failed")
            return True

    # -- sessions --------------------------------------------------------------------------------------
    def session_opened(self, session: str, role: str = "engineer") -> None:
        self.sessions[session] = role

    def session_connected(self, session: str) -> None:
        """A page's connection is up (again): one whose connection had dropped is asked to beat, and its
        first beat gives it back the idle control it kept (:meth:`heartbeat`); it is told to stop
        BEAT_RELEASE_S later if it holds nothing."""
        if session in self.dropped:
            self.dropped.discard(session)
            self._ask(session, True, time.monotonic())

    def _forget_beats(self, session: str) -> None:
        for table in (self.beats, self.beats_live, self.browser_sent, self.holding_since):
            table.pop(session, None)

    def session_closed(self, session: str) -> None:
        """A page's connection dropped (closed, reloaded, or a reconnect under load): stop at once what it
        keeps running (motion, mains outputs). Idle control, which moves nothing, stays with the page until
        it is gone for good (:meth:`session_deleted`), so a page that reconnects keeps it."""
        self._forget_beats(session)
        self.asked.pop(session, None)  # a request sent meanwhile may be lost: asked again when it is back (session_connected)
        self.dropped.add(session)
        reason = Message(N_("the controlling browser disconnected"))
        for name, holder in self._holders():
            if _can(holder, SessionStopper):
                stop = holder.session_stop
            elif _can(holder, SessionHolder):
                stop = holder.session_lost
            else:
                continue
            try:
                stop(session, reason)
            except Exception:  # one adapter's failure must not keep the others running
                log.exception("%s: stopping for a disconnected session failed", name)

    def session_deleted(self, session: str) -> None:
        """A page is gone for good (it did not reconnect): release everything it controlled."""
        self.sessions.pop(session, None)
        self._forget_beats(session)
        self.asked.pop(session, None)
        self.dropped.discard(session)
        self.session_lost(session, "the controlling browser's page is gone")

    def session_lost(self, session: str, reason: str) -> None:
        for name, holder in self._holders():
            if not _can(holder, SessionHolder):
                continue
            try:
                holder.session_lost(session, reason)
            except Exception:  # one adapter's failure must not keep the others running
                log.exception("%s: stopping for a lost session failed", name)

    def heartbeat(self, session: str, sent_ms: float | None = None) -> None:
        """A page confirms it is alive (about every :data:`BEAT_PERIOD_S` while it beats).

        :param sent_ms: the browser's own clock when it sent the beat (``performance.now()`` of its tick
            worker), to tell a beat that came late because this program was busy from a browser that was silent
        """
        now = time.monotonic()
        last = self.beats.get(session)
        if last is None:  # its first beat, or the first since its connection dropped: what it controls is its own again
            for name, holder in self._holders():
                if _can(holder, SessionResumer):
                    try:
                        holder.session_back(session)
                    except Exception:  # noqa: BLE001 - one adapter's failure must not stop the beats
                        log.exception("%s: session_back failed", name)
        self.beats[session] = now
        self.beats_live[session] = self.live_clock(now)
        if isinstance(sent_ms, int | float) and not isinstance(sent_ms, bool) and sent_ms == sent_ms:
            before = self.browser_sent.get(session)
            self.browser_sent[session] = float(sent_ms)
            if last is not None and before is not None and now - last > DEADMAN_TIMEOUT_S:
                browser_gap_s = (float(sent_ms) - before) / 1000
                if browser_gap_s < DEADMAN_TIMEOUT_S:  # sent on time, received late: this program (or the network) was slow
                    self.late_beats += 1
                    log.info("session %s: a beat came %.0f ms after the one before, but the browser's ticks were %.0f ms apart: "
                             "late on the way (this program, the network or the page was busy), not a dead browser",
                             session, (now - last) * 1000, browser_gap_s * 1000)

    # -- the rule --------------------------------------------------------------------------------------
    def supervise(self, now: float) -> bool:
        """Stop what a session keeps running once it has not confirmed it is alive for DEADMAN_TIMEOUT_S
        of this program's running time; renew the leases of the sessions that did (devices/lease.py).
        Returns whether there is anything to supervise: a page connected (it may take control at any
        moment), a session's beats, or something held."""
        holding: set[str] = set()
        for _name, holder in self._holders():
            if _can(holder, SessionHolder):
                holding |= holder.holders()
        for session in list(self.holding_since):
            if session not in holding:
                del self.holding_since[session]
        live_now = self.live_clock(now)
        alive = {session for session in holding if not self._tripped(session, now, live_now)}
        if alive:
            self._renew(alive)
        self._ask_pages(holding, now)
        return bool(holding or self.sessions or self.beats or self.holding_since or self.asked)

    def _ask_pages(self, holding: set[str], now: float) -> None:
        """The pages of the sessions holding something beat; those that held nothing for BEAT_RELEASE_S stop.
        Only what the pages send depends on it: the rule above is applied to every holding session alike."""
        asked = self.asked
        for session in holding:
            if session not in asked:
                self._ask(session, True, now)
            else:
                asked[session] = now
        if len(asked) > len(holding):
            for session, held_at in list(asked.items()):
                if session not in holding and now - held_at >= BEAT_RELEASE_S:
                    del asked[session]
                    self._send_ask(session, False)

    def _ask(self, session: str, on: bool, now: float) -> None:
        self.asked[session] = now
        self._send_ask(session, on)

    def _send_ask(self, session: str, on: bool) -> None:
        ask = self.ask_beat
        if ask is None:
            return
        try:
            ask(session, on)
        except Exception:  # noqa: BLE001 - a page that went away: the rule does not depend on it
            log.exception("session %s: asking its page to %s beating failed", session, "start" if on else "stop")

    def _tripped(self, session: str, now: float, live_now: float) -> bool:
        """Whether ``session`` is silent for too long; if so, what it holds is stopped and the trip noted."""
        last = self.beats_live.get(session)
        if last is None:
            last = self.holding_since.setdefault(session, live_now)
        silent = live_now - last
        heard = self.beats.get(session)
        waited = now - heard if heard is not None else silent
        if silent <= DEADMAN_TIMEOUT_S and waited <= SILENCE_LIMIT_S:
            return False
        busy = max(0.0, waited - silent)
        reason = Message(N_("dead-man: the controlling browser has not confirmed it is alive for {ms:.0f} ms while this program "
                            "ran on time (the browser is frozen, asleep or its network is lost)"), ms=silent * 1000)
        if busy > SUPERVISE_PERIOD_S:
            reason = Message(N_("{reason}; besides, this program was busy for {busy:.0f} ms of the {waited:.0f} ms since its last "
                                "beat"), reason=reason, busy=busy * 1000, waited=waited * 1000)
        log.warning("session %s: %s", session, reason)
        self.session_lost(session, reason)
        self.holding_since.pop(session, None)
        self.trips.append({"session": session, "time": time.time(), "silent_ms": round(silent * 1000),
                           "busy_ms": round(busy * 1000)})
        return True

    def _renew(self, alive: set[str]) -> None:
        for name, holder in self._holders():
            if not _can(holder, LeaseRenewer):
                continue
            try:
                holder.renew_leases(alive)
            except Exception:  # one adapter's failure must not keep the others' leases from renewing
                log.exception("%s: renewing its lease failed", name)
