"""The point-to-point serial line against a device served behind a TCP socket (pyserial socket://)."""

from __future__ import annotations

import asyncio
import time

import pytest
from conftest import closed_after, free_port
from plants import bus, device, plant, plant_text

from app.plant import PlantError, parse_plant
from app.serial_line import SerialClosed, SerialLine, SerialTimeout
from app.state import BusState

pytestmark = pytest.mark.timeout(30)


def answer_length(buffer: bytes) -> int | None:
    """A toy codec: the first byte is the length of what follows."""
    return None if not buffer else 1 + buffer[0]


async def serve(port: int, reply, delay: float = 0.0) -> asyncio.AbstractServer:
    async def handle(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while True:
                request = await reader.read(64)
                if not request:
                    break
                answer = reply(request)
                if answer is None:
                    continue  # silence
                await asyncio.sleep(delay)
                for i in range(0, len(answer), 2):  # in pieces, as a slow wire delivers them
                    writer.write(answer[i:i + 2])
                    await writer.drain()
        except ConnectionError:
            pass
        finally:
            writer.close()

    return await asyncio.start_server(handle, "127.0.0.1", port)


def line(port: int, **options) -> SerialLine:
    opts = {"port": f"socket://127.0.0.1:{port}", "baudrate": 38400, "timeout": 0.3, **options}
    return SerialLine("rs1", opts, BusState("rs1", "serial", opts["port"]))


async def test_request_and_answer_in_pieces():
    port = free_port()
    server = await serve(port, lambda request: bytes([5]) + request[:5].ljust(5, b"."))
    sl = line(port)
    async with closed_after(sl, server):
        answer = await sl.transact(b"RC\x01\x00\xff", answer_length, describe="RC keep-alive", decode=lambda a: f"{len(a)} bytes")
        assert answer == b"\x05RC\x01\x00\xff" and sl.state.connected
        logged = sl.state.transactions[-1]
        assert logged.request == "RC keep-alive" and logged.decoded == "6 bytes" and logged.error == "" and logged.rtt_ms is not None


async def test_silence_is_a_named_timeout_and_the_line_goes_on():
    port = free_port()
    server = await serve(port, lambda request: None if request.startswith(b"XX") else b"\x01A")
    sl = line(port, timeout=0.2)
    async with closed_after(sl, server):
        started = time.monotonic()
        with pytest.raises(SerialTimeout, match="no complete answer within 0.2 s"):
            await sl.transact(b"XX", answer_length)
        assert 0.15 < time.monotonic() - started < 1.0
        assert await sl.transact(b"OK", answer_length) == b"\x01A"  # the next request is answered
        assert sl.state.transactions[-2].error.startswith("no complete answer")


async def test_unplugged_port_says_what_to_check_and_reopens_with_backoff():
    port = free_port()
    sl = line(port)
    with pytest.raises(SerialClosed, match="cannot open socket://127.0.0.1:.*Connection refused. Check the cable"):
        await sl.transact(b"RC", answer_length)
    assert not sl.state.connected
    server = await serve(port, lambda request: b"\x01A")
    async with closed_after(sl, server):
        loop = asyncio.get_running_loop()
        end = loop.time() + 5
        while loop.time() < end:
            try:
                assert await sl.transact(b"RC", answer_length) == b"\x01A"
                break
            except SerialClosed:
                await asyncio.sleep(0.1)
        assert sl.state.connected and sl.state.reconnects == 1


def test_plant_serial_bus_defaults_and_baudrates():
    line = plant(bus("rs1", "serial", port="socket://127.0.0.1:5030"), name=None)
    assert line.buses["rs1"].options == {"port": "socket://127.0.0.1:5030", "baudrate": 38400, "timeout": 0.3,
                                          "poll_period": 0.2, "simulate": False, "wire_delay": False}
    with pytest.raises(PlantError, match="baudrate 57600 is not one of 9600, 19200, 38400"):
        plant(bus("rs1", "serial", port="/dev/ttyUSB0", baudrate=57600), name=None)


def test_one_scu_per_serial_line():
    text = plant_text(bus("rs1", "serial", device("a", "scu", "rs1", actuators=1), device("b", "scu", "rs1", actuators=1),
                          port="socket://127.0.0.1:5031"), name=None)
    with pytest.raises(PlantError, match=r"<plant>:10: device 'b': the point-to-point line \(one SCU per RS232 line"):
        parse_plant(text)
