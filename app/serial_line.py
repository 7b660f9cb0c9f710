"""One point-to-point serial line (RS232: a device path or a pyserial URL) owned by the bus worker.

Every request of the device on the line goes through :meth:`SerialLine.transact`, which
serialises access, writes the request, reads until the device's codec says the answer is
complete (or the timeout passes), counts the outcome and keeps a bounded transaction log for
the bus monitor. pyserial is blocking: the port is opened, written and read in a thread, so
the event loop (and every keep-alive on it) never waits for the wire.

A keep-alive the device needs on time whatever the event loop does (the SCU's RC within 500 ms)
runs in the line's own thread (:meth:`SerialLine.start_cyclic`): the thread calls the device's
``tick(exchange)``, which exchanges requests through the same port under the same lock and says
when it wants to run next. It never waits for the loop, so a stalled loop cannot delay it.

DTR and RTS are switched on before the port opens and kept on: some units (the Ewellix SCU)
take the power of their RS232 converter from them.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import threading
import time
from collections.abc import Callable

import serial

from app import realtime
from app.line_base import LineBase, read_burst, serial_port
from app.state import BusState
from devices.transport import Completion, SerialClosed, SerialLineError, SerialTimeout  # noqa: F401 - raised here, caught by adapters

log = logging.getLogger(__name__)

BAUDRATES = (9600, 19200, 38400)
REOPEN_BACKOFF_S = (0.5, 1.0, 2.0, 5.0)
RESERVE_WINDOW_S = 0.06  # a request of the loop that would start this close before a reserved cyclic one waits for it


# What a cyclic tick gets: ``exchange(request, complete, describe=..., decode=..., timeout=...)`` -> the answer,
# blocking, on the line's thread (raises SerialTimeout / SerialClosed like transact)
Exchange = Callable[..., bytes]
# ``tick(exchange)`` -> seconds until the thread should call it again
Tick = Callable[[Exchange], float]


class _LineThread:
    """One cyclic sender of a line: a daemon thread calling ``tick`` on a clock of its own."""

    def __init__(self, line: SerialLine, key: str, tick: Tick):
        self.line = line
        self.key = key
        self.tick = tick
        self.stop_event = threading.Event()
        self.errors = 0
        self.priority = "as it is"
        self.thread = threading.Thread(target=self._run, name=f"{line.name} {key}", daemon=True)

    def _run(self) -> None:
        self.priority = realtime.raise_sender(threading.get_native_id(), 1.0)  # sleeps between short exchanges
        realtime.hold_keepalive()  # guards the unit's remote session (RC within 500 ms): as a CAN keep-alive does
        try:
            while not self.stop_event.is_set():
                try:
                    delay = self.tick(self.line.exchange_blocking)
                except Exception:  # the thread must go on: a failed tick is logged and counted
                    self.errors += 1
                    log.exception("%s: cyclic %s failed", self.line.name, self.key)
                    delay = 0.05
                self.stop_event.wait(max(0.001, min(float(delay), 1.0)))
        finally:
            realtime.release_keepalive()


class SerialLine(LineBase):
    """The worker's handle on one serial port (``type = "serial"`` in the plant file); implements
    :class:`devices.transport.SerialTransport`."""

    BACKOFF_S = REOPEN_BACKOFF_S

    def __init__(self, name: str, options: dict, state: BusState):
        super().__init__(name, options, state)
        self.port: serial.SerialBase | None = None
        self._lock = asyncio.Lock()
        self._port_lock = threading.Lock()  # the port itself: the loop's requests (in threads) and the line's own thread
        self._cyclic: dict[str, _LineThread] = {}
        self._reserved_at: float | None = None  # when the line's thread wants the port next (reserve)

    # -- the port -----------------------------------------------------------------------
    def _open_blocking(self) -> serial.SerialBase:
        port = serial_port(self.options)
        port.dtr = True  # the unit's RS232 converter is powered from DTR and RTS
        port.rts = True
        port.open()
        port.dtr = True
        port.rts = True
        port.reset_input_buffer()
        return port

    async def connect(self) -> bool:
        """Open the port unless it is open (with backoff after failures); True when open."""
        if self.port is not None:
            return True
        now = time.monotonic()
        if not self.backoff.ready(now):
            return False
        try:
            self.port = await asyncio.to_thread(self._open_blocking)
        except (serial.SerialException, OSError, ValueError) as exc:
            self._open_failed(f"cannot open {self.options['port']}: {exc}. Check the cable, the port name, "
                              "and that nothing else holds the port", now)
            return False
        if self._opened():
            self.state.reconnects += 1
        log.info("%s: %s open at %d baud, 8N1, DTR and RTS on", self.name, self.options["port"], self.options["baudrate"])
        return True

    def close(self) -> None:
        """Close the port; the line's own threads end (a closed line sends nothing)."""
        for key in list(self._cyclic):
            self.stop_cyclic(key)
        port, self.port = self.port, None
        if port is not None:
            try:
                port.close()
            except (serial.SerialException, OSError):
                pass
        self.state.connected = False

    def _lost(self, exc: Exception) -> None:
        self.state.last_error = f"{self.options['port']} lost: {exc}"
        self.close()
        self.backoff.lost()

    # -- resynchronising, waking -----------------------------------------------------------
    def _flush_blocking(self, port: serial.SerialBase, quiet_s: float, limit_s: float) -> int:
        """Read and drop bytes until the line has been quiet for ``quiet_s`` (at most ``limit_s``)."""
        with self._port_lock:
            return self._flush_locked(port, quiet_s, limit_s)

    def _flush_locked(self, port: serial.SerialBase, quiet_s: float, limit_s: float) -> int:
        dropped = 0
        end = time.monotonic() + limit_s
        port.timeout = quiet_s
        while time.monotonic() < end:
            chunk = port.read(max(1, port.in_waiting or 0))
            if not chunk:
                break
            dropped += len(chunk)
        return dropped

    async def flush_input(self, quiet_s: float = 0.03, limit_s: float = 0.3) -> int:
        """Drop whatever is still arriving (the tail of a shifted or late answer) so that the next answer
        starts at its first byte; the number of bytes dropped."""
        async with self._lock:
            if self.port is None:
                return 0
            try:
                dropped = await asyncio.to_thread(self._flush_blocking, self.port, quiet_s, limit_s)
            except (serial.SerialException, OSError) as exc:
                self._lost(exc)
                raise SerialClosed(f"line {self.name}: {self.state.last_error}") from None
        if dropped:
            log.info("%s: %d byte(s) dropped to resynchronise", self.name, dropped)
        return dropped

    async def wake(self, duration_s: float = 0.15) -> None:
        """Hold TxD (the unit's RxD) at space for ``duration_s``: a break, which wakes a unit in low power
        (Ewellix SCU, section 3: at least 100 ms, firmware V2B1). URL ports without a break (socket://) ignore it."""
        async with self._lock:
            if not await self.connect():
                raise SerialClosed(f"line {self.name}: {self.state.last_error}")
            try:
                await asyncio.to_thread(self._break_blocking, self.port, duration_s)
            except (serial.SerialException, OSError) as exc:
                self._lost(exc)
                raise SerialClosed(f"line {self.name}: {self.state.last_error}") from None

    def _break_blocking(self, port: serial.SerialBase, duration_s: float) -> None:
        with self._port_lock:
            port.send_break(duration_s)

    # -- requests -----------------------------------------------------------------------
    def _exchange_blocking(self, port: serial.SerialBase, request: bytes, complete: Completion, timeout: float) -> bytes:
        self._yield_to_cyclic()
        with self._port_lock:
            return self._exchange_locked(port, request, complete, timeout)

    def _yield_to_cyclic(self) -> None:
        """A request of the loop (in a worker thread) that would start just before the line's thread sends its
        cyclic request waits until that has the port: the keep-alive keeps its period."""
        at = self._reserved_at
        if at is None:
            return
        now = time.monotonic()
        if not now < at + 0.02 or at - now > RESERVE_WINDOW_S:
            return
        while self._reserved_at == at and time.monotonic() < at + 0.02:
            time.sleep(0.001)

    def _exchange_locked(self, port: serial.SerialBase, request: bytes, complete: Completion, timeout: float) -> bytes:
        stale = port.read(port.in_waiting or 0) if port.in_waiting else b""
        if stale:
            log.debug("%s: %d stale bytes dropped before a request", self.name, len(stale))
        port.write(request)
        port.flush()
        end = time.monotonic() + timeout
        buffer = b""
        while True:
            need = complete(buffer)
            if need is not None and len(buffer) >= need:
                return buffer
            remaining = end - time.monotonic()
            if remaining <= 0:
                return buffer  # short: the caller names the timeout
            port.timeout = min(remaining, 0.05)
            if need is None:
                buffer += read_burst(port)  # what has come (the whole answer, as a rule), not a byte at a time
            else:
                buffer += port.read(need - len(buffer))

    async def transact(self, request: bytes, complete: Completion, *, timeout: float | None = None,
                       describe: str = "", decode: Callable[[bytes], str] | None = None) -> bytes:
        """Send ``request`` and return the complete answer.

        :param complete: the codec's length rule for an answer (see :data:`Completion`)
        :param timeout: seconds to wait for the whole answer (default: the bus's ``timeout``)
        :param describe: the request in words, for the monitor's log
        :param decode: answer -> text for the monitor's log
        :raises SerialTimeout: no complete answer in time
        :raises SerialClosed: the port is not open (cannot be opened, unplugged)
        """
        timeout = self.options["timeout"] if timeout is None else timeout
        async with self._lock:
            if not await self.connect():
                raise SerialClosed(f"line {self.name}: {self.state.last_error}")
            port = self.port
            started = time.monotonic()
            answer = b""
            try:
                answer = await asyncio.to_thread(self._exchange_blocking, port, request, complete, timeout)
            except (serial.SerialException, OSError) as exc:
                self._lost(exc)
                self._log(request, b"", complete, started, timeout, describe, decode, f"port lost: {exc}")
                raise SerialClosed(f"line {self.name}: {self.state.last_error}") from None
            return self._finish(request, answer, complete, started, timeout, describe, decode)

    def _finish(self, request: bytes, answer: bytes, complete: Completion, started: float, timeout: float,
                describe: str, decode: Callable[[bytes], str] | None) -> bytes:
        need = self._log(request, answer, complete, started, timeout, describe, decode, "")
        if need is None or len(answer) < need:
            raise SerialTimeout(f"line {self.name}: no complete answer within {timeout:g} s ({len(answer)} bytes)")
        return answer[:need]

    def _log(self, request: bytes, answer: bytes, complete: Completion, started: float, timeout: float,
             describe: str, decode: Callable[[bytes], str] | None, error: str) -> int | None:
        """One line of the monitor's transaction log (thread-safe: a deque append); the answer's length."""
        rtt = (time.monotonic() - started) * 1000
        need = complete(answer) if answer or not error else None
        if not error and (need is None or len(answer) < need):
            error = f"no complete answer within {timeout:g} s ({len(answer)} bytes)"
        text: str | Callable[[], str] = ""
        if not error and decode is not None:  # made when the monitor reads the line (_DecodedOnRead says why)
            text = functools.partial(decode, answer[:need])
        self._record(describe or request[:2].decode("ascii", "replace"), request.hex(" ").upper(),
                     answer.hex(" ").upper(), text, None if error else round(rtt, 2), error)
        return None if error else need

    # -- the line's own thread ------------------------------------------------------------------------
    def exchange_blocking(self, request: bytes, complete: Completion, *, timeout: float | None = None,
                          describe: str = "", decode: Callable[[bytes], str] | None = None) -> bytes:
        """:meth:`transact` for the line's own thread: blocking, never waits for the event loop; the port
        is not opened here (the loop opens it).

        :raises SerialTimeout: no complete answer in time
        :raises SerialClosed: the port is not open
        """
        timeout = self.options["timeout"] if timeout is None else timeout
        port = self.port
        if port is None:
            raise SerialClosed(f"line {self.name}: not open")
        started = time.monotonic()
        try:
            with self._port_lock:
                self._reserved_at = None
                answer = self._exchange_locked(port, request, complete, timeout)
        except (serial.SerialException, OSError, AttributeError, TypeError) as exc:  # closed under it by the loop
            self._log(request, b"", complete, started, timeout, describe, decode, f"port lost: {exc}")
            raise SerialClosed(f"line {self.name}: {exc}") from None
        return self._finish(request, answer, complete, started, timeout, describe, decode)

    def reserve(self, at: float) -> None:
        """The line's thread will want the port at ``at`` (monotonic): the loop's requests do not start
        within :data:`RESERVE_WINDOW_S` before it."""
        self._reserved_at = at

    def start_cyclic(self, key: str, tick: Tick) -> None:
        """Run ``tick(exchange)`` in a thread of this line until :meth:`stop_cyclic`; ``tick`` returns the
        seconds until its next call. The clock does not depend on the event loop."""
        self.stop_cyclic(key)
        runner = self._cyclic[key] = _LineThread(self, key, tick)
        runner.thread.start()

    def stop_cyclic(self, key: str) -> None:
        runner = self._cyclic.pop(key, None)
        if runner is not None:
            runner.stop_event.set()  # not joined: a tick in progress ends by itself (the loop never waits for it)

    def cyclic_running(self, key: str) -> bool:
        runner = self._cyclic.get(key)
        return runner is not None and runner.thread.is_alive()
