"""What the bus monitor shows of one CAN bus: the frames, one row per ID, the bus load and the counters.

:class:`CanStats` is told of every frame the link receives or sends and keeps :class:`CanBusState`
up to date in O(1) per frame: the monitor's ring buffer (:data:`MONITOR_FRAMES`), the overwrite view
(one :class:`IdStats` row per ID, at most :data:`MAX_IDS`, with its cycle times), the bits on the wire
and a recording in progress. Every :data:`LOAD_PERIOD_S` the link asks it for the load figures and gives
it the interface's own count of lost frames.
"""

from __future__ import annotations

import logging
import statistics
import time
from collections import OrderedDict, deque
from dataclasses import dataclass, field
from typing import Any

import can

from app.state import BusState
from devices.errors import CommissionError

log = logging.getLogger(__name__)

Key = tuple[bool, int]  # (is_extended_id, arbitration_id)

MONITOR_FRAMES = 20_000
MAX_IDS = 4096  # rows of the overwrite view
CYCLE_GAPS = 16  # gaps kept per ID and frame length for the cycle time (median; O(1) per frame)
CYCLE_STREAMS = 4  # frame lengths told apart per ID (a lock's status, 8 bytes, and its answers, 6 bytes); more share one
BURST_GAP_S = 0.010  # frames of one ID and length closer than this are one burst (the fastest documented cycle is 100 ms)
SHED_WARN_S = 10.0  # at most one log line per bus this often while frames are shed
LOAD_PERIOD_S = 0.5  # bus load and frames/s are taken over this window
LOAD_AVERAGE_S = 5.0  # the steady figure: frames reach the loop in batches, so one window jumps (0 %, then 18 %)
LOAD_PEAK_S, LOAD_PEAK_WINDOW_S = 10.0, 1.0  # the peak: the highest load of any 1 s within the last 10 s


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


class CanStats:
    """The monitor's figures of one bus, kept in its :class:`CanBusState`.

    :param name: the bus's name (for the log)
    :param state: where the figures go
    :param bitrate: the plant file's bit rate (None: no load figures)
    """

    def __init__(self, name: str, state: CanBusState, bitrate: Any = None):
        self.name = name
        self.state = state
        self.bitrate = bitrate if isinstance(bitrate, (int, float)) and bitrate > 0 else None
        self.load_mark = (time.monotonic(), 0, 0)  # (time, frames, bits) at the last load figure
        self.load_marks: deque[tuple[float, int]] = deque()  # (time, bits) of the load figures of the last LOAD_PEAK_S
        self.drop_base: int | None = None  # the interface's drop counter when the bus was opened
        self.shed_warned = 0.0

    def received(self, msg: can.Message) -> None:
        """A frame of the bus (not an echo of one of ours)."""
        state = self.state
        if msg.is_error_frame:
            state.error_frames += 1
        state.rx_frames += 1
        self.record(msg, "rx")

    def sent(self, msg: can.Message) -> None:
        """A frame this program sent (from the loop or a periodic sender's thread)."""
        self.state.tx_frames += 1
        self.record(msg, "tx")

    def send_failed(self, reason: str) -> None:
        self.state.tx_errors += 1
        if reason:
            self.state.last_error = f"send failed: {reason}"

    def handler_failed(self) -> None:
        """A handler failed on a frame: counted as dropped."""
        self.state.dropped += 1

    def shed(self, frames: int) -> None:
        """Frames the hand-over dropped because the loop was behind (a flood); one log line per ``SHED_WARN_S``."""
        state = self.state
        state.shed += frames
        state.dropped += frames
        now = time.monotonic()
        if now - self.shed_warned >= SHED_WARN_S:
            self.shed_warned = now
            log.warning("%s: the program cannot keep up with the bus: %d frames shed so far", self.name, state.shed)

    def opened(self) -> None:
        """A new bus object: its drop counter starts over."""
        self.drop_base = None

    def interface_dropped(self, count: int, source: str) -> None:
        """The interface's own count of lost frames (socketcan's counters run since the interface came up:
        counted from when this program opened it)."""
        if self.drop_base is None:
            self.drop_base = count if source.startswith("driver") else 0
        self.state.interface_dropped = max(0, count - self.drop_base)
        self.state.drop_source = source

    def record(self, msg: can.Message, direction: str) -> None:
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
            except CommissionError as exc:  # the file failed (disk full, gone): stop recording, keep the bus
                state.recorder = None
                state.last_error = f"recording stopped: {exc}"

    def measure_load(self, now: float | None = None) -> None:
        """Frames/s and bus load (bits on the wire per second in % of the bit rate) since the last call, the
        load's average over :data:`LOAD_AVERAGE_S` and its peak (see :data:`LOAD_PEAK_S`)."""
        state = self.state
        now = time.monotonic() if now is None else now
        then, frames, bits = self.load_mark
        total = state.rx_frames + state.tx_frames
        elapsed = now - then
        if elapsed <= 0:
            return
        state.frames_per_s = (total - frames) / elapsed
        bitrate = self.bitrate
        state.load_pct = (state.bits - bits) / elapsed / bitrate * 100 if bitrate else None
        self.load_mark = (now, total, state.bits)
        marks = self.load_marks
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
