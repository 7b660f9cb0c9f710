"""The TCP side of a device twin: the listening port, the clients it serves, the stream of telegrams
each client sends, and the clock that moves the twin's physics.

A simulated line is a TCP port (the master opens it as a pyserial ``socket://`` URL, or as the
barrier's own TCP port). :class:`TwinServer` starts and stops the port and keeps the connected
clients, by one of three rules: a point-to-point line where a new master replaces the old one
(SCU), a device that serves one client at a time and closes a second at once (MO 64 over TCP), or
a bus every client hears (MO 64 on RS485). :func:`serve_telegrams` reads one client's bytes through
the family codec's splitter; :class:`Ticker` steps the twins on their own period. :class:`OwnLoop` runs a
twin on an event loop in a thread of its own, where the program's loop stalling must not stall the twin.
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Awaitable, Callable
from typing import TypeVar
from urllib.parse import urlparse

# what a second client gets (TwinServer ``clients``)
SHARE = "share"  # every client is served (a bus)
REPLACE = "replace"  # the new client replaces the one before (point to point: the old one is closed)
REFUSE = "refuse"  # one client at a time: a second one is closed at once (counted in ``refused``)

Handler = Callable[[asyncio.StreamReader, asyncio.StreamWriter], Awaitable[None]]
T = TypeVar("T")


def host_port(url: str, what: str) -> tuple[str, int]:
    """Host and port of a ``socket://host:port`` URL (the plant file's port of a simulated line).

    :param what: the line in words, for the error (``"a simulated SCU line"``)
    """
    parsed = urlparse(url)
    if parsed.scheme != "socket" or not parsed.port:
        raise ValueError(f"{what} needs a socket://host:port URL, not {url!r}")
    return parsed.hostname or "127.0.0.1", parsed.port


class TwinServer:
    """One listening TCP port of the simulated plant; ``handle(reader, writer)`` serves each client.

    A client that goes away (or a server that stops) ends its handler quietly; the writer is closed
    and leaves :attr:`clients`.

    :param what: the line in words, for the error when the port cannot be taken
    :param clients: :data:`SHARE`, :data:`REPLACE` or :data:`REFUSE`
    """

    def __init__(self, what: str, handle: Handler, clients: str = SHARE):
        if clients not in (SHARE, REPLACE, REFUSE):
            raise ValueError(f"clients must be {SHARE!r}, {REPLACE!r} or {REFUSE!r}")
        self.what = what
        self.handle = handle
        self.rule = clients
        self.server: asyncio.base_events.Server | None = None
        self.clients: list[asyncio.StreamWriter] = []
        self.connections = 0
        self.refused = 0

    async def start(self, host: str, port: int) -> None:
        try:
            self.server = await asyncio.start_server(self._serve, host, port)
        except OSError as exc:
            raise OSError(f"cannot listen on {host}:{port} for {self.what}: {exc}") from None

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        if self.clients and self.rule == REFUSE:
            self.refused += 1
            writer.close()
            return
        if self.rule == REPLACE:
            for old in self.clients:
                old.close()
            self.clients.clear()
        self.clients.append(writer)
        self.connections += 1
        try:
            await self.handle(reader, writer)
        except (ConnectionError, asyncio.CancelledError):
            pass
        finally:
            if writer in self.clients:
                self.clients.remove(writer)
            writer.close()

    async def stop(self) -> None:
        for writer in self.clients:
            writer.close()
        self.clients.clear()
        if self.server:
            self.server.close()
            await self.server.wait_closed()
            self.server = None


async def serve_telegrams(reader: asyncio.StreamReader, splitter, on_item: Callable[[object], Awaitable[None]],
                          silence_s: float | None = None) -> None:
    """Feed a client's bytes to ``splitter`` (devices/framing.py) and await ``on_item`` for each telegram or
    :class:`~devices.framing.FrameError` it yields, until the client closes.

    :param silence_s: a telegram still incomplete after this long without a byte is dropped
        (``splitter.expire()``, nothing is answered); None: it waits for its bytes
    """
    while True:
        try:
            timeout = silence_s if silence_s is not None and splitter.pending else None
            data = await asyncio.wait_for(reader.read(4096), timeout)
        except TimeoutError:
            splitter.expire()
            continue
        if not data:
            return
        for item in splitter.feed(data):
            await on_item(item)


IDLE_S = 0.5  # the longest a resting twin goes unstepped (a change made behind its back is seen this late)


def _resume(sleeper: asyncio.Future) -> None:
    if not sleeper.done():
        sleeper.set_result(None)


class Ticker:
    """Calls ``step(dt_s, now)`` every ``period_s`` on the event loop until :meth:`stop`.

    With ``rest``, a twin at rest is stepped less often: ``rest(now)`` says how long nothing moves or
    falls due (0 while something moves; a pending deadline as seconds from now), and the ticker sleeps
    that long, up to ``idle_s``, instead of ``period_s``. Whatever may set it moving (a telegram, a
    command, a control) calls :meth:`wake` first: the twin is stepped up to now as the ticks would have
    done, and the ticks go on at ``period_s`` from there while it moves. ``catch_up(dt_s, now)``, if given, is
    that step instead: what must not fall due before the telegram that woke it is taken (a watchdog the
    telegram feeds: a tick would have come after it, as its bytes were read first).
    """

    def __init__(self, step: Callable[[float, float], None], period_s: float,
                 rest: Callable[[float], float] | None = None, idle_s: float = IDLE_S,
                 catch_up: Callable[[float, float], None] | None = None):
        self.step = step
        self.catch_up = step if catch_up is None else catch_up
        self.period_s = period_s
        self.rest = rest
        self.idle_s = idle_s
        self.task: asyncio.Task | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: int | None = None  # the thread of the loop it ticks on
        self.ticks = 0  # steps taken (the ticks and the catch-ups of wake())
        self._last = time.monotonic()
        self._sleeper: asyncio.Future | None = None  # set while resting longer than period_s

    def start(self, name: str) -> None:
        self._last = time.monotonic()
        self._loop, self._thread = asyncio.get_running_loop(), threading.get_ident()
        self.task = asyncio.create_task(self._run(), name=name)

    def _step(self, step: Callable[[float, float], None] | None = None) -> None:
        now = time.monotonic()
        (step or self.step)(now - self._last, now)
        self._last = now
        self.ticks += 1

    async def _run(self) -> None:
        loop = asyncio.get_running_loop()
        while True:
            pause = self.period_s
            if self.rest is not None:
                pause = max(pause, min(self.idle_s, self.rest(time.monotonic())))
            if pause > self.period_s:
                self._sleeper = sleeper = loop.create_future()
                timer = loop.call_later(pause, _resume, sleeper)
                try:
                    await sleeper
                finally:
                    timer.cancel()
                    self._sleeper = None
            else:
                await asyncio.sleep(pause)
            self._step()

    def wake(self) -> None:
        """Something may start to move: when resting, step up to now and tick at ``period_s`` again (from
        another thread than the ticker's: on its loop, at once)."""
        if self._loop is not None and self._thread != threading.get_ident():
            if not self._loop.is_closed():
                self._loop.call_soon_threadsafe(self.wake)
            return
        sleeper = self._sleeper
        if sleeper is not None and not sleeper.done():
            self._step(self.catch_up)
            sleeper.set_result(None)

    def stop(self) -> None:
        if self.task:
            self.task.cancel()
            self.task = None


class OwnLoop:
    """An event loop in a daemon thread of its own, for a twin that a real unit would not let stall.

    A real unit counts its watchdog in its own time; a twin on the program's event loop counts it only when the
    loop runs, so a loop held up (a slow page build on a busy laptop) made it find a keep-alive late that the
    program's line thread had sent on time. On a loop of its own the twin reads each telegram when it comes, as
    the unit would, and a keep-alive that is really late is still found late. Started by :meth:`call`-ing the
    twin's start on it; :meth:`close` after its stop.
    """

    def __init__(self, name: str):
        self.name = name
        self.loop: asyncio.AbstractEventLoop | None = None
        self.thread: threading.Thread | None = None

    async def call(self, work: Callable[[], Awaitable[T]]) -> T:
        """Run ``work()`` on the own loop (started on the first call) and await its result here."""
        if self.loop is None:
            self.loop = asyncio.new_event_loop()
            self.thread = threading.Thread(target=self.loop.run_forever, name=self.name, daemon=True)
            self.thread.start()
        return await asyncio.wrap_future(asyncio.run_coroutine_threadsafe(work(), self.loop))

    def close(self) -> None:
        """Stop the loop and its thread (what ran on it was stopped by a :meth:`call` before)."""
        loop, thread = self.loop, self.thread
        self.loop = self.thread = None
        if loop is None or thread is None:
            return
        loop.call_soon_threadsafe(loop.stop)
        thread.join(5)
        if not thread.is_alive():
            loop.close()
