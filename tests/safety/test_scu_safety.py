"""SCU safety and robustness against units written from document 002 alone (issue 25 items 1-5, issue 32 item 1).

Each test runs the real adapter on a ``socket://`` line against the twin in one of the strict modes a
real unit may have: RG refused outside remote mode (section 4.1), groups refused (the document describes
only 0x0010), RC with a cyclic object refused, RS answered with CSE, answers late, a stray byte on the
line, an answer in two pieces. A poll loop runs every 200 ms, as the worker's.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from types import SimpleNamespace

import pytest
from conftest import free_port, wait_for

from app.serial_line import SerialLine
from app.state import BusState
from devices.live import DeviceState
from devices.scu import codec
from devices.scu.adapter import P_WATCH, WATCH_RG, WATCH_SESSION, CommandError, ControlBusy, ScuAdapter
from devices.scu.sim import ScuSim

pytestmark = pytest.mark.timeout(60)
F1 = int(codec.Function.F1)
ESTOP = int(codec.Function.EMERGENCY_STOP)


@contextlib.asynccontextmanager
async def unit(actuators=2, timeout=0.3, **strict):
    """The twin (with ``strict`` modes set before the first byte), the adapter, and a 200 ms poll loop."""
    port = free_port()
    bus = SimpleNamespace(name="rs1", type="serial", options={"port": f"socket://127.0.0.1:{port}", "baudrate": 38400})
    dev = SimpleNamespace(name="scu-1", type="scu", bus="rs1", options={"actuators": actuators})
    sim = ScuSim(bus, [dev])
    twin = sim.twin
    for key, value in strict.items():
        assert hasattr(twin.strict, key), key
        setattr(twin.strict, key, value)
    await sim.start()
    opts = {"port": f"socket://127.0.0.1:{port}", "baudrate": 38400, "timeout": timeout}
    line = SerialLine("rs1", opts, BusState("rs1", "serial", opts["port"]))
    config = SimpleNamespace(name="scu-1", type="scu", bus="rs1", options={"actuators": actuators})
    adapter = ScuAdapter(config, DeviceState("scu-1", "scu", "rs1"), line)

    async def loop():
        while True:
            started = time.monotonic()
            await adapter.poll()
            await asyncio.sleep(max(0.02, 0.2 - (time.monotonic() - started)))

    async def supervise():  # the worker's dead-man supervisor: the pages of s1 and s2 are alive
        while True:
            adapter.renew_leases({"s1", "s2"})
            await asyncio.sleep(0.05)

    tasks = [asyncio.create_task(loop()), asyncio.create_task(supervise())]
    try:
        yield adapter, twin
    finally:
        for task in tasks:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
        await adapter.stopped()
        await sim.stop()
        line.close()


async def session_open(adapter, timeout=5.0) -> None:
    assert await wait_for(lambda: adapter.session == "open", timeout), (adapter.session, adapter.session_reason)


async def in_control(adapter) -> None:
    """The session open and s1 (anna) in control of the unit."""
    await session_open(adapter)
    await adapter.take_control("s1", "anna")


def moving(twin) -> list[int]:
    return [a.number for a in twin.actuators if a.moving]


# -- 25.1: the emergency stop is released only by the person who asks for it -----------------------------
async def test_emergency_stop_survives_a_lost_and_reopened_session():
    async with unit() as (adapter, twin):
        await in_control(adapter)
        await adapter.emergency_stop("s1")
        assert twin.emergency_stop
        twin.drop_line(True)  # cable out: the watchdog drops remote mode, the adapter loses the session
        assert await wait_for(lambda: adapter.session != "open", 5)
        twin.drop_line(False)
        await session_open(adapter, 10)
        assert await wait_for(lambda: adapter.state.counters.responses > 0 and len(adapter.rc_times) > 3, 5)
        assert twin.emergency_stop, "reopening released the emergency stop"
        assert ("RS", ESTOP) not in twin.function_log, twin.function_log
        await adapter.release_scu("s1")  # RA, then "Open the remote session"
        await adapter.reopen("s1")
        await asyncio.sleep(0.3)  # three polls after reopening: the emergency stop must stay
        assert twin.emergency_stop and ("RS", ESTOP) not in twin.function_log
        await adapter.release_emergency_stop("s1")  # only the explicit release switches it off
        assert not twin.emergency_stop and twin.function_log[-1] == ("RS", ESTOP)


async def test_go_while_the_emergency_stop_is_on_does_not_release_it():
    async with unit() as (adapter, twin):
        await in_control(adapter)
        await adapter.emergency_stop("s1")
        with pytest.raises(ControlBusy):
            await adapter.take_control("s2", "bert")  # a second user cannot take control; the holder presses Go
        with pytest.raises((CommandError, codec.CommandRefused)):
            await adapter.run_function("s1", F1, codec.Motion.OUT, codec.Ramp.SOFT)
        await asyncio.sleep(1.5)  # polls, a possible reopening
        assert twin.emergency_stop and ("RS", ESTOP) not in twin.function_log
        assert adapter.session == "open"


# -- 25.2: RS never before its RE --------------------------------------------------------------------------
async def test_a_jog_tap_on_a_busy_line_leaves_the_actuator_stopped():
    async with unit(answer_delay_s=0.03) as (adapter, twin):  # a busy line: every answer 30 ms late
        await in_control(adapter)
        for tap in range(6):
            pressed = time.monotonic()

            async def press():
                await asyncio.sleep(0.01 * (tap % 3))  # the press waits for its audit row (0..20 ms)
                with contextlib.suppress(CommandError):
                    await adapter.jog("s1", F1, +1 if tap % 2 else -1, requested_at=pressed)

            async def release():
                await asyncio.sleep(0.003)  # released 3 ms after the press
                await adapter.jog("s1", F1, 0)

            await asyncio.gather(press(), release())
            await asyncio.sleep(0.4)
            assert moving(twin) == [], f"tap {tap}: the actuator drives on ({twin.function_log[-4:]})"
            assert F1 not in twin.open_re, f"tap {tap}: an RE without its RS ({twin.function_log[-4:]})"
            assert adapter.holders() == set()


async def test_go_then_stop_at_once_on_a_busy_line_leaves_the_actuator_stopped():
    async with unit(answer_delay_s=0.03) as (adapter, twin):
        await in_control(adapter)
        for tap in range(4):
            pressed = time.monotonic()

            async def go_pressed():
                await asyncio.sleep(0.01 * (tap % 3))  # Go waits for its audit row (0..20 ms)
                await adapter.run_function("s1", F1, codec.Motion.OUT if tap % 2 else codec.Motion.IN,
                                           codec.Ramp.SOFT, requested_at=pressed)

            go = asyncio.create_task(go_pressed())
            await asyncio.sleep(0.003)
            await adapter.stop("s1")
            with contextlib.suppress(CommandError):
                await go
            await asyncio.sleep(0.4)
            assert moving(twin) == [] and F1 not in twin.open_re, f"tap {tap}: {twin.function_log[-4:]}"


# -- 25.3: a refused RS is sent again; the function stays held until an acknowledged RS --------------------
async def test_rs_refused_with_cse_is_sent_again_and_the_actuator_stops():
    async with unit() as (adapter, twin):
        await in_control(adapter)
        await adapter.run_function("s1", F1, codec.Motion.OUT, codec.Ramp.SOFT)
        assert await wait_for(lambda: moving(twin) == [1], 2)
        twin.strict.cse_on_rs = 2  # the first two RS are not executed (section 4.2: CSE)
        assert await adapter.stop("s1") == ["F1"]
        assert moving(twin) == [] and F1 not in twin.open_re
        assert adapter.holders() == set() and not adapter.rs_pending


async def test_rs_never_acknowledged_is_a_failed_stop_held_and_retried():
    async with unit() as (adapter, twin):
        await in_control(adapter)
        await adapter.run_function("s1", F1, codec.Motion.OUT, codec.Ramp.SOFT)
        twin.strict.cse_on_rs = -1  # every RS refused
        with pytest.raises(CommandError, match="STOP FAILED"):
            await adapter.stop("s1")
        assert adapter.holders() == {"s1"} and F1 in adapter.rs_pending  # held: the dead-man rule still covers it
        assert "STOP FAILED" in adapter.state.last_error
        with pytest.raises(CommandError):
            await adapter.run_function("s1", F1, codec.Motion.IN, codec.Ramp.SOFT)  # no new RE before the RS
        twin.strict.cse_on_rs = 0
        assert await wait_for(lambda: not adapter.rs_pending, 3)  # the poll sends RS again
        assert moving(twin) == [] and F1 not in twin.open_re and adapter.holders() == set()


# -- 25.4: no remote session with nobody in control ---------------------------------------------------------
async def test_a_unit_that_answers_rg_outside_remote_mode_is_watched_without_a_session():
    async with unit(rg_outside_session=True) as (adapter, twin):
        assert await wait_for(lambda: adapter.watch == WATCH_RG and "A1 position" in adapter.state.points, 5)
        await asyncio.sleep(0.6)  # six polls: no session may be opened
        assert "RO" not in twin.requests and "RC" not in twin.requests and not twin.remote
        assert "without" in adapter.state.live(P_WATCH).text and adapter.session != "open"
        assert await wait_for(lambda: "Battery voltage" in adapter.state.points, 6)
        await adapter.take_control("s1", "anna")  # control opens the session ...
        await session_open(adapter)
        assert twin.remote
        await adapter.release_control("s1")  # ... and its release ends it: the hand switch has the unit again
        assert await wait_for(lambda: not twin.remote and adapter.session == "closed", 3)


async def test_a_unit_that_refuses_rg_outside_remote_mode_is_read_in_a_session_and_the_page_is_told():
    async with unit() as (adapter, twin):
        await session_open(adapter)
        assert adapter.watch == WATCH_SESSION
        assert "reading only" in adapter.state.live(P_WATCH).text
        with pytest.raises(CommandError, match="take control"):
            await adapter.run_function("s2", F1, codec.Motion.OUT)
        assert ("RE", F1) not in twin.function_log


# -- 25.5: a unit that answers only single data IDs ----------------------------------------------------------
LIVE = ("A1 position", "A2 position", "A1 status 1", "A2 status 2", "A1 current", "Error code", "Mains",
        "Battery voltage", "A1 speed", "Binary Output Status")


@pytest.mark.parametrize("strict", [{"single_ids_only": True}, {"refuse_cyclic_rc": True},
                                    {"single_ids_only": True, "refuse_cyclic_rc": True}],
                         ids=["single-ids", "cyclic-rc-refused", "both"])
async def test_every_live_value_from_a_unit_that_refuses_groups_or_the_cyclic_object(strict):
    async with unit(**strict) as (adapter, twin):
        shown = await wait_for(lambda: all(k in adapter.state.points for k in LIVE), 15)
        assert shown, sorted(set(LIVE) - set(adapter.state.points))
        assert adapter.session == "open" and adapter.state.online
        assert twin.session_lost_count == 0, "the watchdog tripped"
        assert twin.requests.get("RO", 0) == 1, "the session was reopened"


# -- 32.1: resynchronise after a stray byte, a split or a late answer ----------------------------------------
async def test_stray_bytes_split_and_late_answers_never_end_the_session():
    async with unit(split_answers=True) as (adapter, twin):
        await session_open(adapter)
        twin.strict.stray_bytes = 5
        await asyncio.sleep(1.0)  # a second of stray bytes on the line
        twin.strict.answer_delay_s = 0.45  # late beyond the 0.3 s timeout: the answers arrive during the next request
        await asyncio.sleep(0.8)  # late answers for a while: each arrives during the next request
        twin.strict.answer_delay_s = 0.0
        await session_open(adapter, 10)
        before = adapter.state.counters.responses
        assert await wait_for(lambda: adapter.state.counters.responses > before + 10, 5)
        assert adapter.session == "open"
        await adapter.take_control("s1", "anna")
        await adapter.run_function("s1", F1, codec.Motion.OUT, codec.Ramp.SOFT)
        await adapter.stop("s1")
        assert moving(twin) == []
