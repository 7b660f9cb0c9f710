"""MO 64 twin servers: simulated Bauer barrier controls (:mod:`devices.mo64.twin`) on LogiTed TCP and on an RS485 line.

Servers: :class:`Mo64TcpSim` (one barrier, one client at a time, chapter 3) and :class:`Mo64Rs485Sim`
(several barriers by bus address, and with ``shared = true`` a second master passing the token,
chapter 2.6, which records how long the tool held it).
"""

from __future__ import annotations

import asyncio
import logging
import math
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

from devices import simserver
from devices.mo64 import codec
from devices.mo64.twin import SIM_LOG_LIMIT, TRAVEL_S, Mo64Twin

log = logging.getLogger(__name__)

TICK_S = 0.02
TOKEN_HOLD_S = 0.05  # how long the second master keeps the token each round
TOKEN_LOST_S = 1.0  # the second master takes the token back when the tool did not pass it by then


# -- servers -----------------------------------------------------------------------------------------
def _twin_for(dev: Any, address: int | None = None) -> Mo64Twin:
    opts = dev.options
    return Mo64Twin(dev.name, address, int(opts.get("serial_number", 6400000 + (address or 1))),
                    float(opts.get("travel_s", TRAVEL_S)), refuse_queries=opts.get("refuse_queries", ()),
                    query_form=opts.get("query_form", "both"), refuse_selectors=opts.get("refuse_selectors", ()),
                    eeprom_write_s=opts.get("eeprom_write_s"))


def _ticker(twins: list[Mo64Twin]) -> simserver.Ticker:
    def step(dt_s: float, now: float) -> None:
        for twin in twins:
            twin.step(dt_s)

    def rest(now: float) -> float:
        return min(twin.rest() for twin in twins) if twins else math.inf

    return simserver.Ticker(step, TICK_S, rest)  # slow while no gate moves; a telegram wakes it (wake())


class Mo64TcpSim:
    """One MO 64 with the TCP module on the bus's host and port (chapter 3).

    The barrier serves one client at a time: a second client is closed at once while the first is
    connected (counted in :attr:`refused`).
    """

    def __init__(self, bus, devices):
        if len(devices) != 1:
            raise ValueError(f"LogiTed TCP bus {bus.name}: one MO 64 per connection ({len(devices)} configured)")
        dev = devices[0]
        self.bus = bus
        self.twin = _twin_for(dev)
        self.twins: dict[str, Mo64Twin] = {dev.name: self.twin}
        self.host = bus.options.get("host", "127.0.0.1")
        self.port = int(bus.options.get("port", codec.TCP_PORT))
        # chapter 3: the next client connects after the first one closed
        self.endpoint = simserver.TwinServer(f"the simulated MO 64 {bus.name}", self._serve, simserver.REFUSE)
        self._ticker = _ticker([self.twin])
        self.garbage = 0

    @property
    def connections(self) -> int:
        return self.endpoint.connections

    @property
    def refused(self) -> int:
        return self.endpoint.refused

    async def start(self) -> None:
        await self.endpoint.start(self.host, self.port)
        self._ticker.start(f"sim {self.bus.name}")

    def _push(self, telegram: bytes) -> None:
        for writer in self.endpoint.clients:
            if not writer.is_closing():
                writer.write(codec.encode_frame(telegram))

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        async def answer(item) -> None:
            if isinstance(item, codec.FrameError):
                self.garbage += 1
                return  # a telegram with a bad checksum is not answered
            self._ticker.wake()  # a command may move the gate: stepped up to now, then at TICK_S
            for delay, telegram in self.twin.handle(item):
                if delay:
                    await asyncio.sleep(delay)
                writer.write(codec.encode_frame(telegram))
                await writer.drain()

        self.twin.listeners.append(self._push)
        try:
            await simserver.serve_telegrams(reader, codec.FrameSplitter(codec.TCP), answer)
        finally:
            if self._push in self.twin.listeners:
                self.twin.listeners.remove(self._push)

    async def stop(self) -> None:
        self._ticker.stop()
        await self.endpoint.stop()


@dataclass
class TokenHold:
    """One time the tool held the token: from the token to it until its token onward."""

    given: float
    passed: float | None = None

    @property
    def held_s(self) -> float | None:
        return None if self.passed is None else self.passed - self.given


class Mo64Rs485Sim:
    """An RS485 line (38400 8N1) served on the TCP port of the bus's ``socket://`` URL.

    Several barriers, each answering only telegrams addressed to it (device option ``address``) and
    never a token telegram (chapter 2.6). Every frame on the line reaches every connected client
    (a bus). With ``shared = true`` a second master at ``next_master`` holds the token at start,
    passes it to the tool's ``master_address``, sometimes queries a barrier itself while it holds
    the token, and records each of the tool's holds in :attr:`holds` (the limit is 200 ms,
    chapter 2.6.1); telegrams the tool sends while it does not hold the token are counted in
    :attr:`sent_without_token`.
    """

    def __init__(self, bus, devices):
        self.bus = bus
        opts = bus.options
        self.master_address = int(opts.get("master_address", codec.RS485_LAYOUT.master_address))
        self.shared = bool(opts.get("shared", False))
        self.next_master = int(opts.get("next_master", self.master_address + 1))
        self.by_address: dict[int, Mo64Twin] = {}
        self.twins: dict[str, Mo64Twin] = {}
        for n, dev in enumerate(devices):
            address = int(dev.options.get("address", 0x10 + n))
            if address in self.by_address or address in (self.master_address, self.next_master):
                raise ValueError(f"RS485 bus {bus.name}: address {address} of {dev.name} is taken")
            twin = _twin_for(dev, address)
            self.by_address[address] = twin
            self.twins[dev.name] = twin
        self.endpoint = simserver.TwinServer(f"the simulated RS485 line {bus.name}", self._serve, simserver.SHARE)
        self._ticker = _ticker(list(self.by_address.values()))
        self._master_task: asyncio.Task | None = None
        self.tool_has_token = not self.shared
        self.holds: deque[TokenHold] = deque(maxlen=SIM_LOG_LIMIT)  # the demo plant runs for hours: bounded
        self.token_lost = 0
        self.sent_without_token = 0
        self.own_queries = 0
        self.own_answers: deque[bytes] = deque(maxlen=SIM_LOG_LIMIT)
        self.unaddressed = 0
        self.garbage = 0
        self.collisions = 0  # answers a barrier sent in another master's turn (see _answer)
        self._answering: set[asyncio.Task] = set()
        self._token_back = asyncio.Event()

    async def start(self) -> None:
        await self.endpoint.start(*simserver.host_port(self.bus.options["port"], "a simulated RS485 line"))
        self._ticker.start(f"sim {self.bus.name}")
        if self.shared:
            self._master_task = asyncio.create_task(self._second_master(), name=f"sim {self.bus.name} master")

    async def _put(self, raw: bytes, source: asyncio.StreamWriter | None = None) -> None:
        """Bytes on the line: every client but the one that sent them hears them."""
        for writer in list(self.endpoint.clients):
            if writer is source or writer.is_closing():
                continue
            writer.write(raw)
            try:
                await writer.drain()
            except ConnectionError:
                pass

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        async def on_line(item) -> None:
            if isinstance(item, codec.FrameError):
                self.garbage += 1
                return
            await self._put(item.raw, writer)
            await self._frame_from_client(item)

        await simserver.serve_telegrams(reader, codec.FrameSplitter(codec.RS485), on_line)

    async def _frame_from_client(self, frame: codec.Frame) -> None:
        if frame.is_token:
            if self.shared and frame.da == self.next_master and self.tool_has_token:
                self.tool_has_token = False
                if self.holds and self.holds[-1].passed is None:
                    self.holds[-1].passed = time.monotonic()
                self._token_back.set()
            return  # a slave ignores token telegrams (chapter 2.6)
        if not self.tool_has_token:
            self.sent_without_token += 1
        await self._to_barrier(frame)

    async def _to_barrier(self, frame: codec.Frame) -> None:
        twin = self.by_address.get(frame.da)
        if twin is None:
            self.unaddressed += 1
            return  # nobody answers a telegram addressed to nobody
        # the barrier answers on its own time while the line goes on (a token passed meanwhile is heard)
        self._ticker.wake()  # a command may move the gate: stepped up to now, then at TICK_S
        task = asyncio.create_task(self._answer(twin, frame, twin.handle(frame)))
        self._answering.add(task)
        task.add_done_callback(self._answering.discard)

    async def _answer(self, twin: Mo64Twin, frame: codec.Frame, answers: list[tuple[float, bytes]]) -> None:
        for delay, telegram in answers:
            await asyncio.sleep(delay or 0.002)
            raw = codec.encode_frame(telegram, codec.RS485, da=frame.sa, sa=twin.address)
            if self.shared and frame.sa == self.master_address and not self.tool_has_token:
                # the other master holds the token and may send at any moment of its turn: a slave's
                # answer in that turn collides with it (two stations at once); everyone hears garbage
                self.collisions += 1
                raw = raw[:-2] + bytes((raw[-2] ^ 0xFF, raw[-1] ^ 0xFF))
            await self._put(raw)

    async def _second_master(self) -> None:
        rounds = 0
        try:
            while True:
                await asyncio.sleep(TOKEN_HOLD_S)
                rounds += 1
                if rounds % 3 == 0 and self.by_address and self.endpoint.clients:
                    address = sorted(self.by_address)[(rounds // 3) % len(self.by_address)]
                    request = codec.encode_frame(codec.encode_query(codec.Q_GATE_STATE), codec.RS485,
                                                 da=address, sa=self.next_master)
                    self.own_queries += 1
                    await self._put(request)
                    self._ticker.wake()
                    answers = self.by_address[address].handle(codec.decode_frame(request, codec.RS485))
                    for delay, telegram in answers:
                        await asyncio.sleep(delay or 0.002)
                        raw = codec.encode_frame(telegram, codec.RS485, da=self.next_master, sa=address)
                        self.own_answers.append(raw)
                        await self._put(raw)
                if not self.endpoint.clients:
                    continue  # nobody to pass the token to
                self._token_back.clear()
                self.tool_has_token = True
                self.holds.append(TokenHold(time.monotonic()))
                await self._put(codec.encode_token(self.master_address, sa=self.next_master))
                try:
                    await asyncio.wait_for(self._token_back.wait(), TOKEN_LOST_S)
                except TimeoutError:
                    self.token_lost += 1  # the token is regenerated by the second master
                    self.tool_has_token = False
        except asyncio.CancelledError:
            pass

    @property
    def hold_times_s(self) -> list[float]:
        """How long the tool held the token each time it passed it on."""
        return [h.held_s for h in self.holds if h.held_s is not None]

    async def stop(self) -> None:
        self._ticker.stop()
        for task in list(self._answering):
            task.cancel()
        if self._master_task:
            self._master_task.cancel()
            self._master_task = None
        await self.endpoint.stop()


__all__ = ["Mo64Twin", "Mo64TcpSim", "Mo64Rs485Sim", "TokenHold"]
