"""Parameter entry on a device page (issue 32 item 6), with NiceGUI's simulated user: the field starts
with the device's value, keeps a typed "12.5" as typed (marked, not rounded to 12), Enter writes, and
after a write the field shows the value read back."""

from __future__ import annotations

from collections.abc import AsyncIterator
from dataclasses import dataclass

import pytest
from conftest import modbus_plant
from nicegui import ui
from nicegui.testing import User
from nicegui.testing.user_interaction import UserInteraction
from webutil import eventually, simulated_user

from app.runtime import Runtime
from devices.hdlock.adapter import SETTINGS_PERIOD_S
from devices.hdlock.params import PARAMS

pytestmark = pytest.mark.timeout(60)


@dataclass
class Env:
    user: User
    runtime: Runtime


@pytest.fixture
async def env(monkeypatch) -> AsyncIterator[Env]:
    from devices.hdlock import adapter as hdlock_adapter

    monkeypatch.setattr(hdlock_adapter, "SETTINGS_PERIOD_S", 2.0)  # settings changed elsewhere are seen at the next settings read
    runtime = Runtime(modbus_plant(locks=(("door-1", 1),)), simulate=True)
    async with simulated_user(runtime) as user:
        state = runtime.store.devices["door-1"]
        await eventually(lambda: state.status == "online" and state.raw(PARAMS.by_name["LockRequestDelay"]) is not None,
                         timeout=10, what="door-1 online with its holding registers read")
        yield Env(user, runtime)


def _entry(user: User, name: str) -> ui.number:
    (entry,) = [e for e in user.client.elements.values() if e.props.get("data-param") == name]
    return entry


async def test_a_parameter_entry_starts_with_the_value_keeps_fractions_writes_on_enter(env: Env):
    state = env.runtime.store.devices["door-1"]
    delay = PARAMS.by_name["LockRequestDelay"]
    await env.user.open("/device/door-1")
    await env.user.should_see("HD-Lock door-1")
    entry = _entry(env.user, "LockRequestDelay")
    await eventually(lambda: entry.value == 200, what="the field showing the current 200 ms")

    entry.value = 12.5
    entry.sanitize()  # what the browser's blur does
    assert entry.value == 12.5, "the typed value must stay as typed, not be rounded"
    UserInteraction(env.user, {entry}, None).trigger("keydown.enter")
    await eventually(lambda: bool(entry.error) and "whole number" in entry.error, what="the refusal on the field")
    assert state.raw(delay) == 200

    entry.value = 250
    UserInteraction(env.user, {entry}, None).trigger("keydown.enter")
    await eventually(lambda: state.raw(delay) == 250, what="Enter writes")
    assert not entry.error
    assert entry.value == 250
    env.runtime.twins["door-1"].holding[delay.address] = 300  # changed elsewhere: the untouched field follows
    # the lock's settings are read again every SETTINGS_PERIOD_S (10 s): the change shows at the next of those reads
    await eventually(lambda: entry.value == 300, timeout=SETTINGS_PERIOD_S + 10, what="the field following the device's new value")
