"""Pages and JSON API with NiceGUI's simulated user, against twins polled over real Modbus RTU.

Each test gets its own NiceGUI app (reset globals), a two-lock plant on a free localhost
port and ``Runtime(plant, simulate=True)``, registered by ``app.web.register`` before the
app's lifespan starts (which starts the twins and the worker through ``app.on_startup``).
"""

from __future__ import annotations

import re
import time

import pytest
from nicegui import ui
from nicegui.testing import User
from nicegui.testing.user_interaction import UserInteraction
from conftest import spy_writes
from webutil import LockPages, eventually, lock_pages_env

from app.worker import PermissionDenied
from devices.hdlock.params import PARAMS, REMOVE_MAGNET

DELAY = PARAMS.by_name["LockRequestDelay"]  # holding 3000, factory 200 ms
REMOVE = PARAMS.by_name["SettingsRemoveMagnet"]  # holding 3005, enum, 1 needs a confirmation

pytestmark = pytest.mark.timeout(30)  # each test takes about a second; waits inside are bounded

Env = LockPages

env = pytest.fixture(lock_pages_env, name="env")  # a simulated user on the app of two locks (door-1 at 1, door-2 at 2)


# -- finding elements by the app's data-* props (the pages set no .mark() markers) --------------


def by_prop(user: User, prop: str, value: str, kind: type[ui.element] = ui.element) -> UserInteraction:
    """The single visible element of ``kind`` whose ``prop`` is ``value``."""
    assert user.client is not None
    found = {e for e in user.client.elements.values() if isinstance(e, kind) and e.props.get(prop) == value and e.visible}
    assert len(found) == 1, f"expected one {kind.__name__} with {prop}={value!r}, found {len(found)}"
    return UserInteraction(user, found, None)


def entry(user: User, param: str) -> UserInteraction:
    return by_prop(user, "data-param", param)


def write_button(user: User, param: str) -> UserInteraction:
    return by_prop(user, "data-write", param, ui.button)


def lamp_on(user: User, name: str) -> str | None:
    """``data-on`` of the lamp named ``name``: "1", "0" or "unknown"."""
    return by_prop(user, "data-lamp", name).elements.copy().pop().props.get("data-on")


# -- overview and device page -------------------------------------------------------------------


async def test_line_cycle_time_is_shown_on_the_overview_and_the_monitor(env: Env):
    user = env.user
    await env.polled()
    line = env.runtime.store.buses["line1"]
    await eventually(lambda: line.cycle_s, timeout=10, what="the line measured a cycle")
    await user.open("/")
    await user.should_see(" · cycle ", retries=30)
    texts = [e.text for e in user.find(" · cycle ").elements]
    assert any(re.search(r"connected · cycle \d+\.\d\d s", t) for t in texts), texts
    await user.open("/monitor/line1")
    await user.should_see("(every device polled once)", retries=30)
    texts = [e.text for e in user.find("(every device polled once)").elements]
    assert any(re.search(r"line cycle \d+\.\d\d s \(every device polled once\)", t) for t in texts), texts


async def test_overview_lists_both_locks_online(env: Env):
    user = env.user
    await user.open("/")
    await user.should_see("Overview")
    await user.should_see("plant: plant")
    for name in ("door-1", "door-2"):
        await user.should_see(name)
    await user.should_see(kind=ui.label, content="HD-Lock on line1")
    assert len(user.find(kind=ui.label, content="HD-Lock on line1").elements) == 2
    await env.polled()
    # the tiles refresh once a second
    await user.should_see(kind=ui.badge, content="online", retries=30)

    def both_online() -> None:
        badges = [e for e in user.find(kind=ui.badge, content="online").elements if e.text == "online"]
        assert len(badges) == 2, f"{len(badges)} tiles say online"

    await eventually(both_online, timeout=5)

    def counted() -> None:  # the counters line follows once a second (a slow watch)
        counters = [e.text for e in user.find(kind=ui.label, content="req ").elements]
        assert len(counters) == 2
        for text in counters:
            words = text.split()
            assert words[0] == "req" and int(words[1]) > 0, f"no requests counted: {text}"
            assert "timeouts 0" in text, text

    await eventually(counted, timeout=5)
    # the declared tile (devices/hdlock TileSpec): door, bolt, bolt position
    await user.should_see(kind=ui.label, content="Door open")
    await user.should_see(kind=ui.label, content="bolt unlocked")
    await user.should_see(kind=ui.label, content=" Inc")
    await eventually(
        lambda: any(e.text == "connected" or e.text.startswith("connected · ")
                    for e in user.find(kind=ui.label, content="connected").elements),
        what="line1 shown as connected",
    )


async def test_tile_click_opens_device_page(env: Env):
    user = env.user
    await user.open("/")
    await user.should_see("door-2")
    tile = by_prop(user, "data-device-link", "door-2", ui.link)  # a link: opens in a new tab too
    tile.click()
    await user.should_see("HD-Lock door-2", retries=20)


async def test_device_page_shows_lamps_and_enums(env: Env):
    user = env.user
    await env.open_page()
    await user.should_see("LockStatus (holding 1000)")
    for lamp in ("LockRequest", "ProximityInPlace", "DoorInPosition", "BoltLocked", "BoltUnlocked", "BoltMovingOut"):
        await user.should_see(kind=ui.label, content=lamp)
        # drawn with the page's next push of the LockStatus word (a loaded machine: a moment after the label)
        await eventually(lambda lamp=lamp: lamp_on(user, lamp) in ("0", "1"), timeout=10, what=f"{lamp} lamp known")
    for key in ("DoorState", "StateMachineState", "MotorState"):
        await user.should_see(kind=ui.label, content=key)
    # the door of door-1 starts open: nothing locks, the bolt is retracted
    assert lamp_on(user, "DoorInPosition") == "0"
    assert lamp_on(user, "BoltUnlocked") == "1"
    await user.should_see("Modbus address 1 · serial 655361")
    await user.should_see("Close door")


async def test_unknown_device_page(env: Env):
    await env.user.open("/device/nope")
    await env.user.should_see("The plant has no device named 'nope'.")


# -- writing parameters -----------------------------------------------------------------------


async def test_write_parameter_then_save_settings(env: Env):
    user, twin, state = env.user, env.twin(), env.state()
    await env.open_page()
    await user.should_not_see(kind=ui.badge, content="unsaved")
    assert twin.holding[3000] == 200
    saved_before = twin.input[101]

    entry_element(user, "LockRequestDelay").value = None  # the field holds the current value: cleared, then typed
    entry(user, "LockRequestDelay").type("500")
    write_button(user, "LockRequestDelay").click()

    await eventually(lambda: twin.holding[3000] == 500, what="twin holding 3000 == 500")
    await user.should_see("LockRequestDelay = 500 ms written and read back", retries=20)
    assert DELAY.key in state.unsaved
    await user.should_see(kind=ui.badge, content="1 unsaved change", retries=20)
    await user.should_see(kind=ui.badge, content="unsaved")
    assert twin.flash[3000] == 200, "a write must stay volatile until Save-Settings"

    user.find(kind=ui.button, content="Save-Settings").click()
    # writing the lock's flash asks first, listing the unsaved change with its value
    await user.should_see("LockRequestDelay (holding 3000) = 500 ms", retries=20)
    assert twin.input[101] == saved_before, "nothing saved before the confirmation"
    user.find(kind=ui.button, content="Save to flash").click()

    await eventually(lambda: twin.input[101] == saved_before + 1, what="SavedSettings counted up")
    await user.should_see("Settings saved to the lock's flash", retries=20)
    assert not state.unsaved
    assert twin.flash[3000] == 500
    await user.should_not_see(kind=ui.badge, content="unsaved", retries=20)


async def test_out_of_range_value_is_refused_without_writing(env: Env):
    user, twin = env.user, env.twin()
    await env.open_page()
    writes = spy_writes(twin)
    requests = env.state().counters.requests

    entry_element(user, "LockRequestDelay").value = None
    entry(user, "LockRequestDelay").type("70000")
    write_button(user, "LockRequestDelay").click()

    # the field keeps what was typed and says why (no toast over the page)
    await eventually(lambda: "70000 is outside 0 .. 65535 ms" in (entry_element(user, "LockRequestDelay").error or ""))
    assert entry_element(user, "LockRequestDelay").value in (70000, "70000")
    await eventually(lambda: env.state().counters.requests > requests)  # polling goes on ...
    assert writes == []  # ... but nothing was written
    assert twin.holding[3000] == 200
    assert not env.state().unsaved


async def test_empty_entry_asks_for_a_value(env: Env):
    user, twin = env.user, env.twin()
    await env.polled("door-1")
    await user.open("/device/door-1")
    writes = spy_writes(twin)
    entry_element(user, "LockRequestDelay").value = None  # the field starts with the current value: cleared
    write_button(user, "LockRequestDelay").click()
    await eventually(lambda: entry_element(user, "LockRequestDelay").error == "enter a value first")
    assert writes == []


def entry_element(user: User, param: str):
    (element,) = entry(user, param).elements
    return element


def choose(user: User, param: str, value: int, options: dict[int, str]) -> None:
    """Open the select of ``param`` and click the option for ``value``, as a person would."""
    select = entry(user, param)
    label = f"{options[value]} ({value})"
    select.click()  # opens the popup
    UserInteraction(user, select.elements, label).click()  # picks the option
    (element,) = select.elements
    assert element.value == value


async def test_remove_magnet_asks_for_confirmation_and_cancel_writes_nothing(env: Env):
    user, twin = env.user, env.twin()
    await env.open_page()
    writes = spy_writes(twin)

    choose(user, "SettingsRemoveMagnet", 1, REMOVE_MAGNET)
    write_button(user, "SettingsRemoveMagnet").click()

    await user.should_see("Write SettingsRemoveMagnet = Retract when magnet removed (1)?", retries=10)
    await user.should_see(kind=ui.label, content="Security risk")
    await user.should_see(kind=ui.label, content="unlocked from outside")
    user.find(kind=ui.button, content="Cancel").click()

    await user.should_not_see(kind=ui.label, content="Security risk", retries=20)
    requests = env.state().counters.requests
    await eventually(lambda: env.state().counters.requests > requests + 2, what="polls after the cancel")
    assert writes == []  # the line was used after the cancel, never for a write
    assert twin.holding[3005] == 0
    assert not env.state().unsaved


async def test_remove_magnet_written_after_confirmation(env: Env):
    user, twin = env.user, env.twin()
    await env.open_page()

    choose(user, "SettingsRemoveMagnet", 1, REMOVE_MAGNET)
    write_button(user, "SettingsRemoveMagnet").click()
    await user.should_see(kind=ui.label, content="Security risk", retries=10)
    user.find(kind=ui.button, content="Write anyway").click()

    await eventually(lambda: twin.holding[3005] == 1, what="twin holding 3005 == 1")
    await user.should_see("written and read back", retries=20)
    assert REMOVE.key in env.state().unsaved


# -- JSON API and the worker's role check -------------------------------------------------------


async def test_api_devices(env: Env):
    await env.polled()
    client = env.user.http_client
    response = await client.get("/api/devices")
    assert response.status_code == 200
    devices = {d["name"]: d for d in response.json()}
    assert set(devices) == {"door-1", "door-2"}
    for d in devices.values():
        assert d["type"] == "hdlock" and d["bus"] == "line1"
        assert d["online"] is True and d["status"] == "online"
        assert d["counters"]["requests"] > 0 and d["counters"]["timeouts"] == 0
        assert "values" not in d


async def test_api_device_values_by_document_name(env: Env):
    await env.polled("door-1")
    response = await env.user.http_client.get("/api/devices/door-1")
    assert response.status_code == 200
    body = response.json()
    assert body["name"] == "door-1" and body["online"] is True
    values = body["values"]
    for key in ("BoltPosition", "LockStatus", "SettingsProximityThresholdUnlock", "SerialNumber", "LockRequestDelay"):
        assert key in values, f"{key} missing from the API values"
        assert {"value", "raw", "unit"} <= set(values[key]), values[key]
    assert values["BoltPosition"]["unit"] == "Inc"
    assert values["BoltPosition"]["value"] == 0  # door open: bolt retracted
    threshold = values["SettingsProximityThresholdUnlock"]
    assert threshold["value"] == -30 and threshold["raw"] == 65506
    serial = values["SerialNumber"]
    assert serial["value"] == serial["raw"] == 0x000A0001  # input 104 << 16 | input 105
    assert values["LockRequestDelay"] == {**values["LockRequestDelay"], "value": 200, "unit": "ms"}
    status = values["LockStatus"]
    assert status["fields"]["BoltUnlocked"] == 1 and status["fields"]["BoltLocked"] == 0
    # the holding copies of BoltPosition carry their own labels and do not shadow the input
    assert "BoltPosition (HR1001)" in values

    missing = await env.user.http_client.get("/api/devices/nope")
    assert missing.status_code == 404


async def test_worker_refuses_writes_for_viewer(env: Env):
    twin = env.twin()
    await env.polled("door-1")
    writes = spy_writes(twin)
    with pytest.raises(PermissionDenied):
        await env.runtime.worker.gate.run(lambda: env.runtime.worker.adapters["door-1"].write_param(DELAY, 999),
                                          device="door-1", role="viewer", user="tester", describe="write LockRequestDelay")
    assert writes == []
    assert twin.holding[3000] == 200
    assert any(e.level == "warning" and "refused for tester (viewer)" in e.text for e in env.state().events)
    # the engineer may
    await env.runtime.worker.gate.run(lambda: env.runtime.worker.adapters["door-1"].write_param(DELAY, 999),
                                      device="door-1", role="engineer", user="local")
    assert twin.holding[3000] == 999
    assert writes == [(3000, 999)]  # the spy sees writes that do happen


async def test_loop_lag_is_coloured_by_its_value_not_by_any_stall(env: Env):
    """Issue 32.16: a stall in the last minute on a busy machine made "loop NN ms" orange all the time;
    the colour follows the p99 (grey below 100 ms, orange from 100 ms, red from 250 ms)."""
    health = env.runtime.worker.loop_health
    figures = {"p99_ms": 20.0, "worst_ms": 180.0, "stalls": 3, "last_stall": time.time() - 5}
    health.summary = lambda: dict(figures)
    await env.user.open("/")
    (chip,) = [e for e in env.user.client.elements.values() if e.props.get("data-testid") == "loop-lag"]
    await eventually(lambda: chip.text == "loop 20 ms", what="the loop chip")
    assert "text-orange-4" not in chip.classes and "text-grey-5" in chip.classes, chip.classes
    figures["p99_ms"] = 140.0
    await eventually(lambda: "text-orange-4" in chip.classes, timeout=5, what="orange at 140 ms")
    figures["p99_ms"] = 300.0
    await eventually(lambda: "text-red-4" in chip.classes, timeout=5, what="red at 300 ms")
