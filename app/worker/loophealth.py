"""Loop health: how late the event loop runs the worker's 50 ms tick.

Every keep-alive and the dead-man rule ride on that tick, so its lateness is the figure an
engineer needs when motion stopped "by itself": the latest lag, the 99th percentile of the last
minute, the worst ever, and how often it stalled (shown in the page header).

While no page is connected and nothing is held for anyone (the idle plant), there is nobody to
supervise and nobody reading the figures: the tick then comes every :data:`IDLE_PERIOD_S`, which
still catches every stall of twice that length. A page connecting or a command coming ends an idle
wait at once (:meth:`Hurry.now`).
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
IDLE_PERIOD_S = 0.1  # the tick while no page is connected and nothing is held (the dead-man rule has nothing to do)
STALL_S = 0.1  # an event-loop stall longer than this is logged and shown
LAG_WINDOW = 1200  # ticks kept for the lag figures (one minute)


@dataclass
class LoopHealth:
    """How late the event loop runs the 50 ms supervision tick (it carries every keep-alive)."""

    lags_ms: deque = field(default_factory=lambda: deque(maxlen=LAG_WINDOW))
    period_s: float = SUPERVISE_PERIOD_S  # the tick's period now (IDLE_PERIOD_S while idle)
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


class Hurry:
    """Ends the tick's idle wait at once (a page connected, a command came): the 50 ms tick resumes now."""

    def __init__(self) -> None:
        self._waiter: asyncio.Future | None = None

    def now(self) -> None:
        waiter = self._waiter
        if waiter is not None and not waiter.done():
            waiter.set_result(None)

    async def wait_until(self, loop: asyncio.AbstractEventLoop, when: float) -> None:
        waiter = self._waiter = loop.create_future()
        handle = loop.call_at(when, _release, waiter)
        try:
            await waiter
        finally:
            handle.cancel()
            self._waiter = None


def _release(waiter: asyncio.Future) -> None:
    if not waiter.done():
        waiter.set_result(None)


async def tick(health: LoopHealth, on_tick: Callable[[float], bool | None], period_s: float = SUPERVISE_PERIOD_S,
               idle_period_s: float | None = None, hurry: Hurry | None = None) -> None:
    """Every ``period_s``: add how late this tick came to ``health``, then call ``on_tick(monotonic time)``.

    With ``idle_period_s``: while ``on_tick`` returns False (nothing to supervise) the next tick comes after
    ``idle_period_s`` instead, or at once when ``hurry`` says so. Runs until cancelled; an exception of
    ``on_tick`` is logged and the ticks go on (at ``period_s``).
    """
    loop = asyncio.get_running_loop()
    period = health.period_s = period_s
    expected = loop.time() + period
    while True:
        if hurry is not None and period != period_s:
            await hurry.wait_until(loop, expected)
        else:
            await asyncio.sleep(max(0.0, expected - loop.time()))
        now = loop.time()
        health.add(now - expected, time.time())
        try:
            busy = on_tick(time.monotonic())
        except Exception:  # the tick itself must never end
            log.exception("supervision tick failed")
            busy = True
        period = period_s if busy is not False or idle_period_s is None else idle_period_s
        health.period_s = period
        expected = now + period
