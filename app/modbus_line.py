"""One Modbus RTU line (RS485 port or pyserial URL) owned by the bus worker.

Every transaction of every device on the line goes through :meth:`ModbusLine.transact`,
which serialises access, counts results per device, classifies failures (timeout,
CRC/framing, an answer from another unit address, Modbus exception, port lost) and keeps a
bounded transaction log.
"""

from __future__ import annotations

import asyncio
import logging
import re
import time
from collections import Counter
from dataclasses import dataclass

from pymodbus.client import AsyncModbusSerialClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException
from pymodbus.framer import FramerRTU, FramerType

from app.state import BusState, Counters
from devices.transport import LineClosed, LineCrcError, LineError, LineException, LineTimeout

__all__ = ["LineClosed", "LineCrcError", "LineError", "LineException", "LineTimeout", "ModbusLine", "Transaction",
           "request_target"]

log = logging.getLogger(__name__)

EXCEPTION_NAMES = {
    1: "illegal function",
    2: "illegal data address",
    3: "illegal data value",
    4: "device failure",
    5: "acknowledge",
    6: "device busy",
    10: "gateway path unavailable",
    11: "gateway target did not respond",
}


@dataclass
class Transaction:
    """One request on the line as the bus monitor lists it.

    ``space``, ``address`` and ``values`` carry what the monitor decodes through the device's
    parameter model: the register space and first address asked, and the register values of
    the answer (for a write without one, the value written).
    """

    time: float
    unit: int
    request: str
    request_hex: str
    response_hex: str
    decoded: str
    rtt_ms: float | None
    error: str
    space: str = ""
    address: int | None = None
    values: tuple[int, ...] = ()


# "read holding 3000+12", "write holding 3006=65476", "scan holding 103", "broadcast write holding 2000=8"
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


class ModbusLine:
    """A pymodbus async RTU client on one serial line; implements :class:`devices.transport.ModbusTransport`.

    :param options: the bus options of the plant file (port, baudrate, parity, ...)
    """

    def __init__(self, name: str, options: dict, state: BusState):
        self.name = name
        self.options = options
        self.state = state
        self.lock = asyncio.Lock()
        self.client: AsyncModbusSerialClient | None = None
        self._tx: list[bytes] = []
        self._rx: list[bytes] = []
        self._backoff = 0.5
        self._next_connect = 0.0
        self.address_conflicts: Counter[tuple[int, int]] = Counter()  # (unit asked, unit that answered) -> count

    # -- connection ----------------------------------------------------------------
    def _trace(self, sending: bool, data: bytes) -> bytes:
        (self._tx if sending else self._rx).append(bytes(data))
        return data

    async def connect(self) -> bool:
        """Open the port; on failure remember the error and back off (0.5 s .. 10 s)."""
        if self.client is not None and self.client.connected:
            return True
        now = time.monotonic()
        if now < self._next_connect:
            return False
        self._next_connect = now + self._backoff
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
        except Exception as exc:  # pyserial raises SerialException / OSError variants
            ok = False
            self.state.last_error = f"cannot open {o['port']}: {exc}"
        if ok:
            if not self.state.connected:
                self.state.reconnects += 1
            self.state.connected = True
            self.state.last_error = ""
            self._backoff = 0.5
            return True
        self.state.connected = False
        if not self.state.last_error:
            self.state.last_error = f"cannot open {o['port']}: check the cable/adapter and the port name"
        self._backoff = min(self._backoff * 2, 10.0)
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
                raise LineClosed(f"line {self.name}: {self.state.last_error}")
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
                error = f"port lost: {exc}"
                self.close()
                self.state.last_error = error
                failure: LineError = LineClosed(f"line {self.name}: {error}")
            except (ModbusIOException, asyncio.TimeoutError) as exc:
                found = _RECEIVED_UNIT.search(str(exc))
                other = int(found.group(1)) if found else foreign_unit(b"".join(self._rx), unit)
                if other is not None and other != unit:
                    error = f"answer from unit {other}: address conflict on the line?"
                    failure = LineError(f"unit {unit}: {error}")
                    self.address_conflicts[(unit, other)] += 1
                elif self._rx:
                    error = "CRC or framing error in the answer"
                    failure = LineCrcError(f"unit {unit}: {error}")
                    if counters:
                        counters.crc_errors += 1
                else:
                    error = f"no answer within {self.options['timeout']} s"
                    failure = LineTimeout(f"unit {unit}: {error}")
                    if counters:
                        counters.timeouts += 1
                log.debug("%s unit %s %s: %s", self.name, unit, what, exc)
            except ModbusException as exc:
                error = f"Modbus error: {exc}"
                failure = LineError(f"unit {unit}: {error}")
                if counters:
                    counters.exceptions += 1
            rtt = (time.perf_counter() - start) * 1000
            if response is not None and response.isError():
                code = getattr(response, "exception_code", 0)
                error = f"exception {code:#04x} ({EXCEPTION_NAMES.get(code, 'unknown')})"
                failure = LineException(f"unit {unit}: {what}: {error}", code)
                if counters:
                    counters.exceptions += 1
                    counters.responses += 1
            elif response is not None and counters:
                counters.responses += 1
            space, address, written = request_target(what)
            answered = response is not None and not error
            registers = getattr(response, "registers", None) if answered else None
            if registers is not None:
                values = tuple(int(v) for v in registers)
            else:
                values = (written,) if written is not None and not error else ()
            self.state.transactions.append(
                Transaction(
                    time=time.time(),
                    unit=unit,
                    request=what,
                    request_hex=" ".join(b.hex(" ") for b in self._tx),
                    response_hex=" ".join(b.hex(" ") for b in self._rx),
                    decoded=_describe(response) if answered else "",
                    rtt_ms=round(rtt, 2) if response is not None else None,
                    error=error,
                    space=space,
                    address=address,
                    values=values,
                )
            )
            if error:
                raise failure
            return response

    async def read_holding(self, unit: int, address: int, count: int, counters: Counters | None = None) -> list[int]:
        rr = await self.transact(
            unit, f"read holding {address}+{count}", counters,
            lambda c: c.read_holding_registers(address, count=count, device_id=unit),
        )
        return list(rr.registers)

    async def read_input(self, unit: int, address: int, count: int, counters: Counters | None = None) -> list[int]:
        rr = await self.transact(
            unit, f"read input {address}+{count}", counters,
            lambda c: c.read_input_registers(address, count=count, device_id=unit),
        )
        return list(rr.registers)

    async def write_register(self, unit: int, address: int, value: int, counters: Counters | None = None) -> None:
        await self.transact(
            unit, f"write holding {address}={value}", counters,
            lambda c: c.write_register(address, value, device_id=unit),
            retries=0,  # a write is not repeated blindly; the caller reads back instead
        )


def _describe(response) -> str:
    registers = getattr(response, "registers", None)
    if registers is not None:
        return f"{type(response).__name__.replace('Response', '')}: {list(registers)}"
    return type(response).__name__
