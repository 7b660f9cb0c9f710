"""SCU adapter: scripted conversations (expected TX/RX in order, as python-canopen's test_sdo) on a
socket:// line, then the adapter against the SCU twin."""

from __future__ import annotations

import asyncio
import time
from types import SimpleNamespace

import pytest
from conftest import free_port, wait_for
from plants import plant, scu_line
from scripts import RX, TX, Script

from app.serial_line import SerialLine
from app.state import BusState
from devices.live import DeviceState
from devices.scu import codec
from devices.scu import params as p
from devices.scu.adapter import CYCLIC_READ_IDS, P_CYCLIC, P_REFUSAL, ControlBusy, ScuAdapter

pytestmark = pytest.mark.timeout(60)

ACK = codec.ACK


def ok(command: bytes, data: bytes | None = None) -> bytes:
    return codec.encode_answer(command, ACK, data)


def refused(command: bytes, status: int) -> bytes:
    return codec.encode_answer(command, status)


def positions(n: int = 2, ends: tuple[int, int] = (0, 3000)) -> bytes:
    value = {name: 0 for name, _ in p.ACTUATOR_POSITIONS.members}
    value["Position_Virtual_Limit_In"], value["Position_Virtual_Limit_Out"] = ends
    return p.encode_data(0x2001, value, remote_only=False)


class ScuScript(Script):
    """A serial peer (through ``socket://``) speaking SCU telegrams (tests/scripts.py)."""

    def __init__(self, steps: list[tuple[str, bytes]]):
        super().__init__(steps, lambda: codec.FrameSplitter(codec.REQUESTS))


_made: list[ScuAdapter] = []


@pytest.fixture(autouse=True)
def close_lines():
    yield
    while _made:
        _made.pop().line.close()


def make_adapter(port: int, keepalive: float = 60.0, thread: bool = False, **options) -> ScuAdapter:
    opts = {"port": f"socket://127.0.0.1:{port}", "baudrate": 38400, "timeout": 0.3}
    line = SerialLine("rs1", opts, BusState("rs1", "serial", opts["port"]))
    config = SimpleNamespace(name="scu-1", type="scu", bus="rs1", options={"actuators": 2, **options})
    adapter = ScuAdapter(config, DeviceState("scu-1", "scu", "rs1"), line)
    adapter.keepalive_period_s = keepalive  # scripted conversations: no RC interleaved unless scripted
    adapter.rc_on_line_thread = thread  # scripted: RC from the poll, in the script's order
    _made.append(adapter)
    return adapter


CYCLIC = p.CyclicDefinition(read_ids=CYCLIC_READ_IDS)
# Section 4.1: RG only in remote mode. The first RG outside a session is refused with PE: the unit is
# then watched through a session opened for reading.
PROBE = [(TX, codec.encode_rg(0x0011)), (RX, refused(codec.RG, codec.Status.PE))]
FACTOR_UNSET = ok(codec.RG, bytes(4))  # conversion factor 0.0: no mm from it


def opening(factor_1: bool = True, factor_2: bool = True) -> list:
    """Probe, RO, RC, the cyclic definition, the end positions and, for an actuator without a scale in the
    plant file, its conversion factor (0x1011..)."""
    steps = PROBE + [
        (TX, codec.encode_ro(1)), (RX, ok(codec.RO)),
        (TX, codec.KEEP_ALIVE), (RX, ok(codec.RC)),
        (TX, codec.encode_rt(0x3001, CYCLIC.encode())), (RX, ok(codec.RT)),
        (TX, codec.encode_rg(0x2001)), (RX, ok(codec.RG, positions()))]
    if factor_1:
        steps += [(TX, codec.encode_rg(0x1011)), (RX, FACTOR_UNSET)]
    steps += [(TX, codec.encode_rg(0x2002)), (RX, ok(codec.RG, positions(ends=(100, 5100))))]
    if factor_2:
        steps += [(TX, codec.encode_rg(0x1012)), (RX, FACTOR_UNSET)]
    return steps


OPENING = opening()


def cyclic_answer(pos1: int = 1500, status1: int = 0x11, error: int = 0) -> bytes:
    values = {
        0x0010: {0x0011: pos1, 0x0012: 100, 0x0013: 0, 0x0014: 0, 0x0015: 0, 0x0016: 0},
        0x0170: {0x0171: status1, 0x0172: 0x01, 0x0173: 0, 0x0174: 0, 0x0175: 0, 0x0176: 0},
        0x00E0: {0x00E1: 0x07, 0x00E2: 0x07, 0x00E3: 0, 0x00E4: 0, 0x00E5: 0, 0x00E6: 0},
        0x00A0: {0x00A1: 2.5, 0x00A2: 0.0, 0x00A3: 0.0, 0x00A4: 0.0, 0x00A5: 0.0, 0x00A6: 0.0},
        0x00D1: error,
        0x0100: 0x01,
    }
    return ok(codec.RC, b"".join(p.encode_data(i, values[i], remote_only=False) for i in CYCLIC.read_ids))


async def test_opening_the_session_defines_the_cyclic_object_and_brings_live_data_with_rc():
    async with ScuScript(opening(False, False)) as script:
        adapter = make_adapter(script.port, actuators=[{"counts_per_mm": 10}, {"stroke_mm": 250}])
        await adapter.poll()
        assert adapter.session == "open" and adapter.cyclic == CYCLIC
        assert "cyclic object 0x3001" in adapter.state.live(P_CYCLIC).value
        script.add((TX, codec.encode_rc(0)), (RX, cyclic_answer()),
                   (TX, codec.encode_rg(0x00F0)), (RX, ok(codec.RG, bytes(12))))
        await adapter.poll()
        script.done()
        pts = adapter.state.points
        assert pts["A1 position"].value == 1500 and pts["A1 position mm"].value == 150.0
        assert pts["A2 position mm"].value == 0.0  # stroke 250 mm between the unit's limits 100 .. 5100
        assert pts["A1 motion"].value is True and pts["A1 present"].value is True
        assert pts["A1 current"].value == 2.5 and pts["A1 initialised"].value is True
        assert pts["Mains"].value is True and pts["Error code"].text == codec.error_text(0) == "no error"
        assert adapter.state.history and adapter.state.online


async def test_refused_cyclic_definition_falls_back_to_rg_and_says_so():
    steps = OPENING[:7] + [(RX, refused(codec.RT, codec.Status.PDE))] + OPENING[8:]  # PDE to the definition
    async with ScuScript(steps) as script:
        adapter = make_adapter(script.port)
        await adapter.poll()
        assert adapter.session == "open" and adapter.cyclic is None
        assert "refused the cyclic object definition (PDE" in adapter.state.live(P_CYCLIC).value
        assert "RG requests instead" in adapter.state.live(P_CYCLIC).value
        script.add((TX, codec.KEEP_ALIVE), (RX, ok(codec.RC)))
        for data_id in CYCLIC_READ_IDS:
            size = p.item(data_id).size
            data = b"\xdc\x05" + bytes(size - 2) if data_id == 0x0010 else bytes(size)
            script.add((TX, codec.encode_rg(data_id)), (RX, ok(codec.RG, data)))
        script.add((TX, codec.encode_rg(0x00F0)), (RX, ok(codec.RG, bytes(12))))
        await adapter.poll()
        script.done()
        assert adapter.state.points["A1 position"].value == 1500


async def test_move_to_a_remote_position_is_followed_by_its_rs():
    async with ScuScript(opening(False, True)) as script:
        adapter = make_adapter(script.port, actuators=[{"counts_per_mm": 10}, {}])
        await adapter.poll()
        await adapter.take_control("s1", "anna")
        with pytest.raises(ControlBusy):
            await adapter.take_control("s2", "bert")
        script.add((TX, p.rt_frame(0x3011, 100)), (RX, ok(codec.RT)),  # section 5: RT 04 00 11 30 01 00 (+ 0x0064)
                   (TX, codec.encode_rg(0x3011)), (RX, ok(codec.RG, (100).to_bytes(2, "little"))),
                   (TX, p.rt_frame(0x3021, 2000)), (RX, ok(codec.RT)),
                   (TX, codec.encode_rg(0x3021)), (RX, ok(codec.RG, (2000).to_bytes(4, "little"))),
                   (TX, codec.encode_re(0, codec.Motion.REMOTE_POSITION, -1)), (RX, ok(codec.RE)))  # RE 00 09 FF
        assert await adapter.set_remote_speed("s1", 1, 100) == 100
        assert await adapter.set_remote_position("s1", 1, mm=200.0) == 2000
        await adapter.run_function("s1", 0, codec.Motion.REMOTE_POSITION, -1)
        assert adapter.holders() == {"s1"}
        script.add((TX, codec.encode_rs(0)), (RX, ok(codec.RS)))
        assert await adapter.stop("s1") == ["F1"]
        script.done()
        assert adapter.holders() == set()


async def running_f2(script):
    """An adapter on ``script``'s line that opened the session, gave s1 (anna) control and runs F2 out; its RS is
    the next answer the script expects."""
    adapter = make_adapter(script.port)
    await adapter.poll()
    await adapter.take_control("s1", "anna")
    script.add((TX, codec.encode_re(1, codec.Motion.OUT, codec.Ramp.SOFT)), (RX, ok(codec.RE)))
    await adapter.run_function("s1", 1, codec.Motion.OUT, codec.Ramp.SOFT)
    script.add((TX, codec.encode_rs(1)), (RX, ok(codec.RS)))
    return adapter


async def test_dead_man_sends_rs_at_once_and_releases_control():
    async with ScuScript(OPENING) as script:
        adapter = await running_f2(script)
        started = time.monotonic()
        adapter.session_lost("s1", "the controlling browser disconnected")
        await adapter.stopped()
        assert time.monotonic() - started < 0.5
        script.done()
        assert adapter.holders() == set() and adapter.controller is None
        assert any("disconnected" in e.text for e in adapter.state.events)


@pytest.mark.parametrize("reason", [
    "dead-man: the controlling browser has not confirmed it is alive for 1200 ms while this program ran on time",
    "the controlling browser disconnected",
])
async def test_a_dead_man_stop_is_named_once_whatever_the_reason_says(reason):
    """The worker's reason for a silent page says "dead-man: ..." already; a page that went away does not. The event
    and the RS's reason name the rule once ("dead-man: dead-man: ..." before)."""
    async with ScuScript(OPENING) as script:
        adapter = await running_f2(script)
        adapter.session_lost("s1", reason)
        await adapter.stopped()
        script.done()
        named = [e.text for e in adapter.state.events if "dead-man" in e.text]
        assert named and all(text.count("dead-man") == 1 for text in named), named
        assert any(text.startswith(f"dead-man: {reason.removeprefix('dead-man: ')}; RS to F2") for text in named), named


async def test_bad_crc_is_counted_and_retried_and_error_answers_are_named():
    bad = bytearray(ok(codec.RO))
    bad[-1] ^= 0xFF
    steps = PROBE + [(TX, codec.encode_ro(1)), (RX, bytes(bad)), (TX, codec.encode_ro(1)), (RX, ok(codec.RO))] + OPENING[4:]
    async with ScuScript(steps) as script:
        adapter = make_adapter(script.port)
        await adapter.poll()
        assert adapter.session == "open" and adapter.state.counters.crc_errors == 1 and adapter.crc_retries == 1
        # a PE alone may be the unit's state (an emergency stop): an RC refused too shows remote mode is gone
        script.add((TX, codec.encode_rg(0x0001)), (RX, refused(codec.RG, codec.Status.PE)),
                   (TX, codec.KEEP_ALIVE), (RX, refused(codec.RC, codec.Status.PE)))
        with pytest.raises(codec.CommandRefused):
            await adapter.read_data(0x0001)
        script.done()
        refusal = adapter.state.live(P_REFUSAL).value
        assert refusal.name == "PE" and "RO" in refusal.remedy
        assert adapter.session == "lost" and "PE" in adapter.session_reason


async def test_no_answer_marks_offline_naming_cable_dtr_rts_and_baud_rate():
    async with ScuScript([]) as script:
        script.problems = []
        adapter = make_adapter(script.port)
        for _ in range(3):
            await adapter.poll()
            await asyncio.sleep(0.25)  # the next poll, spaced as the worker polls
        assert adapter.state.online is False
        text = adapter.state.last_error
        assert "cable" in text and "DTR and RTS" in text and "38400" in text
        adapter.line.close()


# -- against the twin --------------------------------------------------------------------------------
def twin_plant(port: int):
    return plant(scu_line("scu-1", port=port, timeout=None, poll_period=None))


async def start_twin(port: int):
    from devices.scu.sim import ScuSim

    plant = twin_plant(port)
    bus = plant.buses["rs1"]
    sim = ScuSim(bus, plant.devices_on("rs1"))
    await sim.start()
    return plant, sim


async def test_adapter_against_the_twin_keeps_rc_gaps_below_500_ms_moves_and_stops():
    port = free_port()
    plant, sim = await start_twin(port)
    adapter = make_adapter(port, keepalive=codec.KEEP_ALIVE_PERIOD_S, thread=True, actuators=[{"counts_per_mm": 10}, {"stroke_mm": 300}])
    twin = sim.twins["scu-1"]

    async def worker_loop(stop_at: float):
        while time.monotonic() < stop_at:
            t = time.monotonic()
            adapter.renew_leases({"s1"})  # the worker's dead-man supervisor: the browser of s1 is alive
            await adapter.poll()
            await asyncio.sleep(max(0.02, 0.2 - (time.monotonic() - t)))  # a poll every 200 ms, as the worker

    stale: set[str] = set()

    async def watch_quality(start_at: float, stop_at: float):  # as a page sees the points, ten times a second
        await asyncio.sleep(start_at - time.monotonic())  # the page opens at start_at
        while time.monotonic() < stop_at:
            stale.update(name for name in list(adapter.state.points) if adapter.state.point(name)["quality"] == "stale")
            await asyncio.sleep(0.1)

    try:
        begin = time.monotonic()
        loop_task = asyncio.create_task(worker_loop(begin + 10.0))
        # every point read in turn (16 data IDs, one per poll) has been read twice after 7 s
        quality_task = asyncio.create_task(watch_quality(begin + 7.0, begin + 10.0))
        await wait_for(lambda: adapter.session == "open" and "A1 position" in adapter.state.points, timeout=5)
        assert adapter.session == "open" and "A1 position" in adapter.state.points, adapter.session_reason
        twin.add_load(1, 3.0)
        await adapter.take_control("s1", "anna")
        await adapter.set_remote_speed("s1", 1, 100)
        await adapter.set_remote_position("s1", 1, counts=1500)
        start = adapter.state.points["A1 position"].value
        await adapter.run_function("s1", 0, codec.Motion.REMOTE_POSITION, codec.Ramp.SOFT)
        assert await wait_for(lambda: adapter.state.points["A1 position"].value > start, timeout=5)  # towards 1500
        adapter.session_lost("s1", "dead-man test")
        await adapter.stopped()
        assert adapter.holders() == set()
        await loop_task
        await quality_task
        assert not stale, f"points marked stale while read in turn: {sorted(stale)}"
        gaps = adapter.rc_gaps()
        assert gaps and max(gaps) < 0.5, max(gaps)
        assert adapter.session == "open"
    finally:
        await sim.stop()
        adapter.line.close()


async def test_stopped_twin_gives_offline_and_recovery():
    port = free_port()
    plant, sim = await start_twin(port)
    adapter = make_adapter(port, keepalive=codec.KEEP_ALIVE_PERIOD_S, thread=True)
    try:
        for _ in range(5):
            await adapter.poll()
        assert adapter.session == "open"
        await sim.stop()
        deadline = time.monotonic() + 6
        while adapter.state.online is not False and time.monotonic() < deadline:
            await adapter.poll()
            await asyncio.sleep(0.1)
        assert adapter.state.online is False and "DTR and RTS" in adapter.state.last_error
        assert adapter.session in ("lost", "closed")
        await sim.start()
        deadline = time.monotonic() + 10
        while adapter.session != "open" and time.monotonic() < deadline:
            await adapter.poll()
            await asyncio.sleep(0.1)
        assert adapter.session == "open" and adapter.state.online
    finally:
        await sim.stop()
        adapter.line.close()
