"""SCU RC keep-alive on the serial line's own thread, under a lease (issue 28; ARCHITECTURE rule 6).

The worker runs for real (its dead-man supervisor renews the lease while the page of ``s1`` beats);
the twin runs on an event loop of its own in another thread, so that blocking the program's loop on
purpose (``time.sleep`` run as a loop callback, as tests/safety/test_keepalive_lease.py does) does not block
the unit. What the unit saw is read from the twin: RC arrivals, RE/RS with their times, the watchdog.
"""

from __future__ import annotations

import asyncio
import itertools
import threading
import time

import pytest
from conftest import alive, free_port, running_plant, wait_for
from plants import plant_text, scu_line

from app.plant import parse_plant
from app.worker.deadman import SILENCE_LIMIT_S
from devices.scu import codec
from devices.scu.sim import ScuSim

pytestmark = pytest.mark.timeout(90)

F1 = int(codec.Function.F1)
OUTPUT_1 = int(codec.Function.BINARY_OUTPUT_1)
ESTOP = int(codec.Function.EMERGENCY_STOP)
# the stall: far beyond the 0.1 s lease and the unit's 0.5 s watchdog, below the dead-man's SILENCE_LIMIT_S (2 s of no
# sign of life in real time stops the session). At 2.0 s the page's last beat before the stall made it 2.0-2.1 s, and
# whether the dead-man or the page's next beat ran first after it decided whether control stayed (2026-11-29)
BLOCK_S = SILENCE_LIMIT_S - 0.5
BOUND_S = 0.5  # the stated bound: motion stopped within 0.5 s of the stall's start


class TwinThread:
    """The SCU twin on an event loop of its own (a real unit does not stall with this program)."""

    def __init__(self, plant):
        bus = plant.buses["rs1"]
        self.sim = ScuSim(bus, plant.devices_on("rs1"))
        self.twin = self.sim.twin
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, name="scu twin", daemon=True)
        self.samples: list[tuple[float, bool]] = []  # (time, an actuator moves)
        self._sampling = True
        self._sampler = threading.Thread(target=self._sample, name="scu twin sampler", daemon=True)

    def _sample(self) -> None:
        while self._sampling:
            self.samples.append((time.monotonic(), any(a.moving for a in self.twin.actuators)))
            time.sleep(0.005)

    def start(self) -> None:
        self.thread.start()
        asyncio.run_coroutine_threadsafe(self.sim.start(), self.loop).result(5)
        self._sampler.start()

    def stop(self) -> None:
        self._sampling = False
        self._sampler.join(2)
        asyncio.run_coroutine_threadsafe(self.sim.stop(), self.loop).result(5)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(5)
        self.loop.close()

    def stopped_moving_after(self, since: float) -> float | None:
        return next((t for t, moving in list(self.samples) if t >= since and not moving), None)

    def log_since(self, since: float) -> list[tuple[str, int]]:
        return [entry for entry, t in zip(list(self.twin.function_log), list(self.twin.function_times)) if t >= since]

    def rc_gaps(self, since: float, until: float) -> list[float]:
        times = [t for t in list(self.twin.rc_received) if since <= t <= until]
        return [b - a for a, b in itertools.pairwise(times)]


def scu_plant(port: int) -> str:
    return plant_text(scu_line("scu", port=port, actuators=2, baudrate=38400), name=None)


def block_loop(seconds: float) -> float:
    """Stall the event loop for ``seconds`` (a callback that sleeps, as a blocking call would); its start time."""
    started = time.monotonic()
    asyncio.get_running_loop().call_soon(time.sleep, seconds)
    return started


@pytest.fixture
async def scu():
    plant = parse_plant(scu_plant(free_port()))
    unit = TwinThread(plant)
    unit.start()
    try:
        async with running_plant(plant, simulate=False, stop_within_s=10) as runtime, alive(runtime.worker, "s1"):
            adapter = runtime.worker.adapters["scu"]
            assert await wait_for(lambda: adapter.session == "open", 10), adapter.session_reason
            yield runtime, adapter, unit
    finally:
        unit.stop()


@pytest.mark.alone  # the line's thread held to the stated 0.5 s with its wake-ups on time: not beside five other tests
async def test_a_stalled_loop_stops_the_jog_by_rs_from_the_line_thread(scu):
    runtime, adapter, unit = scu
    twin = unit.twin
    await adapter.take_control("s1", "anna")
    await adapter.jog("s1", F1, +1)
    assert await wait_for(lambda: twin.actuators[0].moving, 2)
    await asyncio.sleep(0.6)  # longer than the lease: the supervisor renews it while the page beats
    assert twin.actuators[0].moving and adapter.holders() == {"s1"}, (twin.function_log[-3:], [e.text for e in adapter.state.events][-5:])
    blocked = block_loop(BLOCK_S)
    await asyncio.sleep(0)  # the loop runs the sleeping callback here
    stopped = unit.stopped_moving_after(blocked)
    assert stopped is not None, "the actuator drove on while the program stalled"
    stop_ms = (stopped - blocked) * 1000
    during = unit.log_since(blocked)
    print(f"loop blocked for {BLOCK_S:g} s: motion stopped {stop_ms:.0f} ms after the block; "
          f"the unit saw {during} during it, watchdog trips {[round((t - blocked) * 1000) for t in twin.watchdog_trips]} ms")
    assert stop_ms < BOUND_S * 1000
    # stopped by the explicit RS from the line's thread while the loop still slept, never RS 19 ...
    rs_times = [t for (kind, fn), t in zip(twin.function_log, twin.function_times) if (kind, fn) == ("RS", F1) and t >= blocked]
    assert rs_times and rs_times[0] < blocked + BOUND_S, during
    assert ("RS", ESTOP) not in twin.function_log
    # ... and then RC withheld: the unit's own watchdog ended remote mode (every drive stopped, section 5)
    assert [t for t in twin.watchdog_trips if blocked < t < blocked + BLOCK_S], "RC went on after the lease lapsed"
    # after the stall: the program says why, holds nothing, reopens; nothing restarts by itself
    assert await wait_for(lambda: any("lease" in e.text and "RS to F1" in e.text for e in adapter.state.events
                                      if e.level == "error"), 3)
    assert adapter.holders() == set() and not adapter.rs_pending
    assert await wait_for(lambda: adapter.session == "open", 10), adapter.session_reason
    await asyncio.sleep(0.5)  # five polls after reopening: nothing may move
    assert not any(a.moving for a in twin.actuators) and ("RE", F1) not in unit.log_since(blocked)
    assert adapter.controller is not None  # control stays with the engineer: the next press moves again
    await adapter.jog("s1", F1, -1)
    assert await wait_for(lambda: twin.actuators[0].moving, 2)
    await adapter.jog("s1", F1, 0)
    assert await wait_for(lambda: not twin.actuators[0].moving, 1)


async def test_an_idle_session_is_kept_alive_through_a_stall(scu):
    """Nothing runs: RC goes on from the line's thread through a 1 s stall, the watchdog never trips."""
    runtime, adapter, unit = scu
    twin = unit.twin
    await asyncio.sleep(0.5)  # the session runs idle before the stall
    blocked = block_loop(1.0)
    await asyncio.sleep(0)
    gaps = unit.rc_gaps(blocked - 0.2, blocked + 1.0)
    print(f"idle RC through a 1 s stall: {len(gaps) + 1} RC, worst gap {max(gaps) * 1000:.0f} ms")
    assert len(gaps) >= 4 and max(gaps) < codec.WATCHDOG_S
    assert twin.session_lost_count == 0 and adapter.session == "open"


async def test_a_lapse_never_sends_rs_19_and_keeps_the_emergency_stop_on(scu):
    """Emergency stop on and an output held: the line's thread sends RS to the output only; RC goes on,
    so remote mode (and with it the emergency stop) stays."""
    runtime, adapter, unit = scu
    twin = unit.twin
    await adapter.take_control("s1", "anna")
    await adapter.emergency_stop("s1")
    await adapter.run_function("s1", OUTPUT_1)
    assert twin.emergency_stop and twin.io.binary_outputs & 1
    blocked = block_loop(BLOCK_S)
    await asyncio.sleep(0)
    during = unit.log_since(blocked)
    assert ("RS", OUTPUT_1) in during and ("RS", ESTOP) not in twin.function_log, during
    assert twin.emergency_stop and not twin.io.binary_outputs & 1
    assert twin.session_lost_count == 0, "RC was withheld although the emergency stop is on"
    assert max(unit.rc_gaps(blocked, blocked + BLOCK_S)) < codec.WATCHDOG_S
    assert await wait_for(lambda: adapter.holders() == set() and any("emergency stop is on" in e.text
                                                                      for e in adapter.state.events), 3)
    assert adapter.session == "open" and adapter.estop


async def test_a_lease_ended_beside_the_held_functions_is_stopped_as_a_lapse(scu, caplog):
    """The generic control ends the lease without the keep-alive's guard (a dead-man release): the line's thread
    saw F1 held and no lease, and the loop's report of the lapse failed on its missing time (a TypeError in the
    callback, 2026-11-29), so the lapse was never handed to the session. Now it is a lapse noticed then."""
    runtime, adapter, unit = scu
    twin = unit.twin
    await adapter.take_control("s1", "anna")
    await adapter.jog("s1", F1, +1)
    assert await wait_for(lambda: twin.actuators[0].moving, 2)
    adapter.lease.revoke()  # as devices/control.py idle() does, F1 still held
    assert await wait_for(lambda: not twin.actuators[0].moving, 2), "F1 drove on"
    assert await wait_for(lambda: any("lease" in e.text and "RS to F1" in e.text for e in adapter.state.events
                                      if e.level == "error"), 3), [e.text for e in adapter.state.events][-5:]
    assert "Exception in callback" not in caplog.text, caplog.text


async def test_the_lease_ends_only_with_the_held_functions_so_a_stop_is_never_a_lapse(scu):
    """An acknowledged RS ends the lease (nothing held any more). The loop did so outside the keep-alive's guard
    and told the line's thread of the held functions only later: a thread that looked in between saw F1 held and
    no lease, a lapse that never was. Every end of the lease is checked here as the thread would see it."""
    runtime, adapter, unit = scu
    twin = unit.twin
    lease, seen = adapter.lease, []
    revoke = lease.revoke

    def revoked() -> None:
        # the thread reads the held functions and the lease under the guard: held by the loop now, or nothing held
        seen.append(adapter.rc.guard.locked() or not adapter.rc.held)
        revoke()

    lease.revoke = revoked
    await adapter.take_control("s1", "anna")
    for direction in (+1, -1, +1):
        await adapter.jog("s1", F1, direction)
        assert await wait_for(lambda: twin.actuators[0].moving, 2)
        await adapter.jog("s1", F1, 0)
        assert await wait_for(lambda: not twin.actuators[0].moving and not adapter.holders(), 2)
    assert seen and all(seen), f"the lease ended {seen.count(False)} of {len(seen)} times with functions still held"
    assert adapter.rc.lapses == 0 and not any("lapsed" in e.text for e in adapter.state.events)
