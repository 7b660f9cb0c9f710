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
import functools
import logging
import time
from collections.abc import Awaitable, Callable

from app.i18n import N_
from app.line_base import PORT_GONE, LineBase, read_burst, serial_port
from app.message import Message
from app.state import BusState
from devices.errors import DeviceError
from devices.transport import SerialClosed, SerialTimeout

log = logging.getLogger(__name__)

SD = 0x55  # start delimiter of every telegram (document: "SD = 55h")
BACKOFF_S = (0.5, 1.0, 2.0, 5.0, 10.0)
CONNECT_TIMEOUT_S = 3.0


class _Waiter:
    """The telegrams a request waits for: every one ``answers`` accepts, in order (a syn and its ack may
    arrive in one segment), or the error that ended the wait."""

    def __init__(self, answers: Callable[[bytes], bool]):
        self.answers = answers
        self.queue: asyncio.Queue = asyncio.Queue()
        self.waiting = True  # False once the final answer is in: what follows answers nothing

    def offer(self, telegram: bytes) -> bool:
        if not self.waiting:
            return False
        try:
            accepted = self.answers(telegram)
        except (DeviceError, ValueError):  # a telegram the codec cannot read answers nothing
            accepted = False
        if accepted:
            self.queue.put_nowait(telegram)
        return accepted

    def fail(self, exc: Exception) -> None:
        if self.waiting:
            self.queue.put_nowait(exc)

    async def get(self, timeout: float) -> bytes:
        item = await asyncio.wait_for(self.queue.get(), timeout)
        if isinstance(item, Exception):
            raise item
        return item


def _closing_frames(hooks: list[Callable[[], list[bytes]]], name: str) -> list[bytes]:
    frames: list[bytes] = []
    for hook in hooks:
        try:
            frames += hook()
        except (DeviceError, ValueError):  # one adapter's refusal must not keep the others' frames back
            log.exception("%s: closing frames", name)
    return frames


def telegram_length(buffer: bytes | bytearray) -> int | None:
    """Total length of the telegram at the start of ``buffer`` (SD, LE, LE bytes, CSH, CSL), once known."""
    if len(buffer) < 2:
        return None
    return 2 + buffer[1] + 2


class _LogitedLine(LineBase):
    """What both LogiTed lines have: the adapter's listeners, closing frames and decoding for the log."""

    BACKOFF_S = BACKOFF_S

    def __init__(self, name: str, options: dict, state: BusState):
        super().__init__(name, options, state)
        self.listeners: list[Callable[[bytes], None]] = []
        # called as the line closes for good (the tool stops): frames to send first (an adapter's
        # deactivations of levels it set)
        self.closing: list[Callable[[], list[bytes]]] = []
        self.describe: Callable[[bytes], str] | None = None  # the adapter's decoding for the log
        self.garbage = 0

    def _hear(self, telegram: bytes) -> None:
        """A telegram that answers no request: logged, and given to the adapter's listeners."""
        self._log("unsolicited", b"", telegram, "")
        for listener in self.listeners:
            try:
                listener(telegram)
            except (DeviceError, ValueError):  # a bad telegram must never stop the line
                log.exception("%s: listener failed for %s", self.name, telegram.hex(" "))

    def _text(self, telegram: bytes) -> str:
        if not telegram or self.describe is None:
            return ""
        try:
            return self.describe(telegram)
        except (DeviceError, ValueError) as exc:  # a codec's refusal, shown as what it is
            return Message(N_("cannot decode: {error}"), error=str(exc))

    def _unit(self, request: bytes, answer: bytes) -> int:
        """The device address a log line concerns (0: the line has one device)."""
        return 0

    def _log(self, what: str, request: bytes, answer: bytes, error: str, rtt_ms: float | None = None) -> None:
        # the answer's decoding is made when the monitor reads the line (the adapter's describe reads the telegram only)
        decoded = functools.partial(self._text, answer) if answer and not error and self.describe is not None else ""
        self._record(what, request.hex(" ").upper(), answer.hex(" ").upper(), decoded, rtt_ms, error,
                     unit=self._unit(request, answer))

    # -- one request and its answer (the caller holds the line) -------------------------------------
    LOST_ERRORS: tuple[type[BaseException], ...] = (OSError, ConnectionError)  # a send that finds the line gone

    async def _exchange(self, request: bytes, answers: Callable[[bytes], bool], send: Callable[[bytes], Awaitable[None]],
                        timeout: float, describe: str, interim: Callable[[bytes], bool] | None,
                        interim_timeout: float) -> bytes:
        """``send(request)``, then the first telegram ``answers`` accepts, after any that ``interim`` says
        are not final (each logged); see ``transact``."""
        waiter = self._waiter = _Waiter(answers)
        started = time.monotonic()
        try:
            await send(request)
            answer = await waiter.get(timeout)
            while interim is not None and interim(answer):
                self._log(describe, request, answer, "", round((time.monotonic() - started) * 1000, 2))
                timeout = self._final_timeout(interim_timeout)
                answer = await waiter.get(timeout)
        except asyncio.TimeoutError:
            self._log(describe, request, b"", f"no answer within {timeout:g} s")
            raise SerialTimeout(f"{self.name}: no answer within {timeout:g} s") from None
        except SerialClosed as exc:
            self._log(describe, request, b"", str(exc))
            raise
        except self.LOST_ERRORS as exc:
            self._lost_sending(request, describe, exc)
            raise SerialClosed(f"{self.name}: {self.state.last_error}") from None
        finally:
            waiter.waiting = False
            self._waiter = None
        self._log(describe, request, answer, "", round((time.monotonic() - started) * 1000, 2))
        return answer

    def _final_timeout(self, interim_timeout: float) -> float:
        """How long the final answer after an interim one is awaited."""
        return interim_timeout

    def _lost_sending(self, request: bytes, describe: str, exc: BaseException) -> None:
        """The line went away during an exchange (then SerialClosed is raised)."""
        raise NotImplementedError


class LogitedTcp(_LogitedLine):
    """The worker's TCP connection to one MO 64 (``type = "logited-tcp"``)."""

    def __init__(self, name: str, options: dict, state: BusState):
        super().__init__(name, options, state)
        self.reader: asyncio.StreamReader | None = None
        self.writer: asyncio.StreamWriter | None = None
        self._reader_task: asyncio.Task | None = None
        self._lock = asyncio.Lock()
        self._waiter: _Waiter | None = None
        self.released = False

    # -- connection -----------------------------------------------------------------------
    @property
    def connected(self) -> bool:
        return self.writer is not None and not self.writer.is_closing()

    async def connect(self) -> bool:
        """Connect unless connected, released, or waiting out the backoff; True when connected."""
        if self.connected:
            return True
        if self.released or not self.backoff.ready():
            return False
        host, port = self.options["host"], self.options["port"]
        try:
            self.reader, self.writer = await asyncio.wait_for(asyncio.open_connection(host, port), CONNECT_TIMEOUT_S)
        except (OSError, asyncio.TimeoutError) as exc:
            self._open_failed(f"the barrier at {host}:{port} did not take the connection ({exc or 'no answer'}): "
                         "is it powered and on the network, the address right, or is another client connected? "
                         "The MO 64 serves one client at a time")
            return False
        self._opened()
        self._reader_task = asyncio.create_task(self._read_loop(), name=f"logited {self.name}")
        log.info("%s: connected to %s:%s", self.name, host, port)
        return True

    def _drop(self, message: str) -> None:
        writer, self.writer, self.reader = self.writer, None, None
        task, self._reader_task = self._reader_task, None
        try:
            if writer is not None:
                writer.close()
            if task is not None and task is not asyncio.current_task():
                task.cancel()
        except RuntimeError:  # the event loop it ran on has ended: its socket and reader went with it
            pass
        if self._waiter is not None:
            self._waiter.fail(SerialClosed(f"{self.name}: {message}"))
        self.state.connected = False
        if message:
            self._open_failed(message)

    def close(self) -> None:
        if self.connected:
            for frame in _closing_frames(self.closing, self.name):
                try:
                    self.writer.write(frame)  # flushed by the transport before it closes
                except RuntimeError:  # the event loop it ran on has ended
                    break
                self._log("on close", frame, b"", "")
        self._drop("")
        self.state.connected = False

    def release(self) -> None:
        """Give the barrier's one connection up (another client may take it) until :meth:`resume`."""
        self.released = True
        self._drop("")
        self.state.last_error = "connection released on request: another client may connect to the barrier now"

    def resume(self) -> None:
        self.released = False
        self.backoff.resume()
        self.state.last_error = ""

    # -- telegrams ------------------------------------------------------------------------
    async def _read_loop(self) -> None:
        reader = self.reader
        buffer = bytearray()
        try:
            while True:
                chunk = await reader.read(1024)
                if not chunk:
                    self._drop("the barrier closed the connection (another client, or it restarted); reconnecting")
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
        if self._waiter is not None and self._waiter.offer(telegram):
            return
        self._hear(telegram)

    async def transact(self, request: bytes, answers: Callable[[bytes], bool], *, timeout: float | None = None,
                       describe: str = "", interim: Callable[[bytes], bool] | None = None,
                       interim_timeout: float = 5.0) -> bytes:
        """Send ``request`` and return the first telegram ``answers`` accepts.

        :param interim: says of an accepted telegram that it is not the final answer (a setting's syn,
            after which ack or nak follows, chapter 5.2.4); the final answer is then awaited for up
            to ``interim_timeout`` within the same exchange, and returned
        :raises SerialClosed: not connected (refused, another client, released)
        :raises SerialTimeout: no answer in time
        """
        timeout = self.options["timeout"] if timeout is None else timeout
        async with self._lock:
            if not await self.connect():
                raise SerialClosed(f"{self.name}: {self.state.last_error}")
            return await self._exchange(request, answers, self._send, timeout, describe, interim, interim_timeout)

    async def _send(self, request: bytes) -> None:
        self.writer.write(request)
        await self.writer.drain()

    def _lost_sending(self, request: bytes, describe: str, exc: BaseException) -> None:
        self._drop(f"connection lost: {exc}")
        self._log(describe, request, b"", f"connection lost: {exc}")


class LogitedRs485(_LogitedLine):
    """The worker's RS485 line to several MO 64 (``type = "logited-rs485"``), 38400 8N1.

    Frames carry destination and source addresses and a token telegram passes the right to
    send between masters (both layouts are assumptions of the codec: devices/mo64/codec.py,
    ``RS485_LAYOUT``). With ``shared = false`` this tool is the only master and sends at will.
    With ``shared = true`` it ignores token telegrams addressed elsewhere, sends only while it
    holds the token, and passes it to ``next_master`` within 200 ms of receiving it (chapter
    2.6.1): at once when nothing waits, else when the requests waiting are done, and at the
    latest when the hold budget runs out. Telegrams for this master that answer no request go to
    ``listeners``; every telegram on the line is logged for the bus monitor.

    pyserial is blocking: a reader thread hands the bytes to the event loop, a telegram at a time; a write
    puts a few bytes into the driver's buffer and is made on the loop.
    """

    HOLD_BUDGET_S = 0.15  # pass the token this long after receiving it at the latest (limit 0.2 s)
    TOKEN_LIMIT_S = 0.2  # chapter 2.6.1: "Der Token muss nach spätestens 200ms weitergegeben werden"
    LIMIT_MARGIN_S = 0.015  # the token telegram itself, and the loop's own delays
    FRESH_TOKEN_S = 0.03  # a setting write starts only this soon after the token came (syn, then ack in this turn)

    def __init__(self, name: str, options: dict, state: BusState):
        from devices.registry import line_codec

        codec = line_codec("logited-rs485")  # the framing and token the device type on this line declares

        super().__init__(name, options, state)
        self.codec = codec
        self.master = options["master_address"]
        self.shared = options["shared"]
        self.next_master = options["next_master"]
        self.port = None
        self._lock = asyncio.Lock()
        self._waiter: _Waiter | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread = None
        self._run = False
        self._pending = 0
        self._token = asyncio.Event()
        self._token_since: float | None = None
        self._pass_timer: asyncio.TimerHandle | None = None
        self.token_holds_ms: list[float] = []  # how long this tool held the token, most recent last (bounded)

    # -- the port -----------------------------------------------------------------------
    def _open_blocking(self):
        port = serial_port(self.options)
        port.open()  # no input flush: on a live line it could drop the token meant for this master
        return port

    async def connect(self) -> bool:
        if self.port is not None:
            return True
        if not self.backoff.ready():
            return False
        import serial

        try:
            self.port = await asyncio.to_thread(self._open_blocking)
        except (serial.SerialException, OSError, ValueError) as exc:
            self._open_failed(f"cannot open {self.options['port']}: {exc}. Check the RS485 adapter, "
                              "the port name and that nothing else holds the port")
            return False
        import threading

        self._loop = asyncio.get_running_loop()
        self._run = True
        self._thread = threading.Thread(target=self._read_thread, args=(self.port,), name=f"rs485 {self.name}", daemon=True)
        self._thread.start()
        self._opened()
        return True

    def _read_thread(self, port) -> None:
        """Cuts the line's bytes into telegrams and hands them to the loop, a burst at a time. The token for this
        master while no request waits is passed on from here at once (as :meth:`_got_token` would), without
        waking the loop: on a shared line the token comes round many times a second."""
        splitter = self.codec.FrameSplitter(self.codec.RS485)
        token = self.codec.TOKEN
        while self._run and self.port is port:  # a reader of a port closed meanwhile ends (the line may be open again)
            try:
                data = read_burst(port)  # a telegram at a time: the loop wakes once for it, not once a byte
            except PORT_GONE as exc:  # unplugged or closed: the loop reopens with backoff
                self._loop.call_soon_threadsafe(self._port_lost, port, str(exc))
                return
            if not data:
                continue
            items = [item for item in splitter.feed(data)
                     if isinstance(item, self.codec.FrameError) or item.type != token or item.da == self.master]
            if not items:
                continue  # token telegrams between other masters
            if (len(items) == 1 and not isinstance(items[0], self.codec.FrameError) and items[0].type == token
                    and self.shared and self._pending == 0 and not self._token.is_set()):
                # nothing waits for the line (a request that starts meanwhile waits for the next token)
                if self._pass_from_thread(port):
                    continue
            self._loop.call_soon_threadsafe(self._on_items, items)

    def _pass_from_thread(self, port) -> bool:
        """The token onward from the reader thread; False if the write failed (the loop then sees the token)."""
        try:
            port.write(self.codec.encode_token(self.next_master, self.master))
        except PORT_GONE:  # the loop takes the token and finds the port lost
            return False
        self.token_holds_ms.append(0.0)
        return True

    def _port_lost(self, port, why: str) -> None:
        """The reader of ``port`` failed: the line is lost if ``port`` is still its port. The read of a port closed
        on purpose (or lost before) fails too, maybe after the line was opened again: that must not close the new one."""
        if self.port is port:
            self._lost(why)

    def _lost(self, why: str) -> None:
        self._shut(final=False)
        self.state.last_error = f"{self.options['port']} lost: {why}"
        self.backoff.lost()
        if self._waiter is not None:
            self._waiter.fail(SerialClosed(f"{self.name}: {self.state.last_error}"))

    def close(self) -> None:
        self._shut(final=True)

    def _shut(self, final: bool) -> None:
        self._run = False
        port, self.port = self.port, None
        if port is not None and final and self.closing:
            frames = _closing_frames(self.closing, self.name)
            try:
                for frame in frames:  # out of turn if the token is elsewhere: the tool is going away
                    port.write(frame)
                    self._log("on close", frame, b"", "")
                if frames:
                    port.flush()
            except PORT_GONE as exc:  # a lost port: nothing more can be sent
                log.warning("%s: closing frames not sent: %s", self.name, exc)
        if port is not None:
            try:
                port.close()
            except PORT_GONE:  # closed already
                pass
        self.state.connected = False
        self._token.clear()
        self._token_since = None

    # -- telegrams ------------------------------------------------------------------------
    def _on_items(self, items) -> None:
        """Telegrams (and framing errors) off the line, in order, as the reader thread cut them."""
        for item in items:
            if isinstance(item, self.codec.FrameError):
                self.garbage += len(item.raw or b"")
                self._log("received", b"", item.raw or b"", f"{item.__class__.__name__}: {item}")
                continue
            self._on_frame(item)

    def _on_frame(self, frame) -> None:
        codec = self.codec
        if frame.type == codec.TOKEN:
            if frame.da == self.master and self.shared:
                self._got_token()
            return  # token telegrams addressed elsewhere are ignored
        if frame.da != self.master:
            self._log("between others", b"", frame.raw, "")
            return
        if self._waiter is not None and self._waiter.offer(frame.raw):
            return
        self._hear(frame.raw)

    def _got_token(self) -> None:
        self._token_since = time.monotonic()
        self._token.set()
        if self._pending == 0:
            self._pass_token()  # nothing to send: hand it on at once
        else:
            self._pass_timer = self._loop.call_later(self.HOLD_BUDGET_S, self._pass_if_idle)

    def _pass_if_idle(self) -> None:
        if self._token.is_set() and self._waiter is None:
            self._pass_token()

    def _pass_token(self) -> None:
        if not self._token.is_set() or self.port is None:
            return
        if self._pass_timer is not None:
            self._pass_timer.cancel()
            self._pass_timer = None
        held = (time.monotonic() - self._token_since) * 1000 if self._token_since else 0.0
        self._token.clear()
        self._token_since = None
        self.token_holds_ms.append(round(held, 2))
        del self.token_holds_ms[:-100]
        token = self.codec.encode_token(self.next_master, self.master)
        try:
            self.port.write(token)  # a few bytes into the driver's buffer: does not wait for the wire
        except PORT_GONE as exc:
            self._lost(str(exc))

    def _unit(self, request: bytes, answer: bytes) -> int:
        """The bus address of the barrier a log line concerns (not a master), or 0."""
        masters = {self.master, self.next_master}
        for raw, field in ((request, 2), (answer, 3), (answer, 2)):  # the request's DA, the answer's SA, else its DA
            if len(raw) > field and raw[field] not in masters:
                return raw[field]
        return 0

    async def transact(self, request: bytes, answers: Callable[[bytes], bool], *, timeout: float | None = None,
                       describe: str = "", interim: Callable[[bytes], bool] | None = None,
                       interim_timeout: float = 5.0) -> bytes:
        """Send ``request`` (an addressed RS485 frame) and return the first telegram ``answers`` accepts.

        :param interim: says of an accepted telegram that it is not the final answer: a setting's syn,
            then ack or nak (chapter 5.2.4, "sonst tele_syn, dann tele_ack"). On a shared line the
            token is held until the final answer (the barrier's ack must not land in another
            master's turn), so such a request waits for a fresh token, and the final answer is
            awaited at most until the 200 ms of chapter 2.6.1 run out
        :raises SerialClosed: the port is not open
        :raises SerialTimeout: no token (shared line) or no answer in time
        """
        timeout = self.options["timeout"] if timeout is None else timeout
        self._pending += 1
        try:
            async with self._lock:
                if not await self.connect():
                    raise SerialClosed(f"{self.name}: {self.state.last_error}")
                if self.shared:
                    await self._hold_token(timeout, fresh=interim is not None)
                    left = self.HOLD_BUDGET_S - (time.monotonic() - self._token_since)
                    timeout = max(0.02, min(timeout, left))  # answered within the hold, or given up
                return await self._exchange(request, answers, self._send, timeout, describe, interim, interim_timeout)
        finally:
            self._pending -= 1
            if self.shared and self._token.is_set() and self._pending == 0:
                # done: hand the token on once the caller has had its turn, unless it asks again at once (the
                # next request of the same poll goes out in this hold, not a token round later)
                self._loop.call_soon(self._pass_when_done)

    def _pass_when_done(self) -> None:
        if self._pending == 0:
            self._pass_token()

    async def _send(self, request: bytes) -> None:
        # a telegram is a few bytes into the driver's buffer (like the token, :meth:`_pass_token`): written on
        # the loop, not handed to a worker thread and back for each request
        self.port.write(request)

    LOST_ERRORS = (Exception,)  # a write to a lost port

    def _lost_sending(self, request: bytes, describe: str, exc: BaseException) -> None:
        self._lost(str(exc))

    def _final_timeout(self, interim_timeout: float) -> float:
        if self.shared and self._token_since is not None:
            # the final answer within this turn: the token is passed before the limit
            return max(0.0, min(interim_timeout, self.TOKEN_LIMIT_S - self.LIMIT_MARGIN_S
                                - (time.monotonic() - self._token_since)))
        return interim_timeout

    async def _hold_token(self, timeout: float, fresh: bool = False) -> None:
        """Wait until this master holds the token with enough of its hold budget left (``fresh``: nearly
        all of it, for a request answered by syn and later ack)."""
        end = time.monotonic() + max(timeout, 1.0) + 1.0
        need = self.FRESH_TOKEN_S if fresh else self.HOLD_BUDGET_S - 0.05
        while True:
            if self._token.is_set() and time.monotonic() - self._token_since < need:
                return
            if self._token.is_set():
                self._pass_token()  # too little of the budget left for a request and its answer
            remaining = end - time.monotonic()
            if remaining <= 0:
                raise SerialTimeout(f"{self.name}: the token did not come to master 0x{self.master:02X} "
                                    f"(is another master on the line passing it? next master 0x{self.next_master:02X})")
            try:
                await asyncio.wait_for(self._token.wait(), remaining)
            except asyncio.TimeoutError:
                continue
