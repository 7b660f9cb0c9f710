"""A generic Modbus poll on one RTU line, in the manner of Modbus Poll: several poll windows at once.

Each window (:class:`ModbusPoll`) has its own unit address, function 01/02/03/04, start address, count and period; the answer shown as
unsigned, signed, hex, binary and, over two registers, 32-bit integers and floats in both word
orders. Requests run through the line owner (:meth:`app.modbus_line.ModbusLine.tool_request`),
between the devices' polls; the windows of a page (:class:`PollWindows`) take turns there, one request
each in the order they asked (the line hands its tool slot over first come, first served), and a window
whose unit does not answer waits longer between tries (up to :data:`BACKOFF_MAX_S`), so a silent unit
costs the others at most one timeout per round. Writes (06 single, 16 multiple) are engineer only, audited through
the worker, refused for a known device's registers that are not writable (RO, MFR, never
written, not in its register map) and confirmed when they hit a known device's register.

Addresses here are protocol addresses (0-based, as sent on the wire); the page shows them
0- or 1-based as the engineer chooses and says which.
"""

from __future__ import annotations

import asyncio
import logging
import struct
import time
from dataclasses import dataclass, field

from app.i18n import N_
from app.message import Message, message_of
from app.modbus_line import LineError, ModbusLine, write_words
from devices.errors import CommissionError
from devices.params import Param
from devices.registry import DEVICE_TYPES
from devices.sendpolicy import ModbusMessage, Verdict, check_modbus
from devices.transport import LineClosed, LineCrcError, LineTimeout

log = logging.getLogger(__name__)

FUNCTION_NAMES = {1: N_("Read Coils"), 2: N_("Read Discrete Inputs"), 3: N_("Read Holding Registers"), 4: N_("Read Input Registers")}
FUNCTIONS = {code: f"{code:02d} {name}" for code, name in FUNCTION_NAMES.items()}
SPACES = {3: "holding", 4: "input"}  # the register spaces of the parameter models
MAX_REGISTERS = 125  # Modbus application protocol 6.3/6.4: 1..125 registers per read
MAX_BITS = 2000  # 6.1/6.2: 1..2000 coils or inputs per read
MAX_WRITE_REGISTERS = 123  # 6.12: 1..123 registers per Write Multiple Registers
PERIOD_MIN_S = 0.2  # the line is shared with the devices' polls
PERIOD_MAX_S = 60.0
UNIT_MIN, UNIT_MAX = 0, 254  # 0: broadcast read (an HD-Lock answers it, SPEC-NOTES); writes need 1..254
FORMATS = ("unsigned", "signed", "hex", "binary")
WORD_ORDERS = {"ABCD": "high word first", "CDAB": "low word first", "BADC": "high word first, bytes swapped",
               "DCBA": "low word first, bytes swapped"}
ADDRESS_MAX = 0xFFFF  # register and coil addresses 0..65535
MAX_WRITE_COILS = 1968  # 6.11: 1..0x7B0 coils per write multiple coils
MAX_WINDOWS = 8  # poll windows of one page: each adds a request per period to the line
BACKOFF_MAX_S = 5.0  # a window whose unit stays silent tries again at most this far apart


def count_range(function: int) -> tuple[int, int]:
    """How many values one read of ``function`` may ask for: 01/02 1..2000 bits, 03/04 1..125 registers
    (Modbus application protocol 6.1-6.4)."""
    return 1, MAX_BITS if function in (1, 2) else MAX_REGISTERS


class PollError(CommissionError, ValueError):
    """An entry that cannot be polled or written, or a write refused before anything was sent."""


class NeedsConfirmation(PollError):
    """A write to a known device's register: ask the engineer first."""


@dataclass(frozen=True)
class PollSpec:
    unit: int
    function: int
    address: int  # protocol address (0-based)
    count: int
    period_s: float = 1.0

    def check(self) -> PollSpec:
        if not UNIT_MIN <= self.unit <= UNIT_MAX:
            raise PollError(Message(N_("unit address {unit} is outside {low}..{high}"), unit=self.unit, low=UNIT_MIN, high=UNIT_MAX))
        if self.function not in FUNCTIONS:
            raise PollError(Message(N_("function {function:02d} is not one of 01, 02, 03, 04"), function=self.function))
        low, limit = count_range(self.function)
        if not low <= self.count <= limit:
            raise PollError(Message(N_("count {count} is outside {low}..{limit} for function {function:02d} ({name})"),
                                    count=self.count, low=low, limit=limit, function=self.function,
                                    name=Message(FUNCTION_NAMES[self.function])))
        if not 0 <= self.address <= 0xFFFF or self.address + self.count > 0x10000:
            raise PollError(addresses_refused(self.address, self.count))
        if not PERIOD_MIN_S <= self.period_s <= PERIOD_MAX_S:
            raise PollError(Message(N_("poll period {period} s is outside {low}..{high:g} s"), period=self.period_s,
                                    low=PERIOD_MIN_S, high=PERIOD_MAX_S))
        return self


# -- formats ----------------------------------------------------------------------------------


def to_signed(raw: int) -> int:
    return raw - 0x10000 if raw & 0x8000 else raw


def pair_u32(first: int, second: int, order: str) -> int:
    """Two registers (``first`` at the lower address) as uint32; ABCD = high word first, CDAB = low word
    first, BADC and DCBA the same with the bytes of each word swapped."""
    high, low = (first, second) if order in ("ABCD", "BADC") else (second, first)
    if order in ("BADC", "DCBA"):  # the two bytes of each word swapped
        high, low = (_swap(high), _swap(low))
    return (high & 0xFFFF) << 16 | (low & 0xFFFF)


def _swap(word: int) -> int:
    return (word & 0xFF) << 8 | (word >> 8 & 0xFF)


def pair_i32(first: int, second: int, order: str) -> int:
    value = pair_u32(first, second, order)
    return value - (1 << 32) if value & 0x80000000 else value


def pair_f32(first: int, second: int, order: str) -> float:
    return struct.unpack(">f", pair_u32(first, second, order).to_bytes(4, "big"))[0]


def format_register(raw: int, fmt: str) -> str:
    raw &= 0xFFFF
    if fmt == "unsigned":
        return str(raw)
    if fmt == "signed":
        return str(to_signed(raw))
    if fmt == "hex":
        return f"0x{raw:04X}"
    if fmt == "binary":
        return f"{raw >> 8:08b} {raw & 0xFF:08b}"
    raise ValueError(fmt)


def format_float(value: float) -> str:
    return f"{value:.7g}"


@dataclass
class Row:
    """One register (or coil) of the answer as the page shows it."""

    address: int
    raw: int
    name: str = ""
    cells: dict[str, str] = field(default_factory=dict)


def rows_for(spec: PollSpec, values: list[int], names: dict[int, str] | None = None) -> list[Row]:
    """Every format of every value; the 32-bit columns on the first register of each pair (offset 0, 2, ...)."""
    names = names or {}
    rows = []
    for offset, raw in enumerate(values):
        address = spec.address + offset
        row = Row(address, int(raw), names.get(address, ""))
        if spec.function in (1, 2):
            row.cells = {"unsigned": str(int(bool(raw)))}
        else:
            row.cells = {fmt: format_register(raw, fmt) for fmt in FORMATS}
            if offset % 2 == 0 and offset + 1 < len(values):
                nxt = values[offset + 1]
                for order in WORD_ORDERS:
                    row.cells[f"u32 {order}"] = str(pair_u32(raw, nxt, order))
                    row.cells[f"i32 {order}"] = str(pair_i32(raw, nxt, order))
                    row.cells[f"f32 {order}"] = format_float(pair_f32(raw, nxt, order))
        rows.append(row)
    return rows


# -- known devices ---------------------------------------------------------------------------------


def known_device(plant, bus: str, unit: int):
    """The plant's device at ``unit`` on the line, or None."""
    return next((d for d in plant.devices_on(bus) if d.options.get("address") == unit), None)


def _param_at(params, space: str, address: int) -> tuple[Param | None, int]:
    """The parameter covering ``address`` and the word index within it."""
    param = params.get(space, address)
    if param is not None:
        return param, 0
    for p in params.space(space):
        if address in p.addresses:
            return p, address - p.address
    return None, 0


def register_names(plant, bus: str, unit: int, function: int, address: int, count: int) -> dict[int, str]:
    """Names from the parameter model of the known device at ``unit`` (registers only)."""
    dev = known_device(plant, bus, unit)
    space = SPACES.get(function)
    if dev is None or space is None:
        return {}
    params = DEVICE_TYPES[dev.type].params
    if params is None:
        return {}
    names = {}
    for a in range(address, address + count):
        p, word = _param_at(params, space, a)
        if p is not None:
            name = p.label or p.name
            names[a] = f"{dev.name}: {name}" + (f" (word {word + 1} of {p.words})" if p.words > 1 else "")
    return names


def write_verdict(plant, bus: str, unit: int, address: int, values: list[int], function: int = 6) -> Verdict:
    """The send policy's verdict on a write (:func:`devices.sendpolicy.check_modbus`), after the protocol's limits.

    :raises PollError: outside what Modbus allows (unit, count, addresses, 16-bit values)
    """
    if not 1 <= unit <= UNIT_MAX:
        raise PollError(one_unit_refused(unit))
    if not 1 <= len(values) <= MAX_WRITE_REGISTERS:
        raise PollError(Message(N_("1..{limit} registers per write, not {n}"), limit=MAX_WRITE_REGISTERS, n=len(values)))
    if not 0 <= address <= 0xFFFF or address + len(values) > 0x10000:
        raise PollError(addresses_refused(address, len(values)))
    for v in values:
        if not -0x8000 <= v <= 0xFFFF:
            raise PollError(Message(N_("{value} does not fit a 16-bit register (-32768..65535)"), value=v))
    return check_modbus(plant.devices_on(bus), ModbusMessage(unit, function, address, tuple(v & 0xFFFF for v in values)))


def check_write(plant, bus: str, unit: int, address: int, values: list[int], function: int = 6,
                verdict: Verdict | None = None) -> str:
    """Refuse (raise :class:`PollError`) or return the confirmation text a write needs ("" if none).

    What a unit's device type never takes (RO, MFR, never written, not in its register map, firmware
    update, factory reset) is refused by name; a unit that is not in the plant file is checked by the
    type of the line's devices, and a unit of no known type asks before every write (the send policy).
    ``verdict``: the write's :func:`write_verdict`, where the caller has it already.
    """
    verdict = verdict or write_verdict(plant, bus, unit, address, values, function)
    if verdict.refused:
        raise PollError(unit_refused(unit, verdict.refused))
    dev = known_device(plant, bus, unit)
    if dev is None and not verdict.confirm:
        return ""
    what = verdict.name or Message(N_("unit {unit} holding {address}"), unit=unit, address=address)
    if dev is not None and dev.name not in verdict.name:
        head = Message(N_("This writes {what} of {device} ({type})"), what=what, device=dev.name, type=dev.type)
    else:
        head = Message(N_("This writes {what}"), what=what)
    return write_question(head, verdict)


def write_question(head: Message, verdict: Verdict) -> Message:
    """``head`` (what a write writes), the risks the send policy names (each once), and the question."""
    if verdict.confirm:
        return Message(N_("{head}. {risks} Write?"), head=head, risks=verdict.question)
    return Message(N_("{head}. Write?"), head=head)


def unit_refused(unit: int, refusal: str) -> Message:
    """The send policy's ``refusal`` of a write to ``unit``."""
    return Message(N_("unit {unit}: {refusal}"), unit=unit, refusal=refusal)


def one_unit_refused(unit: int) -> Message:
    """A write to ``unit`` that is no single unit (0 is the broadcast, which answers nothing)."""
    return Message(N_("writes go to one unit (1..{high}), not {unit}"), high=UNIT_MAX, unit=unit)


def addresses_refused(address: int, count: int) -> Message:
    """``count`` registers from ``address`` on that run past the last address."""
    return Message(N_("addresses {first}..{last} do not fit 0..65535"), first=address, last=address + count - 1)


# -- the poll ----------------------------------------------------------------------------------------


@dataclass
class PollResult:
    time: float
    values: list[int]
    error: str = ""
    rtt_ms: float | None = None


async def read_once(line: ModbusLine, spec: PollSpec) -> list[int]:
    """One read through the line owner; raises :class:`LineError` on failure."""
    spec.check()
    unit, a, n = spec.unit, spec.address, spec.count
    calls = {  # the request's words in the line's log: the English stored, the monitor's language shown
        1: (N_("poll coils {address}+{count}"), lambda c: c.read_coils(a, count=n, device_id=unit)),
        2: (N_("poll discrete inputs {address}+{count}"), lambda c: c.read_discrete_inputs(a, count=n, device_id=unit)),
        3: (N_("poll holding {address}+{count}"), lambda c: c.read_holding_registers(a, count=n, device_id=unit)),
        4: (N_("poll input {address}+{count}"), lambda c: c.read_input_registers(a, count=n, device_id=unit)),
    }
    words, call = calls[spec.function]
    response = await line.tool_request(unit, Message(words, address=a, count=n), call)
    if spec.function in (1, 2):
        return [int(bool(b)) for b in list(response.bits)[:n]]
    return [int(v) & 0xFFFF for v in response.registers]


class ModbusPoll:
    """One poll window: its request, the last answer, counts (polls, errors, of them timeouts), the loop task."""

    def __init__(self, worker, bus: str, number: int = 1):
        line = worker.lines.get(bus)
        if not isinstance(line, ModbusLine):
            raise KeyError(f"{bus} is not a Modbus RTU line")
        self.worker = worker
        self.bus = bus
        self.line = line
        self.number = number  # the window's number on its page ("Window 2")
        self.spec: PollSpec | None = None
        self.last: PollResult | None = None
        self.last_answer: float | None = None  # time.time() of the last good answer: the table's age
        self.polls = 0
        self.errors = 0
        self.timeouts = 0  # errors where the unit did not answer at all
        self.crc_errors = 0
        self.silent = 0  # unanswered polls in a row (the backoff)
        self.listeners: list = []  # called with no arguments after every poll (a page shows the answer at once)
        self._task: asyncio.Task | None = None

    @property
    def running(self) -> bool:
        return self._task is not None and not self._task.done()

    def start(self, spec: PollSpec) -> None:
        """Poll ``spec`` every ``period_s`` (reads change nothing: any role may poll)."""
        self.stop()
        self.spec = spec.check()
        self.polls = self.errors = self.timeouts = self.crc_errors = self.silent = 0
        self.last = None
        self.last_answer = None
        self._task = asyncio.get_running_loop().create_task(self._run(self.spec), name=f"modbus poll {self.bus}")

    def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            self._task = None

    def interval_s(self, spec: PollSpec) -> float:
        """Start to start of two polls: the period, doubled for every unanswered poll in a row (at most
        :data:`BACKOFF_MAX_S`, never below the period), back to the period with the first answer."""
        if not self.silent:
            return spec.period_s
        return max(spec.period_s, min(spec.period_s * 2 ** self.silent, BACKOFF_MAX_S))

    async def _run(self, spec: PollSpec) -> None:
        loop = asyncio.get_running_loop()
        while True:
            started = loop.time()
            await self.poll_once(spec)
            await asyncio.sleep(max(0.0, self.interval_s(spec) - (loop.time() - started)))

    async def poll_once(self, spec: PollSpec) -> PollResult:
        start = time.perf_counter()
        try:
            values = await read_once(self.line, spec)
            result = PollResult(time.time(), values, rtt_ms=round((time.perf_counter() - start) * 1000, 1))
            self.silent = 0
            self.last_answer = result.time
        except LineError as exc:
            self.errors += 1
            if isinstance(exc, (LineTimeout, LineClosed)):
                self.timeouts += isinstance(exc, LineTimeout)
                self.silent += 1
            else:
                self.silent = 0  # the unit answered (an exception, a bad CRC): no reason to wait longer
                self.crc_errors += isinstance(exc, LineCrcError)
            result = PollResult(time.time(), self.last.values if self.last else [], error=message_of(exc))
        except CommissionError as exc:  # a refused request is shown, never ends the page
            self.errors += 1
            log.debug("%s poll: %s", self.bus, exc)
            result = PollResult(time.time(), self.last.values if self.last else [], error=f"{type(exc).__name__}: {exc}")
        self.polls += 1
        self.last = result
        for listener in list(self.listeners):
            try:
                listener()
            except Exception:  # a page's listener (one that went away, or its bug) must not end the poll loop
                log.exception("%s poll window %s: listener failed", self.bus, self.number)
        return result

    def rows(self) -> list[Row]:
        if self.spec is None or self.last is None:
            return []
        names = register_names(self.worker.plant, self.bus, self.spec.unit, self.spec.function, self.spec.address,
                               len(self.last.values))
        return rows_for(self.spec, self.last.values, names)

    async def write(self, unit: int, address: int, values: list[int], *, user: str, role: str,
                    confirmed: bool = False, multiple: bool | None = None) -> str:
        """Function 06 (one register) or 16 (several, or ``multiple``): checked, confirmed, audited.

        :raises NeedsConfirmation: a known device's register and ``confirmed`` is False
        """
        raws = [v & 0xFFFF for v in values]
        fc = 16 if (multiple if multiple is not None else len(values) > 1) else 6
        describe = (f"Modbus poll {self.bus}: write unit {unit} holding {address}"
                    + (f"+{len(values)}" if fc == 16 else "") + f" = {raws} (function {fc:02d})")
        try:
            verdict = write_verdict(self.worker.plant, self.bus, unit, address, values, fc)
        except PollError:
            verdict = None
        parameter = (verdict.name if verdict else "") or f"unit {unit} holding {address}"  # by name where the type knows it
        try:
            confirm = check_write(self.worker.plant, self.bus, unit, address, values, fc, verdict)
        except PollError as exc:
            await self.worker.gate.refused(device=self.bus, user=user, role=role, describe=describe, reason=str(exc),
                                           parameter=parameter, new=raws)
            raise
        if confirm and not confirmed:
            raise NeedsConfirmation(confirm)
        if fc == 6:
            words, call = write_words(address, raws[0]), lambda c: c.write_register(address, raws[0], device_id=unit)
        else:
            words, call = (Message(N_("write holding {address}+{count}"), address=address, count=len(raws)),
                           lambda c: c.write_registers(address, raws, device_id=unit))
        return await self._send(unit, describe, words, call, user=user, role=role, parameter=parameter, new=raws)

    async def _send(self, unit: int, describe: str, words: str, call, *, user: str, role: str, parameter: str, new) -> str:
        """Send one write the checks let through: an audited write of the unit's device (of the bus for an unknown unit)."""
        dev = known_device(self.worker.plant, self.bus, unit)

        async def do() -> str:
            await self.line.tool_request(unit, words, call)
            return ""

        await self.worker.gate.run(do, user=user, role=role, describe=describe, device=dev.name if dev else self.bus,
                                   parameter=parameter, new=new, kind="write")
        return describe


    async def write_coils(self, unit: int, address: int, bits: list[bool], *, user: str, role: str,
                          confirmed: bool = False) -> str:
        """Function 05 (one coil) or 15 (several): through the send policy like a register write, confirmed, audited.

        :raises PollError: refused by the unit's device type (e.g. a device without coils) or outside Modbus;
        :raises NeedsConfirmation: the policy names a risk and ``confirmed`` is False
        """
        states = [bool(b) for b in bits]
        fc = 5 if len(states) == 1 else 15
        describe = (f"Modbus poll {self.bus}: write unit {unit} coil {address}"
                    + (f"+{len(states)}" if fc == 15 else "") + f" = {[int(b) for b in states]} (function {fc:02d})")
        try:
            if not 1 <= unit <= UNIT_MAX:
                raise PollError(one_unit_refused(unit))
            if not 1 <= len(states) <= MAX_WRITE_COILS:
                raise PollError(Message(N_("1..{limit} coils per write, not {n}"), limit=MAX_WRITE_COILS, n=len(states)))
            if not 0 <= address <= ADDRESS_MAX or address + len(states) > ADDRESS_MAX + 1:
                raise PollError(Message(N_("coils {first}..{last} do not fit 0..{high}"), first=address,
                                        last=address + len(states) - 1, high=ADDRESS_MAX))
            verdict = check_modbus(self.worker.plant.devices_on(self.bus),
                                   ModbusMessage(unit, fc, address, tuple(int(b) for b in states)))
            if verdict.refused:
                raise PollError(unit_refused(unit, verdict.refused))
        except PollError as exc:
            await self.worker.gate.refused(device=self.bus, user=user, role=role, describe=describe, reason=str(exc),
                                           parameter=f"unit {unit} coil {address}", new=[int(b) for b in states])
            raise
        if verdict.confirm and not confirmed:
            what = verdict.name or Message(N_("unit {unit} coil {address}"), unit=unit, address=address)
            raise NeedsConfirmation(write_question(Message(N_("This writes {what}"), what=what), verdict))
        if fc == 5:
            words, call = (Message(N_("write coil {address}={value}"), address=address, value=int(states[0])),
                           lambda c: c.write_coil(address, states[0], device_id=unit))
        else:
            words, call = (Message(N_("write coils {address}+{count}"), address=address, count=len(states)),
                           lambda c: c.write_coils(address, states, device_id=unit))
        return await self._send(unit, describe, words, call, user=user, role=role,
                                parameter=verdict.name or f"unit {unit} coil {address}", new=[int(b) for b in states])


class PollWindows:
    """The poll windows of one page on one line, numbered 1, 2, ... as they were opened.

    Every window polls on its own clock; their requests meet in the line's tool slot
    (:meth:`app.modbus_line.ModbusLine.tool_request`), which takes them first come, first served between
    the devices' polls: with several windows due at once they go in turn, one request each.
    """

    def __init__(self, worker, bus: str):
        self.writer = ModbusPoll(worker, bus, 0)  # the page's writes (checked, confirmed, audited): no window's own
        self.worker = worker
        self.bus = bus
        self.windows: list[ModbusPoll] = []

    def add(self) -> ModbusPoll:
        """A new window (not polling yet), numbered after the highest one open.

        :raises PollError: :data:`MAX_WINDOWS` are open already
        """
        if len(self.windows) >= MAX_WINDOWS:
            raise PollError(Message(N_("at most {n} poll windows on one page: each adds its requests to the line"), n=MAX_WINDOWS))
        window = ModbusPoll(self.worker, self.bus, max((w.number for w in self.windows), default=0) + 1)
        self.windows.append(window)
        return window

    def remove(self, window: ModbusPoll) -> None:
        window.stop()
        if window in self.windows:
            self.windows.remove(window)

    def stop(self) -> None:
        for window in self.windows:
            window.stop()

    @property
    def running(self) -> int:
        return sum(w.running for w in self.windows)
