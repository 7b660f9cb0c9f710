"""What the idle plant sends and reads less often than its live values, and what still comes at once.

A slow value is read at start, after a write or a change that concerns it, and marked stale by its own
age; a live value keeps its rate. No timing is asserted: the periods the adapters choose are.
"""

from __future__ import annotations

import asyncio
import contextlib

import pytest
from conftest import wait_for
from test_scu_keepalive import scu  # noqa: F401 (fixture)

from app.plant import parse_plant
from app.runtime import Runtime
from devices.m3io import codec as m3io
from devices.m3io.adapter import IDLE_DIGOUT_PERIOD_S
from plants import can_bus, channel, m3io_can, plant_text


async def _beat(worker, session: str) -> None:
    while True:
        worker.heartbeat(session)
        await asyncio.sleep(0.1)


async def test_m3io_served_idle_slower_and_at_100_ms_under_control():
    """``master = "always"`` with nobody in control: DigOut (every output off) at the idle period, well inside
    the 2 s watchdog; an engineer taking control brings the 100 ms keep-alive back, releasing it the idle one."""
    assert m3io.DIGOUT_PERIOD_S < IDLE_DIGOUT_PERIOD_S <= m3io.WATCHDOG_S / 4
    text = plant_text(can_bus(m3io_can(master="always"), name="can3", channel_name=channel("idle"), bitrate=500000,
                              poll_period=0.2), name=None)
    runtime = Runtime(parse_plant(text), simulate=True)
    await runtime.start()
    beat = asyncio.create_task(_beat(runtime.worker, "s1"))
    try:
        adapter, bus = runtime.worker.adapters["hm"], runtime.worker.can_buses["can3"]
        state = runtime.store.devices["hm"]
        assert await wait_for(lambda: state.status == "online", timeout=4)  # served idle: the module answers
        assert bus.senders.periodic[adapter.key].period_s == IDLE_DIGOUT_PERIOD_S
        await adapter.take_control("s1", "engineer")
        assert bus.senders.periodic[adapter.key].period_s == m3io.DIGOUT_PERIOD_S
        adapter.set_output("s1", "SSR1", True)
        assert await wait_for(lambda: runtime.twins["hm"].ssr[1].on, timeout=1)
        adapter.release_control("s1")
        assert await wait_for(lambda: adapter.key in bus.senders.periodic, timeout=3)  # served idle again after listening
        assert bus.senders.periodic[adapter.key].period_s == IDLE_DIGOUT_PERIOD_S
        assert await wait_for(lambda: not runtime.twins["hm"].ssr[1].on, timeout=1)
    finally:
        beat.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await beat
        await asyncio.wait_for(runtime.stop(), 5)


def test_a_reader_takes_a_telegram_in_one_read_from_a_socket_port():
    """pyserial's socket:// port says 1 for ``in_waiting`` whatever it holds; the RS485 reader thread still takes
    a whole telegram in one read (one wake-up of the event loop for it, not one per byte)."""
    import socket

    import serial

    from app.line_base import read_burst

    server = socket.create_server(("127.0.0.1", 0))
    port = serial.serial_for_url(f"socket://127.0.0.1:{server.getsockname()[1]}", timeout=0.5)
    try:
        peer, _ = server.accept()
        telegram = bytes(range(0x55, 0x55 + 12))
        peer.sendall(telegram)
        got = read_burst(port)
        while len(got) < len(telegram):  # the segment may arrive in parts: each read still takes all that is there
            more = read_burst(port)
            assert more, "the rest of the telegram did not come"
            got += more
        assert got == telegram
        assert port.timeout == 0.5  # the port's read timeout is as it was
        assert read_burst(port) == b""  # nothing more: waits the timeout and returns
        peer.close()
    finally:
        port.close()
        server.close()


async def test_mo64_counters_one_a_cycle_at_start_and_after_a_command_then_slower_and_stale_by_their_age():
    """The counters read in turn change only with the barrier's use: each once at start (one a cycle), then one
    every COUNTER_EVERY-th cycle; a command brings one a cycle again; each is marked stale by its own period."""
    from test_mo64_adapter import adapter_on_twin

    from devices.live import STALE_READINGS
    from devices.mo64 import codec
    from devices.mo64.adapter import COUNTER_EVERY, ROTATING_QUERIES

    async with adapter_on_twin() as (_sim, adapter):
        asked: list[int] = []
        counter_now = adapter._counter_now

        def recording():
            index = counter_now()
            if index is not None:
                asked.append(index)
            return index

        adapter._counter_now = recording

        async def counters_of_cycles(n: int) -> list[list[int]]:
            cycles = []
            for _ in range(n):
                asked.clear()
                await adapter.poll()
                cycles.append(list(asked))
            return cycles

        start = await counters_of_cycles(len(ROTATING_QUERIES))
        assert [c for cycle in start for c in cycle] == list(ROTATING_QUERIES)  # each once, one a cycle
        later = await counters_of_cycles(2 * COUNTER_EVERY)
        assert sum(len(cycle) for cycle in later) == 2  # one every COUNTER_EVERY-th cycle
        assert await adapter.command("s1", codec.Command.OPEN, confirmed=True) == "ack"
        after = await counters_of_cycles(len(ROTATING_QUERIES))
        assert sorted(c for cycle in after for c in cycle) == sorted(ROTATING_QUERIES)  # read again at once
        state = adapter.state
        point = state.points["Service counter"]
        assert point.every == adapter._rotation_s == len(ROTATING_QUERIES) * adapter.poll_period * COUNTER_EVERY
        assert state.quality(point.time, point.periodic, point.time + 1.0, point.every) == "good"
        aged = point.time + STALE_READINGS * point.every + 1.0
        assert state.quality(point.time, point.periodic, aged, point.every) == "stale"


async def test_supervision_tick_slower_while_no_page_and_nothing_held_and_fast_at_once_when_one_connects():
    """Nobody to supervise: the tick comes every IDLE_PERIOD_S; a page connecting ends the idle wait at once and
    the 50 ms tick goes on while it is connected or anything is held."""
    from test_deadman_worker import Holder

    from app.worker import IDLE_PERIOD_S, SUPERVISE_PERIOD_S, Worker
    from app.worker.loophealth import STALL_S

    assert SUPERVISE_PERIOD_S < IDLE_PERIOD_S <= STALL_S  # a stall of twice STALL_S is still always caught
    worker = Worker(parse_plant('name = "empty"\n'))
    await worker.start()
    try:
        health = worker.loop_health
        assert await wait_for(lambda: health.period_s == IDLE_PERIOD_S, timeout=2)
        ticks = len(health.lags_ms)
        worker.session_opened("tab")
        assert health.period_s == IDLE_PERIOD_S  # the hurried tick runs in the loop's next turn
        assert await wait_for(lambda: len(health.lags_ms) > ticks, timeout=2)
        assert health.period_s == SUPERVISE_PERIOD_S
        worker.session_deleted("tab")
        assert await wait_for(lambda: health.period_s == IDLE_PERIOD_S, timeout=2)
        worker.add_holder("output", Holder("api"))  # held for a session without a page: supervised again
        assert await wait_for(lambda: health.period_s == SUPERVISE_PERIOD_S, timeout=2)
    finally:
        await asyncio.wait_for(worker.stop(), 10)


@pytest.mark.alone  # the line's thread keeps up with its RC only with the cores to itself (else the loop reads them)
async def test_scu_data_read_in_turn_rides_on_the_rc_of_the_line_thread(scu):  # noqa: F811 - the fixture imported above
    """With the remote session open and the cyclic object, the data IDs read in turn are read by the line's thread
    right after its RC (one wake-up of the loop for both), not each through a worker thread of the loop; they are
    still read one a poll, and published with their own period."""
    from devices.scu.adapter import ROTATING_IDS

    runtime, adapter, _unit = scu
    assert await wait_for(lambda: adapter.cyclic is not None, timeout=5)
    sent: list[bytes] = []
    transact = adapter.line.transact

    async def spying(request, *args, **kwargs):
        sent.append(bytes(request))
        return await transact(request, *args, **kwargs)

    adapter.line.transact = spying
    read_at = dict(adapter.live.read_at)
    turn = set(ROTATING_IDS)
    taken_over = adapter.rc.rgs_taken_over
    assert await wait_for(lambda: turn <= {i for i, t in adapter.live.read_at.items() if t > read_at.get(i, 0.0)}, timeout=10)
    # through the loop's worker threads only what the poll read itself: those it took over from a line thread three
    # polls behind, or one read while the thread was not to read it (a machine so busy that the thread did not get
    # its turn): most of the turn rides on the RC
    through_loop = [r for r in sent if r[:2] == b"RG"]
    assert len(through_loop) < len(turn) / 2, (through_loop, adapter.rc.rgs_taken_over - taken_over)
    point = adapter.state.points["Battery voltage"]
    assert point.every is not None and point.every < 2 * adapter.live.rotation_s
