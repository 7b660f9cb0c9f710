"""A third node on a CAN bus for the tests: every frame it hears, time-stamped on arrival in a thread of its
own (which a blocked event loop cannot hold up)."""

from __future__ import annotations

import threading
import time

import can


class FrameListener:
    """Every frame on ``bus`` as ``(arrival time.monotonic(), ID, data)``; ``close()`` ends it and the bus."""

    def __init__(self, bus: can.BusABC, poll_s: float = 0.05):
        self.bus = bus
        self.poll_s = poll_s
        self.frames: list[tuple[float, int, bytes]] = []
        self._run = True
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        while self._run:
            msg = self.bus.recv(self.poll_s)
            if msg is not None:
                self.frames.append((time.monotonic(), msg.arbitration_id, bytes(msg.data)))

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
