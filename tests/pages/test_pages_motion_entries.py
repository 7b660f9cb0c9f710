"""Lift (Electrak), SCU and MO 64 pages with NiceGUI's simulated user: entries keep what was typed and are
refused with their range (nothing sent, refusal audited); a silent device disables its start buttons with
the reason while STOP stays enabled; the Events log lists the device's events, newest first."""

from __future__ import annotations

from collections.abc import AsyncIterator

import pytest
from nicegui import ui
from nicegui.testing import User
from nicegui.testing.user_interaction import UserInteraction
from plants import motion_plant_text
from webutil import by_testid, eventually, user_on

from app.plant import parse_plant
from app.runtime import Runtime

pytestmark = pytest.mark.timeout(60)


@pytest.fixture
async def env() -> AsyncIterator[tuple[User, Runtime]]:
    async with user_on(parse_plant(motion_plant_text())) as env:
        yield env


def click(user: User, testid: str) -> None:
    UserInteraction(user, {by_testid(user, testid)}, None).click()


async def click_enabled(user: User, testid: str) -> None:
    """Click the button once it is enabled: a disabled one (a remote session still being set up, a device that
    missed a poll on a loaded machine) takes no click."""
    button = by_testid(user, testid)
    await eventually(lambda: button.enabled, timeout=10, what=f"{testid} enabled")
    click(user, testid)


async def open_online(user: User, runtime: Runtime, device: str) -> None:
    await eventually(lambda: runtime.store.devices[device].status == "online", timeout=10, what=f"{device} online")
    await user.open(f"/device/{device}")


async def refused(runtime: Runtime, device: str, *words: str) -> bool:
    """An audit row of ``device`` says "refused: ..." with every one of ``words``."""
    return any(r.device == device and r.result.startswith("refused") and all(w in r.result for w in words)
               for r in await runtime.audit.aquery())


async def test_lift_speed_50_is_kept_marked_with_the_range_and_not_sent(env):
    user, runtime = env
    adapter = runtime.worker.adapters["lift"]
    await open_online(user, runtime, "lift")
    await user.should_see("actuator 1")  # each actuator's numbers, not only chart traces
    await eventually(lambda: " mm" in by_testid(user, "actuator-2-position").default_slot.children[0].text, timeout=5,
                     what="actuator 2's position as a number")
    user.find(kind=ui.button, content="Take control").click()
    await eventually(lambda: adapter.controller is not None, timeout=5, what="control taken")
    before = adapter.command
    speed = by_testid(user, "speed")
    speed.value = 50
    apply_button = by_testid(user, "apply")
    await eventually(lambda: apply_button.enabled, timeout=10, what="Apply enabled (the network answers)")
    user.find(kind=ui.button, content="Apply").click()
    await eventually(lambda: speed.error, timeout=3, what="speed marked invalid")
    assert speed.value == 50  # kept as typed, not clamped to 32
    assert "6 .. 32 mm/s" in speed.error
    assert adapter.command == before  # nothing sent
    assert not user.notify.messages  # no toast over the chart
    await eventually(lambda: refused(runtime, "lift", "50", "6 .. 32"), timeout=10, what="refusal audited")
    # a good entry goes out
    speed.value = 20
    user.find(kind=ui.button, content="Apply").click()
    await eventually(lambda: adapter.command.speed_mm_s == 20, timeout=3, what=str(user.notify.messages))
    assert not speed.error


async def test_scu_and_mo64_entries_are_kept_and_refused_with_their_range(env):
    user, runtime = env
    scu = runtime.worker.adapters["scu"]
    await open_online(user, runtime, "scu")
    user.find(kind=ui.button, content="Take control").click()
    await eventually(lambda: scu.controller is not None, timeout=5, what="SCU control taken")
    speed = by_testid(user, "remote-speed")
    speed.value = 5000
    await click_enabled(user, "set-speed")
    await eventually(lambda: speed.error, timeout=3, what="SCU speed marked invalid")
    assert speed.value == 5000 and "0 .. 100 " in speed.error + " "  # relative speed select (0-100 %) by default
    assert scu.state.point("F1 remote speed") is None  # nothing written
    await eventually(lambda: refused(runtime, "scu", "5000", "0 .. 100"), timeout=10, what="refusal audited")

    mo64 = runtime.worker.adapters["gate"]
    await open_online(user, runtime, "gate")
    t_open = by_testid(user, "entry-t_open")
    t_open.value = 700
    await click_enabled(user, "write-t_open")
    await eventually(lambda: t_open.error, timeout=3, what="open time marked invalid")
    assert t_open.value == 700 and "0 .. 655 s" in t_open.error
    assert mo64.eeprom_writes_total == 0  # nothing sent, not even the EEPROM question
    relays = by_testid(user, "entry-multi_relays")
    relays.value = "1,x"
    await click_enabled(user, "write-multi_relays")
    await eventually(lambda: relays.error, timeout=3, what="raw entry marked invalid")
    assert relays.value == "1,x"
    assert not user.notify.messages
    await eventually(lambda: refused(runtime, "gate", "700", "655"), timeout=10, what="open time refusal audited")
    await eventually(lambda: refused(runtime, "gate", "1,x"), timeout=10, what="raw entry refusal audited")


async def test_silent_devices_disable_start_buttons_with_the_reason_and_keep_stop(env):
    user, runtime = env
    for device in ("lift", "scu", "gate"):
        await eventually(lambda device=device: runtime.store.devices[device].status == "online", timeout=10)
    await runtime.sim.stop()  # every twin stops answering
    for device in ("lift", "scu", "gate"):
        await eventually(lambda device=device: runtime.store.devices[device].status == "offline", timeout=15,
                         what=f"{device} offline")
    for device, starts in (("lift", ("take-control", "go", "jog-out", "write-01")),
                           ("scu", ("take-control", "go", "jog-in", "set-speed")),
                           ("gate", ("pulse-open", "activate-close", "write-t_open"))):
        await user.open(f"/device/{device}")
        for testid in starts:
            button = by_testid(user, testid)
            await eventually(lambda button=button: not button.enabled, timeout=3, what=f"{device} {testid} disabled")
            reason = button.props.get("data-disabled-reason", "")
            # the SCU names the lost remote session with its cause (the port that cannot be opened)
            assert "does not answer" in reason or (device == "scu" and "remote session is lost" in reason), \
                (device, testid, button.props)
        if device != "gate":
            assert by_testid(user, "big-stop").enabled and by_testid(user, "stop").enabled  # STOP never disabled
        events = by_testid(user, "events")
        assert events.rows and events.rows[0]["level"] == "error", events.rows[:3]  # newest first: going offline
