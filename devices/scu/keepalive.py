"""The SCU's RC keep-alive on the serial line's own thread, under a lease (document 002, section 5; issue 28).

The RC leaves from the line's thread (:meth:`RcKeepAlive.tick`), on a clock no page work can delay, under the
lease the worker's dead-man supervisor renews while a function runs. Once that lease has lapsed the thread sends
RS to every running function by itself (never RS 19: the emergency stop stays on) and then withholds RC, so the
unit's own watchdog ends remote mode and stops every drive even if an RS was lost. What the thread learns reaches
the event loop with ``call_soon_threadsafe`` (the ``on_...`` methods run there).
"""

from __future__ import annotations

import asyncio
import functools
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol, runtime_checkable

from devices import values as v
from devices.decoding import malformed
from devices.message import Message, N_
from devices.scu import codec
from devices.scu import params as p
from devices.scu.control import LEASE_LAPSED, NOT_HELD, RS_ATTEMPTS
from devices.scu.facts import answer_length, describe_answer, header_offset
from devices.transport import SerialLineError, SerialTimeout

if TYPE_CHECKING:
    from devices.scu.adapter import ScuAdapter

RC_KEY = "scu rc"  # the RC keep-alive in the serial line's own thread (SerialLine.start_cyclic)
RC_RETRY_S = 0.05  # an RC not answered is sent again this soon (the watchdog allows 500 ms)
LEASE_CHECK_S = 0.02  # while a function runs the line's thread looks at the lease this often
CYCLIC_INDEX = 0  # RC index 0 = CyclicObj 1 (0x3001)


@runtime_checkable
class ThreadedLine(Protocol):
    """A serial line with a thread of its own for a telegram it sends by itself (app/serial_line.py)."""

    def reserve(self, at: float) -> None:
        """The thread wants the port at ``at`` (monotonic): the loop's requests give way."""

    def start_cyclic(self, key: str, tick: Callable[..., float]) -> None:
        """Run ``tick(exchange)`` in the line's thread; it returns the seconds until its next call."""

    def stop_cyclic(self, key: str) -> None: ...

    def cyclic_running(self, key: str) -> bool: ...


class RcKeepAlive:
    """The RC keep-alive of one SCU adapter: armed while the session is open, on the line's own thread."""

    def __init__(self, adapter: ScuAdapter):
        self.adapter = adapter
        self.wanted = True  # False: RC from the poll on the loop (a line without a thread of its own)
        # ``guard`` makes the set of held functions and the lease one state for the thread: no RS and no withheld RC
        # for a stop the loop has just made.
        self.guard = threading.Lock()
        self.held: frozenset[int] = frozenset()  # running functions the lease covers (never 19)
        self.armed = False
        self.withheld = False  # the lease lapsed: RC is withheld until the session is opened again
        self.plain = False  # the unit refused RC with the cyclic object: the thread sends RC without data
        self.last = 0.0  # monotonic time the last acknowledged RC was sent (any sender)
        self.loop: asyncio.AbstractEventLoop | None = None
        self.stopped_by_thread: set[int] = set()  # RS acknowledged by the line's thread, not yet seen by the loop
        self.times: deque[float] = deque(maxlen=50)  # when the last acknowledged RCs were sent
        # the data IDs read in turn that the line's thread reads right after its next RC (the same wake-up brings
        # them to the loop with the RC): one added by every poll while the session is open with the cyclic object
        self.thread_rgs: deque[int] = deque()
        self.rgs_taken_over = 0  # of them, read by the poll after all: the line's thread fell three polls behind
        self.lapses = 0

    def gaps(self) -> list[float]:
        """Seconds between the acknowledged RCs kept (the last 50)."""
        with self.guard:
            times = list(self.times)
        return [b - a for a, b in zip(times, times[1:])]

    def due(self) -> bool:
        return time.monotonic() - self.last >= self.adapter.keepalive_period_s

    def note(self, sent_at: float) -> None:
        with self.guard:
            self.last = max(self.last, sent_at)
            self.times.append(time.monotonic())

    def threaded(self) -> bool:
        return self.wanted and isinstance(self.adapter.line, ThreadedLine)

    def arm(self) -> None:
        """The session is open: RC every ``keepalive_period_s`` from the line's thread from now on."""
        if not self.threaded():
            return
        self.loop = asyncio.get_running_loop()
        with self.guard:
            self.armed = True
            self.withheld = False
            self.plain = False
        if not self.adapter.line.cyclic_running(RC_KEY):
            self.adapter.line.start_cyclic(RC_KEY, self.tick)

    def disarm(self) -> None:
        with self.guard:
            self.armed = False
        if self.threaded():
            self.adapter.line.stop_cyclic(RC_KEY)

    def call_loop(self, callback, *args) -> None:
        loop = self.loop
        if loop is None:
            return
        try:
            loop.call_soon_threadsafe(callback, *args)
        except RuntimeError:  # the loop is closed: nothing to report to any more
            pass

    def request(self, exchange, frame: bytes, describe: str) -> codec.Answer:
        """One request from the line's thread (blocking); raises SerialLineError or codec.FrameError."""
        expected = bytes(frame[:2])
        raw = exchange(frame, functools.partial(answer_length, expected=expected), describe=describe,
                       decode=describe_answer)
        start = header_offset(raw, expected) or 0
        return codec.decode_answer(raw[start:], expected)

    def send_rs(self, exchange, fn: int, why: str) -> bool:
        """RS of ``fn`` from the line's thread, sent again on CSE or no answer (RS_ATTEMPTS); True once acknowledged."""
        if fn in NOT_HELD:
            return False  # never RS 19: it would end the emergency stop
        label = codec.FUNCTIONS[codec.Function(fn)].label
        three = self.adapter.core.rs_three_bytes
        for attempt in range(1, RS_ATTEMPTS + 1):
            frame = codec.encode_rs(fn, -1, -1) if three else codec.encode_rs(fn)
            try:
                answer = self.request(exchange, frame, f"RS {label} ({why})"
                                              + (f", attempt {attempt}" if attempt > 1 else ""))
            except (SerialLineError, codec.CodecError):
                continue
            if answer.ok:
                return True
            if answer.status == codec.Status.PCE and not three:
                three = True  # the unit takes the three-byte form of table 3 (remembered by the loop's next RS)
                continue
            if answer.status == codec.Status.PE:
                return False  # remote mode gone: the unit has stopped remote motion (section 5)
        return False

    def tick(self, exchange) -> float:
        """On the serial line's own thread: RC when due; after a lapse of the lease RS and no more RC.

        Reads only what the loop sets atomically (``_guard``); reports to the loop with ``call_soon_threadsafe``.
        Returns the seconds until it wants to run again.
        """
        period = self.adapter.keepalive_period_s
        with self.guard:
            if not self.armed:
                return period
            held = self.held
            lapsed = bool(held) and not self.adapter.lease.valid()
            first = lapsed and not self.withheld
            if first:
                self.withheld = True
            withheld = self.withheld
            # the loop ends the lease only under this guard, together with the held functions (adapter.sync_held,
            # _rs_action): a lease ended while functions are still held would be a fault of this program, so it is
            # taken as a lapse noticed now, stopped and reported as one
            lapsed_at = self.adapter.lease.lapsed_at or time.monotonic()
        if first:
            why = "lease lapsed: this program stalled or the controlling browser is gone"
            results = {fn: self.send_rs(exchange, fn, why) for fn in sorted(held)}
            with self.guard:
                self.stopped_by_thread |= {fn for fn, ok in results.items() if ok}
            self.call_loop(self.on_lapse, lapsed_at, results)
        if withheld and not self.estop_confirmed():
            # The unit's own watchdog now ends remote mode and stops every drive (section 5), also one whose RS
            # was lost. With the emergency stop on, RC goes on: nothing moves, and remote mode keeps F20 in force.
            return period
        check = LEASE_CHECK_S if held and not withheld else period  # a lapse is noticed within 20 ms
        now = time.monotonic()
        due = self.last + period
        if now < due:
            self.adapter.line.reserve(due)  # the poll's requests give way to the RC due then
            return min(due - now, check)
        cyclic = self.adapter.cyclic
        frame = codec.encode_rc(CYCLIC_INDEX) if cyclic is not None and not self.plain else codec.KEEP_ALIVE
        sent_at = time.monotonic()
        try:
            answer = self.request(exchange, frame, "RC keep-alive" + (" with CyclicObj 1" if frame != codec.KEEP_ALIVE else ""))
        except SerialLineError as exc:
            self.call_loop(self.on_failed, exc)
            return RC_RETRY_S
        except codec.FrameError as exc:
            self.call_loop(self.on_failed, exc)
            return 0.0  # a bad CRC or a shifted answer: at once again
        if answer.ok:
            self.note(sent_at)
            with self.guard:  # while a function runs the poll reads them
                data_ids = [] if held else list(self.thread_rgs)
                if data_ids:
                    self.thread_rgs.clear()
            reads: list[tuple[int, codec.Answer | Exception]] = []
            for data_id in data_ids:
                try:
                    reads.append((data_id, self.request(exchange, codec.encode_rg(data_id), f"RG 0x{data_id:04X}")))
                except (SerialLineError, codec.CodecError) as exc:
                    reads.append((data_id, exc))
            self.call_loop(self.on_answer, answer, cyclic if frame != codec.KEEP_ALIVE else None, reads)
            return min(max(0.0, sent_at + period - time.monotonic()), check)  # on the clock: period from send to send
        self.call_loop(self.on_refused, answer)
        if answer.status == codec.Status.CSE:
            return 0.0  # "Fehler in der Telegramm-Checksumme" (section 4.2): line noise, RC again at once
        if answer.status == codec.Status.PE:
            with self.guard:
                self.armed = False  # remote mode is gone: the loop reopens the session
            return period
        self.plain = True  # RC with the cyclic object refused: RC without data, at once
        return 0.0

    def estop_confirmed(self) -> bool:
        """F20 is on in the unit (acknowledged since the session opened): remote mode keeps it in force."""
        estop = self.adapter.core.estop
        return estop is not None and estop.confirmed

    def on_answer(self, answer: codec.Answer, cyclic: p.CyclicDefinition | None,
                          reads: list[tuple[int, codec.Answer | Exception]] = ()) -> None:
        """In the loop: an RC the line's thread sent was acknowledged; its cyclic data published, and the data ID read
        in turn that the thread read after it (a refusal or a failed read is left to the next poll, which tells why)."""
        self.adapter.state.counters.requests += 1
        self.adapter.state.counters.responses += 1
        self.adapter.link.answered()
        if cyclic is not None and answer.has_ctp and cyclic is self.adapter.cyclic:
            try:
                self.adapter.live.publish_cyclic_data(cyclic, bytes(answer.data))
            except (v.DecodeError, ValueError) as exc:
                self.adapter.state.error(f"RC cyclic data: {exc}", log=False)
        for data_id, rg in reads:
            self.adapter.state.counters.requests += 1
            if not isinstance(rg, codec.Answer) or not rg.ok:
                if isinstance(rg, SerialTimeout):
                    self.adapter.state.counters.timeouts += 1
                elif isinstance(rg, codec.Answer):
                    self.adapter.state.counters.responses += 1
                self.adapter.live.rg_on_loop.append(data_id)
                continue
            self.adapter.state.counters.responses += 1
            self.adapter.live.publish_read(data_id, rg)

    def on_failed(self, exc: Exception) -> None:
        self.adapter.state.counters.requests += 1
        if isinstance(exc, SerialTimeout):
            self.adapter.state.counters.timeouts += 1
        elif isinstance(exc, codec.ChecksumError):
            self.adapter.state.counters.crc_errors += 1
        elif isinstance(exc, codec.FrameError):
            malformed(self.adapter.state)
        self.adapter.link.no_answer()

    def on_refused(self, answer: codec.Answer) -> None:
        self.adapter.state.counters.requests += 1
        self.adapter.state.counters.exceptions += 1
        info = codec.CommandRefused(answer.command, answer.status).info
        if answer.status == codec.Status.PE:
            self.adapter.lost(Message(N_("PE (permission error) to the RC keep-alive: the unit is no longer in remote mode")))
            return
        if answer.status == codec.Status.CSE:
            return  # line noise (section 4.2): sent again, remembered as nothing
        if self.adapter.cyclic is not None:
            self.adapter.cyclic = None
            self.adapter.cyclic_refused = True
            self.adapter.cyclic_note = Message(N_("the unit refused RC with the cyclic object ({name}: {title}); RC "
                                                  "without data keeps the session, live data is read with RG"),
                                               name=info.name, title=info.title)
            self.adapter.publish_cyclic()
            self.adapter.state.event("warning", self.adapter.cyclic_note)

    def on_lapse(self, lapsed_at: float, results: dict[int, bool]) -> None:
        """In the loop: the lease lapsed and the line's thread has sent RS by itself and withholds RC."""
        self.lapses += 1
        renewed = self.adapter.lease.renewed_at
        late_ms = (lapsed_at - renewed) * 1000 if renewed is not None else self.adapter.lease.valid_s * 1000
        stopped = [fn for fn, ok in results.items() if ok]
        with self.guard:
            self.stopped_by_thread -= set(stopped)
        for fn in stopped:
            self.adapter.running.pop(fn, None)
            self.adapter.rs_pending.pop(fn, None)
        for fn, ok in results.items():
            if not ok and fn in self.adapter.running:
                self.adapter.rs_pending[fn] = "lease lapsed"
        self.adapter.sync_held()
        names = lambda fns: ", ".join(codec.FUNCTIONS[codec.Function(f)].label for f in fns)  # noqa: E731
        sent_to = names(results) or Message(N_("nothing"))
        unacknowledged = ""
        if [fn for fn, ok in results.items() if not ok]:
            unacknowledged = Message(N_(" (not acknowledged: {functions}; RS is sent again)"),
                                     functions=names([f for f, ok in results.items() if not ok]))
        confirmed = self.estop_confirmed()
        rc = (Message(N_("and kept RC going: the emergency stop is on (F20, confirmed by the unit)")) if confirmed else
              Message(N_("and withheld RC, so the unit's watchdog ends remote mode and stops every drive (section 5); the "
                         "session is opened again only after that")))
        self.adapter.state.event("error", Message(N_(
            "motion stopped: the lease of the running functions lapsed (not renewed for {ms:.0f} ms: this program stalled, "
            "or the controlling browser stopped confirming it is alive); the serial line's own thread sent RS to "
            "{functions} by itself{unacknowledged} {rc}. Press again to move"),
            ms=late_ms, functions=sent_to, unacknowledged=unacknowledged, rc=rc))
        if confirmed:
            with self.guard:
                self.withheld = False  # RC went on; a function still held after a failed RS gets RS again
        else:
            # not reopened before the unit's watchdog has tripped: a reopening's RO + RC would feed it again
            withheld_at = min(time.monotonic(), lapsed_at + 0.05)
            self.adapter.core.withhold(Message(LEASE_LAPSED), withheld_at)
            self.adapter.sync_phase()
