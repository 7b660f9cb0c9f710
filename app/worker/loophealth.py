"""Loop health: how late the event loop runs the worker's 50 ms tick.

Every keep-alive and the dead-man rule ride on that tick, so its lateness is the figure an
engineer needs when motion stopped "by itself": the latest lag, the 99th percentile of the last
minute, the worst ever, and how often it stalled (shown in the page header).
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

log = logging.getLogger(__name__)

SUPERVISE_PERIOD_S = 0.05  # the tick
STALL_S = 0.1  # an event-loop stall longer than this is logged and shown
LAG_WINDOW = 1200  # ticks kept for the lag figures (one minute)


@dataclass
class LoopHealth:
    """How late the event loop runs the 50 ms supervision tick (it carries every keep-alive)."""

    lags_ms: deque = field(default_factory=lambda: deque(maxlen=LAG_WINDOW))
    stalls: int = 0
    worst_ms: float = 0.0
    last_stall: float | None = None

    def add(self, lag_s: float, now: float) -> None:
        lag_ms = max(0.0, lag_s * 1000)
        self.lags_ms.append(lag_ms)
        self.worst_ms = max(self.worst_ms, lag_ms)
        if lag_s > STALL_S:
            self.stalls += 1
            self.last_stall = now
            log.warning("event loop stalled for %.0f ms: keep-alives were late", lag_ms)

    def p99_ms(self) -> float:
        if not self.lags_ms:
            return 0.0
        ordered = sorted(self.lags_ms)
        return ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))]

    def summary(self) -> dict:
        recent = self.lags_ms[-1] if self.lags_ms else 0.0
        return {"lag_ms": round(recent, 1), "p99_ms": round(self.p99_ms(), 1), "worst_ms": round(self.worst_ms, 1),
                "stalls": self.stalls, "last_stall": self.last_stall}


async def tick(health: LoopHealth, on_tick: Callable[[float], None], period_s: float = SUPERVISE_PERIOD_S) -> None:
    """Every ``period_s``: add how late this tick came to ``health``, then call ``on_tick(monotonic time)``.

    Runs until cancelled; an exception of ``on_tick`` is logged and the ticks go on.
    """
    loop = asyncio.get_running_loop()
    expected = loop.time() + period_s
    while True:
        await asyncio.sleep(max(0.0, expected - loop.time()))
        now = loop.time()
        health.add(now - expected, time.time())
        expected = now + period_s
        try:
            on_tick(time.monotonic())
        except Exception:  # the tick itself must never end
            log.exception("supervision tick failed")
