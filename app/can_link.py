"""The link to one python-can bus: opening it (again), receiving through a ``can.Notifier``, sending.

python-can's :class:`can.Notifier` reads the bus in a thread of its own and hands every frame to the
listeners; the one listener here, :class:`Handover`, passes the frames to the event loop in batches
(one wake-up per batch, never one per frame). The loop dispatches each frame to the handlers
subscribed to its ID, tells the statistics (:class:`app.can_stats.CanStats`) and offers frames of
unknown IDs to discovery listeners. A bus that fails to open, dies or goes bus-off is reopened with
backoff; a listener's ``on_error`` is how the link learns that the interface failed.

A flood never stalls the loop: the hand-over holds at most ``INBOX_FRAMES`` frames per kind (frames of
subscribed IDs, and all others), the oldest are shed and counted in ``CanBusState.shed`` when the loop
falls behind, frames of subscribed IDs go first, and the loop drains for at most ``DRAIN_BUDGET_S`` at a
time before it runs anything else.

Sending: every frame leaves under :attr:`CanLink.send_lock`, the one lock the periodic senders
(:mod:`app.can_cyclic`) send under too; python-can's interfaces are not all safe to send on from two
threads at once.

No loss is silent: where the interface can say how many frames it lost before the notifier read them
(the kernel's drop counter of a ``udp_multicast`` socket, a SocketCAN driver's overrun counters),
``CanBusState.interface_dropped`` counts them; a ``udp_multicast`` socket gets a receive buffer of
``UDP_RCVBUF`` bytes so the notifier can wait for the interpreter lock without losing frames. Both are
reached through the bus's public ``fileno()``. Unknown IDs are offered to discovery once per
``NO_DISCOVERY_S`` when no device type recognises their frames (a bounded table).

A quiet bus costs little: the notifier waits in the interface's own ``recv`` at most ``READ_WAIT_S`` at
a time (two wake-ups a second), which is also how soon a closing bus ends it; python-can's in-process
``virtual`` bus (the simulated plant, tests) waits ``VIRTUAL_READ_WAIT_S``, so that it closes sooner.
"""

from __future__ import annotations

import asyncio
import importlib
import logging
import os
import socket
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable
from typing import Any

import can

from app import host
from app.can_stats import LOAD_PERIOD_S, CanStats, Key

log = logging.getLogger(__name__)

Handler = Callable[[can.Message], None]

INBOX_FRAMES = 4096  # per kind waiting for the loop: about 0.45 s of a full 1 Mbit/s bus; beyond, the oldest are shed
DRAIN_BUDGET_S = 0.004  # the loop drains one bus this long at most, then runs timers and other tasks
DRAIN_CHECK = 4  # frames between two looks at the clock
READER_BACKOFF_S = 0.001  # the notifier pauses this long when the hand-over is full (bench/can_ingest.py: 7.7x -> 12x)
READ_WAIT_S = 0.5  # the notifier's longest wait in recv: a quiet bus wakes it twice a second, a closing one ends it as soon
VIRTUAL_READ_WAIT_S = 0.1  # the same on python-can's in-process virtual bus (the simulated plant, tests): closed sooner
ERROR_PAUSE_S = 0.1  # the notifier's pause after the interface failed, until the supervisor reopens the bus
SENT_FRAMES = 4096  # frames the periodic senders sent, waiting for the loop's monitor and echo filter
UDP_RCVBUF = 4 * 2**20  # receive buffer of a udp_multicast socket: about 0.4 s of a full 1 Mbit/s bus (capped by net.core.rmem_max)
NO_DISCOVERY_S = 10.0  # an unknown ID whose frames no device type recognises is offered to discovery again after this
NO_DISCOVERY_IDS = 4096  # negative results remembered per bus (least recently heard goes first)
ECHO_WAIT_S = 1.0  # a sent frame whose echo has not come back by then is forgotten
BACKOFF_S = (0.5, 10.0)  # the first wait before reopening, and the longest (doubled per failure)
OPTIONS_NOT_FOR_PYTHON_CAN = {"simulate", "poll_period", "filter_own", "timeout", "rcvbuf"}
BUS_STATE_NAMES = {
    can.BusState.ACTIVE: "error-active",
    can.BusState.PASSIVE: "error-passive",
    can.BusState.ERROR: "bus-off",
}
SOCKETCAN_ERRNOS = {97, 19, 100}  # EAFNOSUPPORT (no SocketCAN: not Linux, no can module), ENODEV, ENETDOWN


def open_error(options: dict[str, Any], exc: Exception) -> str:
    """What the bus page says when python-can cannot open the bus; for SocketCAN, what it needs and how."""
    interface, channel = options.get("interface"), options.get("channel")
    text = f"cannot open {interface} {channel}: {exc}"
    code = exc.errno if isinstance(exc, OSError) else exc.error_code if isinstance(exc, can.CanError) else None
    if interface == "socketcan" and code in SOCKETCAN_ERRNOS:
        bitrate = options.get("bitrate") or 500000
        text += (f" - SocketCAN needs Linux (with the can modules) and the interface up: "
                 f"`sudo ip link set {channel or 'can0'} up type can bitrate {bitrate}`")
    return text


def udp_socket(bus: can.BusABC, options: dict[str, Any]) -> socket.socket | None:
    """A socket object on a duplicate of a ``udp_multicast`` bus's descriptor (its public ``fileno()``): the
    options and counters of the bus's own socket, read and set without its private attributes. Close it
    when done (the bus's socket stays open)."""
    if options.get("interface") != "udp_multicast":
        return None
    try:
        fd = bus.fileno()
    except (NotImplementedError, OSError, ValueError):
        return None
    if not isinstance(fd, int) or fd < 0:
        return None
    try:
        return socket.socket(fileno=os.dup(fd))
    except OSError:
        return None


def interface_drops(bus: can.BusABC, options: dict[str, Any], sock: socket.socket | None = None) -> tuple[int, str] | None:
    """``(frames lost by the interface, where the figure comes from)``, or None where it does not say.

    udp_multicast: the socket's kernel drop counter (receive buffer full), from one system call that does not
    block (:func:`app.host.socket_drops`; else from /proc); ``sock`` is the bus's :func:`udp_socket` where the
    caller keeps one. SocketCAN: the driver's ``rx_dropped + rx_over_errors + rx_fifo_errors`` of the network
    interface, read from /sys: blocking, call it in a thread.
    """
    own = sock is None
    if own:
        sock = udp_socket(bus, options)
    if sock is not None:
        try:
            drops = host.socket_drops(sock)
            if drops is None:
                drops = host.udp_drops(os.fstat(sock.fileno()).st_ino)
        finally:
            if own:
                sock.close()
        return None if drops is None else (drops, "kernel socket drops")
    if options.get("interface") == "socketcan" and isinstance(options.get("channel"), str):
        total = host.netdev_drops(options["channel"])  # /sys (Linux, where SocketCAN is)
        return None if total is None else (total, "driver overruns")
    return None


_RECOGNISERS: list[Callable[[int, bool, bytes], Any]] | None = None


def recognised_by_a_device_type(arbitration_id: int, is_extended: bool, data: bytes) -> bool:
    """Whether some device type's codec takes the frame for one of its devices (``discovered``)."""
    global _RECOGNISERS
    if _RECOGNISERS is None:
        from devices.registry import DEVICE_TYPES

        hooks = []
        for t in DEVICE_TYPES.values():
            if t.can_codec and "can" in t.bus_types:
                hooks.append(importlib.import_module(t.can_codec).discovered)  # DeviceType.can_codec has one
        _RECOGNISERS = hooks
    for hook in _RECOGNISERS:
        try:
            if hook(arbitration_id, is_extended, data):
                return True
        except ValueError:  # a frame a codec cannot parse (its CodecError) is not its device's
            continue
    return False


def read_wait_s(options: dict[str, Any]) -> float:
    """The notifier's longest wait in ``recv`` on this bus: how often a quiet bus wakes it, and how soon a
    closing bus ends it (a ``virtual`` bus, in this process only, ends sooner)."""
    return VIRTUAL_READ_WAIT_S if options.get("interface") == "virtual" else READ_WAIT_S


class Handover(can.Listener):
    """The notifier's listener: frames from its thread to the event loop, in batches, bounded.

    ``known`` holds frames of subscribed IDs (handled first), ``other`` the rest (monitor and discovery
    only), at most ``limit`` each; ``sent`` the frames the periodic senders' threads sent. The loop
    takes them in :meth:`CanLink.drain`.
    """

    def __init__(self, link: CanLink, limit: int):
        self.link = link
        self.handlers = link.handlers  # subscribed IDs (the link's own dict, changed in place)
        self.limit = limit
        self.known: deque[can.Message] = deque()
        self.other: deque[can.Message] = deque()
        self.sent: deque[can.Message] = deque(maxlen=SENT_FRAMES)
        self.shed_count = 0  # written by the notifier's thread only
        self.shed_seen = 0
        self.scheduled = False
        self.thread: threading.Thread | None = None  # the notifier's thread, once it has handed a frame over
        self.closing = threading.Event()

    def on_message_received(self, msg: can.Message) -> None:
        """In the notifier's thread, once per frame (kept short: it shares the interpreter with the loop)."""
        inbox = self.known if (msg.is_extended_id, msg.arbitration_id) in self.handlers else self.other
        limit = self.limit
        if len(inbox) >= limit:
            # the loop is behind: give it the interpreter for a moment instead of reading and shedding
            # at full speed (frames wait in the interface's buffer meanwhile); then shed the oldest
            self.closing.wait(READER_BACKOFF_S)
            if len(inbox) >= limit:
                try:
                    inbox.popleft()
                    self.shed_count += 1
                except IndexError:  # the loop emptied it meanwhile
                    pass
        inbox.append(msg)
        if not self.scheduled:
            if self.thread is None:
                self.thread = threading.current_thread()
            self.wake()

    def sent_by_thread(self, msg: can.Message) -> None:
        self.sent.append(msg)
        self.wake()

    def wake(self) -> None:
        """Have the loop drain (once per batch)."""
        loop = self.link.loop
        if not self.scheduled and loop is not None:
            self.scheduled = True
            try:
                loop.call_soon_threadsafe(self.link.drain)
            except RuntimeError:  # the loop is closed: nothing to hand over any more
                pass

    def on_error(self, exc: Exception) -> None:
        """The interface failed under the notifier (python-can calls this in its thread and goes on reading):
        the supervisor reopens the bus; until then the notifier pauses between tries."""
        if self.closing.is_set():
            return  # the bus closing under it
        self.link.failure = f"receive failed: {exc}"
        self.closing.wait(ERROR_PAUSE_S)

    def take_shed(self) -> int:
        shed = self.shed_count
        new, self.shed_seen = shed - self.shed_seen, shed
        return new


class CanLink:
    """One python-can bus: its life cycle, the notifier and its hand-over, the dispatch by ID, the send path.

    :param name: the bus's name
    :param options: plant-file options, passed to :class:`can.Bus` except ``OPTIONS_NOT_FOR_PYTHON_CAN``
    :param stats: the bus's statistics, told of every frame
    :param inbox_frames: frames the hand-over holds per kind
    """

    def __init__(self, name: str, options: dict[str, Any], stats: CanStats, inbox_frames: int = INBOX_FRAMES):
        self.name = name
        self.options = options
        self.stats = stats
        self.state = stats.state
        self.bus: can.BusABC | None = None
        self.notifier: can.Notifier | None = None
        self.sock: socket.socket | None = None  # a udp_multicast bus's socket (a duplicate of its descriptor)
        self.send_lock = threading.Lock()  # every send of this bus: the loop's and the periodic senders'
        self.loop: asyncio.AbstractEventLoop | None = None
        self.handlers: dict[Key, list[Handler]] = {}
        self.listeners: list[Handler] = []  # every received frame whose ID has no handler
        self.handover = Handover(self, inbox_frames)
        self.failure = ""  # set by the notifier's thread when the interface failed
        self.shutting_down = False  # while close() runs
        self.filter_own = options.get("filter_own", options.get("interface") == "udp_multicast")
        # frames this instance sent, by content, with send times: udp_multicast hands them back
        self.own: dict[tuple[bool, int, bytes], deque[float]] = {}
        # discovery: (ext, id, length) -> monotonic time until which its frames are not offered
        self.no_discovery: OrderedDict[tuple[bool, int, int], float] = OrderedDict()
        self.no_discovery_skipped = 0
        self.recognise: Callable[[int, bool, bytes], bool] | None = recognised_by_a_device_type
        self.backoff_s = BACKOFF_S[0]
        self.on_open: Callable[[can.BusABC], None] | None = None  # the bus is open: the periodic senders start on it
        self.before_close: Callable[[], None] | None = None  # the bus is about to shut down: they end first
        self.on_tick: Callable[[], None] | None = None  # once per LOAD_PERIOD_S while it runs

    # -- subscriptions ---------------------------------------------------------------
    def subscribe(self, is_extended: bool, arbitration_id: int, handler: Handler) -> None:
        self.handlers.setdefault((is_extended, arbitration_id), []).append(handler)

    def unsubscribe(self, is_extended: bool, arbitration_id: int, handler: Handler) -> None:
        handlers = self.handlers.get((is_extended, arbitration_id), [])
        if handler in handlers:
            handlers.remove(handler)
        if not handlers:
            self.handlers.pop((is_extended, arbitration_id), None)

    # -- life cycle ------------------------------------------------------------------
    def open(self) -> can.BusABC:
        """A new python-can bus from the options (blocking: call it in a thread); a ``udp_multicast`` socket
        gets its large receive buffer."""
        bus = can.Bus(**{k: v for k, v in self.options.items() if k not in OPTIONS_NOT_FOR_PYTHON_CAN})
        if self.sock is not None:
            self.sock.close()
        self.sock = sock = udp_socket(bus, self.options)
        if sock is not None:
            try:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, int(self.options.get("rcvbuf", UDP_RCVBUF)))
                self.state.rcvbuf = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
            except OSError as exc:
                log.warning("%s: cannot enlarge the socket's receive buffer: %s", self.name, exc)
        self.stats.opened()
        return bus

    def listen(self) -> None:
        """Start the notifier on the open bus (python-can's reader thread) and the periodic senders."""
        assert self.bus is not None
        self.failure = ""
        self.handover.closing.clear()
        self.handover.thread = None
        self.notifier = can.Notifier(self.bus, [self.handover], timeout=read_wait_s(self.options))
        self.state.connected = True
        self.state.reconnects += 1
        if self.on_open is not None:
            self.on_open(self.bus)
        self.state.last_error = ""
        self.backoff_s = BACKOFF_S[0]

    def close(self) -> None:
        """Stop the notifier (its thread ends within ``READ_WAIT_S``), the periodic senders, then the bus
        (blocking: call it in a thread)."""
        self.shutting_down = True  # the supervisor does not start a notifier on the bus meanwhile
        self.handover.closing.set()
        notifier = self.notifier
        if notifier is not None:
            notifier.stop(timeout=READ_WAIT_S + 1.5)
        self.notifier = None
        # the periodic senders end before their bus does: a cyclic thread that sent on the closed bus would
        # log a traceback every period ("Cannot operate on a closed bus"). A reopened bus starts them again
        if self.before_close is not None:
            self.before_close()
        if self.bus is not None:
            try:
                self.bus.shutdown()
            except (can.CanError, OSError) as exc:  # a dying interface may fail to shut down; it is gone anyway
                log.debug("shutdown of %s failed: %s", self.name, exc)
            self.bus = None
        if self.sock is not None:
            self.sock.close()
            self.sock = None
        self.state.connected = False
        self.shutting_down = False

    async def supervise(self) -> None:
        """Open the bus, watch the notifier and the bus state, reopen with backoff."""
        loop = self.loop = asyncio.get_running_loop()
        while True:
            if self.shutting_down:  # closed from elsewhere (a thread): open again once that is done
                await asyncio.sleep(LOAD_PERIOD_S)
                continue
            if self.bus is None:
                try:
                    self.bus = await loop.run_in_executor(None, self.open)
                except (can.CanError, OSError, ValueError) as exc:  # no driver, no such channel, bad options: retried
                    self.state.connected = False
                    self.state.last_error = open_error(self.options, exc)
                    log.warning("%s: %s", self.name, self.state.last_error)
                    await self._back_off()
                    continue
            if self.notifier is None:
                self.listen()
            await asyncio.sleep(LOAD_PERIOD_S)
            if self.on_tick is not None:
                self.on_tick()
            self.expire_own()
            self.stats.measure_load()
            await self.count_interface_drops(loop)
            bus_state = self.bus_state()
            if bus_state:
                self.state.bus_state = bus_state
            if self.failure or bus_state == "bus-off":
                reason = self.failure or "bus-off"
                self.state.last_error = f"{reason}: reopening"
                log.warning("%s: %s", self.name, self.state.last_error)
                await loop.run_in_executor(None, self.close)
                await self._back_off()

    async def _back_off(self) -> None:
        await asyncio.sleep(self.backoff_s)
        self.backoff_s = min(self.backoff_s * 2, BACKOFF_S[1])

    async def count_interface_drops(self, loop: asyncio.AbstractEventLoop) -> None:
        """The interface's own count of lost frames since the bus was opened: a socket's from one system call
        here, a SocketCAN driver's from /sys in a thread; an interface that does not say costs nothing."""
        bus = self.bus
        if bus is None or (self.sock is None and self.options.get("interface") != "socketcan"):
            return  # it does not say (interface_drops would find nothing)
        try:
            if self.sock is not None:
                found = interface_drops(bus, self.options, self.sock)
            else:
                found = await loop.run_in_executor(None, interface_drops, bus, self.options)
        except OSError as exc:  # a counter that cannot be read is "not reported", never a failure
            log.debug("%s: drop counter unreadable: %s", self.name, exc)
            found = None
        if found is not None:
            self.stats.interface_dropped(*found)

    def expire_own(self) -> None:
        """Forget sent frames whose echo did not come back within ``ECHO_WAIT_S``."""
        limit = time.monotonic() - ECHO_WAIT_S
        for key in list(self.own):
            pending = self.own[key]
            while pending and pending[0] < limit:
                pending.popleft()
            if not pending:
                del self.own[key]

    def bus_state(self) -> str:
        if self.bus is None:
            return ""
        try:
            return BUS_STATE_NAMES.get(self.bus.state, "unknown")
        except (NotImplementedError, can.CanError):
            return "error-active" if self.state.connected else ""

    # -- receive path ------------------------------------------------------------------
    def drain(self) -> None:
        """In the loop: what the periodic senders sent, then the handed-over frames, subscribed IDs first,
        for at most ``DRAIN_BUDGET_S``."""
        handover = self.handover
        handover.scheduled = False
        sent = handover.sent
        while sent:
            try:
                msg = sent.popleft()
            except IndexError:
                break
            self._sent(msg)
        shed = handover.take_shed()
        if shed:
            self.stats.shed(shed)
        deadline = time.perf_counter() + DRAIN_BUDGET_S
        done = False
        for inbox in (handover.known, handover.other):
            while inbox and not done:
                for _ in range(min(len(inbox), DRAIN_CHECK)):
                    try:
                        msg = inbox.popleft()
                    except IndexError:  # shed by the notifier's thread meanwhile
                        break
                    self.dispatch(msg)
                done = time.perf_counter() >= deadline
        if (handover.known or handover.other) and not handover.scheduled:
            handover.scheduled = True
            asyncio.get_running_loop().call_soon(self.drain)

    def dispatch(self, msg: can.Message) -> None:
        """Echo filter, statistics, then the handlers of the frame's ID (or the listeners)."""
        key = (msg.is_extended_id, msg.arbitration_id)
        if self.filter_own and self.own:
            own = (key[0], key[1], bytes(msg.data))
            pending = self.own.get(own)
            if pending:
                pending.popleft()
                if not pending:
                    del self.own[own]
                return
        self.stats.received(msg)
        handlers = self.handlers.get(key)
        try:
            if handlers:
                for handler in handlers:
                    handler(msg)
            elif self.listeners and self._offer(key, msg):
                for listener in self.listeners:
                    listener(msg)
        except Exception:  # a bad frame, or an adapter's bug, must never stop the bus's dispatch: counted, traceback logged
            log.debug("%s: handler failed for %s", self.name, msg, exc_info=True)
            self.stats.handler_failed()

    def _offer(self, key: Key, msg: can.Message) -> bool:
        """Whether discovery hears this frame: not when no device type recognised a frame of this ID and
        length within ``NO_DISCOVERY_S`` (a remembered negative result: one check per ID, not per frame)."""
        shape = (key[0], key[1], len(msg.data))
        refused = self.no_discovery
        until = refused.get(shape)
        now = time.monotonic()
        if until is not None:
            if now < until:
                refused.move_to_end(shape)
                self.no_discovery_skipped += 1
                return False
            del refused[shape]
        if self.recognise is None or self.recognise(msg.arbitration_id, msg.is_extended_id, bytes(msg.data)):
            return True
        if len(refused) >= NO_DISCOVERY_IDS:
            refused.popitem(last=False)
        refused[shape] = now + NO_DISCOVERY_S
        return True  # this frame still goes to the listeners: what they do with it is unchanged

    # -- transmit path ----------------------------------------------------------------
    def send(self, arbitration_id: int, data: bytes, is_extended_id: bool = False) -> bool:
        """Send one frame; False (and counted) when the bus is not open or refuses it."""
        bus = self.bus
        if bus is None:
            self.stats.send_failed("")
            return False
        msg = can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=is_extended_id, timestamp=time.time(), is_rx=False)
        try:
            with self.send_lock:
                bus.send(msg, timeout=0.1)
        except can.CanError as exc:
            self.stats.send_failed(str(exc))
            return False
        self._sent(msg)
        return True

    def sent_by_thread(self, msg: can.Message) -> None:
        """From a periodic sender's thread, just before it sends: the loop records it (monitor, echo filter)."""
        self.handover.sent_by_thread(msg)

    def _sent(self, msg: can.Message) -> None:
        if self.filter_own:
            self.own.setdefault((msg.is_extended_id, msg.arbitration_id, bytes(msg.data)), deque()).append(time.monotonic())
        self.stats.sent(msg)

