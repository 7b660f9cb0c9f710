"""M3IO page with NiceGUI's simulated user: entries keep what was typed, switches and commands
disabled with the reason while the module does not answer, events newest first, no page timers."""

from __future__ import annotations

import time

import pytest
from nicegui import ui
from nicegui.testing import User
from nicegui.testing.user_interaction import UserInteraction
from plants import can_bus, device, plant_text
from webutil import eventually, simulated_user

from app.plant import parse_plant
from app.runtime import Runtime

pytestmark = pytest.mark.timeout(40)

# no module on the bus (simulate = false): the page waits, then the module is offline
PLANT = plant_text(can_bus(device("io", "m3io", "can9", variant="HMR", sw1=0xCA), name="can9",
                           channel_name="pages-devices-m3io", simulate=None), name="m")


@pytest.fixture
async def env():
    """The simulated user on io's page."""
    runtime = Runtime(parse_plant(PLANT), simulate=False)
    async with simulated_user(runtime) as user:
        await user.open("/device/io")
        await user.should_see("CAN-M3IO io (HMR)")
        yield user, runtime


def one(user: User, prop: str, value: str, kind=ui.element):
    found = [e for e in user.client.elements.values() if isinstance(e, kind) and e.props.get(prop) == value]
    assert len(found) == 1, f"{len(found)} elements with {prop}={value!r}"
    return found[0]


async def test_record_20_stays_typed_marked_and_nothing_is_sent(env):
    user, runtime = env
    state = runtime.store.devices["io"]
    record = one(user, "data-testid", "record", ui.number)
    record.value = 20
    one(user, "data-testid", "record-bytes", ui.input).value = "01 02"
    button = one(user, "data-testid", "record-write", ui.button)
    button.enabled = True  # the guard disables it while the module is silent; the entry check must hold anyway
    requests = state.counters.requests
    UserInteraction(user, {button}, None).click()
    await eventually(lambda: record.error and "1 .. 15" in record.error, what="record marked with its range")
    assert record.value == 20  # not clamped to 15
    assert state.counters.requests == requests

    async def refusal_audited() -> bool:
        return any("write customer data" in r.action and r.result.startswith("refused: 20")
                   for r in await runtime.audit.aquery())

    await eventually(refusal_audited, what="the refusal in the audit log")


async def test_silent_module_disables_switches_with_the_reason_but_not_all_off(env):
    user, runtime = env
    state = runtime.store.devices["io"]
    switch = one(user, "data-output", "SSR4", ui.switch)
    assert not switch.enabled
    assert switch.props["data-disabled-reason"] == "waiting for the device's first answer"
    runtime.worker.adapters["io"].last_answer = time.time() - 10  # it answered once, 10 s ago, then went silent
    await eventually(lambda: state.status == "offline", timeout=10, what="module offline")
    await eventually(lambda: switch.props.get("data-disabled-reason", "").startswith("the device does not answer"),
                     what="reason says the module does not answer")
    assert not one(user, "data-testid", "record-write", ui.button).enabled
    assert one(user, "data-testid", "all-off", ui.button).enabled  # stopping is never refused
    assert one(user, "data-lamp", "E1").props["data-on"] == "unknown"
    events = one(user, "data-testid", "events", ui.table)
    await eventually(lambda: events.rows and events.rows[0]["level"] == "error", what="offline event newest first")
    timers = [e for e in user.client.elements.values() if isinstance(e, ui.timer)
              and getattr(getattr(e, "callback", None), "__module__", "").startswith("pages.m3io")]
    assert timers == []
