"""The SCU's fault sequences of issue 40, each against the real adapter on a ``socket://`` line and the twin
in the strict mode that shows it (devices/scu/sim.py): stops never acknowledged, an emergency stop refused
by the unit or pressed while the session is released, a reopening whose cyclic object gets no answer, the
other forms of RO and RS in table 3, a single CSE, a unit asleep from the start."""

from __future__ import annotations

import asyncio

import pytest
from conftest import wait_for
from test_scu_safety import F1, in_control, moving, session_open, unit

from devices.scu import codec
from devices.scu.adapter import CommandError

pytestmark = pytest.mark.timeout(60)
ESTOP = int(codec.Function.EMERGENCY_STOP)


async def running_f1(adapter, twin) -> None:
    await in_control(adapter)
    await adapter.run_function("s1", F1, codec.Motion.OUT, codec.Ramp.SOFT)
    assert await wait_for(lambda: moving(twin) == [1], 2)


async def test_a_stop_never_acknowledged_with_the_browser_gone_ends_with_the_units_watchdog():
    async with unit() as (adapter, twin):
        await running_f1(adapter, twin)
        twin.strict.cse_on_rs = -1  # every RS answered CSE: not executed
        adapter.session_lost("s1", "the page is gone")
        await adapter.stopped()
        assert await wait_for(lambda: moving(twin) == [], 2.0), "F1 still drives after a refused stop"
        assert twin.watchdog_trips, "the unit's watchdog did not stop it: RC was not withheld"
        ro_before = twin.requests.get("RO", 0)
        await asyncio.sleep(0.4)  # four RC periods: a reopening must not start the drive
        assert moving(twin) == [], "a reopening started the drive again"
        assert "STOP FAILED" in adapter.state.last_error and "watchdog" in adapter.state.last_error
        twin.strict.cse_on_rs = 0
        assert await wait_for(lambda: not adapter.rs_pending, 5), "the owed RS was not sent on reopening"
        assert twin.requests.get("RO", 0) > ro_before


async def test_a_stop_failed_with_the_browser_still_open_withholds_rc():
    async with unit() as (adapter, twin):
        await running_f1(adapter, twin)
        twin.strict.cse_on_rs = -1
        with pytest.raises(CommandError, match="STOP FAILED.*watchdog"):
            await adapter.stop("s1")
        assert await wait_for(lambda: moving(twin) == [], 1.5), "RC went on after STOP FAILED and F1 drove on"
        assert twin.watchdog_trips


async def test_a_unit_that_takes_only_the_three_byte_rs_is_stopped():
    async with unit(rs_three_bytes_only=True) as (adapter, twin):
        await running_f1(adapter, twin)
        assert await adapter.stop("s1", F1) == ["F1"]
        assert moving(twin) == [] and not adapter.rs_pending


async def test_the_emergency_stop_stops_motion_when_the_unit_refuses_re_19():
    async with unit(v2b0=True) as (adapter, twin):  # firmware V2B0: no F20 (table 8)
        await running_f1(adapter, twin)
        text = await adapter.emergency_stop("s2")  # anyone may press it; it is never refused
        assert "ON" in text and "PDE" in text
        assert moving(twin) == [], "RE 19 refused left F1 running"
        assert adapter.estop
        with pytest.raises(CommandError, match="emergency stop"):
            await adapter.run_function("s1", F1, codec.Motion.OUT, codec.Ramp.SOFT)


async def test_the_emergency_stop_is_never_refused_while_the_session_is_released():
    async with unit() as (adapter, twin):
        await in_control(adapter)
        await adapter.release_scu("s1")
        assert adapter.session == "released"
        await adapter.emergency_stop("s9")  # a viewer's page: anyone may press it
        assert twin.emergency_stop and adapter.estop
        assert "confirmed by the unit" in adapter.estop_text()


async def test_a_reopening_switches_f20_on_again_when_the_cyclic_definition_gets_no_answer():
    async with unit() as (adapter, twin):
        await in_control(adapter)
        await adapter.emergency_stop("s1")
        assert twin.emergency_stop
        twin.strict.rt_cyclic_unanswered = True
        twin.drop_line(True)
        assert await wait_for(lambda: adapter.session != "open", 5)
        twin.emergency_stop = False  # the unit was reset meanwhile
        twin.drop_line(False)
        assert await wait_for(lambda: twin.emergency_stop, 10), "F20 was not switched on again after reopening"
        assert adapter.estop


async def test_a_unit_that_takes_only_the_two_byte_ro_opens_a_session():
    async with unit(ro_two_bytes_only=True) as (adapter, twin):
        await adapter.take_control("s1", "anna")
        await session_open(adapter, 8)


async def test_one_cse_is_line_noise_and_remembered_as_nothing():
    async with unit() as (adapter, twin):
        twin.strict.cse_next = {"RT": 1, "RG": 1}
        await in_control(adapter)
        await asyncio.sleep(1.0)  # ten polls with a single CSE each: none may be remembered as a refusal
        assert not adapter.cyclic_refused, "a CSE to the cyclic definition was remembered as a refusal"
        assert not adapter.single_ids, "a CSE to a group read was remembered as a refusal of groups"


async def test_a_unit_asleep_at_start_up_is_woken_before_the_first_request():
    async with unit() as (adapter, twin):
        woken = []
        wake = adapter.line.wake

        async def spy(duration_s: float = 0.15) -> None:
            woken.append(adapter.state.counters.requests)
            await wake(duration_s)

        adapter.line.wake = spy
        adapter.link.last_answer = None  # as at start-up: nothing heard from the unit yet
        adapter.watch = None
        assert await wait_for(lambda: adapter.watch is not None, 5)
        assert woken, "no wake-up before the first request to a unit that never answered"
