"""M3IO outputs belong to the page session that switched them on (dead-man rule, issue 9 items 1-2).

Adapter-only tests call ``session_lost`` directly; the worker tests keep a session alive with
heartbeats and let the worker trip it.
"""

from __future__ import annotations

import asyncio
import contextlib
import time

import pytest
import plants
from conftest import running_plant, wait_for
from plants import can_bus, device

from app.plant import parse_plant
from app.worker import DEADMAN_BOUND_S
from devices.m3io.adapter import ControlBusy

TAB_A, TAB_B = "client-a", "client-b"  # NiceGUI client ids of two page sessions


def plant_text() -> str:
    return plants.plant_text(can_bus(device("hm", "m3io", "can3", variant="HM", sw1=0x1A), name="can3", bitrate=500000,
                                     poll_period=0.2), name=None)


@pytest.fixture
async def module():
    async with running_plant(parse_plant(plant_text())) as runtime:
        yield runtime


async def control(runtime, session: str = TAB_A) -> None:
    """Take control for ``session`` (this tool serves the watchdog only then) and wait for the module's answers."""
    await runtime.worker.adapters["hm"].take_control(session, "engineer")
    assert await wait_for(lambda: runtime.store.devices["hm"].status == "online", timeout=4)


async def test_outputs_belong_to_the_session_that_switched_them(module):
    await control(module, TAB_A)
    adapter = module.worker.adapters["hm"]
    twin = module.twins["hm"]
    state = module.store.devices["hm"]
    bus_state = module.worker.can_buses["can3"].state
    assert adapter.holders() == set()
    adapter.set_output(TAB_A, "SSR2", True)
    adapter.set_output(TAB_A, "SSR3", True)
    with pytest.raises(ControlBusy):  # another tab switches nothing on while this one controls the module
        adapter.set_output(TAB_B, "SSR4", True)
    assert await wait_for(lambda: twin.ssr[2].on and twin.ssr[3].on, timeout=1)
    assert adapter.holders() == {TAB_A}
    adapter.session_lost(TAB_B, "the other tab stopped answering")  # not its business
    assert adapter.outputs["SSR2"] and adapter.controller is not None
    sent = bus_state.tx_frames
    started = time.monotonic()
    adapter.session_lost(TAB_A, "the browser tab stopped answering")
    assert bus_state.tx_frames > sent  # DigOut sent at once, not at the next period
    assert not adapter.outputs["SSR2"] and not adapter.outputs["SSR3"]
    assert await wait_for(lambda: not twin.ssr[2].on and not twin.ssr[3].on, timeout=DEADMAN_BOUND_S, interval=0.005)
    print(f"SSR2 off in the module {1000 * (time.monotonic() - started):.1f} ms after session_lost")
    assert adapter.holders() == set() and adapter.controller is None  # its control ended with it
    assert any("SSR2" in e.text and "the browser tab stopped answering" in e.text for e in state.events)
    assert not module.worker.can_buses["can3"].cyclic_running(adapter.key)  # no DigOut without an engineer


async def test_switching_off_and_all_off_release_the_outputs(module):
    await control(module, TAB_A)
    adapter = module.worker.adapters["hm"]
    state = module.store.devices["hm"]
    adapter.set_output(TAB_A, "SSR1", True)
    adapter.set_output(TAB_A, "LED", True)
    adapter.set_output(TAB_B, "SSR1", False)  # any session may switch off
    assert adapter.holders() == {TAB_A}  # still holds the LED
    adapter.set_output(TAB_A, "SSR4", True)
    adapter.all_off("all off pressed")
    assert adapter.holders() == set() and not any(adapter.outputs.values())
    events = len(state.events)
    adapter.session_lost(TAB_B, "disconnected")  # owns nothing, controls nothing: nothing to do
    assert len(state.events) == events
    assert state.live("Outputs on").value == ()


async def _beat(worker, session: str, last: dict | None = None) -> None:
    """A page's heartbeat, about every 0.1 s; ``last[session]`` is the time of the latest one."""
    while True:
        worker.heartbeat(session)
        if last is not None:
            last[session] = time.monotonic()
        await asyncio.sleep(0.1)


async def test_worker_switches_off_when_the_owner_stops_confirming(module):
    worker = module.worker
    adapter = worker.adapters["hm"]
    twin = module.twins["hm"]
    worker.session_opened(TAB_A)
    worker.session_opened(TAB_B)  # another tab of the same browser (the overview)
    last: dict[str, float] = {}
    beats = {s: asyncio.create_task(_beat(worker, s, last)) for s in (TAB_A, TAB_B)}
    try:
        await control(module, TAB_A)
        adapter.set_output(TAB_A, "SSR1", True)
        assert await wait_for(lambda: twin.ssr[1].on, timeout=2)
        await asyncio.sleep(1.0)  # confirmed alive: stays on for twice app.worker.DEADMAN_BOUND_S (0.5 s)
        assert twin.ssr[1].on and adapter.outputs["SSR1"]
        beats.pop(TAB_A).cancel()  # the tab freezes
        assert await wait_for(lambda: not twin.ssr[1].on, timeout=2, interval=0.005)
        elapsed = time.monotonic() - last[TAB_A]
        print(f"SSR1 off in the module {1000 * elapsed:.0f} ms after the last heartbeat")
        assert elapsed <= DEADMAN_BOUND_S
        assert not adapter.outputs["SSR1"] and TAB_A not in adapter.holders()
    finally:
        for task in beats.values():
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task


async def test_closing_the_page_switches_off_although_another_tab_is_open(module):
    """Issue 9.2: the overview open in another tab does not keep the M3IO page's outputs on."""
    worker = module.worker
    adapter = worker.adapters["hm"]
    twin = module.twins["hm"]
    worker.session_opened(TAB_A)
    worker.session_opened(TAB_B)
    beat = asyncio.create_task(_beat(worker, TAB_B))
    try:
        worker.heartbeat(TAB_A)
        await control(module, TAB_A)
        worker.heartbeat(TAB_A)
        adapter.set_output(TAB_A, "SSR5", True)
        assert await wait_for(lambda: twin.ssr[5].on, timeout=1)
        closed = time.monotonic()
        worker.session_closed(TAB_A)
        assert not adapter.outputs["SSR5"]
        assert await wait_for(lambda: not twin.ssr[5].on, timeout=DEADMAN_BOUND_S, interval=0.005)
        print(f"SSR5 off in the module {1000 * (time.monotonic() - closed):.1f} ms after the page closed")
    finally:
        beat.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await beat
