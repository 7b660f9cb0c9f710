"""The MO 64 twin over real TCP sockets, as a LogiTed client or an RS485 master would see it.

Requests and expected answers are raw frames; the golden frames of SPEC-NOTES and the checksums of
the expected answers come from ``binascii.crc_hqx(data, 0xFFFF)`` (chapter 2.3), not from the codec.
"""

from __future__ import annotations

import asyncio
import binascii
import socket
import time
from types import SimpleNamespace

import pytest

from conftest import wait_for
from webutil import eventually

from devices.mo64 import codec
from devices.mo64.sim import Mo64Rs485Sim, Mo64TcpSim
from devices.mo64.twin import EEPROM_WRITE_S

pytestmark = pytest.mark.timeout(30)


def h(text: str) -> bytes:
    return bytes.fromhex(text)


def seal(body: str | bytes) -> bytes:
    body = h(body) if isinstance(body, str) else body
    return body + binascii.crc_hqx(body, 0xFFFF).to_bytes(2, "big")


ACK, NAK, BUSY, SYN = seal("55 01 01"), seal("55 01 02"), seal("55 01 03"), seal("55 01 04")
Q_DEVICE, Q_STATUS, Q_GATE = h("55 02 02 00 45 BC"), h("55 02 02 02 65 FE"), h("55 02 02 07 35 5B")  # SPEC-NOTES
OPEN, CLOSE = h("55 03 01 01 00 B8 B4"), h("55 03 01 02 00 ED E7")  # SPEC-NOTES
Q_POSITION = seal("55 02 02 18")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Client:
    """One end of the connection: send raw frames, read whole frames (with a bound)."""

    def __init__(self, reader, writer, framing=codec.TCP, me: int = 0):
        self.reader, self.writer, self.me = reader, writer, me
        self.splitter = codec.FrameSplitter(framing)
        self.frames: list[codec.Frame] = []

    async def frame(self, timeout: float = 1.0, match=lambda f: True) -> codec.Frame | None:
        end = time.monotonic() + timeout
        while True:
            for i, f in enumerate(self.frames):
                if match(f):
                    return self.frames.pop(i)
            left = end - time.monotonic()
            if left <= 0:
                return None
            try:
                data = await asyncio.wait_for(self.reader.read(1024), left)
            except TimeoutError:
                return None
            if not data:
                return None
            self.frames += [f for f in self.splitter.feed(data) if isinstance(f, codec.Frame)]

    async def send(self, raw: bytes) -> None:
        self.writer.write(raw)
        await self.writer.drain()

    async def talk(self, raw: bytes, timeout: float = 1.0, types=None) -> bytes | None:
        """Send ``raw``; the first telegram to this client (of ``types`` if given), tokens skipped."""
        await self.send(raw)
        f = await self.frame(timeout, lambda f: not f.is_token and f.da in (None, self.me)
                             and (types is None or f.type in types))
        return None if f is None else f.raw

    async def query(self, index: int) -> codec.Answer:
        raw = await self.talk(codec.encode_frame(codec.encode_query(index)), types={index + 5})
        assert raw is not None, f"no answer to query 0x{index:02X}"
        return codec.decode_answer(raw)


@pytest.fixture
async def barrier():
    port = free_port()
    bus = SimpleNamespace(name="gate-tcp", type="logited-tcp", options={"host": "127.0.0.1", "port": port})
    dev = SimpleNamespace(name="gate1", type="mo64", bus="gate-tcp", options={"travel_s": 1.0})
    sim = Mo64TcpSim(bus, [dev])
    await sim.start()
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    try:
        yield sim, sim.twins["gate1"], Client(reader, writer)
    finally:
        writer.close()
        await sim.stop()


async def _is(value, *expected) -> bool:
    return await value in expected


async def _below(value, limit) -> bool:
    return await value < limit


# -- golden queries --------------------------------------------------------------------------------------
async def test_golden_queries_answered(barrier):
    sim, twin, client = barrier
    assert await client.talk(Q_DEVICE) == seal("55 03 05 05 00")  # 0x0005 = MO 64-V4 (chapter 5.1.5)
    assert await client.talk(Q_STATUS) == seal("55 06 07 00 00 00 00 00")
    assert await client.talk(Q_GATE) == seal("55 02 0C 05")  # closed
    assert await client.talk(Q_POSITION) == seal("55 02 1D 00")
    for index in codec.QUERY_INDEXES:  # every query is answered with its telegram type (index + 5)
        answer = await client.query(index)
        assert answer.type == index + 5 and answer.error is None, answer
    entry = codec.decode_answer(await client.talk(codec.encode_frame(codec.encode_query(0x12, 3))))
    assert entry.value == {"index": 3, "flags": 0, "timestamp_h": 0}
    vehicle = codec.decode_answer(await client.talk(seal("55 02 02 17")))
    assert vehicle.value == 0  # RAM only: 0 after power-up (chapter 5.2.5)


async def test_nak_for_forbidden_and_invalid(barrier):
    sim, twin, client = barrier
    for index in (0x1B, 0x1C, 0x1D, 0x1E, 0x1F, 0x40):
        assert await client.talk(seal(bytes((0x55, 0x02, 0x02, index)))) == NAK  # table 21
    assert await client.talk(seal("55 03 01 05 00")) == NAK  # unknown command
    assert await client.talk(seal("55 03 01 01 03")) == NAK  # function 3: "alle anderen sind ungültig"
    assert await client.talk(seal("55 04 04 09 01 00")) == NAK  # unknown setting selector
    assert await client.talk(seal("55 04 04 00 DD FF")) == NAK  # t_open 65501 > 65500
    assert await client.talk(seal("55 01 42")) == NAK  # unknown telegram type
    assert await client.talk(seal("55 02 03 00")) == NAK  # short command: no code is known
    assert twin.setting_writes == {}
    bad_crc = bytearray(Q_GATE)
    bad_crc[-1] ^= 0xFF
    assert await client.talk(bytes(bad_crc), timeout=0.3) is None  # no answer to a broken telegram
    assert await client.talk(Q_GATE) == seal("55 02 0C 05")


# -- motion ------------------------------------------------------------------------------------------------
async def test_open_pulse_opening_then_open_at_100(barrier):
    sim, twin, client = barrier
    assert await client.talk(OPEN) == ACK
    seen = []
    end = time.monotonic() + 5
    while time.monotonic() < end:
        state = (await client.query(codec.Q_GATE_STATE)).value
        seen.append(int(state))
        if state == codec.GateState.OPEN:
            break
        await asyncio.sleep(0.05)  # the next sample of the gate state
    assert seen[-1] == codec.GateState.OPEN
    order = [s for i, s in enumerate(seen) if i == 0 or seen[i - 1] != s]
    assert order == [codec.GateState.PREWARN_OPEN, codec.GateState.OPENING, codec.GateState.OPEN]
    assert await client.talk(Q_POSITION) == seal("55 02 1D 64")  # 100 %
    assert (await client.query(codec.Q_SERVICE_COUNTER)).value == 1
    assert list(twin.commands) == [("open", "pulse")]


async def test_light_barrier_reverses_close(barrier):
    sim, twin, client = barrier
    twin.gate, twin.position = codec.GateState.OPEN, 100.0
    assert await client.talk(CLOSE) == ACK

    async def gate_state():
        return (await client.query(codec.Q_GATE_STATE)).value

    async def position():
        return (await client.query(codec.Q_BARRIER_POSITION)).value

    await eventually(lambda: _is(gate_state(), codec.GateState.CLOSING), timeout=3, what="closing")
    await eventually(lambda: _below(position(), 100), timeout=3, what="the boom left the open position")
    twin.break_light_barrier()
    await eventually(lambda: _is(gate_state(), codec.GateState.OPENING, codec.GateState.OPEN), timeout=3,
                     what="reversed by the light barrier")
    assert await position() > 0  # reversed on the way down, never closed
    status = (await client.query(codec.Q_BARRIER_STATUS)).value["status"]
    assert status["LS"] is True
    twin.break_light_barrier(False)


async def test_open_level_holds_until_deactivated(barrier):
    sim, twin, client = barrier
    twin.settings["t_open"] = 10  # 0.1 s
    assert await client.talk(seal("55 03 01 01 01")) == ACK  # activate BT

    async def gate_state():
        return (await client.query(codec.Q_GATE_STATE)).value

    await eventually(lambda: _is(gate_state(), codec.GateState.OPEN), timeout=4, what="open")
    assert await client.talk(CLOSE) == ACK
    await asyncio.sleep(0.3)  # three times t_open (0.1 s, 16-bit setting 0x00, chapter 5.2.4): the open level holds it
    assert await gate_state() == codec.GateState.OPEN  # page 33: closing prevented
    assert await client.talk(seal("55 03 01 01 02")) == ACK  # deactivate
    await eventually(lambda: _is(gate_state(), codec.GateState.PREWARN_CLOSE, codec.GateState.CLOSING,
                                 codec.GateState.CLOSED), timeout=3, what="closing after the level was deactivated")


# -- settings ----------------------------------------------------------------------------------------------
async def test_setting_busy_while_moving_then_syn_ack(barrier):
    sim, twin, client = barrier
    write = codec.encode_frame(codec.encode_setting("t_open", 500))
    assert write == seal("55 04 04 00 F4 01")
    assert await client.talk(OPEN) == ACK
    assert await wait_for(lambda: twin.motor_runs, timeout=3)
    assert await client.talk(write) == BUSY  # "tele_busy, wenn der Motor läuft" (chapter 5.2.4)
    assert twin.setting_writes == {}
    assert await wait_for(lambda: not twin.motor_runs, timeout=5)
    await client.send(write)
    started = time.monotonic()
    assert (await client.frame(1.0, lambda f: f.type in codec.REPLY_TYPES)).raw == SYN
    assert (await client.frame(1.0, lambda f: f.type in codec.REPLY_TYPES)).raw == ACK
    assert time.monotonic() - started >= EEPROM_WRITE_S * 0.8
    assert twin.setting_writes == {"t_open": 1}
    assert (await client.query(codec.Q_T_OPEN)).value == 500
    assert await client.talk(codec.encode_frame(codec.encode_setting("vehicle_counter", -7))) == ACK  # RAM only
    assert (await client.query(codec.Q_VEHICLE_COUNTER)).value == -7
    assert twin.eeprom_writes == 1


# -- TCP specifics ----------------------------------------------------------------------------------------
async def test_one_client_at_a_time(barrier):
    sim, twin, client = barrier
    port = sim.port
    reader2, writer2 = await asyncio.open_connection("127.0.0.1", port)
    try:
        writer2.write(Q_GATE)
        await writer2.drain()
        assert await asyncio.wait_for(reader2.read(100), 2.0) == b""  # closed: another client holds it
    except ConnectionError:
        pass
    finally:
        writer2.close()
    assert sim.refused == 1
    assert await client.talk(Q_GATE) == seal("55 02 0C 05")  # the first client is still served
    client.writer.close()
    assert await wait_for(lambda: not twin.listeners, timeout=2)  # the barrier saw the first client go
    reader3, writer3 = await asyncio.open_connection("127.0.0.1", port)
    try:
        assert await Client(reader3, writer3).talk(Q_GATE) == seal("55 02 0C 05")
    finally:
        writer3.close()


async def test_change_monitoring_sends_unsolicited(barrier):
    sim, twin, client = barrier
    assert await wait_for(lambda: twin.listeners and twin.clock > 0, timeout=2)  # it serves this client and runs
    twin.vehicle_counter = 5  # a change (its telegram 0x1C is monitored with bit 5)
    assert await client.frame(0.2) is None  # nothing is sent unasked by default (change monitoring 0, SPEC-NOTES)
    twin.vehicle_counter, clock = 0, twin.clock
    assert await wait_for(lambda: twin.clock > clock, timeout=2)  # the twin has seen the counter back at 0
    flags = (1 << 3) | (1 << 6) | (1 << 5)  # gate state, barrier position, vehicle counter
    await client.send(codec.encode_frame(codec.encode_setting("change_monitoring", flags)))
    assert (await client.frame(1.0)).raw == SYN
    assert (await client.frame(1.0)).raw == ACK
    assert await client.talk(OPEN, types=codec.REPLY_TYPES) == ACK
    states, positions = [], []
    end = time.monotonic() + 4
    while time.monotonic() < end and (codec.GateState.OPEN not in states or positions[-1:] != [100]):
        f = await client.frame(end - time.monotonic(), lambda f: f.type in (0x0C, 0x1D))
        if f is None:
            break
        value = codec.decode_answer(f).value
        (states if f.type == 0x0C else positions).append(int(value))
    assert states == [codec.GateState.PREWARN_OPEN, codec.GateState.OPENING, codec.GateState.OPEN]
    assert positions and positions == sorted(positions) and positions[-1] == 100
    twin.settings["t_open"] = 0  # stays open
    twin.drive_vehicle()
    f = await client.frame(4.0, lambda f: f.type == 0x1C)
    assert f is not None and codec.decode_answer(f).value == 1  # the vehicle counted, sent unasked


async def test_status_change_telegram_follows_mask(barrier):
    sim, twin, client = barrier
    await client.send(codec.encode_frame(codec.encode_setting("change_monitoring", 1)))  # barrier status
    assert [(await client.frame()).raw for _ in range(2)] == [SYN, ACK]
    twin.raise_fault()
    assert await client.frame(0.3, lambda f: f.type == 0x07) is None  # mask 0: no bit watched (page 18)
    await client.send(codec.encode_frame(codec.encode_setting("status_mask", {"LS": 1})))
    assert [(await client.frame()).raw for _ in range(2)] == [SYN, ACK]
    twin.break_light_barrier()
    f = await client.frame(1.0, lambda f: f.type == 0x07)
    assert f is not None and codec.decode_answer(f).value["status"]["LS"] is True
    memory = (await client.query(codec.Q_ERROR_MEMORY)).value
    assert memory[0]["flags"] == 1 and memory[0]["timestamp_h"] == twin.operating_hours
    assert twin.setting_writes == {"change_monitoring": 1, "status_mask": 1}


# -- RS485 -------------------------------------------------------------------------------------------------
def rs485_bus(port: int, **options):
    bus = SimpleNamespace(name="gates-485", type="logited-rs485",
                          options={"port": f"socket://127.0.0.1:{port}", "baudrate": 38400, **options})
    devs = [SimpleNamespace(name=f"gate{a:X}", type="mo64", bus="gates-485", options={"address": a})
            for a in (0x10, 0x11)]
    return bus, devs


def q485(index: int, da: int, sa: int = 0) -> bytes:
    return codec.encode_frame(codec.encode_query(index), codec.RS485, da=da, sa=sa)


async def test_rs485_answers_only_its_address():
    port = free_port()
    sim = Mo64Rs485Sim(*rs485_bus(port))
    await sim.start()
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    client = Client(reader, writer, codec.RS485)
    try:
        assert q485(7, 0x10) == seal("55 04 10 00 02 07")
        assert await client.talk(q485(7, 0x10)) == seal("55 04 00 10 0C 05")  # to master 0 from 0x10
        sim.twins["gate11"].settings["t_open"] = 0  # open without an open time: it stays open
        sim.twins["gate11"].gate = codec.GateState.OPEN
        assert await client.talk(q485(7, 0x11)) == seal("55 04 00 11 0C 04")
        assert await client.talk(q485(7, 0x12), timeout=0.3) is None  # nobody at 0x12: silence
        assert await client.talk(codec.encode_token(0x10), timeout=0.3) is None  # token telegrams are ignored
        assert await client.talk(seal("55 04 10 00 02 1B")) == seal("55 03 00 10 02")  # nak
        open_ = codec.encode_frame(codec.encode_command(codec.Command.OPEN), codec.RS485, da=0x11)
        assert await client.talk(open_) == seal("55 03 00 11 01")
        assert not sim.twins["gate10"].commands and sim.unaddressed == 1
    finally:
        writer.close()
        await sim.stop()


async def test_rs485_second_master_passes_token_and_measures_hold():
    port = free_port()
    sim = Mo64Rs485Sim(*rs485_bus(port, shared=True, master_address=0, next_master=1))
    await sim.start()
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    client = Client(reader, writer, codec.RS485)
    try:
        for _ in range(4):
            token = await client.frame(2.0, lambda f: f.is_token and f.da == 0)
            assert token is not None and token.sa == 1
            given = time.monotonic()
            assert await client.talk(q485(2, 0x10)) == seal("55 08 00 10 07 00 00 00 00 00")
            await client.send(codec.encode_token(1, sa=0))
            assert time.monotonic() - given < codec.TOKEN_PASS_LIMIT_S
        await client.send(q485(2, 0x10))  # at once after passing the token on: a violation, counted
        assert await wait_for(lambda: sim.sent_without_token, timeout=2)
        assert sim.sent_without_token == 1
        assert len(sim.hold_times_s) >= 4
        assert all(0 < held < codec.TOKEN_PASS_LIMIT_S for held in sim.hold_times_s)
        assert sim.token_lost == 0
        assert sim.own_queries >= 1  # the other master queried a barrier while it held the token
        assert sim.own_answers[0][2] == 0x01  # and the barrier answered master 1, not this tool
        # the token is not passed back within 200 ms (chapter 2.6.1): the other master takes it back
        assert await wait_for(lambda: sim.token_lost >= 1, timeout=3)
    finally:
        writer.close()
        await sim.stop()


# -- the twin on its own (simulated time) ---------------------------------------------------------------
def run(twin, seconds: float, dt: float = 0.02) -> None:
    for _ in range(round(seconds / dt)):
        twin.step(dt)


def test_twin_vehicle_fault_error_memory_and_power_up():
    from devices.mo64.twin import Mo64Twin
    twin = Mo64Twin("gate", travel_s=1.0)
    twin.settings["t_open"] = 50  # 0.5 s
    twin.drive_vehicle()
    assert twin.loops["A"] and twin.gate == codec.GateState.PREWARN_OPEN  # presence on loop A opens
    run(twin, 1.6)
    assert twin.gate == codec.GateState.OPEN
    run(twin, 1.0)
    assert twin.vehicle_counter == 1 and not any(twin.loops.values()) and not twin.light_barrier
    run(twin, 0.4)
    assert twin.gate in (codec.GateState.PREWARN_CLOSE, codec.GateState.CLOSING)  # t_open after the vehicle left
    run(twin, 0.6)
    twin.raise_fault(0x04)  # a fault stops the boom where it is
    assert twin.gate == codec.GateState.INTERMEDIATE and 0 < twin.position_pct < 100
    twin.clock += 7200  # two operating hours later
    twin.clear_fault()
    assert twin.error_memory[:3] == [(0, twin.operating_hours), (0x04, twin.operating_hours - 2), (0, 0)]
    status = codec.decode_answer(codec.encode_frame(twin.answer(0x07))).value["status"]
    assert status["F_ereignis"] is False
    twin.power_up()
    assert twin.answer(0x1D) == h("1D FF") and twin.answer(0x1C) == h("1C 00 00 00 00")  # -1 %, counter 0
    assert twin.service_counter == 1 and twin.setting_writes == {}
