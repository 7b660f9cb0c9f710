"""HD-Lock page with NiceGUI's simulated user: one entry behaviour, Save-Settings confirmation,
offline marking with write buttons disabled, the events log, no page timers of its own (issue 15, 16)."""

from __future__ import annotations

import pytest
from conftest import modbus_plant
from nicegui import ui
from nicegui.testing import User
from nicegui.testing.user_interaction import UserInteraction
from webutil import eventually, simulated_user

from app.runtime import Runtime
from devices.hdlock.params import PARAMS

pytestmark = pytest.mark.timeout(40)


@pytest.fixture
async def env():
    runtime = Runtime(modbus_plant(locks=(("door-1", 1),)), simulate=True)
    async with simulated_user(runtime) as user:
        yield user, runtime


async def open_page(user: User, runtime: Runtime) -> None:
    state = runtime.store.devices["door-1"]
    await eventually(lambda: state.status == "online" and state.value("SerialNumber") is not None, timeout=10)
    await user.open("/device/door-1")
    await user.should_see("HD-Lock door-1")


def one(user: User, prop: str, value: str, kind=ui.element):
    found = [e for e in user.client.elements.values() if isinstance(e, kind) and e.props.get(prop) == value]
    assert len(found) == 1, f"{len(found)} elements with {prop}={value!r}"
    return found[0]


def test_elapsed_times_have_a_unit_and_the_register_top_is_named():
    for name in ("StateMachineElapsed", "Time since last change", "Last time since last change"):
        p = PARAMS.by_name[name]
        assert p.unit == "ms"
        assert p.display(1234) == "1234 ms"
        assert p.display(0xFFFF) == "65535 ms (at its top: 65.5 s or more)"


async def test_address_300_stays_typed_marked_with_the_range_and_send_is_refused(env):
    user, runtime = env
    await open_page(user, runtime)
    twin = runtime.twins["door-1"]
    (field,) = [e for e in user.client.elements.values() if isinstance(e, ui.number) and e.props.get("label") == "New address"
                and "data-testid" not in e.props]  # the broadcast card's has one
    send = one(user, "data-testid", "sa-send")
    field.value = 300
    await eventually(lambda: field.error and "1 .. 254" in field.error, what="address field marked with its range")
    assert field.value == 300  # not clamped to 254
    # Send is off while the field refuses the entry, and says why: nothing can be sent
    await eventually(lambda: not send.enabled, what="Send off")
    reason = send.props.get("data-disabled-reason", "")
    assert reason.startswith("address 300 is refused: out of range") and "1 .. 254" in reason, reason
    await user.should_not_see("Change the Modbus address")  # no confirmation: nothing will be sent
    assert twin.address == 1
    field.value = 9  # a valid entry: Send is on again
    await eventually(lambda: send.enabled, what="Send on for address 9")


async def test_save_settings_asks_listing_the_unsaved_changes(env):
    user, runtime = env
    await open_page(user, runtime)
    twin, state = runtime.twins["door-1"], runtime.store.devices["door-1"]
    saved = twin.input[101]
    one(user, "data-param", "LockRequestDelay").value = 500
    UserInteraction(user, {one(user, "data-write", "LockRequestDelay", ui.button)}, None).click()
    await eventually(lambda: PARAMS.by_name["LockRequestDelay"].key in state.unsaved, what="write done")

    user.find(kind=ui.button, content="Save-Settings").click()
    await user.should_see("Save-Settings: write the settings to the lock's flash?")
    await user.should_see("LockRequestDelay (holding 3000) = 500 ms")
    user.find(kind=ui.button, content="Cancel").click()
    await user.should_not_see("Save-Settings: write the settings")
    assert twin.input[101] == saved and twin.flash[3000] == 200  # cancelled: nothing saved

    user.find(kind=ui.button, content="Save-Settings").click()
    await user.should_see("LockRequestDelay (holding 3000) = 500 ms")
    user.find(kind=ui.button, content="Save to flash").click()
    await eventually(lambda: twin.flash[3000] == 500 and twin.input[101] == saved + 1, what="saved after the confirmation")


async def test_silent_lock_greys_the_page_and_disables_writes_with_the_reason(env):
    user, runtime = env
    await open_page(user, runtime)
    state = runtime.store.devices["door-1"]
    write = one(user, "data-write", "LockRequestDelay", ui.button)
    save = one(user, "data-testid", "save-settings", ui.button)
    assert write.enabled and save.enabled
    runtime.twins["door-1"].silent = True
    await eventually(lambda: state.status == "offline", timeout=10)

    def greyed() -> None:
        for button in (write, save, one(user, "data-testid", "sa-send", ui.button)):
            assert not button.enabled
            assert button.props.get("data-disabled-reason", "").startswith("the device does not answer")
        assert one(user, "data-lamp", "BoltUnlocked").props["data-quality"] == "offline"
        assert one(user, "data-lamp", "BoltUnlocked").props["data-on"] == "unknown"

    await eventually(greyed, timeout=3)
    events = one(user, "data-testid", "events", ui.table)
    await eventually(lambda: events.rows and events.rows[0]["level"] == "error", what="offline event on top")

    runtime.twins["door-1"].silent = False
    await eventually(lambda: state.status == "online", timeout=10)
    await eventually(lambda: write.enabled, timeout=3, what="writes enabled again")
    texts = [row["text"] for row in events.rows]
    back = next(i for i, text in enumerate(texts) if "back online" in text)
    offline = next(i for i, row in enumerate(events.rows) if row["level"] == "error")
    assert back < offline, f"newest first: {texts[:5]}"


async def test_page_has_no_timers_of_its_own(env):
    user, runtime = env
    await open_page(user, runtime)
    timers = [e for e in user.client.elements.values() if isinstance(e, ui.timer)
              and getattr(getattr(e, "callback", None), "__module__", "").startswith("pages.hdlock")]
    assert timers == []
