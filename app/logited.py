"""LogiTed transports (Bauer MO 64), owned by the bus worker.

:class:`LogitedTcp` is the TCP/IP side: the MO 64 is a server that accepts one client at a
time (default port 52719). A reader task splits the byte stream into telegrams
``[0x55, LE, ... LE bytes ..., CSH, CSL]``; a request waits for the telegram its adapter says
answers it, and every other telegram (unsolicited change-monitoring telegrams, which may
arrive between a request and its answer) goes to the adapter's listener. The checksum and
the meaning of a telegram are the codec's business (devices/mo64/codec.py); the transport only
frames by the length byte, so a telegram the codec cannot decode is still shown in the log.

Every telegram sent and received lands in the bus's transaction log (the bus monitor), with
the decoding the adapter gives it.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

from app.state import BusState
from devices.transport import SerialClosed, SerialTimeout

log = logging.getLogger(__name__)

SD = 0x55  # start delimiter of every telegram (document: "SD = 55h")
BACKOFF_S = (0.5, 1.0, 2.0, 5.0, 10.0)
CONNECT_TIMEOUT_S = 3.0


@dataclass
class LogitedTransaction:
    """One line of the bus monitor's log: a request with its answer, or a telegram on its own."""

    time: float
    request: str
    request_hex: str
    response_hex: str
    decoded: str
    rtt_ms: float | None
    error: str
    unit: int = 0


def telegram_length(buffer: bytes | bytearray) -> int | None:
    """Total length of the telegram at the start of ``buffer`` (SD, LE, LE bytes, CSH, CSL), once known."""
    if len(buffer) < 2:
        return None
    return 2 + buffer[1] + 2


class LogitedTcp:
    """The worker's TCP connection to one MO 64 (``type = "logited-tcp"``)."""

    def __init__(self, name: str, options: dict, state: BusState):
        self.name = name
        self.options = options
        self.state = state
        self.reader: asyncio.StreamReader | None = None
        self.writer: asyncio.StreamWriter | None = None
        self._reader_task: asyncio.Task | None = None
        self._lock = asyncio.Lock()
        self._waiter: tuple[Callable[[bytes], bool], asyncio.Future] | None = None
        self.listeners: list[Callable[[bytes], None]] = []
        self.describe: Callable[[bytes], str] | None = None  # the adapter's decoding for the log
        self.released = False
        self.garbage = 0
        self._failures = 0
        self._next_connect = 0.0

    # -- connection -----------------------------------------------------------------------
    @property
    def connected(self) -> bool:
        return self.writer is not None and not self.writer.is_closing()

    async def connect(self) -> bool:
        """Connect unless connected, released, or waiting out the backoff; True when connected."""
        if self.connected:
            return True
        if self.released or time.monotonic() < self._next_connect:
            return False
        host, port = self.options["host"], self.options["port"]
        try:
            self.reader, self.writer = await asyncio.wait_for(asyncio.open_connection(host, port), CONNECT_TIMEOUT_S)
        except (OSError, asyncio.TimeoutError) as exc:
            self._failed(f"the barrier at {host}:{port} did not take the connection ({exc or 'no answer'}): "
                         "is it powered and on the network, the address right, or is another client connected? "
                         "The MO 64 serves one client at a time")
            return False
        self._failures = 0
        self.state.connected = True
        self.state.last_error = ""
        self._reader_task = asyncio.create_task(self._read_loop(), name=f"logited {self.name}")
        log.info("%s: connected to %s:%s", self.name, host, port)
        return True

    def _failed(self, message: str) -> None:
        self._failures += 1
        self._next_connect = time.monotonic() + BACKOFF_S[min(self._failures - 1, len(BACKOFF_S) - 1)]
        self.state.connected = False
        self.state.last_error = message

    def _drop(self, message: str) -> None:
        writer, self.writer, self.reader = self.writer, None, None
        if writer is not None:
            writer.close()
        task, self._reader_task = self._reader_task, None
        if task is not None and task is not asyncio.current_task():
            task.cancel()
        if self._waiter is not None and not self._waiter[1].done():
            self._waiter[1].set_exception(SerialClosed(f"{self.name}: {message}"))
        self.state.connected = False
        if message:
            self._failed(message)

    def close(self) -> None:
        self._drop("")
        self.state.connected = False

    def release(self) -> None:
        """Give the barrier's one connection up (another client may take it) until :meth:`resume`."""
        self.released = True
        self._drop("")
        self.state.last_error = "connection released on request: another client may connect to the barrier now"

    def resume(self) -> None:
        self.released = False
        self._next_connect = 0.0
        self.state.last_error = ""

    # -- telegrams ------------------------------------------------------------------------
    async def _read_loop(self) -> None:
        reader = self.reader
        buffer = bytearray()
        try:
            while True:
                chunk = await reader.read(1024)
                if not chunk:
                    self._drop(f"the barrier closed the connection (another client, or it restarted); reconnecting")
                    return
                buffer += chunk
                while buffer:
                    if buffer[0] != SD:
                        skip = buffer.find(SD)
                        skip = len(buffer) if skip < 0 else skip
                        self.garbage += skip
                        self._log("received", b"", bytes(buffer[:skip]), f"{skip} bytes outside a telegram (no 0x55)")
                        del buffer[:skip]
                        continue
                    need = telegram_length(buffer)
                    if need is None or len(buffer) < need:
                        break
                    telegram = bytes(buffer[:need])
                    del buffer[:need]
                    self._deliver(telegram)
        except asyncio.CancelledError:
            raise
        except (OSError, ConnectionError) as exc:
            self._drop(f"connection lost: {exc}")

    def _deliver(self, telegram: bytes) -> None:
        waiter = self._waiter
        if waiter is not None and not waiter[1].done():
            try:
                answers = waiter[0](telegram)
            except Exception:  # noqa: BLE001 - a telegram the codec cannot read answers nothing
                answers = False
            if answers:
                waiter[1].set_result(telegram)
                return
        self._log("unsolicited", b"", telegram, "")
        for listener in self.listeners:
            try:
                listener(telegram)
            except Exception:  # a bad telegram must never stop the connection
                log.exception("%s: listener failed for %s", self.name, telegram.hex(" "))

    def _text(self, telegram: bytes) -> str:
        if not telegram or self.describe is None:
            return ""
        try:
            return self.describe(telegram)
        except Exception as exc:  # noqa: BLE001 - shown as what it is
            return f"cannot decode: {exc}"

    def _log(self, what: str, request: bytes, answer: bytes, error: str, rtt_ms: float | None = None) -> None:
        self.state.transactions.append(LogitedTransaction(
            time.time(), what, request.hex(" ").upper(), answer.hex(" ").upper(),
            self._text(answer) if answer and not error else "", rtt_ms, error))

    async def transact(self, request: bytes, answers: Callable[[bytes], bool], *, timeout: float | None = None,
                       describe: str = "") -> bytes:
        """Send ``request`` and return the first telegram ``answers`` accepts.

        :raises SerialClosed: not connected (refused, another client, released)
        :raises SerialTimeout: no answer in time
        """
        timeout = self.options["timeout"] if timeout is None else timeout
        async with self._lock:
            if not await self.connect():
                raise SerialClosed(f"{self.name}: {self.state.last_error}")
            future = asyncio.get_running_loop().create_future()
            self._waiter = (answers, future)
            started = time.monotonic()
            try:
                self.writer.write(request)
                await self.writer.drain()
                answer = await asyncio.wait_for(future, timeout)
            except asyncio.TimeoutError:
                self._log(describe, request, b"", f"no answer within {timeout:g} s")
                raise SerialTimeout(f"{self.name}: no answer within {timeout:g} s") from None
            except (OSError, ConnectionError) as exc:
                self._drop(f"connection lost: {exc}")
                self._log(describe, request, b"", f"connection lost: {exc}")
                raise SerialClosed(f"{self.name}: {self.state.last_error}") from None
            except SerialClosed as exc:
                self._log(describe, request, b"", str(exc))
                raise
            finally:
                self._waiter = None
            self._log(describe, request, answer, "", round((time.monotonic() - started) * 1000, 2))
            return answer
