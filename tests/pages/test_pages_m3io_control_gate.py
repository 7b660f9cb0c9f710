"""M3IO page with NiceGUI's simulated user and a simulated module: without control the SSR switches are
off with the reason (no mains-voltage question first); Take control is not offered while held."""

from __future__ import annotations

import pytest
from nicegui import ui
from plants import can_bus, device, plant_text
from test_pages_devices_m3io import one
from webutil import eventually, simulated_user

from app.plant import parse_plant
from app.runtime import Runtime

pytestmark = pytest.mark.timeout(40)

PLANT = plant_text(can_bus(device("io", "m3io", "can9", variant="HM", sw1=0x1A, master="always"), name="can9", bitrate=500000, poll_period=0.2,
                           channel_name="pages-m3io-control-gate"), name="m")


@pytest.fixture
async def env():
    runtime = Runtime(parse_plant(PLANT), simulate=True)
    async with simulated_user(runtime) as user:
        yield user, runtime


async def test_switches_need_control_and_say_so(env):
    user, runtime = env
    await user.open("/device/io")
    await user.should_see("CAN-M3IO io (HM)")
    state = runtime.store.devices["io"]
    await eventually(lambda: state.status == "online", timeout=10, what="module answers")
    ssr = one(user, "data-output", "SSR4", ui.switch)
    await eventually(lambda: not ssr.enabled and ssr.props.get("data-disabled-reason") == "take control of the module first",
                     what="SSR4 disabled: take control first")
    assert not one(user, "data-output", "LED", ui.switch).enabled
    take = one(user, "data-testid", "take-control", ui.button)
    release = one(user, "data-testid", "release-control", ui.button)
    assert take.enabled and not release.enabled
    from nicegui.testing.user_interaction import UserInteraction
    UserInteraction(user, {take}, None).click()
    await eventually(lambda: ssr.enabled and "data-disabled-reason" not in ssr.props, timeout=10,
                     what="SSR4 enabled with control")
    await eventually(lambda: not take.enabled and take.props.get("data-disabled-reason") == "you control the module",
                     what="Take control not offered while held")
    assert release.enabled
