"""What an adapter may call on a transport, and the errors a transport raises.

The bus worker (``app/``) owns every transport: ``app.modbus_line.ModbusLine`` implements
:class:`ModbusTransport` and raises the :class:`LineError` family below, ``app.can_bus.CanBus``
implements :class:`CanTransport`. Adapters are handed their transport (pass the bus in) and
type against these protocols, so ``devices/`` never imports ``app/``. Pure declarations: no I/O.

``app.serial_line.SerialLine`` (point-to-point RS232, SCU) is described by :class:`SerialTransport`;
its errors are declared here for it to raise (see the Serial errors below). Both families derive
from :class:`TransportError`, and their timeouts and closed-port errors from :class:`TransportTimeout`
and :class:`TransportClosed`, so code that handles any line's failure catches those.
"""

from __future__ import annotations

from devices.errors import DeviceError

from collections.abc import Awaitable, Callable, Mapping
from typing import Any, Protocol, runtime_checkable

from devices.live import Counters

# -- what every line raises ----------------------------------------------------------------


class TransportError(DeviceError):
    """A request on a line that did not give a usable answer; ``kind`` says why (for the counters)."""

    kind = "error"


class TransportTimeout(TransportError):
    """No (complete) answer in time."""

    kind = "timeout"


class TransportClosed(TransportError):
    """The port or connection is not open (cannot be opened, unplugged, lost)."""

    kind = "closed"


# -- Modbus RTU line ------------------------------------------------------------------------


class LineError(TransportError):
    """A transaction that did not give a usable answer."""


class LineTimeout(LineError, TransportTimeout):
    pass


class LineCrcError(LineError):
    kind = "crc"


class LineException(LineError):
    """The device answered with a Modbus exception."""

    kind = "exception"

    def __init__(self, message: str, code: int):
        super().__init__(message)
        self.code = code


class LineClosed(LineError, TransportClosed):
    """The port could not be opened or was lost."""


@runtime_checkable
class ModbusTransport(Protocol):
    """One Modbus RTU line shared by the devices on it; every call raises a :class:`LineError` on failure.

    Register values are unsigned 16-bit words; ``counters`` (the device's) are counted by the line.
    """

    name: str

    async def read_holding(self, unit: int, address: int, count: int, counters: Counters | None = None) -> list[int]: ...

    async def read_input(self, unit: int, address: int, count: int, counters: Counters | None = None) -> list[int]: ...

    async def write_register(self, unit: int, address: int, value: int, counters: Counters | None = None) -> None: ...

    async def transact(self, unit: int, what: str, counters: Counters | None,
                       call: Callable[[Any], Awaitable[Any]], *, retries: int | None = None) -> Any:
        """Run ``call(client)`` on the line's Modbus client, holding the line; ``what`` names it in the monitor
        (``"read holding 3000+12"``, ``"broadcast write holding 2000=8"``)."""
        ...


# -- CAN bus --------------------------------------------------------------------------------


class CanFrame(Protocol):
    """A received frame as handlers get it (a ``can.Message``): ``is_rx`` is False for a frame of this
    tool's own that the interface handed back."""

    arbitration_id: int
    is_extended_id: bool
    data: bytearray
    timestamp: float
    is_rx: bool


class TransportStatus(Protocol):
    """What an adapter may read of a transport's state (to say why a command cannot go out)."""

    connected: bool
    last_error: str
    reconnects: int


FrameHandler = Callable[[Any], None]  # called on the event loop with a CanFrame


@runtime_checkable
class CanTransport(Protocol):
    """One CAN bus shared by every adapter on it. Handlers run on the event loop and must not block."""

    name: str
    options: Mapping[str, Any]  # the plant file's bus options (bitrate, timeout, ...)
    state: TransportStatus

    def subscribe(self, is_extended: bool, arbitration_id: int, handler: FrameHandler) -> None: ...

    def unsubscribe(self, is_extended: bool, arbitration_id: int, handler: FrameHandler) -> None: ...

    def send(self, arbitration_id: int, data: bytes, is_extended_id: bool = False) -> bool:
        """Send one frame; False when the bus is not open or refused it."""
        ...

    def start_cyclic(self, key: str, period_s: float, make: Callable[[], tuple[int, bytes, bool] | None]) -> None:
        """Send ``make()`` every ``period_s`` until :meth:`stop_cyclic` (``None``: skip this period)."""
        ...

    def start_periodic(self, key: str, period_s: float, arbitration_id: int, data: bytes, is_extended_id: bool = False, *,
                       lease: Any = None, stop_form: Callable[[bytes], bytes] | None = None,
                       on_lapse: Callable[[float], None] | None = None) -> None:
        """Send ``data`` every ``period_s`` on a clock that does not depend on the event loop; while
        ``lease`` (devices/lease.py) is not valid only ``stop_form(data)`` leaves."""
        ...

    def modify_periodic(self, key: str, data: bytes, *, send_now: bool = False) -> bool:
        """New contents from the next period on; ``send_now``: also once at once."""
        ...

    def stop_cyclic(self, key: str) -> None: ...

    def cyclic_running(self, key: str) -> bool: ...


# -- LogiTed line (MO 64): TCP to one barrier, or a multi-master RS485 line ------------------


@runtime_checkable
class TelegramLine(Protocol):
    """A LogiTed line: one request and the first telegram ``answers`` accepts at a time; raises a
    :class:`SerialLineError` on failure. The adapter hooks itself in through the three lists and slots."""

    name: str
    options: Mapping[str, Any]
    state: TransportStatus
    listeners: list[Callable[[bytes], None]]  # given every telegram that answers no request
    closing: list[Callable[[], list[bytes]]]  # frames to send first as the line closes for good
    describe: Callable[[bytes], str] | None  # the adapter's decoding of a telegram, for the line's log

    async def transact(self, request: bytes, answers: Callable[[bytes], bool], *, timeout: float | None = None,
                       describe: str = "", interim: Callable[[bytes], bool] | None = None,
                       interim_timeout: float = 5.0) -> bytes: ...


@runtime_checkable
class TelegramTcpLine(TelegramLine, Protocol):
    """The TCP connection to one barrier, which serves one client at a time: it can be given up to another."""

    released: bool  # given up on request until :meth:`resume`
    connected: bool

    def release(self) -> None: ...

    def resume(self) -> None: ...


# -- point-to-point serial line -------------------------------------------------------------


class SerialLineError(TransportError):
    """A serial request that did not give a usable answer."""


class SerialTimeout(SerialLineError, TransportTimeout):
    pass


class SerialClosed(SerialLineError, TransportClosed):
    """The port is not open (cannot be opened, unplugged)."""


# ``complete(buffer)`` -> total length of the answer once it can be told, else None (read more)
Completion = Callable[[bytes], "int | None"]


@runtime_checkable
class SerialTransport(Protocol):
    """One serial port owned by the worker; one request and its answer at a time."""

    name: str
    options: Mapping[str, Any]
    state: TransportStatus

    async def transact(self, request: bytes, complete: Completion, *, timeout: float | None = None,
                       describe: str = "", decode: Callable[[bytes], str] | None = None) -> bytes:
        """Send ``request`` and return the complete answer; raises a :class:`SerialLineError` on failure."""
        ...

    async def flush_input(self, quiet_s: float = 0.03, limit_s: float = 0.3) -> int:
        """Drop what the line still holds until it has been quiet ``quiet_s`` (at most ``limit_s``); the bytes dropped."""
        ...

    async def wake(self, duration_s: float = 0.15) -> None:
        """Hold the transmit line at space for ``duration_s`` (a low-power unit's wake-up)."""
        ...
