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

No loss is silent: where the interface can say how many frames it lost before they reached
the reader (the kernel's drop counter of a ``udp_multicast`` socket, a SocketCAN driver's
overrun counters), ``CanBusState.interface_dropped`` counts them; a ``udp_multicast``
socket gets a receive buffer of ``UDP_RCVBUF`` bytes so the reader can wait for the
interpreter lock without losing frames. Unknown IDs are offered to discovery once per
``NO_DISCOVERY_S`` when no device type recognises their frames (a bounded table).

A quiet bus costs nothing: the reader waits until a frame comes (a ``socketcan`` or
``udp_multicast`` socket together with a pipe that ends the wait when the bus closes, the
``virtual`` interface's queue, woken by a frame of its own), never on a short timeout; only
interfaces without either wait at most ``READ_WAIT_S`` at a time.
"""

from __future__ import annotations

import asyncio
import importlib
import logging
import os
import queue
import select
import socket
import statistics
import threading
import time
import weakref
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import can

from app import host, realtime
from app.state import BusState
from devices.lease import Lease

log = logging.getLogger(__name__)

Key = tuple[bool, int]  # (is_extended_id, arbitration_id)
Handler = Callable[[can.Message], None]

MONITOR_FRAMES = 20_000
MAX_IDS = 4096  # rows of the overwrite view
INBOX_FRAMES = 4096  # per kind waiting for the loop: about 0.45 s of a full 1 Mbit/s bus; beyond, the oldest are shed
DRAIN_BUDGET_S = 0.004  # the loop drains one bus this long at most, then runs timers and other tasks
DRAIN_CHECK = 4  # frames between two looks at the clock
READER_BACKOFF_S = 0.001  # the reader pauses this long when the hand-over is full (bench/can_ingest.py: 7.7x -> 12x)
SHED_WARN_S = 10.0  # at most one log line per bus this often while frames are shed
CYCLE_GAPS = 16  # gaps kept per ID and frame length for the cycle time (median; O(1) per frame)
CYCLE_STREAMS = 4  # frame lengths told apart per ID (a lock's status, 8 bytes, and its answers, 6 bytes); more share one
BURST_GAP_S = 0.010  # frames of one ID and length closer than this are one burst (the fastest documented cycle is 100 ms)
UDP_RCVBUF = 4 * 2**20  # receive buffer of a udp_multicast socket: about 0.4 s of a full 1 Mbit/s bus (capped by net.core.rmem_max)
NO_DISCOVERY_S = 10.0  # an unknown ID whose frames no device type recognises is offered to discovery again after this
NO_DISCOVERY_IDS = 4096  # negative results remembered per bus (least recently heard goes first)
READ_WAIT_S = 0.5  # the reader's longest wait where nothing can wake it early (interfaces other than the ones below)
LOAD_PERIOD_S = 0.5  # bus load and frames/s are taken over this window
LOAD_AVERAGE_S = 5.0  # the steady figure: frames reach the loop in batches, so one window jumps (0 %, then 18 %)
LOAD_PEAK_S, LOAD_PEAK_WINDOW_S = 10.0, 1.0  # the peak: the highest load of any 1 s within the last 10 s
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
    dt: float | None = None  # seconds since the previous frame of the same ID (None: the first one heard)


def frame_bits(dlc: int, is_extended: bool) -> int:
    """Bits of a classic CAN data frame on the wire without stuff bits: SOF, arbitration, control,
    data, CRC, ACK, EOF and the 3-bit interframe space (47 + 8n standard, 67 + 8n extended)."""
    return (67 if is_extended else 47) + 8 * min(dlc, 8)


@dataclass(slots=True)
class CycleStream:
    """Gaps of one ID's frames of one length: the cycle time is the median of recent gaps.

    Frames closer than ``BURST_GAP_S`` form a burst (a register read answered frame by frame);
    the gaps between burst starts are kept apart, so an ID that carries bursts shows the burst
    period and its size instead of the gaps inside a burst.
    """

    count: int = 0
    last: float = 0.0
    burst_start: float = 0.0
    burst_frames: int = 0
    gaps: deque = field(default_factory=lambda: deque(maxlen=CYCLE_GAPS))  # every gap
    burst_gaps: deque = field(default_factory=lambda: deque(maxlen=CYCLE_GAPS))  # from burst start to burst start
    burst_sizes: deque = field(default_factory=lambda: deque(maxlen=CYCLE_GAPS))

    def add(self, t: float) -> float | None:
        """One frame at ``t`` (interface time, seconds); the gap to the previous one."""
        gap = None
        if self.count:
            gap = t - self.last
            self.gaps.append(gap)
            if gap >= BURST_GAP_S:
                self.burst_gaps.append(t - self.burst_start)
                self.burst_sizes.append(self.burst_frames)
                self.burst_start, self.burst_frames = t, 0
        else:
            self.burst_start = t
        self.burst_frames += 1
        self.count += 1
        self.last = t
        return gap

    def cycle(self) -> tuple[float | None, float]:
        """(cycle time in s or None before two frames, mean frames per burst); O(CYCLE_GAPS)."""
        if not self.gaps:
            return None, 1.0
        median = statistics.median(self.gaps)
        if median >= BURST_GAP_S or not self.burst_gaps:
            return median, 1.0
        return statistics.median(self.burst_gaps), sum(self.burst_sizes) / len(self.burst_sizes)


@dataclass(slots=True)
class IdStats:
    """Overwrite view: one row per ID."""

    count: int = 0
    last_time: float = 0.0
    period: float | None = None  # the last gap
    data: bytes = b""
    prev: bytes | None = None  # the frame before (None: only one heard); ``changed`` is worked out when asked
    direction: str = "rx"
    last_ts: float = 0.0  # the interface's time stamp of the last frame
    streams: dict = field(default_factory=dict)  # frame length -> CycleStream (at most CYCLE_STREAMS)

    @property
    def changed(self) -> int:
        """Bit n set: byte n differs from the previous frame (read by the monitor a few times a second,
        so it is not worked out for every frame)."""
        old, data = self.prev, self.data
        if old is None or old == data:
            return 0
        changed = 0
        for i in range(max(len(old), len(data))):
            if i >= len(old) or i >= len(data) or old[i] != data[i]:
                changed |= 1 << i
        return changed

    def add_time(self, t: float, length: int) -> None:
        streams = self.streams
        stream = streams.get(length)
        if stream is None:
            if len(streams) >= CYCLE_STREAMS - 1:
                length = -1  # further lengths share the last stream
                stream = streams.get(length)
            if stream is None:
                stream = streams[length] = CycleStream()
        stream.add(t)

    def cycles(self) -> list[tuple[int, int, float, float]]:
        """(frame length, frames, cycle time s, frames per burst) per length heard twice, most frequent first."""
        out = []
        for length, stream in self.streams.items():
            cycle, burst = stream.cycle()
            if cycle is not None:
                out.append((length, stream.count, cycle, burst))
        out.sort(key=lambda c: -c[1])
        return out


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
    interface_dropped: int | None = None  # frames the interface lost before the reader saw them; None: it does not say
    drop_source: str = ""  # where interface_dropped comes from
    bits: int = 0  # bits on the wire of every frame heard or sent (no stuff bits)
    frames_per_s: float = 0.0  # over the last LOAD_PERIOD_S
    load_pct: float | None = None  # bits per second in % of the bit rate; None without a bit rate
    load_avg_pct: float | None = None  # the same over LOAD_AVERAGE_S
    load_peak_pct: float | None = None  # the highest over LOAD_PEAK_WINDOW_S within LOAD_PEAK_S
    rcvbuf: int | None = None  # the receive buffer granted to a socket interface, bytes
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


def _udp_socket(bus: can.BusABC) -> socket.socket | None:
    """The datagram socket of a python-can ``udp_multicast`` bus, else None."""
    multicast = getattr(bus, "_multicast", None)
    sock = getattr(multicast, "_socket", None)
    return sock if isinstance(sock, socket.socket) else None


def _socket_drops(sock: socket.socket) -> int | None:
    """The kernel's drop counter of ``sock`` from one getsockopt (Linux: :func:`app.host.socket_drops`),
    or None where the system does not give it."""
    return host.socket_drops(sock)


_WAKE = can.Message(arbitration_id=0, data=b"")  # put into a virtual bus's queue: its reader stops waiting
SOCKET_INTERFACES = ("socketcan", "udp_multicast")  # one frame per datagram, nothing kept back in the process


def _is_virtual(bus: can.BusABC) -> bool:
    return type(bus).__name__ == "VirtualBus" and isinstance(getattr(bus, "queue", None), queue.Queue)


def _socket_fd(bus: can.BusABC | None, options: dict[str, Any]) -> int | None:
    """The socket a ``socketcan`` or ``udp_multicast`` bus reads from (readable = a frame is there), else None."""
    if bus is None or options.get("interface") not in SOCKET_INTERFACES:
        return None
    try:
        fd = bus.fileno()
    except (NotImplementedError, AttributeError, OSError, ValueError):
        return None
    return fd if isinstance(fd, int) and fd >= 0 else None


def _proc_udp_drops(inode: int) -> int | None:
    """The kernel's drop counter of the UDP socket with ``inode`` (Linux's /proc: :func:`app.host.udp_drops`)."""
    return host.udp_drops(inode)


def interface_drops(bus: can.BusABC, options: dict[str, Any]) -> tuple[int, str] | None:
    """``(frames lost by the interface, where the figure comes from)``, or None where it does not say.

    udp_multicast: the socket's kernel drop counter (receive buffer full), from one system call that does not
    block (:func:`_socket_drops`; else from /proc). SocketCAN: the driver's ``rx_dropped + rx_over_errors +
    rx_fifo_errors`` of the network interface, read from /sys: blocking, call it in a thread.
    """
    sock = _udp_socket(bus)
    if sock is not None:
        drops = _socket_drops(sock)
        if drops is None:
            drops = _proc_udp_drops(os.fstat(sock.fileno()).st_ino)
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
                hook = getattr(importlib.import_module(t.can_codec), "discovered", None)
                if callable(hook):
                    hooks.append(hook)
        _RECOGNISERS = hooks
    for hook in _RECOGNISERS:
        try:
            if hook(arbitration_id, is_extended, data):
                return True
        except Exception:  # noqa: BLE001, S112 - a frame a codec cannot parse is not its device's
            continue
    return False


_BUSES: "weakref.WeakSet[CanBus]" = weakref.WeakSet()


def keepalives_running() -> bool:
    """Whether a periodic keep-alive (``start_periodic``) runs on some CAN bus of this process: what a long hold
    of the interpreter lock would make late (see app.runtime.FullCollections)."""
    return any(periodic.running() for bus in list(_BUSES) for periodic in list(bus._periodic.values()))


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
        self._wake_pipe: tuple[int, int] | None = None  # ends the reader's wait on a socket when the bus closes
        self._failure: str = ""
        self._backoff = 0.5
        self._task: asyncio.Task | None = None
        self._cyclic: dict[str, asyncio.Task] = {}
        self._periodic: dict[str, _Periodic] = {}  # keep-alives on python-can's cyclic tasks (their own clock)
        self._thread_sent: deque[can.Message] = deque(maxlen=4096)  # sent by those tasks, not yet in the monitor
        interface = options.get("interface")
        self.filter_own = options.get("filter_own", interface == "udp_multicast")
        # frames this instance sent, by content, with send times: udp_multicast hands them back
        self._own: dict[tuple[bool, int, bytes], deque[float]] = {}
        # discovery: (ext, id, length) -> monotonic time until which its frames are not offered
        self._no_discovery: OrderedDict[tuple[bool, int, int], float] = OrderedDict()
        self.no_discovery_skipped = 0
        self.recognise: Callable[[int, bool, bytes], bool] | None = recognised_by_a_device_type
        self._drop_base: int | None = None  # the interface's drop counter when the bus was opened
        self._load_mark = (time.monotonic(), 0, 0)  # (time, frames, bits) at the last load figure
        self._load_marks: deque[tuple[float, int]] = deque()  # (time, bits) of the load figures of the last LOAD_PEAK_S
        _BUSES.add(self)

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
        skip = {"simulate", "poll_period", "filter_own", "timeout", "rcvbuf"}
        return {k: v for k, v in self.options.items() if k not in skip}

    def _open(self) -> can.BusABC:
        bus = can.Bus(**self._bus_kwargs())
        sock = _udp_socket(bus)
        if sock is not None:
            try:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, int(self.options.get("rcvbuf", UDP_RCVBUF)))
                self.state.rcvbuf = sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF)
            except OSError as exc:
                log.warning("%s: cannot enlarge the socket's receive buffer: %s", self.name, exc)
        self._drop_base = None
        return bus

    async def start(self) -> None:
        self._loop = asyncio.get_running_loop()
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
        self._wake_reader()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(timeout=2)
        wake, self._wake_pipe = self._wake_pipe, None
        if wake is not None and (thread is None or not thread.is_alive()):  # never under a reader still polling it
            for end in wake:
                try:
                    os.close(end)
                except OSError:
                    pass
        # the periodic senders end before their bus does: a cyclic thread that sent on the closed bus would
        # log a traceback every period ("Cannot operate on a closed bus"). A reopened bus starts them again
        for periodic in list(self._periodic.values()):
            periodic.stop(join=True)
        if self.bus is not None:
            try:
                self.bus.shutdown()
            except Exception as exc:  # noqa: BLE001 - a dying interface may fail to shut down; it is gone anyway
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
                except Exception as exc:  # noqa: BLE001 - CanInterfaceNotImplementedError, CanInitializationError, OSError ...
                    self.state.connected = False
                    self.state.last_error = open_error(self.options, exc)
                    log.warning("%s: %s", self.name, self.state.last_error)
                    await asyncio.sleep(self._backoff)
                    self._backoff = min(self._backoff * 2, 10.0)
                    continue
            if self._thread is None:
                self._failure = ""
                self._stop.clear()
                self._wake_pipe = os.pipe() if _socket_fd(self.bus, self.options) is not None else None
                self._thread = threading.Thread(target=self._read, name=f"can-rx {self.name}", daemon=True)
                self._thread.start()
                self.state.connected = True
                self.state.reconnects += 1
                self._restart_periodic()
                self.state.last_error = ""
                self._backoff = 0.5
            await asyncio.sleep(LOAD_PERIOD_S)
            if self._periodic:  # threads started since the keep-alive began get their place (app/realtime.py)
                realtime.refresh_holders()
            self._expire_own()
            self._measure_load()
            await self._count_interface_drops(loop)
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

    def _measure_load(self, now: float | None = None) -> None:
        """Frames/s and bus load (bits on the wire per second in % of the bit rate) since the last call, the
        load's average over :data:`LOAD_AVERAGE_S` and its peak (see :data:`LOAD_PEAK_S`)."""
        state = self.state
        now = time.monotonic() if now is None else now
        then, frames, bits = self._load_mark
        total = state.rx_frames + state.tx_frames
        elapsed = now - then
        if elapsed <= 0:
            return
        state.frames_per_s = (total - frames) / elapsed
        bitrate = self.options.get("bitrate")
        state.load_pct = (state.bits - bits) / elapsed / bitrate * 100 if isinstance(bitrate, (int, float)) and bitrate > 0 else None
        self._load_mark = (now, total, state.bits)
        marks = self._load_marks
        if not marks:
            marks.append((then, bits))
        marks.append((now, state.bits))
        while len(marks) > 2 and now - marks[1][0] >= LOAD_PEAK_S:
            marks.popleft()
        if state.load_pct is None:
            state.load_avg_pct = state.load_peak_pct = None
            return
        listed = list(marks)
        # the oldest mark inside the averaging window, but never the one just added (no span of time)
        start = next((m for m in listed[:-1] if now - m[0] <= LOAD_AVERAGE_S + 1e-6), listed[-2])
        state.load_avg_pct = (state.bits - start[1]) / (now - start[0]) / bitrate * 100
        spans = []
        for i, (t0, b0) in enumerate(listed):  # each figure to the first one at least 1 s later
            later = next(((t1, b1) for t1, b1 in listed[i + 1:] if t1 - t0 >= LOAD_PEAK_WINDOW_S - 1e-6), None)
            if later is not None:
                spans.append((later[1] - b0) / (later[0] - t0) / bitrate * 100)
        state.load_peak_pct = max(spans) if spans else state.load_pct

    async def _count_interface_drops(self, loop: asyncio.AbstractEventLoop) -> None:
        """The interface's own count of lost frames since the bus was opened: a socket's from one system call
        here, a SocketCAN driver's from /sys in a thread; an interface that does not say costs nothing."""
        if self.bus is None:
            return
        sock = _udp_socket(self.bus)
        if sock is None and self.options.get("interface") != "socketcan":
            return  # it does not say (interface_drops would find nothing)
        try:
            if sock is not None and (drops := _socket_drops(sock)) is not None:
                found = (drops, "kernel socket drops")
            else:
                found = await loop.run_in_executor(None, interface_drops, self.bus, self.options)
        except Exception as exc:  # noqa: BLE001 - a counter that cannot be read is "not reported", never a failure
            log.debug("%s: drop counter unreadable: %s", self.name, exc)
            found = None
        if found is None:
            return
        count, source = found
        if self._drop_base is None:  # socketcan counters run since the interface came up: count from our start
            self._drop_base = count if source.startswith("driver") else 0
        self.state.interface_dropped = max(0, count - self._drop_base)
        self.state.drop_source = source

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
        """Reader thread: wait until frames come (:meth:`_frames`), batch them into the loop, shed the oldest
        when it is behind."""
        bus, loop = self.bus, self._loop
        assert bus is not None and loop is not None
        handlers, known, other = self.handlers, self._inbox, self._inbox_other
        stop = self._stop
        try:
            for msg in self._frames(bus):
                inbox = known if (msg.is_extended_id, msg.arbitration_id) in handlers else other
                if len(inbox) >= INBOX_FRAMES:
                    # the loop is behind: give it the interpreter for a moment instead of reading and shedding
                    # at full speed (frames wait in the interface's buffer meanwhile); then shed the oldest
                    stop.wait(READER_BACKOFF_S)
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
        except Exception as exc:  # noqa: BLE001 - CanOperationError when the interface goes away
            if not stop.is_set():  # not the bus closing under it
                self._failure = f"receive failed: {exc}"

    def _frames(self, bus: can.BusABC):
        """The frames of ``bus`` as they come, until the bus closes (:meth:`_wake_reader`); raises what the interface
        raises. Never wakes while the bus is quiet: a socket interface is waited on with a pipe that the closing
        writes to, the ``virtual`` interface's queue gets a frame of its own; others wait ``READ_WAIT_S`` at most."""
        stop = self._stop
        fd = _socket_fd(bus, self.options)
        wake = self._wake_pipe
        if fd is not None and wake is not None:
            poller = select.poll()
            poller.register(fd, select.POLLIN)
            poller.register(wake[0], select.POLLIN)
            trouble = select.POLLERR | select.POLLHUP | select.POLLNVAL
            while not stop.is_set():
                events = dict(poller.poll())
                if wake[0] in events or stop.is_set():
                    return
                got = False
                while (msg := bus.recv(0.0)) is not None:  # what has come by now, then wait again
                    got = True
                    yield msg
                if not got and events.get(fd, 0) & trouble:
                    raise can.CanOperationError(f"the interface reports an error on its socket (poll events {events[fd]:#x})")
            return
        timeout = None if _is_virtual(bus) else READ_WAIT_S
        while not stop.is_set():
            msg = bus.recv(timeout)
            if msg is None or msg is _WAKE:
                continue
            yield msg

    def _wake_reader(self) -> None:
        """End the reader's wait (the bus closes): a byte into its pipe, or a frame of its own into a virtual bus's queue."""
        wake = self._wake_pipe
        if wake is not None:
            try:
                os.write(wake[1], b"\0")
            except OSError:
                pass
        bus = self.bus
        if bus is not None and _is_virtual(bus):
            try:
                bus.queue.put_nowait(_WAKE)
            except (AttributeError, queue.Full):
                pass

    def _drain(self) -> None:
        """In the loop: handle buffered frames, subscribed IDs first, for at most ``DRAIN_BUDGET_S``."""
        self._scheduled = False
        if self._thread_sent:
            self._take_thread_sent()
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
            elif self.listeners and self._offer(key, msg):
                for listener in self.listeners:
                    listener(msg)
        except Exception as exc:  # noqa: BLE001 - a bad frame must never stop the bus
            log.debug("%s: handler failed for %s: %s", self.name, msg, exc)
            state.dropped += 1

    def _offer(self, key: Key, msg: can.Message) -> bool:
        """Whether discovery hears this frame: not when no device type recognised a frame of this ID and
        length within ``NO_DISCOVERY_S`` (a remembered negative result: one check per ID, not per frame)."""
        shape = (key[0], key[1], len(msg.data))
        refused = self._no_discovery
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

    def _record(self, msg: can.Message, direction: str) -> None:
        """Monitor ring buffer, overwrite view, bits on the wire and the recorder: O(1) per frame."""
        state = self.state
        now = time.time()
        ts = msg.timestamp or now  # the interface's time: frames handed over in a batch keep their own gaps
        data = bytes(msg.data)
        ext = msg.is_extended_id
        key = (ext, msg.arbitration_id)
        ids = state.ids
        stats = ids.get(key)
        if stats is None:
            if len(ids) >= MAX_IDS:  # a flood of random IDs must not grow memory without bound:
                ids.popitem(last=False)  # the ID heard least recently goes, in O(1)
            stats = ids[key] = IdStats()
            dt = None
        else:
            ids.move_to_end(key)
            dt = ts - stats.last_ts
        dlc = msg.dlc
        error = msg.is_error_frame
        state.frames.append(FrameRecord(now, key[1], ext, dlc, data, direction, error, msg.is_remote_frame, dt))
        if not error:
            state.bits += (67 if ext else 47) + 8 * (dlc if dlc < 8 else 8)  # frame_bits(), inlined: this runs per frame
        if stats.count:
            stats.period = dt
            stats.prev = stats.data
        stream = stats.streams.get(len(data))  # add_time(), its common case inlined: this runs per frame
        if stream is not None:
            stream.add(ts)
        else:
            stats.add_time(ts, len(data))
        stats.count += 1
        stats.last_time = now
        stats.last_ts = ts
        stats.data = data
        stats.direction = direction
        if state.recorder is not None:
            try:
                state.recorder.on_message_received(msg)
            except Exception as exc:  # noqa: BLE001 - disk full or closed file: stop recording, keep the bus
                state.recorder = None
                state.last_error = f"recording stopped: {exc}"

    # -- cyclic transmissions ------------------------------------------------------------
    def start_cyclic(self, key: str, period_s: float, make: Callable[[], tuple[int, bytes, bool] | None]) -> None:
        """Send ``make()`` every ``period_s`` (absolute schedule, no drift) until stopped.

        A loop task: for telegrams that keep nothing running (an engineer's transmit list).
        Keep-alives of watchdogs use :meth:`start_periodic`, whose clock does not depend on the loop.
        """
        self.stop_cyclic(key)
        self._cyclic[key] = asyncio.get_running_loop().create_task(self._cyclic_task(period_s, make), name=f"cyclic {key}")

    def stop_cyclic(self, key: str) -> None:
        task = self._cyclic.pop(key, None)
        if task is not None:
            task.cancel()
        periodic = self._periodic.pop(key, None)
        if periodic is not None:
            periodic.stop()

    def cyclic_running(self, key: str) -> bool:
        periodic = self._periodic.get(key)
        if periodic is not None:
            return periodic.running()
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

    def start_periodic(
        self, key: str, period_s: float, arbitration_id: int, data: bytes, is_extended_id: bool = False, *,
        lease: Lease | None = None, stop_form: Callable[[bytes], bytes] | None = None,
        on_lapse: Callable[[float], None] | None = None,
    ) -> None:
        """Send ``data`` every ``period_s`` on a clock of its own (python-can's ``send_periodic``: a
        thread, or the interface's own scheduler), whatever the event loop does, until :meth:`stop_cyclic`.

        With a ``lease``, the sender checks it before every period: while it is not valid (not granted,
        or lapsed because the loop stopped renewing it) only ``stop_form(data)`` leaves, and
        ``on_lapse(lapsed_at)`` is called in the loop once per lapse. New contents: :meth:`modify_periodic`.
        """
        self.stop_cyclic(key)
        periodic = _Periodic(self, key, period_s, arbitration_id, bytes(data), is_extended_id, lease, stop_form, on_lapse)
        self._periodic[key] = periodic
        if self.bus is not None:
            periodic.start(self.bus)

    def modify_periodic(self, key: str, data: bytes, *, send_now: bool = False) -> bool:
        """New contents for a periodic telegram from the next period on (python-can's ``modify_data``);
        ``send_now``: also send it once at once (a stop does not wait for the next period)."""
        periodic = self._periodic.get(key)
        if periodic is None:
            return False
        periodic.modify(bytes(data))
        if send_now:
            return self.send(periodic.arbitration_id, periodic.stop_checked(bytes(data)), periodic.is_extended_id)
        return True

    def _restart_periodic(self) -> None:
        """The bus was (re)opened: its periodic telegrams start again on the new bus object."""
        for periodic in self._periodic.values():
            if self.bus is not None:
                periodic.start(self.bus)

    def _note_thread_send(self, msg: can.Message) -> None:
        """From a cyclic task's thread, just before it sends: hand the frame to the loop (monitor, echo filter)."""
        self._thread_sent.append(msg)
        if not self._scheduled and self._loop is not None:
            self._scheduled = True
            try:
                self._loop.call_soon_threadsafe(self._drain)
            except RuntimeError:  # the loop is closed: nothing to record any more
                pass

    def _take_thread_sent(self) -> None:
        """In the loop: frames the cyclic threads sent, into the echo filter and the monitor."""
        sent = self._thread_sent
        while sent:
            try:
                msg = sent.popleft()
            except IndexError:
                break
            if self.filter_own:
                self._own.setdefault((msg.is_extended_id, msg.arbitration_id, bytes(msg.data)), deque()).append(time.monotonic())
            self.state.tx_frames += 1
            self._record(msg, "tx")

    # -- transmit path ----------------------------------------------------------------
    def send(self, arbitration_id: int, data: bytes, is_extended_id: bool = False) -> bool:
        """Send one frame; False (and counted) when the bus is not open or refuses it."""
        if self.bus is None:
            self.state.tx_errors += 1
            return False
        msg = can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=is_extended_id, timestamp=time.time(), is_rx=False)
        lock = getattr(self.bus, "_lock_send_periodic", None)  # python-can's cyclic threads send under it
        try:
            if lock is not None:
                with lock:
                    self.bus.send(msg, timeout=0.1)
            else:
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


class _Periodic:
    """One keep-alive on python-can's cyclic send task, with the lease check before every period."""

    def __init__(self, owner: CanBus, key: str, period_s: float, arbitration_id: int, data: bytes, is_extended_id: bool,
                 lease: Lease | None, stop_form: Callable[[bytes], bytes] | None, on_lapse: Callable[[float], None] | None):
        self.owner, self.key, self.period_s = owner, key, period_s
        self.arbitration_id, self.is_extended_id = arbitration_id, is_extended_id
        self.data = data  # the newest contents (replaced whole by the loop; read by the cyclic thread)
        self.lease, self.stop_form, self.on_lapse = lease, stop_form, on_lapse
        self.task: Any = None
        self.errors = 0
        self.last_error = ""
        self._reported_lapse: float | None = None
        self.priority = "as it is"  # the sender thread's place in the scheduling (app/realtime.py)
        self._holding = False  # holds off the automatic full collection while it sends (app/realtime.py)
        self._boosting = False  # and, leased, has the interpreter's other threads run real-time below it

    def _message(self, data: bytes) -> can.Message:
        return can.Message(arbitration_id=self.arbitration_id, data=data, is_extended_id=self.is_extended_id, is_rx=False)

    def start(self, bus: can.BusABC) -> None:
        self.stop()
        self.task = bus.send_periodic(self._message(self.stop_checked(self.data)), self.period_s, modifier_callback=self._before_send)
        if not self._holding:  # no full collection holds the interpreter lock while this sends, and a busy thread
            self._holding = True  # gives it up sooner (the switch interval, app/realtime.py); a leased one (motion,
            self._boosting = self.lease is not None  # mains outputs) also has the other threads run real-time below it
            realtime.hold_keepalive(boost=self._boosting)
        if hasattr(self.task, "on_error"):  # python-can's thread ends at the first error unless told otherwise
            self.task.on_error = self._on_error
        thread = getattr(self.task, "thread", None)
        if thread is not None:  # ahead of busy processes of the same machine where the system allows it; else as it is
            self.priority = realtime.raise_sender(thread.native_id, self.period_s)

    def stop(self, join: bool = False) -> None:
        """End the sender; ``join``: also wait (at most a period and a bit) until its thread has sent its
        last frame, before the bus it sends on is shut down (never from the thread itself, never in the loop)."""
        task, self.task = self.task, None
        if self._holding:
            self._holding = False
            realtime.release_keepalive(boost=self._boosting)
        if task is not None:
            try:
                task.stop()
            except Exception as exc:  # noqa: BLE001 - a closed interface has stopped it already
                log.debug("%s: stopping %s: %s", self.owner.name, self.key, exc)
            thread = getattr(task, "thread", None)
            if join and thread is not None and thread is not threading.current_thread() and thread.is_alive():
                thread.join(timeout=self.period_s + 0.5)

    def running(self) -> bool:
        task = self.task
        if task is None:
            return False
        thread = getattr(task, "thread", None)
        return not getattr(task, "stopped", False) and (thread is None or thread.is_alive())

    def modify(self, data: bytes) -> None:
        self.data = data
        task = self.task
        if task is not None and hasattr(task, "modify_data"):
            try:
                task.modify_data(self._message(self.stop_checked(data)))
            except Exception as exc:  # noqa: BLE001 - the callback below sends the new contents anyway
                log.debug("%s: modify_data for %s: %s", self.owner.name, self.key, exc)

    def stop_checked(self, data: bytes) -> bytes:
        """``data`` while the lease holds (or there is none), else its stop form."""
        if self.lease is None or self.stop_form is None or self.lease.valid():
            return data
        return self.stop_form(data)

    def _on_error(self, exc: Exception) -> bool:
        self.errors += 1
        self.last_error = str(exc)
        return True  # keep trying every period: the stop form must get out once the bus takes frames again

    def _before_send(self, msg: can.Message) -> None:
        """In the cyclic task's thread, before every period: the newest contents, or the stop form once the lease lapsed."""
        data = self.stop_checked(self.data)
        if msg.data != data:
            msg.data = bytearray(data)
            msg.dlc = len(data)
        lapsed = self.lease.lapsed_at if self.lease is not None else None
        loop = self.owner._loop
        if lapsed is not None and lapsed != self._reported_lapse and self.on_lapse is not None and loop is not None:
            self._reported_lapse = lapsed
            try:
                loop.call_soon_threadsafe(self.on_lapse, lapsed)
            except RuntimeError:  # the loop is closed
                pass
        msg.timestamp = time.time()
        self.owner._note_thread_send(can.Message(arbitration_id=msg.arbitration_id, data=bytes(data), is_extended_id=msg.is_extended_id,
                                                 timestamp=msg.timestamp, is_rx=False))
