"""Twins at rest are stepped only when something falls due, at full rate as soon as something moves (issue 34).

No timing is asserted: a resting ticker is compared with one stepping at full rate over the same stretch,
and the return to full rate is waited for by its steps.
"""

from __future__ import annotations

import asyncio
import math
import time
from types import SimpleNamespace

from conftest import wait_for
from test_mo64_sim import Client, free_port

from devices import simserver
from devices.electrak import codec as electrak_codec
from devices.electrak.sim import ElectrakNetworkTwin
from devices.mo64 import codec as mo_codec
from devices.mo64.sim import TICK_S as MO_TICK_S
from devices.mo64.sim import Mo64TcpSim
from devices.scu import codec as scu_codec
from devices.scu.sim import ScuTwin


async def test_a_resting_ticker_is_not_stepped_and_wakes_to_full_rate():
    moving = False
    rested, full = [], []
    resting = simserver.Ticker(lambda dt, now: rested.append(dt), 0.01, lambda now: 0.0 if moving else math.inf,
                               idle_s=3600.0)
    reference = simserver.Ticker(lambda dt, now: full.append(dt), 0.01)
    resting.start("resting")
    reference.start("reference")
    try:
        assert await wait_for(lambda: len(full) >= 20, timeout=10)
        assert len(rested) == 0 and resting.ticks == 0  # no step at all while at rest
        moving = True
        resting.wake()  # what starts the motion calls it first: one step up to now
        assert rested and rested[0] > 0.1  # the time at rest is handed to the twin at once
        assert await wait_for(lambda: len(rested) >= 10, timeout=10)  # then at full rate
        assert max(rested[1:]) < 1.0
        moving = False
        assert await wait_for(lambda: resting._sleeper is not None, timeout=5)  # at rest again
    finally:
        resting.stop()
        reference.stop()


def test_scu_twin_rests_unless_moving_or_watched():
    twin = ScuTwin("scu", 2)
    assert twin.rest(100.0) == math.inf
    twin.remote, twin.last_rc = True, 100.0
    assert 0 < twin.rest(100.1) <= scu_codec.WATCHDOG_S  # the remote watchdog falls due
    twin.actuators[0].target = 1000.0
    assert twin.rest(100.1) == 0.0


def test_electrak_twin_at_rest_until_a_motion_is_requested():
    twin = ElectrakNetworkTwin([electrak_codec.Actuator("HD24", "B026", 300)], "electrak")
    twin.step(0.01, 1.0)
    assert twin.at_rest()
    position = twin.present[0].position_mm
    twin.on_control(electrak_codec.ControlFrame(position + 20.0, 0, 20, enable=True), 1.0)
    assert not twin.at_rest()


async def test_mo64_barrier_rests_when_closed_and_moves_at_full_rate_after_open():
    port = free_port()
    bus = SimpleNamespace(name="gate-tcp", type="logited-tcp", options={"host": "127.0.0.1", "port": port})
    dev = SimpleNamespace(name="gate1", type="mo64", bus="gate-tcp", options={"travel_s": 2.0})
    sim = Mo64TcpSim(bus, [dev])
    twin, ticker = sim.twins["gate1"], sim._ticker
    await sim.start()
    reference = simserver.Ticker(lambda dt, now: None, MO_TICK_S)
    reference.start("reference")
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    try:
        client = Client(reader, writer)
        assert twin.rest() == math.inf
        start = ticker.ticks
        assert await wait_for(lambda: reference.ticks >= 25, timeout=10)
        assert ticker.ticks - start <= 3  # ~0.5 s at rest: at most a step per IDLE_S, not one per TICK_S
        await client.send(mo_codec.encode_frame(mo_codec.encode_command(mo_codec.Command.OPEN)))
        assert await wait_for(lambda: twin.gate in (mo_codec.GateState.OPENING, mo_codec.GateState.PREWARN_OPEN), timeout=5)
        assert twin.rest() == 0.0
        moved = ticker.ticks
        assert await wait_for(lambda: ticker.ticks >= moved + 10, timeout=5)  # full rate while it moves
    finally:
        writer.close()
        reference.stop()
        await sim.stop()


class _Can:
    """A CAN endpoint that keeps what the twin sends."""

    def __init__(self, *_args):
        self.sent: list[tuple[int, bytes]] = []
        self.handlers: dict = {}

    def subscribe(self, extended, can_id, handler):
        self.handlers[can_id] = handler

    def send(self, can_id, data):
        self.sent.append((can_id, bytes(data)))
        return True

    async def start(self):
        pass

    async def stop(self):
        pass


async def test_m3io_module_rests_until_digout_and_a_toggled_input_is_sent_at_once():
    from devices.m3io import codec as m3_codec
    from devices.m3io.sim import M3ioSim

    bus = SimpleNamespace(name="can0", options={"bitrate": 500_000})
    dev = SimpleNamespace(name="heater", options={"variant": "HM", "sw1": 1})
    sim = M3ioSim(bus, [dev], _Can)
    twin = sim.twins["heater"]
    now = asyncio.get_running_loop().time()
    assert sim._rest(now) == math.inf  # silent until the master talks
    await sim.start()
    try:
        assert await wait_for(lambda: sim.ticker._sleeper is not None, timeout=5)
        sim.can.handlers[twin.ids.dig_out](SimpleNamespace(data=m3_codec.encode_dig_out(twin.variant, {"LED": True})))
        assert 0 < sim._rest(time.monotonic()) <= m3_codec.TEMP_PERIOD_S + 0.01  # temperatures due
        sent = len(sim.can.sent)
        twin.toggle_input("E1")  # a control: the module is stepped at once and sends its inputs
        assert await wait_for(lambda: any(i == twin.ids.dig_in and d == twin.dig_in() for i, d in sim.can.sent[sent:]), timeout=5)
    finally:
        await sim.stop()


def test_scu_woken_by_a_late_rc_takes_it_before_its_watchdog():
    """A line read late (a busy machine) still has the RC in time: woken by it, the twin is stepped up to now
    without the watchdog's check, which the RC then feeds (as a tick would come after its bytes were read)."""
    from devices.scu.sim import ScuSim

    bus = SimpleNamespace(name="rs1", options={"port": "socket://127.0.0.1:1"})
    sim = ScuSim(bus, [SimpleNamespace(name="scu", options={"actuators": 2})])
    twin = sim.twin
    now = time.monotonic()
    twin.remote, twin.last_rc = True, now - 2 * scu_codec.WATCHDOG_S
    sim._ticker.catch_up(1.0, now)
    assert twin.remote and twin.session_lost_count == 0
    sim._ticker.step(0.02, now)  # the next tick without an RC: remote mode ends
    assert not twin.remote and twin.session_lost_count == 1
