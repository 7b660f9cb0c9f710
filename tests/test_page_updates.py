"""What pages send the browser: the header is built once and changed in place, counters and read
times go out once a second, and a chart in a hidden page waits (merged, bounded) until it is shown."""

from __future__ import annotations

import asyncio
import time

import pytest
from nicegui import ui
from webutil import simulated_user

from app.plant import parse_plant
from app.runtime import Runtime

pytestmark = pytest.mark.timeout(60)

PLANT = """
name = "u"
[[bus]]
name = "can9"
type = "can"
interface = "virtual"
channel = "page-updates"
[[device]]
name = "io"
type = "m3io"
bus = "can9"
variant = "HM"
sw1 = 0x1A
"""


@pytest.fixture
async def user_runtime():
    runtime = Runtime(parse_plant(PLANT), simulate=False)
    async with simulated_user(runtime) as user:
        yield user, runtime


def _ids(user) -> set[int]:
    return set(user.client.elements)


async def test_header_changes_in_place_audit_problem_and_bus_state(user_runtime):
    user, runtime = user_runtime
    await user.open("/backup")  # any page with the header
    await user.should_not_see("audit log not writable")
    bus = runtime.store.buses["can9"]
    icon_names = lambda: {e.props.get("name") for e in user.find(ui.icon).elements}  # noqa: E731
    await asyncio.sleep(2.2)  # one header round (every 2 s) with the bus as the worker left it
    before = _ids(user)
    runtime.audit.problem = "audit.sqlite: disk I/O error"
    bus.connected, bus.last_error = False, "unplugged"
    await user.should_see("audit log not writable", retries=40)
    assert "link_off" in icon_names()
    bus.connected, bus.last_error = True, ""
    runtime.audit.problem = ""
    await user.should_not_see("audit log not writable", retries=40)
    assert "lan" in icon_names() and "link_off" not in icon_names()
    assert _ids(user) == before  # nothing was built again: only texts, colours and visibility changed


async def test_tile_counters_move_once_a_second(user_runtime):
    user, runtime = user_runtime
    await user.open("/")
    state = runtime.store.devices["io"]
    tile_label = next(e for e in user.client.elements.values() if "data-tile-counters" in e.props)
    store = runtime.store
    store._aged = time.monotonic() + 1e9  # no once-a-second round from the producer for now
    shown = tile_label.text
    for _ in range(5):
        state.counters.responses += 1
        state.version += 1
        await asyncio.sleep(0.15)  # a push round each time: the device changed
    assert tile_label.text == shown  # not redrawn ten times a second
    store._aged = 0.0  # the next round is the once-a-second round
    await asyncio.sleep(0.3)
    assert tile_label.text != shown and f"frames heard {state.counters.responses}" in tile_label.text
