"""The telegrams a CAN bus sends by itself: keep-alives on a clock of their own, and loop-timed lists.

A keep-alive (:meth:`CyclicSenders.start_periodic`) is python-can's cyclic send task
(:class:`can.broadcastmanager.ThreadBasedCyclicSendTask`): a thread that sends on an absolute schedule
whatever the event loop does, under the bus's one send lock (:attr:`app.can_link.CanLink.send_lock`),
so its frames and the loop's never reach the interface at the same time. Before every period it takes
the newest contents, or, once its lease has lapsed, their stop form (ARCHITECTURE rule 7). An
engineer's transmit list (:meth:`CyclicSenders.start_cyclic`) keeps nothing running and is a loop task.

The senders outlive a reopening of their bus: :meth:`CyclicSenders.restart` starts them again on the
new bus object, :meth:`CyclicSenders.halt` ends them before it is shut down.
"""

from __future__ import annotations

import asyncio
import logging
import threading
import time
import weakref
from collections.abc import Callable
from typing import Protocol

import can
from can.broadcastmanager import ThreadBasedCyclicSendTask

from app import realtime
from devices.lease import Lease

log = logging.getLogger(__name__)

Make = Callable[[], tuple[int, bytes, bool] | None]


class SendingLink(Protocol):
    """What the senders need of the bus they send on (:class:`app.can_link.CanLink`)."""

    name: str
    bus: can.BusABC | None
    send_lock: threading.Lock
    loop: asyncio.AbstractEventLoop | None

    def send(self, arbitration_id: int, data: bytes, is_extended_id: bool = False) -> bool: ...

    def sent_by_thread(self, msg: can.Message) -> None: ...


class PeriodicSender:
    """One keep-alive on python-can's cyclic send task, with the lease check before every period."""

    def __init__(self, link: SendingLink, key: str, period_s: float, arbitration_id: int, data: bytes, is_extended_id: bool,
                 lease: Lease | None, stop_form: Callable[[bytes], bytes] | None, on_lapse: Callable[[float], None] | None):
        self.link, self.key, self.period_s = link, key, period_s
        self.arbitration_id, self.is_extended_id = arbitration_id, is_extended_id
        self.data = data  # the newest contents (replaced whole by the loop; read by the cyclic thread)
        self.lease, self.stop_form, self.on_lapse = lease, stop_form, on_lapse
        self.task: ThreadBasedCyclicSendTask | None = None
        self.errors = 0
        self.last_error = ""
        self.reported_lapse: float | None = None
        self.priority = "as it is"  # the sender thread's place in the scheduling (app/realtime.py)
        self.holding = False  # holds off the automatic full collection while it sends (app/realtime.py)
        self.boosting = False  # and, leased, has the interpreter's other threads run real-time below it

    def message(self, data: bytes) -> can.Message:
        return can.Message(arbitration_id=self.arbitration_id, data=data, is_extended_id=self.is_extended_id, is_rx=False)

    def start(self, bus: can.BusABC) -> None:
        self.stop()
        self.task = ThreadBasedCyclicSendTask(bus, self.link.send_lock, self.message(self.stop_checked(self.data)), self.period_s,
                                              on_error=self.on_error, modifier_callback=self.before_send)
        if not self.holding:  # no full collection holds the interpreter lock while this sends, and a busy thread
            self.holding = True  # gives it up sooner (the switch interval, app/realtime.py); a leased one (motion,
            self.boosting = self.lease is not None  # mains outputs) also has the other threads run real-time below it
            realtime.hold_keepalive(boost=self.boosting)
        thread = self.task.thread
        if thread is not None:  # ahead of busy processes of the same machine where the system allows it; else as it is
            self.priority = realtime.raise_sender(thread.native_id, self.period_s)

    def stop(self, join: bool = False) -> None:
        """End the sender; ``join``: also wait (at most a period and a bit) until its thread has sent its
        last frame, before the bus it sends on is shut down (never from the thread itself, never in the loop)."""
        task, self.task = self.task, None
        if self.holding:
            self.holding = False
            realtime.release_keepalive(boost=self.boosting)
        if task is None:
            return
        task.stop()
        thread = task.thread
        if join and thread is not None and thread is not threading.current_thread() and thread.is_alive():
            thread.join(timeout=self.period_s + 0.5)

    def running(self) -> bool:
        task = self.task
        if task is None:
            return False
        thread = task.thread
        return not task.stopped and (thread is None or thread.is_alive())

    def modify(self, data: bytes) -> None:
        self.data = data
        if self.task is not None:
            try:
                self.task.modify_data(self.message(self.stop_checked(data)))
            except ValueError as exc:  # the callback below sends the new contents anyway
                log.debug("%s: modify_data for %s: %s", self.link.name, self.key, exc)

    def stop_checked(self, data: bytes) -> bytes:
        """``data`` while the lease holds (or there is none), else its stop form."""
        if self.lease is None or self.stop_form is None or self.lease.valid():
            return data
        return self.stop_form(data)

    def on_error(self, exc: Exception) -> bool:
        self.errors += 1
        self.last_error = str(exc)
        return True  # keep trying every period: the stop form must get out once the bus takes frames again

    def before_send(self, msg: can.Message) -> None:
        """In the cyclic task's thread, before every period: the newest contents, or the stop form once the lease lapsed."""
        data = self.stop_checked(self.data)
        if msg.data != data:
            msg.data = bytearray(data)
            msg.dlc = len(data)
        lapsed = self.lease.lapsed_at if self.lease is not None else None
        loop = self.link.loop
        if lapsed is not None and lapsed != self.reported_lapse and self.on_lapse is not None and loop is not None:
            self.reported_lapse = lapsed
            try:
                loop.call_soon_threadsafe(self.on_lapse, lapsed)
            except RuntimeError:  # the loop is closed
                pass
        msg.timestamp = time.time()
        self.link.sent_by_thread(can.Message(arbitration_id=msg.arbitration_id, data=bytes(data), is_extended_id=msg.is_extended_id,
                                             timestamp=msg.timestamp, is_rx=False))


_SENDERS: weakref.WeakSet[CyclicSenders] = weakref.WeakSet()


def keepalives_running() -> bool:
    """Whether a periodic keep-alive (``start_periodic``) runs on some CAN bus of this process: what a long hold
    of the interpreter lock would make late (see app.runtime.FullCollections)."""
    return any(senders.keepalives_running() for senders in list(_SENDERS))


class CyclicSenders:
    """The keep-alives and transmit lists of one bus, by key (one telegram per key)."""

    def __init__(self, link: SendingLink):
        self.link = link
        self.periodic: dict[str, PeriodicSender] = {}  # keep-alives on python-can's cyclic tasks (their own clock)
        self.tasks: dict[str, asyncio.Task] = {}  # loop-timed lists
        _SENDERS.add(self)

    def keepalives_running(self) -> bool:
        return any(periodic.running() for periodic in list(self.periodic.values()))

    def tick(self) -> None:
        """Now and then while the bus runs: sender threads started since a keep-alive began get their place
        (app/realtime.py)."""
        if self.periodic:
            realtime.refresh_holders()

    def start_cyclic(self, key: str, period_s: float, make: Make) -> None:
        """Send ``make()`` every ``period_s`` (absolute schedule, no drift) until stopped.

        A loop task: for telegrams that keep nothing running (an engineer's transmit list).
        Keep-alives of watchdogs use :meth:`start_periodic`, whose clock does not depend on the loop.
        """
        self.stop(key)
        self.tasks[key] = asyncio.get_running_loop().create_task(self._cyclic_task(period_s, make), name=f"cyclic {key}")

    def stop(self, key: str) -> None:
        task = self.tasks.pop(key, None)
        if task is not None:
            task.cancel()
        periodic = self.periodic.pop(key, None)
        if periodic is not None:
            periodic.stop()

    def stop_all(self) -> None:
        for key in list(self.tasks) + list(self.periodic):
            self.stop(key)

    def running(self, key: str) -> bool:
        periodic = self.periodic.get(key)
        if periodic is not None:
            return periodic.running()
        task = self.tasks.get(key)
        return task is not None and not task.done()

    async def _cyclic_task(self, period_s: float, make: Make) -> None:
        loop = asyncio.get_running_loop()
        due = loop.time()
        while True:
            frame = make()
            if frame is not None:
                self.link.send(*frame)
            due += period_s
            delay = due - loop.time()
            if delay < 0:  # late (loop busy): do not send a burst to catch up
                due = loop.time()
                delay = 0
            await asyncio.sleep(delay)

    def start_periodic(
        self, key: str, period_s: float, arbitration_id: int, data: bytes, is_extended_id: bool = False, *,
        lease: Lease | None = None, stop_form: Callable[[bytes], bytes] | None = None,
        on_lapse: Callable[[float], None] | None = None,
    ) -> None:
        """Send ``data`` every ``period_s`` on a clock of its own, whatever the event loop does, until :meth:`stop`.

        With a ``lease``, the sender checks it before every period: while it is not valid (not granted,
        or lapsed because the loop stopped renewing it) only ``stop_form(data)`` leaves, and
        ``on_lapse(lapsed_at)`` is called in the loop once per lapse. New contents: :meth:`modify_periodic`.
        """
        self.stop(key)
        periodic = PeriodicSender(self.link, key, period_s, arbitration_id, bytes(data), is_extended_id, lease, stop_form, on_lapse)
        self.periodic[key] = periodic
        if self.link.bus is not None:
            periodic.start(self.link.bus)

    def modify_periodic(self, key: str, data: bytes, *, send_now: bool = False) -> bool:
        """New contents for a periodic telegram from the next period on; ``send_now``: also send it once at
        once (a stop does not wait for the next period)."""
        periodic = self.periodic.get(key)
        if periodic is None:
            return False
        periodic.modify(bytes(data))
        if send_now:
            return self.link.send(periodic.arbitration_id, periodic.stop_checked(bytes(data)), periodic.is_extended_id)
        return True

    def restart(self, bus: can.BusABC) -> None:
        """The bus was (re)opened: its periodic telegrams start again on the new bus object."""
        for periodic in self.periodic.values():
            periodic.start(bus)

    def halt(self) -> None:
        """Before the bus shuts down (never in the loop): every periodic sender ends and its thread is joined, so none
        sends on the closed bus ("Cannot operate on a closed bus" every period). They stay listed for :meth:`restart`."""
        for periodic in list(self.periodic.values()):
            periodic.stop(join=True)
