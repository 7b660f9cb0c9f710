"""A plant of a hundred devices (bench/scale_plants.py: 64 HD-Locks on four RS485 lines, locks and M3IOs on CAN,
Electrak networks, SCUs, MO 64 on RS485) runs for a short while in one process with its twins: the overview lists
every device, its filters narrow the list, and the keep-alives under control keep their period.

The keep-alive bound asserted is the device's own (the Electrak's message timeout, the M3IO's watchdog), with
the worst gap printed against the 1.2 x period goal, which ``bench/plant_scale.py`` measures on a quiet machine:
a test beside other tests on two shared cores cannot hold a goal in milliseconds without being flaky. The gaps
are those of the telegrams as sent (python-can's virtual bus stamps them in ``send``), not the twins' own
message-timeout flags: here the twins share the tool's event loop, and a stalled loop delays their check of a
telegram that left on time (``bench/keepalive_jitter.py`` keeps its twin on a loop of its own for that).
The RS485 twins answer at once (no wire time): the lines' timing is the benchmark's.
"""

from __future__ import annotations

import asyncio
import time

import can
from can_listener import FrameListener
from scale_plants import family_counts, scale_plant_text
from webutil import eventually, simulated_user

from app.plant import parse_plant
from app.runtime import Runtime
from devices.electrak import codec as electrak
from devices.m3io import codec as m3io

ELECTRAK_TIMEOUT_S = electrak.DEFAULT_TIMEOUT_MS / 1000  # the actuator's message timeout: control must come within it


def heard(channel: str) -> FrameListener:
    """The frames on a virtual CAN ``channel`` as a third node hears them, stamped when they were sent."""
    return FrameListener(can.Bus(interface="virtual", channel=channel), sent_time=True)


async def _beat(runtime, session: str) -> None:
    while True:
        runtime.worker.heartbeat(session)
        await asyncio.sleep(0.1)


def _listed(rows) -> set[str]:
    return {e.props["data-glance"] for e in rows if e.visible}


async def _choose(user, testid: str, value: str) -> None:
    select = next(e for e in user.client.elements.values() if e.props.get("data-testid") == testid)
    select.set_value(value)


def _worst_gap(times: list[float]) -> float:
    return max((b - a for a, b in zip(times, times[1:], strict=False)), default=float("inf"))


async def test_a_hundred_devices_are_listed_and_keep_alives_stay_on_time(tmp_path):
    text = scale_plant_text(100, wire_delay=False)
    plant = parse_plant(text)
    assert len(plant.devices) == 100 and family_counts(100)["hdlock-modbus"] == 64
    channels = {b.name: b.options["channel"] for b in plant.buses.values() if b.type == "can"}
    lift_heard, heater_heard = heard(channels["can-lift-1"]), heard(channels["can-io"])
    runtime = Runtime(plant, simulate=True, data_dir=tmp_path / "data")
    beating: asyncio.Task | None = None
    try:
        async with simulated_user(runtime) as user:
            await eventually(lambda: all(s.status == "online" for s in runtime.store.devices.values()), timeout=45,
                             what="every device online")
            lift, heater = runtime.worker.adapters["lift-01"], runtime.worker.adapters["heater-01"]
            beating = asyncio.create_task(_beat(runtime, "scale"))
            await lift.take_control("scale", "engineer")
            await heater.take_control("scale", "engineer")
            start = time.time() + 0.5  # the keep-alives at their controlled period from here on

            # the overview while the hundred devices poll and the keep-alives run: every device in the table
            await user.open("/")
            rows = [e for e in user.client.elements.values() if "data-glance" in e.props]
            assert sorted(e.props["data-glance"] for e in rows) == sorted(plant.devices)
            assert {e.props["data-device"] for e in user.client.elements.values() if "data-device" in e.props} <= set(plant.devices)
            await user.should_see("All devices (100)")
            # a large plant: its buses are closed sections with their counts; a filter narrows the table
            sections = {e.props["data-bus-section"]: e for e in user.client.elements.values() if "data-bus-section" in e.props}
            assert set(sections) == set(plant.buses)
            assert "16 devices" in sections["rs485-4"].props["caption"]
            await _choose(user, "filter-bus", "rs485-4")
            await eventually(lambda: _listed(rows) == {f"door-4-{a:02d}" for a in range(1, 17)}, timeout=5,
                             what="the table lists the line's locks only")
            await eventually(lambda: sections["rs485-4"].value, timeout=5, what="the chosen bus opened")
            await eventually(lambda: len([e for e in user.client.elements.values() if "data-device" in e.props]) == 16,
                             timeout=5, what="the opened bus's tiles drawn")
            await _choose(user, "filter-bus", "")
            await _choose(user, "filter-type", "electrak")
            await eventually(lambda: _listed(rows) == {f"lift-{i:02d}" for i in range(1, 5)}, timeout=5,
                             what="the Electrak networks only")
            await _choose(user, "filter-type", "")
            await _choose(user, "filter-state", "online")
            await eventually(lambda: len(_listed(rows)) == 100, timeout=5, what="every device online")

            await eventually(lambda: time.time() > start + 3.0, timeout=10, interval=0.1, what="3 s of keep-alives")
            lift_times = [t for t, _ in lift_heard.of(electrak.CONTROL_ID, start)]
            heater_times = [t for t, _ in heater_heard.of(m3io.derive_ids(1).dig_out, start)]
            lift_gap, heater_gap = _worst_gap(lift_times), _worst_gap(heater_times)
            print(f"Electrak control: {len(lift_times)} telegrams, worst gap {lift_gap * 1000:.0f} ms = "
                  f"{lift_gap / electrak.CONTROL_PERIOD_S:.2f} x period; M3IO DigOut: {len(heater_times)} telegrams, "
                  f"worst gap {heater_gap * 1000:.0f} ms = {heater_gap / m3io.DIGOUT_PERIOD_S:.2f} x period")
            assert len(lift_times) >= 20 and len(heater_times) >= 20
            assert lift_gap < ELECTRAK_TIMEOUT_S, lift_gap
            assert heater_gap < m3io.WATCHDOG_S / 4, heater_gap
            lift.release_control("scale")
            heater.release_control("scale")
    finally:
        if beating is not None:
            beating.cancel()
        lift_heard.close()
        heater_heard.close()
