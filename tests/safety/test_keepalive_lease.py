"""Keep-alives on a clock of their own, under a lease (issue 28; ARCHITECTURE rule 6).

The control telegram of the Electrak and the M3IO's DigOut leave on python-can's cyclic task,
not on the event loop; the loop's dead-man supervisor renews a short lease while motion or a
mains output runs. These tests block the event loop on purpose (``time.sleep`` run as a loop
callback: the program stalls) and listen on the same virtual CAN channel from a thread of
their own, so what they see on the bus does not depend on the blocked loop.
"""

from __future__ import annotations

import asyncio
import itertools
import threading
import time

import can
import pytest
from conftest import alive, running_plant, wait_for
from can_listener import FrameListener
from plants import can_bus, channel, m3io_can, plant_text
from test_electrak import beat, lift, start_lift  # noqa: F401 (fixture)

from app.plant import parse_plant
from app.runtime import Runtime
from devices.electrak import codec as electrak
from devices.lease import Lease
from devices.m3io import codec as m3io
from devices.m3io.adapter import CommandError as M3ioError
from devices.m3io.adapter import ForeignMaster

BLOCK_S = 2.0
BOUND_S = 0.5  # the stated bound: the stop form on the bus within 0.5 s of the stall's start


class Listener(FrameListener):
    """Every frame of one virtual channel, time-stamped in a thread that the blocked loop cannot hold up."""

    def __init__(self, channel: str):
        super().__init__(can.Bus(interface="virtual", channel=channel, receive_own_messages=False), poll_s=0.02)


def block_loop(seconds: float) -> float:
    """Stall the event loop for ``seconds`` (a callback that sleeps, as a blocking call would); its start time."""
    started = time.monotonic()
    asyncio.get_running_loop().call_soon(time.sleep, seconds)
    return started


# -- the lease primitive ----------------------------------------------------------------------------------


def test_lease_lapses_and_stays_lapsed_until_granted_again():
    lease = Lease(0.3)
    assert not lease.valid(10.0) and not lease.renew(10.0)  # never granted: nothing may run
    lease.grant(10.0)
    assert lease.valid(10.2) and lease.renew(10.25) and lease.valid(10.5)
    assert not lease.valid(10.6)  # 0.35 s after the last renewal
    assert lease.lapsed_at == pytest.approx(10.55)
    assert not lease.renew(10.61) and not lease.valid(10.62)  # a program that wakes up does not restart motion
    lease.grant(11.0)
    assert lease.valid(11.1) and lease.lapsed_at is None
    lease.revoke()
    assert not lease.valid(11.1) and lease.lapsed_at is None  # stopped on purpose: no lapse


def test_lease_is_thread_safe_under_contention():
    lease = Lease(0.05)
    lease.grant()
    errors = []

    def hammer():
        try:
            for _ in range(20_000):
                lease.valid()
                lease.renew()
        except Exception as exc:  # noqa: BLE001
            errors.append(exc)

    threads = [threading.Thread(target=hammer) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(30)
    assert not errors


# -- Electrak: the control telegram 0x06 ------------------------------------------------------------------


async def test_a_stalled_loop_stops_the_jog_by_itself(lift):  # noqa: F811
    runtime, adapter, state, twin = lift
    listener = Listener(runtime.plant.buses["can2"].options["channel"])
    try:
        await adapter.take_control("s1", "engineer")
        adapter.jog("s1", +1)
        assert await wait_for(lambda: state.live("Motion flags").value & 1, timeout=2)
        await asyncio.sleep(0.4)  # enabled telegrams go on while the loop renews the lease
        assert adapter.command.enable
        blocked = block_loop(BLOCK_S)
        await asyncio.sleep(0)  # the loop runs the sleeping callback here
        during = listener.of(electrak.CONTROL_ID, since=blocked, until=blocked + BLOCK_S)
        stops = [t for t, d in during if not d[7] & 0x01]
        assert stops, "enable stayed set on the bus while the program stalled"
        stop_ms = (stops[0] - blocked) * 1000
        print(f"loop blocked for {BLOCK_S:g} s: enable cleared on the bus {stop_ms:.0f} ms after the block, "
              f"{len(during)} control telegrams during it")
        assert stop_ms < BOUND_S * 1000
        assert len(during) >= BLOCK_S / electrak.CONTROL_PERIOD_S / 2  # the keep-alive went on during the stall
        assert not [d for t, d in during if t > stops[0] and d[7] & 0x01]  # and never enabled again
        # after the stall: the program knows the motion stopped and says why; nothing restarts by itself
        assert await wait_for(lambda: not adapter.command.enable, timeout=1)
        assert any("stalled" in e.text and "browser was not at fault" in e.text for e in state.events if e.level == "error")
        await asyncio.sleep(0.3)  # three control periods after the stall: nothing may enable again
        assert not [d for t, d in listener.of(electrak.CONTROL_ID, since=stops[0]) if d[7] & 0x01]
        assert adapter.controller is not None  # control stays with the engineer: the next press moves again
    finally:
        listener.close()


async def test_stop_and_jog_release_leave_at_once(lift):  # noqa: F811
    """Issue 26 item 7: the page says "at once"; the frame must not wait for the next 100 ms period."""
    runtime, adapter, state, twin = lift
    bus_state = runtime.worker.can_buses["can2"].state
    await adapter.take_control("s1", "engineer")
    adapter.jog("s1", +1)
    assert await wait_for(lambda: state.live("Motion flags").value & 1 and (adapter.position_mm() or 0) > 2.0, timeout=3)
    sent = bus_state.tx_frames
    adapter.jog("s1", 0)  # released
    assert bus_state.tx_frames == sent + 1  # sent within the call
    adapter.jog("s1", -1)
    assert await wait_for(lambda: state.live("Motion flags").value & 2, timeout=2)
    sent = bus_state.tx_frames
    adapter.stop("s1")
    assert bus_state.tx_frames == sent + 1
    assert await wait_for(lambda: twin.control is not None and not twin.control.enable, timeout=0.5)


async def test_idle_control_is_kept_alive_during_a_stall(lift):  # noqa: F811
    """Control held, nothing moving: the keep-alive (enable cleared) goes on through a stall, so no
    message-timeout flag rises because the program was busy."""
    runtime, adapter, state, twin = lift
    listener = Listener(runtime.plant.buses["can2"].options["channel"])
    try:
        await adapter.take_control("s1", "engineer")
        assert await wait_for(lambda: not state.live("Error flags").value & 0x20, timeout=2)
        blocked = block_loop(1.0)
        await asyncio.sleep(0)
        times = [t for t, _ in listener.of(electrak.CONTROL_ID, since=blocked - 0.2, until=blocked + 1.0)]
        gaps = [b - a for a, b in itertools.pairwise(times)]
        print(f"idle keep-alive through a 1 s stall: {len(times)} telegrams, worst gap {max(gaps) * 1000:.0f} ms")
        assert len(times) >= 5 and max(gaps) < electrak.DEFAULT_TIMEOUT_MS / 1000
    finally:
        listener.close()


# -- M3IO: DigOut -----------------------------------------------------------------------------------------

def m3io_plant(**options) -> str:
    """An M3IO HM ``hm`` (SW1 0x1A) on a CAN bus of its own, simulated (``options``: the module's, such as ``master``)."""
    return plant_text(can_bus(m3io_can(**options), name="can3", channel_name=channel("ka"), bitrate=500000, poll_period=0.2),
                      name=None)


@pytest.fixture
async def m3io_module():
    plant = parse_plant(m3io_plant())
    listener = Listener(plant.buses["can3"].options["channel"])
    try:
        async with running_plant(plant) as runtime, alive(runtime.worker, "s1"):
            yield runtime, listener
    finally:
        listener.close()


async def test_no_digout_without_an_engineer_in_control(m3io_module):
    """Issue 26 item 4: with no browser open the tool sends no DigOut; the module stays silent (7.1)."""
    runtime, listener = m3io_module
    adapter, twin = runtime.worker.adapters["hm"], runtime.twins["hm"]
    dig_out = adapter.ids.dig_out
    await asyncio.sleep(1.0)  # five poll periods
    assert listener.of(dig_out) == [] and twin.last_digout is None
    with pytest.raises(M3ioError, match="take control"):
        adapter.set_output("s1", "SSR1", True)
    await adapter.take_control("s1", "engineer")
    assert await wait_for(lambda: runtime.store.devices["hm"].status == "online", timeout=3)
    adapter.set_output("s1", "SSR1", True)
    assert await wait_for(lambda: twin.ssr[1].on, timeout=1)
    adapter.release_control("s1")
    assert not twin.ssr[1].on or await wait_for(lambda: not twin.ssr[1].on, timeout=1)
    released = time.monotonic()
    await asyncio.sleep(0.5)  # five DigOut periods after the release: nothing may be sent
    assert listener.of(dig_out, since=released + 0.05) == []  # nothing after the release


async def test_control_refused_while_another_master_sends_digout(m3io_module):
    runtime, listener = m3io_module
    adapter, twin = runtime.worker.adapters["hm"], runtime.twins["hm"]
    plc_outputs = m3io.encode_dig_out(adapter.variant, {"SSR1": True})

    def plc_send() -> None:  # a third node of the bus: a PLC serving the module
        listener.bus.send(can.Message(arbitration_id=adapter.ids.dig_out, data=plc_outputs, is_extended_id=False))

    async def plc(seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            plc_send()
            await asyncio.sleep(0.5)

    task = asyncio.create_task(plc(1.5))
    try:
        assert await wait_for(lambda: twin.ssr[1].on, timeout=2)
        with pytest.raises(ForeignMaster, match="another master"):
            await adapter.take_control("s1", "engineer")
        assert not runtime.worker.can_buses["can3"].cyclic_running(adapter.key)
        assert listener.of(adapter.ids.dig_out) == []  # this tool sent none: the PLC's outputs never chattered
    finally:
        await task
    # the PLC stopped: the module answers until its 2 s watchdog runs out, and those answers age out of the
    # 2 s window; then control is granted
    assert await wait_for(lambda: not adapter.foreign_master(), timeout=2 * m3io.WATCHDOG_S + 1.5)
    await adapter.take_control("s1", "engineer")
    assert adapter.controller is not None
    # a master that starts while this tool controls: the tool stops sending instead of fighting it
    plc_send()
    assert await wait_for(lambda: adapter.controller is None, timeout=1)
    assert not runtime.worker.can_buses["can3"].cyclic_running(adapter.key)
    assert any("another master" in e.text for e in runtime.store.devices["hm"].events if e.level == "error")


async def test_a_stalled_loop_switches_mains_outputs_off_by_itself(m3io_module):
    runtime, listener = m3io_module
    adapter, twin = runtime.worker.adapters["hm"], runtime.twins["hm"]
    state = runtime.store.devices["hm"]
    await adapter.take_control("s1", "engineer")
    assert await wait_for(lambda: state.status == "online", timeout=3)
    adapter.set_output("s1", "SSR1", True)
    assert await wait_for(lambda: twin.ssr[1].on, timeout=1)
    await asyncio.sleep(0.4)  # the lease is renewed while the page beats
    assert adapter.outputs["SSR1"]
    blocked = block_loop(BLOCK_S)
    await asyncio.sleep(0)
    during = listener.of(adapter.ids.dig_out, since=blocked, until=blocked + BLOCK_S)
    offs = [t for t, d in during if not d[0] & 0x02]
    assert offs, "SSR1 stayed on on the bus while the program stalled"
    off_ms = (offs[0] - blocked) * 1000
    print(f"loop blocked for {BLOCK_S:g} s: SSR1 off on the bus {off_ms:.0f} ms after the block, {len(during)} DigOut during it")
    assert off_ms < BOUND_S * 1000
    assert not [d for t, d in during if t > offs[0] and d[0] & 0x02]
    assert await wait_for(lambda: not adapter.outputs["SSR1"], timeout=1)
    assert any("stalled" in e.text for e in state.events if e.level == "error")
    await asyncio.sleep(0.3)  # after the stall: SSR1 must stay off while the watchdog is served
    assert not twin.ssr[1].on and twin.watchdog_alive  # off, and the watchdog still served


async def test_master_always_serves_idle_and_yields_to_a_plc():
    """``master = "always"`` (a bench without a PLC): the watchdog is served with every output off while
    nobody controls the module, after listening first; a PLC's DigOut ends it at once."""
    text = m3io_plant(master="always")
    runtime = Runtime(parse_plant(text), simulate=True)
    listener = Listener(runtime.plant.buses["can3"].options["channel"])
    await runtime.start()
    try:
        adapter = runtime.worker.adapters["hm"]
        assert await wait_for(lambda: runtime.store.devices["hm"].status == "online", timeout=4)
        sent = listener.of(adapter.ids.dig_out)
        assert sent and all(d == b"\x00" for _, d in sent)  # every output off
        with pytest.raises(M3ioError, match="take control"):
            adapter.set_output("s1", "SSR1", True)  # switching on still needs an engineer in control
        plc = m3io.encode_dig_out(adapter.variant, {"SSR2": True})
        listener.bus.send(can.Message(arbitration_id=adapter.ids.dig_out, data=plc, is_extended_id=False))
        assert await wait_for(lambda: not runtime.worker.can_buses["can3"].cyclic_running(adapter.key), timeout=1)
        stopped = time.monotonic()
        await asyncio.sleep(0.5)  # five periods after the PLC took over: this tool must send nothing
        assert [d for t, d in listener.of(adapter.ids.dig_out, since=stopped + 0.05) if d != plc] == []
    finally:
        await asyncio.wait_for(runtime.stop(), 5)
        listener.close()


def test_master_option_is_checked():
    from app.plant import PlantError

    with pytest.raises(PlantError, match="master"):
        parse_plant(m3io_plant(master="sometimes"))
