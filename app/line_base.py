"""What the worker's request/answer lines share: the bus monitor's transaction record, reopening
after a failure with backoff, and the connection counters of the bus.

:class:`LineBase` is the base of :class:`app.modbus_line.ModbusLine` (pymodbus), :class:`app.serial_line.SerialLine`
(point-to-point RS232) and the LogiTed lines of :mod:`app.logited` (TCP and RS485). Each line keeps
its own port handling and request rules; here are only the parts that are the same for all of them:

* :class:`Transaction`: one line of the bus monitor's log, appended by :meth:`LineBase._record`;
* :class:`Backoff`: when a line that could not open (or was lost) may try again;
* :meth:`LineBase._opened` / :meth:`LineBase._open_failed`: ``BusState.connected``, ``last_error``
  and the backoff, kept together;
* :func:`serial_port`: the 8N1 pyserial port of the serial lines, and :func:`read_burst`, which a
  reader thread uses to take a telegram's bytes in one piece instead of one by one.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from app.state import BusState


@dataclass
class Transaction:
    """One request on a line (or a telegram on its own) as the bus monitor lists it.

    ``unit`` is the device address the line concerns (0: none). ``space``, ``address`` and ``values``
    are Modbus only: what the monitor decodes through the device's parameter model (the register
    space and first address asked, and the register values of the answer; for a write without one,
    the value written).
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


class _DecodedOnRead(Transaction):
    """A :class:`Transaction` whose ``decoded`` text is worked out when it is first read (the monitor, a
    recording, an export), not for every telegram of a line that nobody looks at: the decoding is a pure
    function of the telegram, so the text is the same whenever it is made."""

    @property
    def decoded(self) -> str:  # type: ignore[override]
        text = self.__dict__.get("_decoded")
        if text is None:
            try:
                text = self.__dict__["_decode"]()
            except Exception as exc:  # noqa: BLE001 - read lazily by the monitor, a recording or an export: whatever a
                # decoder raises is the entry's text there, never an error of the reader
                text = f"cannot decode: {exc}"
            self.__dict__["_decoded"] = text
        return text

    @decoded.setter
    def decoded(self, value) -> None:
        if callable(value):
            self.__dict__["_decode"], self.__dict__["_decoded"] = value, None
        else:
            self.__dict__["_decoded"] = value


class Backoff:
    """When a line may try to open again: after the n-th failure in a row it waits ``steps_s[n - 1]``
    (the last step repeats); a success starts over.

    :param steps_s: the waits in seconds, shortest first
    """

    def __init__(self, steps_s: tuple[float, ...]):
        self.steps_s = steps_s
        self.failures = 0
        self.next_try = 0.0  # time.monotonic() before which no attempt is made

    def ready(self, now: float | None = None) -> bool:
        return (time.monotonic() if now is None else now) >= self.next_try

    def _hold(self, now: float | None, failures: int) -> None:
        now = time.monotonic() if now is None else now
        self.next_try = now + self.steps_s[min(max(failures, 1), len(self.steps_s)) - 1]

    def attempt(self, now: float | None = None) -> None:
        """Hold the next attempt back from the start of this one, by the wait its failure would bring
        (for a line whose failures come from the attempt itself; then :meth:`failed` without a time)."""
        self._hold(now, self.failures + 1)

    def failed(self, now: float | None = None, *, hold: bool = True) -> None:
        """One more failure; the next attempt waits from ``now`` (``hold=False``: as :meth:`attempt` set it)."""
        self.failures += 1
        if hold:
            self._hold(now, self.failures)

    def lost(self, now: float | None = None) -> None:
        """An open line was lost: the next attempt after the first wait."""
        self.failures = 1
        self._hold(now, 1)

    def succeeded(self) -> int:
        """The line opened; the failures before it (0: none)."""
        failures, self.failures = self.failures, 0
        return failures

    def resume(self) -> None:
        """Try at once next time."""
        self.next_try = 0.0


# what a pyserial port's read, write or close raises when the port went away: its SerialException is an OSError;
# a port closed under a reader or writer thread fails with AttributeError or TypeError (its descriptor is None)
PORT_GONE: tuple[type[Exception], ...] = (OSError, AttributeError, TypeError)


def serial_port(options: dict):
    """An unopened pyserial port (device path or URL) for the plant file's ``port`` and ``baudrate``:
    8N1, reads that wait at most 50 ms, writes at most 1 s."""
    import serial  # pyserial only for the lines that use a serial port

    return serial.serial_for_url(options["port"], do_not_open=True, baudrate=options["baudrate"], bytesize=8,
                                 parity=serial.PARITY_NONE, stopbits=1, timeout=0.05, write_timeout=1.0)


class LineBase:
    """A line the bus worker owns: ``name``, the plant file's ``options``, its :class:`BusState` and its
    :class:`Backoff` (``BACKOFF_S``)."""

    BACKOFF_S: tuple[float, ...] = (0.5, 1.0, 2.0, 5.0)

    def __init__(self, name: str, options: dict, state: BusState):
        self.name = name
        self.options = options
        self.state = state
        self.backoff = Backoff(self.BACKOFF_S)

    def _opened(self) -> int:
        """The port or connection is open: connected, no error shown, the backoff starts over. Returns the
        failures before it (a line that counts reopenings counts one when there were any)."""
        self.state.connected = True
        self.state.last_error = ""
        return self.backoff.succeeded()

    def _open_failed(self, message: str, now: float | None = None, *, hold: bool = True) -> None:
        """The port could not be opened (or the connection was refused): say why and back off."""
        self.backoff.failed(now, hold=hold)
        self.state.connected = False
        self.state.last_error = message

    def _record(self, request: str, request_hex: str, response_hex: str, decoded: str | Callable[[], str],
                rtt_ms: float | None, error: str, *, unit: int = 0, **modbus) -> Transaction:
        """Append one line to the bus monitor's log (thread-safe: a deque append). ``decoded``: the text, or a
        function that makes it from the telegram alone, called when the line is first read."""
        kind = _DecodedOnRead if callable(decoded) else Transaction
        entry = kind(time.time(), unit, request, request_hex, response_hex, decoded, rtt_ms, error, **modbus)
        self.state.transactions.append(entry)
        return entry


def _counts_one_only(port) -> bool:
    """pyserial's ``socket://`` port (an RS485 or RS232 gateway on TCP) says 1 for ``in_waiting`` whatever it holds."""
    return type(port).__module__.endswith("protocol_socket")


def read_burst(port, limit: int = 4096) -> bytes:
    """The next bytes on ``port``: waits for the first one (at most the port's read timeout, then b""), then
    takes what else has arrived by then without waiting. One read per burst (a telegram), not one per byte:
    a reader thread hands the event loop one wake-up per telegram."""
    first = port.read(1)
    if not first:
        return b""
    if _counts_one_only(port):
        if not port.in_waiting:
            return first
        timeout = port.timeout
        port.timeout = 0  # a socket port's read then takes what the socket holds and returns (no waiting)
        try:
            return first + port.read(limit)
        finally:
            port.timeout = timeout
    waiting = port.in_waiting
    return first + port.read(min(waiting, limit)) if waiting else first
