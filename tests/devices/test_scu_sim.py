"""The SCU twin over a real TCP socket, as a master on a ``socket://`` line would see it.

Requests and expected answers are raw bytes; checksums come from ``binascii.crc_hqx`` (the
document's CRC-16, start value 0, section 6), not from the codec under test. Examples of section 5.
"""

from __future__ import annotations

import asyncio
import binascii
import socket
import struct
import time
from types import SimpleNamespace

import pytest
from conftest import wait_for
from webutil import eventually

from devices.scu import codec
from devices.scu.sim import ScuSim

pytestmark = pytest.mark.timeout(30)


def h(text: str) -> bytes:
    return bytes.fromhex(text)


def seal(body: bytes | str) -> bytes:
    body = h(body) if isinstance(body, str) else body
    return body + binascii.crc_hqx(body, 0).to_bytes(2, "little")


def cmd(letters: str, params: str = "") -> bytes:
    return seal(letters.encode() + h(params))


def ack(letters: str, data: bytes | None = None) -> bytes:
    body = letters.encode() + b"\x06"
    if data is not None:
        body += len(data).to_bytes(2, "little") + data
    return seal(body)


def err(letters: str, code: int) -> bytes:
    return seal(letters.encode() + bytes([code]))


RO = cmd("RO", "01")
RC = cmd("RC", "01 00 FF")  # section 5, table 12
RA = cmd("RA")
CSE, PDE, PCE, ICE, PE = 0x80, 0x81, 0x82, 0x83, 0x84


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Line:
    """The master's end of the line: send raw bytes, read one answer (or nothing)."""

    def __init__(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter):
        self.reader, self.writer = reader, writer
        self.splitter = codec.FrameSplitter(codec.ANSWERS)
        self.lock = asyncio.Lock()

    async def talk(self, request: bytes, timeout: float = 1.0) -> bytes | None:
        async with self.lock:
            self.writer.write(request)
            await self.writer.drain()
            end = time.monotonic() + timeout
            while True:
                left = end - time.monotonic()
                if left <= 0:
                    return None
                try:
                    data = await asyncio.wait_for(self.reader.read(256), left)
                except TimeoutError:
                    return None
                for item in self.splitter.feed(data):
                    return item.raw

    async def position(self, actuator: int = 1) -> int:
        answer = await self.talk(cmd("RG", f"{0x10 + actuator:02X} 00"))
        assert answer[:5] == h("52 47 06 04 00"), answer.hex(" ")
        return struct.unpack("<i", answer[5:9])[0]

    async def status_1(self, actuator: int = 1) -> int:
        answer = await self.talk(cmd("RG", f"{0x70 + actuator:02X} 01"))
        assert answer[:5] == h("52 47 06 01 00"), answer.hex(" ")
        return answer[5]


@pytest.fixture
async def unit():
    port = free_port()
    bus = SimpleNamespace(name="scu-line", type="serial", options={"port": f"socket://127.0.0.1:{port}",
                                                                  "baudrate": 38400})
    dev = SimpleNamespace(name="scu1", type="scu", bus="scu-line", options={"actuators": 2, "safety_id": 1})
    sim = ScuSim(bus, [dev])
    await sim.start()
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    line = Line(reader, writer)
    try:
        yield sim, sim.twins["scu1"], line
    finally:
        writer.close()
        await sim.stop()


async def open_session(line: Line) -> None:
    assert await line.talk(RO) == ack("RO")
    assert await line.talk(RC) == ack("RC", b"")


class KeepAlive:
    """RC every 100 ms in the background, as the worker does while a session holds the unit."""

    def __init__(self, line: Line, request: bytes = RC):
        self.line, self.request, self.answers = line, request, []

    async def _run(self):
        while True:
            self.answers.append(await self.line.talk(self.request))
            await asyncio.sleep(0.1)  # RC every 100 ms, well within the 500 ms watchdog (section 4.1)

    async def __aenter__(self):
        self.task = asyncio.create_task(self._run())
        return self

    async def __aexit__(self, *exc):
        self.task.cancel()
        try:
            await self.task
        except asyncio.CancelledError:
            pass


# -- the conversation of section 5 -----------------------------------------------------------------------
async def test_section_5_conversation_byte_for_byte(unit):
    sim, twin, line = unit
    assert await line.talk(h("52 4F 00 5C 2D")) == h("52 4F 06 9A 4D")  # RO 00 -> ACK
    assert await line.talk(h("52 43 01 00 FF 31 8D")) == h("52 43 06 00 00 51 16")  # RC 01 00 FF -> ACK, ctp 0
    assert await line.talk(h("52 54 04 00 11 30 01 00 B5 F2")) == h("52 54 06 13 92")  # RT 0x3011 = 1
    assert twin.remote_speed[0] == 1
    assert await line.talk(seal("52 54 06 00 21 30 20 03 00 00")) == h("52 54 06 13 92")  # RT 0x3021 = 800
    assert await line.talk(h("52 45 00 09 FF 00 27")) == h("52 45 06 51 A2")  # RE 00 09 FF
    assert await wait_for(lambda: twin.actuators[0].moving, timeout=2)
    answer = await line.talk(h("52 47 71 01 27 2B"))  # RG 0x0171: status 1 of actuator 1
    assert answer[:5] == h("52 47 06 01 00") and answer[5] & 1 << 4, answer.hex(" ")  # bit 4: motion active
    assert answer == seal(answer[:-2])
    answer = await line.talk(h("52 47 11 00 2C 30"))  # RG 0x0011: position, ctp 04 00
    assert answer[:5] == h("52 47 06 04 00") and len(answer) == 11 and answer == seal(answer[:-2])
    assert await line.talk(cmd("RS", "00 FF")) == ack("RS")
    assert await line.talk(h("52 41 38 30")) == h("52 41 06 95 6E")  # RA
    assert twin.re_without_rs == 0 and not twin.remote


# -- remote mode and error answers ----------------------------------------------------------------------------
async def test_remote_commands_answer_pe_outside_remote_mode(unit):
    sim, twin, line = unit
    assert await line.talk(cmd("RG", "11 00")) == err("RG", PE)
    assert await line.talk(RC) == err("RC", PE)
    assert await line.talk(cmd("RE", "00 02 00")) == err("RE", PE)
    assert await line.talk(cmd("RS", "00 FF")) == err("RS", PE)
    assert await line.talk(cmd("RT", "04 00 11 30 32 00")) == err("RT", PE)
    assert await line.talk(RA) == ack("RA")  # RO and RA are always available (section 4.1)
    assert await line.talk(RO) == ack("RO")
    # section 5: an RC must come before the first command of the session
    assert await line.talk(cmd("RG", "11 00")) == err("RG", PE)
    assert await line.talk(RC) == ack("RC", b"")
    assert await line.talk(cmd("RG", "11 00")) == ack("RG", h("00 00 00 00"))
    assert await line.talk(RA) == ack("RA")
    assert await line.talk(cmd("RG", "11 00")) == err("RG", PE)


async def test_bad_checksum_answers_cse_and_the_line_goes_on(unit):
    sim, twin, line = unit
    await open_session(line)
    good = cmd("RG", "11 00")
    assert await line.talk(good[:-1] + bytes([good[-1] ^ 0x01])) == err("RG", CSE)
    assert await line.talk(RC[:-2] + b"\x00\x00") == err("RC", CSE)
    assert await line.talk(good) == ack("RG", h("00 00 00 00"))


async def test_count_data_and_command_errors(unit):
    sim, twin, line = unit
    await open_session(line)
    assert await line.talk(cmd("RG", "00 05")) == err("RG", PDE)  # no data ID 0x0500
    assert await line.talk(cmd("RT", "06 00 11 00 01 00 00 00")) == err("RT", PDE)  # 0x0011 is not remote data
    assert await line.talk(cmd("RT", "03 00 11 30 01")) == err("RT", PCE)  # UINT16 needs 2 bytes
    assert await line.talk(cmd("RT", "04 00 11 30 65 00")) == err("RT", PDE)  # 101 % is out of range
    assert await line.talk(cmd("RC", "00 00")) == err("RC", PCE)  # ctp 0: the index is missing
    assert await line.talk(cmd("RC", "01 00 07")) == err("RC", PDE)  # cyclic object index 7
    assert await line.talk(cmd("RE", "0C FF FF")) == err("RE", PDE)  # fnc_ID 12 is not in table 8
    assert await line.talk(cmd("RE", "04 02 00")) == err("RE", PDE)  # F5: no actuator 5 on this unit
    assert await line.talk(cmd("RX", "01 02")) == err("RX", ICE)
    assert await line.talk(h("00 11 22"), timeout=0.3) is None  # bytes that start no telegram: silence
    assert await line.talk(RC) == ack("RC", b"")


# -- the watchdog -----------------------------------------------------------------------------------------------
async def test_watchdog_drops_remote_mode_and_stops_motion_after_500_ms_without_rc(unit):
    sim, twin, line = unit
    await open_session(line)
    async with KeepAlive(line):
        assert await line.talk(cmd("RE", "00 02 01")) == ack("RE")  # F1 out, soft
        await asyncio.sleep(0.5)  # a whole 500 ms watchdog period (section 4.1), RC every 100 ms: still moving
        assert twin.actuators[0].moving
    last_rc = time.monotonic()
    assert await wait_for(lambda: not twin.remote, timeout=2, interval=0.01)
    gap = time.monotonic() - last_rc
    assert 0.35 <= gap <= 0.65, gap  # 500 ms after the last RC (plus the tick)
    assert not twin.actuators[0].moving and twin.error_code & codec.REMOTE_TIMEOUT_MASK  # error bit 22
    stopped_at = twin.actuators[0].position
    await asyncio.sleep(0.2)  # ten 20 ms steps of the twin (sim.TICK_S): the stop of the watchdog (section 4.1) holds
    assert twin.actuators[0].position == stopped_at
    assert twin.re_without_rs == 1  # the RE was never stopped with RS
    assert await line.talk(RC) == err("RC", PE)
    await open_session(line)  # reopened, the error code still tells why the session was lost
    answer = await line.talk(cmd("RG", "D1 00"))
    assert answer[:5] == h("52 47 06 04 00") and int.from_bytes(answer[5:9], "little") & 1 << 21


async def test_rc_within_500_ms_keeps_remote_mode(unit):
    sim, twin, line = unit
    await open_session(line)
    for _ in range(12):
        await asyncio.sleep(0.2)  # RC every 200 ms, inside the 500 ms watchdog (section 4.1) of a twin on its own loop
        assert await line.talk(RC) == ack("RC", b"")
    assert twin.remote and not twin.error_code


# -- motion ---------------------------------------------------------------------------------------------------
async def test_move_to_remote_position_rises_and_stops_at_the_target(unit):
    sim, twin, line = unit
    await open_session(line)
    async with KeepAlive(line) as keep:
        assert await line.talk(cmd("RT", "06 00 21 30 20 03 00 00")) == ack("RT")  # A1 remote position 800
        assert await line.talk(cmd("RT", "04 00 11 30 64 00")) == ack("RT")  # F1 speed 100 %
        assert await line.talk(cmd("RE", "00 09 01")) == ack("RE")  # F1 to the remote position, soft
        seen, speeds, t0 = [], [], time.monotonic()
        while time.monotonic() - t0 < 5:
            seen.append(await line.position())
            speed = await line.talk(cmd("RG", "F1 00"))
            speeds.append(int.from_bytes(speed[5:7], "little"))
            if not await line.status_1() & 1 << 4:
                break
            await asyncio.sleep(0.05)  # the next sample
        # the last sample may be taken just before the motion ends; the position then is the target
        assert seen == sorted(seen) and seen[-1] <= 800 and await line.position() == 800
        assert 0 < min(s for s in speeds if s) < 60 and max(speeds) >= 90  # soft start: ramps up to 100 %
        assert seen[0] < 100
        assert await line.talk(cmd("RS", "00 FF")) == ack("RS")
        assert all(a == ack("RC", b"") for a in keep.answers)
    assert twin.actuators[0].relay_out == 1 and twin.actuators[0].cumulated_stroke == pytest.approx(800)
    assert twin.re_without_rs == 0


async def test_actuator_stops_at_its_end_position(unit):
    sim, twin, line = unit
    act = twin.actuators[1]
    act.position = act.out_counts - 150.0
    await open_session(line)
    async with KeepAlive(line):
        assert await line.talk(cmd("RE", "01 02 00")) == ack("RE")  # F2 out, fast start/stop
        assert await line.status_1(2) & 1 << 4  # motion active

        async def at_the_end():  # the position reaches the end a tick before the motion is reported ended
            return await line.position(2) == act.out_counts and not await line.status_1(2) & 1 << 4

        await eventually(at_the_end, timeout=3, what="F2 stopped at its out position")
        status = await line.status_1(2)
        assert await line.position(2) == act.out_counts
        assert status & 1 << 6 and status & 1 << 1 and not status & 1 << 4  # out position, limit, no motion
        status_2 = await line.talk(cmd("RG", "E2 00"))
        assert status_2 == ack("RG", bytes([0b011]))  # initialised, inward enabled, outward not
        assert await line.talk(cmd("RE", "01 02 00")) == ack("RE")  # again, without RS: counted
        assert await line.talk(cmd("RS", "01 FF")) == ack("RS")
    assert twin.re_without_rs == 1 and act.position == act.out_counts


# -- cyclic objects -----------------------------------------------------------------------------------------------
async def test_cyclic_object_carries_write_and_read_data_with_rc(unit):
    sim, twin, line = unit
    await open_session(line)
    slots = [0x3021] + [0xFFFF] * 5 + [0x0011, 0x0012, 0x0171, 0x00D1] + [0xFFFF] * 2
    definition = struct.pack("<12H", *slots)
    assert await line.talk(cmd("RT", "1A 00 01 30 " + definition.hex())) == ack("RT")  # 2 + 24 bytes
    assert await line.talk(cmd("RG", "01 30")) == ack("RG", definition)
    answer = await line.talk(cmd("RC", "05 00 00 F4 01 00 00"))  # index 0 + remote position A1 = 500
    expected = struct.pack("<iiBI", 0, 0, 0b1010_0011, 0)  # positions, status 1 of A1 (present, limit, in, stroke)
    assert answer == ack("RC", expected)
    assert twin.remote_position[0] == 500
    assert await line.talk(cmd("RC", "03 00 00 F4 01")) == err("RC", PCE)  # write data too short
    bad = struct.pack("<12H", *([0x0011] + [0xFFFF] * 11))  # a write slot outside 0x3xxx
    assert await line.talk(cmd("RT", "1A 00 02 30 " + bad.hex())) == err("RT", PDE)
    unknown = struct.pack("<12H", *([0xFFFF] * 6 + [0x0999] + [0xFFFF] * 5))
    assert await line.talk(cmd("RT", "1A 00 02 30 " + unknown.hex())) == err("RT", PDE)
    assert await line.talk(cmd("RC", "01 00 01")) == ack("RC", b"")  # CyclicObj 2 undefined: no data


# -- data directory -----------------------------------------------------------------------------------------------
async def test_group_ids_and_the_error_history(unit):
    sim, twin, line = unit
    twin.actuators[1].position = 1234.0
    await open_session(line)
    assert await line.talk(cmd("RG", "10 00")) == ack("RG", struct.pack("<6i", 0, 1234, 0, 0, 0, 0))
    twin.trip_actuator_error(1)
    twin.trip_actuator_error(2)
    answer = await line.talk(cmd("RG", "D0 00"))
    assert answer == ack("RG", struct.pack("<5I", 1 << 14 | 1 << 15, 1 << 14, 0, 0, 0))  # bits 15, 16; history
    counter = await line.talk(cmd("RG", "81 00"))
    assert counter == ack("RG", struct.pack("<HBB", 1, 1, 0))  # 2 B errors, 1 B peak current, 1 B short circuit


async def test_demo_controls_load_battery_and_outputs(unit):
    sim, twin, line = unit
    await open_session(line)
    assert await line.talk(cmd("RG", "00 01")) == ack("RG", bytes([0b0111]))  # mains, battery, charger on; full: not charging
    twin.switch_to_battery()
    assert await line.talk(cmd("RG", "00 01")) == ack("RG", bytes([0b0010]))
    volts = await line.talk(cmd("RG", "64 01"))
    assert 200 <= int.from_bytes(volts[5:7], "little") <= 260
    async with KeepAlive(line):
        twin.add_load(1, 4.0)
        assert await line.talk(cmd("RE", "00 02 00")) == ack("RE")

        async def loaded():
            current = await line.talk(cmd("RG", "A1 00"))
            return int.from_bytes(current[5:7], "little") >= 40  # 0.1 A units, the load adds 4 A

        await eventually(loaded, timeout=3, what="A1 current with the 4 A load")
        twin.add_load(1, 20.0)  # beyond the peak current: the actuator trips
        assert await wait_for(lambda: not twin.actuators[0].moving, timeout=2)
        assert not twin.actuators[0].moving and twin.error_code & 1 << 14
        assert await line.talk(cmd("RS", "00 FF")) == ack("RS")
        assert await line.talk(cmd("RE", "10 FF FF")) == ack("RE")  # binary output 1
        assert await line.talk(cmd("RE", "0A FF FF")) == ack("RE")  # buzzer
        assert await line.talk(cmd("RG", "10 01")) == ack("RG", b"\x01")
        assert await line.talk(cmd("RG", "40 01")) == ack("RG", b"\x01")
        assert await line.talk(cmd("RE", "13 FF FF")) == ack("RE")  # emergency stop
        assert await line.talk(cmd("RE", "00 02 00")) == err("RE", PE)  # no motion while it is held
        for fn in ("13", "10", "0A"):
            assert await line.talk(cmd("RS", f"{fn} FF")) == ack("RS")
        assert await line.talk(cmd("RG", "10 01")) == ack("RG", b"\x00")
    twin.drop_line()
    assert await line.talk(RC, timeout=0.7) is None  # a dropped line stays silent
    twin.drop_line(False)
    assert await line.talk(RC) == err("RC", PE)  # meanwhile the watchdog ended remote mode


async def test_a_telegram_cut_short_gets_no_answer_and_the_next_one_does(unit):
    sim, twin, line = unit
    assert await line.talk(RO[:3], timeout=1.2) is None  # inter-byte limit 1000 ms (section 3): dropped, silent
    assert await line.talk(RO) == ack("RO")


def test_one_unit_per_line_and_actuator_tables():
    bus = SimpleNamespace(name="rs", type="serial", options={"port": "socket://127.0.0.1:1"})
    dev = SimpleNamespace(name="a", type="scu", bus="rs",
                          options={"actuators": [{"counts_per_mm": 10}, {"stroke_mm": 300, "in_counts": 100,
                                                                         "out_counts": 3100}]})
    with pytest.raises(ValueError, match="point to point"):
        ScuSim(bus, [dev, SimpleNamespace(**{**vars(dev), "name": "b"})])
    twin = ScuSim(bus, [dev]).twins["a"]
    first, second = twin.actuators
    assert (first.in_counts, first.out_counts, first.counts_per_mm) == (0, 3000, 10)
    assert (second.in_counts, second.out_counts, second.counts_per_mm) == (100, 3100, 10)
    assert second.position == 100 and len(twin.actuators) == 2
