"""One Modbus RTU line (RS485 port or pyserial URL) owned by the bus worker.

Every transaction of every device on the line goes through :meth:`ModbusLine.transact`,
which serialises access, counts results per device, classifies failures (timeout,
CRC/framing, an answer from another unit address, Modbus exception, port lost) and keeps a
bounded transaction log.

What it says is a :class:`~app.message.Message` (docs/i18n.md): its diagnoses (the errors it raises, the bus's and the
transaction's error) and the words of a request (``read holding 3000+9``, :func:`read_words`), English where they are
stored, recorded and parsed (:func:`request_target`), in the reader's language where a page shows them.
"""

from __future__ import annotations

import asyncio
import logging
import re
import statistics
import time
from collections import Counter, deque

from pymodbus.client import AsyncModbusSerialClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException
from pymodbus.framer import FramerRTU, FramerType

from app.i18n import N_
from app.line_base import LineBase, Transaction
from app.message import Message
from app.state import BusState, Counters, DeviceState
from devices.transport import LineClosed, LineCrcError, LineError, LineException, LineTimeout

__all__ = ["LineClosed", "LineCrcError", "LineError", "LineException", "LineTimeout", "ModbusLine", "Transaction",
           "read_words", "request_target", "stale_threshold", "write_words"]

log = logging.getLogger(__name__)

EXCEPTION_NAMES = {  # the Modbus application protocol's names of the exception codes (section 7)
    1: N_("illegal function"),
    2: N_("illegal data address"),
    3: N_("illegal data value"),
    4: N_("device failure"),
    5: N_("acknowledge"),
    6: N_("device busy"),
    10: N_("gateway path unavailable"),
    11: N_("gateway target did not respond"),
}


# Issue 16 item 5: a device is stale only when it missed more than two of the line's measured
# cycles (16 locks at 19200 baud take over 4 s per cycle), and never sooner than 3 s.
STALE_MIN_S = 3.0
STALE_CYCLES = 2.5
CYCLE_SAMPLES = 8  # intervals per unit the cycle time is the median of
CYCLE_FORGET_S = 60.0  # a unit not polled for this long no longer counts for the line's cycle


def stale_threshold(cycle_s: float | None) -> float:
    """Seconds without an answer after which a device on a line with this cycle time is stale."""
    return STALE_MIN_S if cycle_s is None else max(STALE_MIN_S, STALE_CYCLES * cycle_s)


def read_words(space: str, address: int, count: int) -> Message:
    """The words of a read of ``count`` registers of ``space`` (holding, input) from ``address``: read holding 3000+9."""
    if space == "input":
        return Message(N_("read input {address}+{count}"), address=address, count=count)
    return Message(N_("read holding {address}+{count}"), address=address, count=count)


def write_words(address: int, value: int) -> Message:
    """The words of a write of ``value`` to holding register ``address``: write holding 3006=65476."""
    return Message(N_("write holding {address}={value}"), address=address, value=value)


# "read holding 3000+12", "write holding 3006=65476", "scan holding 103", "broadcast write holding 2000=8": the English
# a request is stored as (a Message's str), whatever language a page shows it in
_TARGET = re.compile(r"\b(holding|input) (\d+)(?:\+\d+|=(\d+))?")


def request_target(what: str) -> tuple[str, int | None, int | None]:
    """``(space, address, value written)`` named by a request text, or ``("", None, None)``."""
    m = _TARGET.search(what)
    if m is None:
        return "", None, None
    return m.group(1), int(m.group(2)), None if m.group(3) is None else int(m.group(3))


# pymodbus skips an RTU answer whose unit differs from the request ("... but got id=N, Skipping") and
# then times out, or raises ModbusIOException "... but received N"; either way the answer was sound.
_RECEIVED_UNIT = re.compile(r"(?:but received|but got id=)\s*(\d+)")


def _rtu_frame_length(data: bytes) -> int | None:
    """Length of the RTU answer starting at ``data[0]`` from its function code, or None if unknown."""
    if len(data) < 2:
        return None
    function = data[1]
    if function & 0x80:
        return 5  # unit, function | 0x80, exception code, CRC
    if function in (1, 2, 3, 4):
        return 5 + data[2] if len(data) > 2 else None  # unit, function, byte count, data, CRC
    if function in (5, 6, 15, 16):
        return 8  # unit, function, address, value/count, CRC
    return None


def foreign_unit(received: bytes, unit: int) -> int | None:
    """The unit address of a well-formed (CRC-correct) answer in ``received`` that is not ``unit``."""
    for start in range(len(received)):
        length = _rtu_frame_length(received[start:])
        if length is None or start + length > len(received):
            continue
        frame = received[start:start + length]
        if FramerRTU.check_CRC(frame[:-2], frame[-2] << 8 | frame[-1]) and frame[0] != unit:
            return frame[0]
    return None


class ModbusLine(LineBase):
    """A pymodbus async RTU client on one serial line; implements :class:`devices.transport.ModbusTransport`.

    :param options: the bus options of the plant file (port, baudrate, parity, ...)
    """

    BACKOFF_S = (0.5, 1.0, 2.0, 4.0, 8.0, 10.0)  # held from the start of an attempt

    def __init__(self, name: str, options: dict, state: BusState):
        super().__init__(name, options, state)
        self.lock = asyncio.Lock()
        self.client: AsyncModbusSerialClient | None = None
        self._tx: list[bytes] = []
        self._rx: list[bytes] = []
        self.address_conflicts: Counter[tuple[int, int]] = Counter()  # (unit asked, unit that answered) -> count
        self.conflicts_by_unit: Counter[int] = Counter()  # unit asked -> answers from another unit (per device)
        self._last_request: dict[tuple[int, str], float] = {}  # (unit, request) of a device's poll -> when last asked
        self._intervals: dict[tuple[int, str], deque] = {}  # (unit, request) -> recent intervals between its repeats
        self._medians: dict[tuple[int, str], float] = {}  # (unit, request) -> the median of its intervals
        self._forget_at = 0.0  # monotonic time of the next look for requests and units not asked for CYCLE_FORGET_S
        self._unit_seen: dict[int, float] = {}
        self.cycle_s: float | None = None  # measured time for one poll of every device on the line
        self.devices: dict[int, tuple[DeviceState, float]] = {}  # unit -> (state, its configured threshold)
        self._tool = asyncio.Lock()  # one request of an engineer's tool (generic poll) at a time
        self.tool_requests = 0
        self.state.cycle_s = None  # shown by the overview and the monitor (see _measure_cycle)
        self.state.address_conflicts = 0

    # -- connection ----------------------------------------------------------------
    def _trace(self, sending: bool, data: bytes) -> bytes:
        (self._tx if sending else self._rx).append(bytes(data))
        return data

    async def connect(self) -> bool:
        """Open the port; on failure remember the error and back off (0.5 s .. 10 s)."""
        if self.client is not None and self.client.connected:
            return True
        now = time.monotonic()
        if not self.backoff.ready(now):
            return False
        self.backoff.attempt(now)
        o = self.options
        if self.client is None:
            self.client = AsyncModbusSerialClient(
                port=o["port"],
                framer=FramerType.RTU,
                baudrate=o["baudrate"],
                bytesize=o.get("bytesize", 8),
                parity=o["parity"],
                stopbits=o["stopbits"],
                timeout=o["timeout"],
                retries=0,
                reconnect_delay=0,
                name=self.name,
                trace_packet=self._trace,
            )
        try:
            ok = await self.client.connect()
        except (ModbusException, OSError, ValueError) as exc:  # pyserial's SerialException is an OSError; bad options
            ok = False
            self.state.last_error = Message(N_("cannot open {port}: {error}"), port=o["port"], error=str(exc))
        if ok:
            if not self.state.connected:
                self.state.reconnects += 1
            self._opened()
            return True
        self._open_failed(self.state.last_error or Message(N_("cannot open {port}: check the cable/adapter and the port name"),
                                                           port=o["port"]), hold=False)
        self.client.close()
        self.client = None
        return False

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None
        self.state.connected = False

    # -- transactions ----------------------------------------------------------------
    async def transact(self, unit: int, what: str, counters: Counters | None, call, *, retries: int | None = None):
        """Run one pymodbus request ``call(client)`` with retries; return the response.

        Raises a :class:`LineError` subclass that says what went wrong.
        """
        retries = self.options.get("retries", 1) if retries is None else retries
        last_error: LineError | None = None
        for _attempt in range(retries + 1):
            try:
                return await self._once(unit, what, counters, call)
            except LineException:
                raise  # the device answered: repeating will not help
            except LineClosed:
                raise
            except LineError as exc:
                last_error = exc
        assert last_error is not None
        raise last_error

    async def _once(self, unit: int, what: str, counters: Counters | None, call):
        async with self.lock:
            if not await self.connect():
                raise LineClosed(Message(N_("line {name}: {error}"), name=self.name, error=self.state.last_error))
            assert self.client is not None
            self._tx.clear()
            self._rx.clear()
            if counters:
                counters.requests += 1
            start = time.perf_counter()
            error = ""
            response = None
            try:
                response = await call(self.client)
            except ConnectionException as exc:
                error = Message(N_("port lost: {error}"), error=str(exc))
                self.close()
                self.state.last_error = error
                failure: LineError = LineClosed(Message(N_("line {name}: {error}"), name=self.name, error=error))
            except (ModbusIOException, asyncio.TimeoutError) as exc:
                found = _RECEIVED_UNIT.search(str(exc))
                other = int(found.group(1)) if found else foreign_unit(b"".join(self._rx), unit)
                if other is not None and other != unit:
                    error = Message(N_("answer from unit {other}: address conflict on the line?"), other=other)
                    failure = LineError(_unit_said(unit, error))
                    self.address_conflicts[(unit, other)] += 1
                    self.conflicts_by_unit[unit] += 1
                    self.state.address_conflicts = sum(self.conflicts_by_unit.values())
                    if counters is not None:
                        counters.address_conflicts += 1
                elif self._rx:
                    error = Message(N_("CRC or framing error in the answer"))
                    failure = LineCrcError(_unit_said(unit, error))
                    if counters:
                        counters.crc_errors += 1
                else:
                    error = Message(N_("no answer within {timeout} s"), timeout=self.options["timeout"])
                    failure = LineTimeout(_unit_said(unit, error))
                    if counters:
                        counters.timeouts += 1
                log.debug("%s unit %s %s: %s", self.name, unit, what, exc)
            except ModbusException as exc:
                error = Message(N_("Modbus error: {error}"), error=str(exc))
                failure = LineError(_unit_said(unit, error))
                if counters:
                    counters.exceptions += 1
            rtt = (time.perf_counter() - start) * 1000
            if response is not None and response.isError():
                code = response.exception_code
                name = Message(EXCEPTION_NAMES.get(code, N_("unknown")))
                error = Message(N_("exception {code:#04x} ({name})"), code=code, name=name)
                failure = LineException(Message(N_("unit {unit}: {request}: {error}"), unit=unit, request=what, error=error), code)
                if counters:
                    counters.exceptions += 1
                    counters.responses += 1
            elif response is not None and counters:
                counters.responses += 1
            space, address, written = request_target(what)
            answered = response is not None and not error
            registers = response.registers if answered else None  # every pymodbus PDU has them ([] if none)
            if registers is not None:
                values = tuple(int(v) for v in registers)
            else:
                values = (written,) if written is not None and not error else ()
            self._record(what, " ".join(b.hex(" ") for b in self._tx), " ".join(b.hex(" ") for b in self._rx),
                         _describe(response) if answered else "", round(rtt, 2) if response is not None else None,
                         error, unit=unit, space=space, address=address, values=values)
            if counters is not None:
                self._measure_cycle(unit, what)
            if error:
                raise failure
            return response

    # -- cycle time and stale thresholds (issue 16 item 5) ------------------------------------
    def attach_device(self, unit: int, state: DeviceState) -> None:
        """Let the stale threshold of the device at ``unit`` follow the line's measured cycle time
        (never below the threshold it has from its poll period and timeout)."""
        self.devices[unit] = (state, state.stale_after)
        self._apply_thresholds(time.monotonic())

    def _measure_cycle(self, unit: int, what: str) -> None:
        """The line's cycle is the time of one poll round of its devices: the longest of their poll intervals.

        A device's poll asks the same requests once per round, but not all of them every round: an HD-Lock
        reads its settings only every few seconds (SETTINGS_PERIOD_S), and an engineer's write and its
        read-back come now and then. The interval between two asks of one request is therefore the poll
        interval only for the requests asked every round, the ones repeated most often: a device's poll
        interval is the shortest among its requests (each the median of its recent repeats, and at least the
        time since it was last asked, so that a request no longer asked does not count).
        """
        now = time.monotonic()
        key = (unit, what)
        last = self._last_request.get(key)
        self._last_request[key] = now
        if len(self._last_request) > 4096:  # bounded: drop the oldest requests
            for old in list(self._last_request)[:1024]:
                del self._last_request[old]
                self._intervals.pop(old, None)
                self._medians.pop(old, None)
        self._unit_seen[unit] = now
        if now >= self._forget_at:  # what is older than CYCLE_FORGET_S goes (the figures skip it meanwhile)
            self._forget_at = now + 1.0
            for old in [u for u, seen in self._unit_seen.items() if now - seen > CYCLE_FORGET_S]:
                self._unit_seen.pop(old, None)
            for old in [k for k in self._intervals if now - self._last_request.get(k, 0.0) > CYCLE_FORGET_S]:
                self._intervals.pop(old, None)
                self._medians.pop(old, None)
        if last is not None and now - last <= CYCLE_FORGET_S:
            intervals = self._intervals.get(key)
            if intervals is None:
                intervals = self._intervals[key] = deque(maxlen=CYCLE_SAMPLES)
            intervals.append(now - last)
            self._medians[key] = statistics.median(intervals)  # worked out when it changes, not at every look
            self.cycle_s = self._line_cycle(now)
            self.state.cycle_s = self.cycle_s
        self._apply_thresholds(now)

    def _poll_intervals(self, now: float) -> dict[int, float]:
        """unit -> its poll interval: the shortest interval among its requests (see _measure_cycle)."""
        shortest: dict[int, float] = {}
        seen, asked = self._unit_seen, self._last_request
        for (unit, what), median in self._medians.items():
            last = asked.get((unit, what), now)
            if unit not in seen or now - seen[unit] > CYCLE_FORGET_S or now - last > CYCLE_FORGET_S:
                continue
            interval = max(median, now - last)
            if interval < shortest.get(unit, float("inf")):
                shortest[unit] = interval
        return shortest

    def _line_cycle(self, now: float) -> float | None:
        intervals = self._poll_intervals(now)
        return round(max(intervals.values()), 3) if intervals else None

    def cycle_lower_bound(self, now: float | None = None) -> float:
        """The cycle in progress is at least as long as the time since the least recently asked device
        was asked (this covers the first cycle, before any interval was measured)."""
        now = time.monotonic() if now is None else now
        return max((now - seen for seen in self._unit_seen.values() if now - seen <= CYCLE_FORGET_S), default=0.0)

    def _apply_thresholds(self, now: float) -> None:
        cycle = max(self.cycle_s or 0.0, self.cycle_lower_bound(now)) or None
        for state, floor in self.devices.values():
            state.stale_after = max(floor, stale_threshold(cycle))

    def conflicts(self, unit: int) -> int:
        """Answers from another unit address while ``unit`` was asked (an address conflict on the line?)."""
        return self.conflicts_by_unit[unit]

    # -- an engineer's tool (generic Modbus poll) ---------------------------------------------------
    async def tool_request(self, unit: int, what: str, call):
        """Run one request of an engineer's tool in the line's own queue, between the devices' polls.

        At most one tool request waits for the line at a time, and the line's lock hands the line over
        in arrival order, so a device transaction that waits runs before the tool's next request: the
        devices' polls are never starved. Not repeated on failure (a write is never repeated blindly).
        """
        async with self._tool:
            self.tool_requests += 1
            return await self.transact(unit, what, None, call, retries=0)

    async def read_holding(self, unit: int, address: int, count: int, counters: Counters | None = None) -> list[int]:
        rr = await self.transact(
            unit, read_words("holding", address, count), counters,
            lambda c: c.read_holding_registers(address, count=count, device_id=unit),
        )
        return list(rr.registers)

    async def read_input(self, unit: int, address: int, count: int, counters: Counters | None = None) -> list[int]:
        rr = await self.transact(
            unit, read_words("input", address, count), counters,
            lambda c: c.read_input_registers(address, count=count, device_id=unit),
        )
        return list(rr.registers)

    async def write_register(self, unit: int, address: int, value: int, counters: Counters | None = None) -> None:
        await self.transact(
            unit, write_words(address, value), counters,
            lambda c: c.write_register(address, value, device_id=unit),
            retries=0,  # a write is not repeated blindly; the caller reads back instead
        )


def _unit_said(unit: int, error: Message) -> Message:
    """A diagnosis of a transaction with the unit asked: ``unit 3: no answer within 0.5 s``."""
    return Message(N_("unit {unit}: {error}"), unit=unit, error=error)


def _describe(response) -> str:
    return f"{type(response).__name__.replace('Response', '')}: {list(response.registers)}"  # every PDU has them ([] if none)
