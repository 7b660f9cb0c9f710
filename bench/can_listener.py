"""A third node on a CAN bus for the tests and the benchmarks: every frame it hears, time-stamped in a thread of its
own (which a blocked event loop cannot hold up). python-can and the standard library only."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import can


def _every(msg: can.Message) -> bool:
    return True


class FrameListener:
    """Every frame on ``bus`` that ``keep`` accepts, as ``(time, ID, data)``; ``close()`` ends it and the bus.

    The time is when the frame arrived here (``time.monotonic()``), or with ``sent_time`` the interface's time
    stamp of the frame (wall clock; ``virtual``: stamped in the sender's send(), ``udp_multicast``: the kernel's
    receive time), not when this thread got the interpreter to look at it."""

    def __init__(self, bus: can.BusABC, poll_s: float = 0.05, keep: Callable[[can.Message], bool] = _every,
                 sent_time: bool = False):
        self.bus = bus
        self.poll_s = poll_s
        self.keep = keep
        self.sent_time = sent_time
        self.frames: list[tuple[float, int, bytes]] = []
        self._run = True
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        while self._run:
            msg = self.bus.recv(self.poll_s)
            if msg is not None and self.keep(msg):
                stamp = msg.timestamp if self.sent_time else time.monotonic()
                self.frames.append((stamp, msg.arbitration_id, bytes(msg.data)))

    def of(self, can_id: int, since: float = 0.0, until: float = float("inf")) -> list[tuple[float, bytes]]:
        """``(time, data)`` of the frames with ``can_id`` heard from ``since`` to ``until``."""
        return [(t, d) for t, i, d in list(self.frames) if i == can_id and since <= t <= until]

    def first(self, can_id: int, test, since: float = 0.0, timeout: float = 5.0) -> float | None:
        """When the first frame with ``can_id`` since ``since`` whose data passes ``test`` came (waiting up to
        ``timeout``), or None."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for t, data in self.of(can_id, since):
                if test(data):
                    return t
            time.sleep(0.01)
        return None

    def close(self) -> None:
        self._run = False
        self._thread.join(2)
        self.bus.shutdown()
