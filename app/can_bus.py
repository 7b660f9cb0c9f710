"""One CAN bus of the plant, shared by every device adapter on it.

A python-can bus (any interface: socketcan, pcan, kvaser, slcan, gs_usb, virtual,
udp_multicast, ...) is read by one reader thread that hands frames to the event loop
in batches (one wake-up per batch, never one per frame). The loop dispatches each
frame to the handlers subscribed to its ID, feeds the monitor's bounded buffers and
offers frames of unknown IDs to discovery listeners. A bus that fails to open, dies
or goes bus-off is reopened with backoff.

A flood never stalls the loop: the hand-over holds at most ``INBOX_FRAMES`` frames per
kind (frames of subscribed IDs, and all others), the oldest are shed and counted in
``CanBusState.shed`` when the loop falls behind, frames of subscribed IDs go first, and
the loop drains for at most ``DRAIN_BUDGET_S`` at a time before it runs anything else
(the keep-alives of every bus among it).
"""

from __future__ import annotations

import asyncio
import logging
import sys
import threading
import time
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import can

from app.state import BusState

log = logging.getLogger(__name__)

Key = tuple[bool, int]  # (is_extended_id, arbitration_id)
Handler = Callable[[can.Message], None]

MONITOR_FRAMES = 20_000
MAX_IDS = 4096  # rows of the overwrite view
INBOX_FRAMES = 4096  # per kind waiting for the loop: about 0.45 s of a full 1 Mbit/s bus; beyond, the oldest are shed
DRAIN_BUDGET_S = 0.004  # the loop drains one bus this long at most, then runs timers and other tasks
DRAIN_CHECK = 4  # frames between two looks at the clock
GIL_SWITCH_S = 0.001  # a busy reader thread holds the GIL at most this long while the loop owes a keep-alive (5 ms by default)
SHED_WARN_S = 10.0  # at most one log line per bus this often while frames are shed
BUS_STATE_NAMES = {
    can.BusState.ACTIVE: "error-active",
    can.BusState.PASSIVE: "error-passive",
    can.BusState.ERROR: "bus-off",
}


@dataclass(slots=True)
class FrameRecord:
    """One frame as the monitor keeps it."""

    time: float
    arbitration_id: int
    is_extended_id: bool
    dlc: int
    data: bytes
    direction: str  # "rx" or "tx"
    is_error_frame: bool = False
    is_remote_frame: bool = False


@dataclass(slots=True)
class IdStats:
    """Overwrite view: one row per ID."""

    count: int = 0
    last_time: float = 0.0
    period: float | None = None
    data: bytes = b""
    changed: int = 0  # bit n set: byte n differs from the previous frame
    direction: str = "rx"


@dataclass
class CanBusState(BusState):
    """Bus state plus what the monitor shows."""

    bus_state: str = "unknown"
    rx_frames: int = 0
    tx_frames: int = 0
    error_frames: int = 0
    tx_errors: int = 0
    dropped: int = 0  # frames not handled: shed at the hand-over, or a handler failed on them
    shed: int = 0  # of those, frames the reader dropped because the loop was behind (a flood)
    frames: deque = field(default_factory=lambda: deque(maxlen=MONITOR_FRAMES))
    ids: OrderedDict[Key, IdStats] = field(default_factory=OrderedDict)  # least recently heard first
    recorder: Any = None  # a python-can writer while recording


SOCKETCAN_ERRNOS = {97, 19, 100}  # EAFNOSUPPORT (no SocketCAN: not Linux, no can module), ENODEV, ENETDOWN


def open_error(options: dict[str, Any], exc: Exception) -> str:
    """What the bus page says when python-can cannot open the bus; for SocketCAN, what it needs and how."""
    interface, channel = options.get("interface"), options.get("channel")
    text = f"cannot open {interface} {channel}: {exc}"
    code = getattr(exc, "errno", None) or getattr(exc, "error_code", None)
    if interface == "socketcan" and code in SOCKETCAN_ERRNOS:
        bitrate = options.get("bitrate") or 500000
        text += (f" - SocketCAN needs Linux (with the can modules) and the interface up: "
                 f"`sudo ip link set {channel or 'can0'} up type can bitrate {bitrate}`")
    return text


class CanBus:
    """A python-can bus owned by the worker; implements :class:`devices.transport.CanTransport`.

    :param options: plant-file options: ``interface``, ``channel``, ``bitrate`` and any
        further keys, which are passed to :class:`can.Bus` unchanged.
    """

    def __init__(self, name: str, options: dict[str, Any], state: CanBusState):
        self.name = name
        self.options = options
        self.state = state
        self.bus: can.BusABC | None = None
        self.handlers: dict[Key, list[Handler]] = {}
        self.listeners: list[Handler] = []  # every received frame whose ID has no handler
        self._inbox: deque[can.Message] = deque()  # frames of subscribed IDs: handled first
        self._inbox_other: deque[can.Message] = deque()  # the rest: monitor and discovery only
        self._shed = 0  # written by the reader thread only
        self._shed_seen = 0
        self._shed_warned = 0.0
        self._scheduled = False
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._failure: str = ""
        self._backoff = 0.5
        self._task: asyncio.Task | None = None
        self._cyclic: dict[str, asyncio.Task] = {}
        interface = options.get("interface")
        self.filter_own = options.get("filter_own", interface == "udp_multicast")
        # frames this instance sent, by content, with send times: udp_multicast hands them back
        self._own: dict[tuple[bool, int, bytes], deque[float]] = {}

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
    def _bus_kwargs(self) -> dict[str, Any]:
        skip = {"simulate", "poll_period", "filter_own", "timeout"}
        return {k: v for k, v in self.options.items() if k not in skip}

    def _open(self) -> can.BusABC:
        return can.Bus(**self._bus_kwargs())

    async def start(self) -> None:
        self._loop = asyncio.get_running_loop()
        if sys.getswitchinterval() > GIL_SWITCH_S:  # measured by bench/can_flood.py: worst control gap 226 -> 121 ms at 6x
            sys.setswitchinterval(GIL_SWITCH_S)
        self._task = asyncio.create_task(self._supervise(), name=f"can {self.name}")

    async def stop(self) -> None:
        for key in list(self._cyclic):
            self.stop_cyclic(key)
        if self._task:
            self._task.cancel()
            try:
                await self._task
            except asyncio.CancelledError:
                pass
            self._task = None
        await asyncio.get_running_loop().run_in_executor(None, self._close)

    def _close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
            self._thread = None
        if self.bus is not None:
            try:
                self.bus.shutdown()
            except Exception as exc:  # a dying interface may fail to shut down; it is gone anyway
                log.debug("shutdown of %s failed: %s", self.name, exc)
            self.bus = None
        self.state.connected = False

    async def _supervise(self) -> None:
        """Open the bus, watch the reader and the bus state, reopen with backoff."""
        loop = asyncio.get_running_loop()
        while True:
            if self.bus is None:
                try:
                    self.bus = await loop.run_in_executor(None, self._open)
                except Exception as exc:  # CanInterfaceNotImplementedError, CanInitializationError, OSError ...
                    self.state.connected = False
                    self.state.last_error = open_error(self.options, exc)
                    log.warning("%s: %s", self.name, self.state.last_error)
                    await asyncio.sleep(self._backoff)
                    self._backoff = min(self._backoff * 2, 10.0)
                    continue
            if self._thread is None:
                self._failure = ""
                self._stop.clear()
                self._thread = threading.Thread(target=self._read, name=f"can-rx {self.name}", daemon=True)
                self._thread.start()
                self.state.connected = True
                self.state.reconnects += 1
                self.state.last_error = ""
                self._backoff = 0.5
            await asyncio.sleep(0.5)
            self._expire_own()
            bus_state = self._bus_state()
            if bus_state:
                self.state.bus_state = bus_state
            if self._failure or bus_state == "bus-off":
                reason = self._failure or "bus-off"
                self.state.last_error = f"{reason}: reopening"
                log.warning("%s: %s", self.name, self.state.last_error)
                await loop.run_in_executor(None, self._close)
                await asyncio.sleep(self._backoff)
                self._backoff = min(self._backoff * 2, 10.0)

    def _expire_own(self) -> None:
        """Forget sent frames whose echo did not come back within a second."""
        limit = time.monotonic() - 1.0
        for key in list(self._own):
            pending = self._own[key]
            while pending and pending[0] < limit:
                pending.popleft()
            if not pending:
                del self._own[key]

    def _bus_state(self) -> str:
        if self.bus is None:
            return ""
        try:
            return BUS_STATE_NAMES.get(self.bus.state, "unknown")
        except (NotImplementedError, can.CanError, AttributeError):
            return "error-active" if self.state.connected else ""

    # -- receive path ------------------------------------------------------------------
    def _read(self) -> None:
        """Reader thread: recv() with a timeout, batch frames into the loop, shed the oldest when it is behind."""
        bus, loop = self.bus, self._loop
        assert bus is not None and loop is not None
        handlers, known, other = self.handlers, self._inbox, self._inbox_other
        while not self._stop.is_set():
            try:
                msg = bus.recv(0.1)
            except Exception as exc:  # CanOperationError when the interface goes away
                self._failure = f"receive failed: {exc}"
                return
            if msg is None:
                continue
            inbox = known if (msg.is_extended_id, msg.arbitration_id) in handlers else other
            if len(inbox) >= INBOX_FRAMES:
                try:
                    inbox.popleft()
                    self._shed += 1
                except IndexError:  # the loop emptied it meanwhile
                    pass
            inbox.append(msg)
            if not self._scheduled:
                self._scheduled = True
                try:
                    loop.call_soon_threadsafe(self._drain)
                except RuntimeError:  # loop closed while stopping
                    return

    def _drain(self) -> None:
        """In the loop: handle buffered frames, subscribed IDs first, for at most ``DRAIN_BUDGET_S``."""
        self._scheduled = False
        self._count_shed()
        deadline = time.perf_counter() + DRAIN_BUDGET_S
        done = False
        for inbox in (self._inbox, self._inbox_other):
            while inbox and not done:
                for _ in range(min(len(inbox), DRAIN_CHECK)):
                    try:
                        msg = inbox.popleft()
                    except IndexError:  # shed by the reader meanwhile
                        break
                    self.dispatch(msg)
                done = time.perf_counter() >= deadline
        if (self._inbox or self._inbox_other) and not self._scheduled:
            self._scheduled = True
            asyncio.get_running_loop().call_soon(self._drain)

    def _count_shed(self) -> None:
        shed = self._shed
        if shed == self._shed_seen:
            return
        new, self._shed_seen = shed - self._shed_seen, shed
        self.state.shed += new
        self.state.dropped += new
        now = time.monotonic()
        if now - self._shed_warned >= SHED_WARN_S:
            self._shed_warned = now
            log.warning("%s: the program cannot keep up with the bus: %d frames shed so far", self.name, self.state.shed)

    def dispatch(self, msg: can.Message) -> None:
        """Monitor, echo filter, then the handlers of the frame's ID (or the listeners)."""
        key = (msg.is_extended_id, msg.arbitration_id)
        if self.filter_own and self._own:
            own = (key[0], key[1], bytes(msg.data))
            pending = self._own.get(own)
            if pending:
                pending.popleft()
                if not pending:
                    del self._own[own]
                return
        state = self.state
        if msg.is_error_frame:
            state.error_frames += 1
        state.rx_frames += 1
        self._record(msg, "rx")
        handlers = self.handlers.get(key)
        try:
            if handlers:
                for handler in handlers:
                    handler(msg)
            else:
                for listener in self.listeners:
                    listener(msg)
        except Exception as exc:  # a bad frame must never stop the bus
            log.debug("%s: handler failed for %s: %s", self.name, msg, exc)
            state.dropped += 1

    def _record(self, msg: can.Message, direction: str) -> None:
        state = self.state
        now = time.time()
        data = bytes(msg.data)
        state.frames.append(
            FrameRecord(now, msg.arbitration_id, msg.is_extended_id, msg.dlc, data, direction, msg.is_error_frame, msg.is_remote_frame)
        )
        key = (msg.is_extended_id, msg.arbitration_id)
        stats = state.ids.get(key)
        if stats is None:
            if len(state.ids) >= MAX_IDS:  # a flood of random IDs must not grow memory without bound:
                state.ids.popitem(last=False)  # the ID heard least recently goes, in O(1)
            stats = state.ids[key] = IdStats()
        else:
            state.ids.move_to_end(key)
        if stats.count:
            stats.period = now - stats.last_time
            old = stats.data
            changed = 0
            for i in range(max(len(old), len(data))):
                if i >= len(old) or i >= len(data) or old[i] != data[i]:
                    changed |= 1 << i
            stats.changed = changed
        stats.count += 1
        stats.last_time = now
        stats.data = data
        stats.direction = direction
        if state.recorder is not None:
            try:
                state.recorder.on_message_received(msg)
            except Exception as exc:  # disk full or closed file: stop recording, keep the bus
                state.recorder = None
                state.last_error = f"recording stopped: {exc}"

    # -- cyclic transmissions ------------------------------------------------------------
    def start_cyclic(self, key: str, period_s: float, make: Callable[[], tuple[int, bytes, bool] | None]) -> None:
        """Send ``make()`` every ``period_s`` (absolute schedule, no drift) until stopped."""
        self.stop_cyclic(key)
        self._cyclic[key] = asyncio.get_running_loop().create_task(self._cyclic_task(period_s, make), name=f"cyclic {key}")

    def stop_cyclic(self, key: str) -> None:
        task = self._cyclic.pop(key, None)
        if task is not None:
            task.cancel()

    def cyclic_running(self, key: str) -> bool:
        task = self._cyclic.get(key)
        return task is not None and not task.done()

    async def _cyclic_task(self, period_s: float, make) -> None:
        loop = asyncio.get_running_loop()
        due = loop.time()
        while True:
            frame = make()
            if frame is not None:
                self.send(*frame)
            due += period_s
            delay = due - loop.time()
            if delay < 0:  # late (loop busy): do not send a burst to catch up
                due = loop.time()
                delay = 0
            await asyncio.sleep(delay)

    # -- transmit path ----------------------------------------------------------------
    def send(self, arbitration_id: int, data: bytes, is_extended_id: bool = False) -> bool:
        """Send one frame; False (and counted) when the bus is not open or refuses it."""
        if self.bus is None:
            self.state.tx_errors += 1
            return False
        msg = can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=is_extended_id, timestamp=time.time(), is_rx=False)
        try:
            self.bus.send(msg, timeout=0.1)
        except can.CanError as exc:
            self.state.tx_errors += 1
            self.state.last_error = f"send failed: {exc}"
            return False
        if self.filter_own:
            self._own.setdefault((is_extended_id, arbitration_id, bytes(data)), deque()).append(time.monotonic())
        self.state.tx_frames += 1
        self._record(msg, "tx")
        return True
