"""Electrak HD control: listen before taking control, a foreign 0x06 sender, the dead-man rule, Saturated."""

from __future__ import annotations

import asyncio

import pytest
from conftest import wait_for
from test_electrak import beat, lift, start_lift  # noqa: F401 (fixture)

import app.worker
from devices.electrak import codec
from devices.electrak.adapter import ControlBusy, ForeignControl


def plc_send(runtime, frame: codec.ControlFrame) -> None:
    """A frame from another node of the bus (the simulator's side of the virtual channel)."""
    runtime.sim.servers[0].can.send(codec.CONTROL_ID, frame.encode())


async def plc(runtime, frame: codec.ControlFrame, seconds: float) -> None:
    loop = asyncio.get_running_loop()
    end = loop.time() + seconds
    while loop.time() < end:
        plc_send(runtime, frame)
        await asyncio.sleep(codec.CONTROL_PERIOD_S)


# -- listen before taking control ---------------------------------------------------------------


async def test_take_control_is_refused_while_a_manual_line_sends(lift):  # noqa: F811
    _runtime, adapter, state, twin = lift
    twin.set_manual_line(+1)  # an actuator's control line is active: it sends 0x06 itself
    assert await wait_for(lambda: state.live("Foreign control sender").value, timeout=1)
    with pytest.raises(ForeignControl, match="0x06.*(PLC|control line)"):
        await adapter.take_control("s1", "engineer")
    assert adapter.controller is None
    twin.set_manual_line(0)
    await asyncio.sleep(codec.LISTEN_S + 0.1)  # "CAN-Steuerung": three 100 ms control periods without 0x06 mean no other master
    await adapter.take_control("s1", "engineer")
    assert adapter.controller is not None


async def test_take_control_is_refused_while_a_plc_sends(lift):  # noqa: F811
    runtime, adapter, _state, _twin = lift
    task = asyncio.create_task(plc(runtime, codec.ControlFrame(10, 0, 20), 1.0))
    await asyncio.sleep(0.05)  # a PLC that has just started: one frame so far, half of its 100 ms control period
    try:
        with pytest.raises(ForeignControl, match="PLC"):
            await adapter.take_control("s1", "engineer")
    finally:
        await task
    assert not runtime.worker.can_buses["can2"].cyclic_running(adapter.key)


async def test_a_foreign_control_telegram_ends_our_control(lift):  # noqa: F811
    runtime, adapter, state, twin = lift
    await adapter.take_control("s1", "engineer")
    adapter.set_command("s1", 200.0, 20.0, 0)
    adapter.go("s1")
    assert await wait_for(lambda: state.live("Motion flags").value & 1, timeout=2)
    plc_send(runtime, codec.ControlFrame(0, 0, 20, enable=False))
    assert await wait_for(lambda: adapter.controller is None, timeout=0.5)
    assert not adapter.command.enable and not runtime.worker.can_buses["can2"].cyclic_running(adapter.key)
    assert any("another sender" in e.text and "0x06" in e.text for e in state.events if e.level == "error")
    assert await wait_for(lambda: state.live("Motion flags").value == 0, timeout=1)


# -- the dead-man rule: holders() and session_lost() -------------------------------------------


async def test_holders_are_sessions_with_motion_running(lift):  # noqa: F811
    _runtime, adapter, _state, _twin = lift
    assert adapter.holders() == set()
    await adapter.take_control("s1", "engineer")
    assert adapter.holders() == set()  # control without enable keeps nothing running
    adapter.set_command("s1", 100.0, 20.0, 0)
    adapter.go("s1")
    assert adapter.holders() == {"s1"}
    adapter.stop("s1")
    assert adapter.holders() == set()
    adapter.jog("s1", +1)
    assert adapter.holders() == {"s1"}
    adapter.jog("s1", 0)
    adapter.override("s1", True, confirmed=True)
    assert adapter.holders() == {"s1"}


async def test_session_lost_stops_at_once(lift):  # noqa: F811
    runtime, adapter, state, twin = lift
    await adapter.take_control("s1", "engineer")
    adapter.jog("s1", +1)
    assert await wait_for(lambda: state.live("Motion flags").value & 1, timeout=2)
    adapter.session_lost("other", "frozen")
    assert adapter.controller is not None  # not its business
    loop = asyncio.get_running_loop()
    lost = loop.time()
    adapter.session_lost("s1", "the browser stopped confirming it is alive")
    assert adapter.controller is None and adapter.holders() == set()
    assert not runtime.worker.can_buses["can2"].cyclic_running(adapter.key)
    assert await wait_for(lambda: twin.control is not None and not twin.control.enable, timeout=0.5)
    assert loop.time() - lost < 0.2  # sent at once, not at the next cycle
    stopped = [a.position_mm for a in twin.actuators]
    await asyncio.sleep(0.3)  # three status periods (0x07 every 100 ms): standing still
    assert [a.position_mm for a in twin.actuators] == stopped
    assert any("stopped confirming" in e.text for e in state.events)


async def test_worker_trips_a_silent_session_within_the_bound():
    runtime, adapter, state, twin = await start_lift()
    beating = asyncio.create_task(beat(runtime, ("alive",)))
    try:
        await adapter.take_control("alive", "engineer")
        adapter.jog("alive", +1)
        await asyncio.sleep(0.6)  # the beating session keeps its jog longer than app.worker.DEADMAN_BOUND_S (0.5 s)
        assert adapter.command.enable and adapter.controller is not None
        beating.cancel()  # the browser freezes
        loop = asyncio.get_running_loop()
        frozen = loop.time()
        assert await wait_for(lambda: twin.control is not None and not twin.control.enable, timeout=2, interval=0.01)
        assert loop.time() - frozen <= app.worker.DEADMAN_BOUND_S + 0.1  # 0.1 s: this test's beat period
        assert adapter.controller is None
    finally:
        beating.cancel()
        await asyncio.wait_for(runtime.stop(), 5)


# -- Saturated must not stay set ----------------------------------------------------------------


async def test_saturated_that_stays_on_is_warned(lift):  # noqa: F811
    _runtime, adapter, state, twin = lift
    await adapter.take_control("s1", "engineer")
    twin.set_load(6.0)
    adapter.set_command("s1", 290.0, 32.0, 0)
    adapter.go("s1")
    assert await wait_for(lambda: state.live("Motion flags").value & 0x04, timeout=2)
    assert await wait_for(lambda: state.live("Saturated warning").value, timeout=codec.SATURATED_WARN_S + 1)
    assert "Saturated" in state.live("Saturated warning").value and "speed" in state.live("Saturated warning").value
    assert any("Saturated" in e.text for e in state.events if e.level == "warning")
    adapter.stop("s1")
    assert await wait_for(lambda: not state.live("Saturated warning").value, timeout=1)


async def test_a_dropped_connection_stops_motion_but_keeps_idle_control(lift):  # noqa: F811
    """A page whose connection drops (a reconnect under load) must not lose its control: motion stops at
    once, the idle keep-alive goes on (no message timeout); control goes only when the page is gone."""
    runtime, adapter, state, twin = lift
    await adapter.take_control("s1", "engineer")
    adapter.jog("s1", +1)
    assert await wait_for(lambda: state.live("Motion flags").value & 1, timeout=2)
    runtime.worker.session_closed("s1")  # the socket dropped; the page may reconnect
    assert not adapter.command.enable and adapter.controller is not None
    assert runtime.worker.can_buses["can2"].cyclic_running(adapter.key)
    assert await wait_for(lambda: twin.control is not None and not twin.control.enable, timeout=0.5)
    await asyncio.sleep(0.4)  # longer than the 250 ms message timeout: the keep-alive went on
    assert not state.live("Error flags").value & 0x20
    runtime.worker.session_deleted("s1")  # it did not come back
    assert adapter.controller is None and not runtime.worker.can_buses["can2"].cyclic_running(adapter.key)


async def test_another_page_may_take_over_control_from_a_disconnected_one(lift):  # noqa: F811
    runtime, adapter, _state, _twin = lift
    await adapter.take_control("s1", "engineer")
    with pytest.raises(ControlBusy):
        await adapter.take_control("s2", "engineer")
    runtime.worker.session_closed("s1")  # its page closed (NiceGUI deletes it only seconds later)
    await adapter.take_control("s2", "engineer")
    assert adapter.controller.session == "s2"
    runtime.worker.session_closed("s2")
    runtime.worker.heartbeat("s2")  # it reconnected: control is its own again
    with pytest.raises(ControlBusy):
        await adapter.take_control("s3", "engineer")
