"""HD-Lock page with NiceGUI's simulated user: the address changes of section 4.3.

A two-lock plant (door-1 at 1, door-2 at 2) on a free localhost port, polled over real
Modbus RTU frames, with the app registered as in production (``app.web.register``).
"""

from __future__ import annotations


import pytest
from nicegui import ui
from nicegui.testing import User
from nicegui.testing.user_interaction import UserInteraction
from webutil import LockPages, eventually, lock_pages_env


pytestmark = pytest.mark.timeout(30)


Env = LockPages

env = pytest.fixture(lock_pages_env, name="env")  # a simulated user on the app of two locks (door-1 at 1, door-2 at 2)


def by_testid(user: User, testid: str) -> UserInteraction:
    assert user.client is not None
    found = {e for e in user.client.elements.values() if e.props.get("data-testid") == testid and e.visible}
    assert len(found) == 1, f"expected one element with data-testid={testid!r}, found {len(found)}"
    return UserInteraction(user, found, None)


def fill(user: User, testid: str, value) -> None:
    (element,) = by_testid(user, testid).elements
    element.value = value


async def test_broadcast_address_change_names_the_known_locks_and_moves_the_one_that_meets_it(env: Env):
    user = env.user
    await env.polled("door-1", "door-2", point="LockStatus")
    env.twin("door-2").close_door()  # door-2 locks; door-1 stays open
    await eventually(lambda: (env.state("door-2").value("LockStatus") or 0) & 0x0104 == 0x0104, timeout=5)
    await user.open("/device/door-1")
    await user.should_see("HD-Lock door-1")

    fill(user, "bc-address", 9)
    fill(user, "bc-p1", "0x010C")  # DoorInPosition, ProximityOverrange, BoltLocked (section 4.3, example 1)
    fill(user, "bc-p2", "0x0104")
    await user.should_see("2 locks known on line1 (2 in the plant, 0 found by a scan)", retries=20)
    await user.should_see("By the last LockStatus read: door-2 would take it", retries=20)
    by_testid(user, "bc-send").click()

    await user.should_see("Up to 2 locks on line1 may take address 9", retries=10)
    await user.should_see(kind=ui.label, content="may be affected (2 in the plant, 0 found by a scan): door-1, door-2")
    user.find(kind=ui.button, content="Send to all (2)").click()

    await eventually(lambda: env.twin("door-2").address == 9, timeout=5, what="door-2 took address 9")
    await user.should_see(f"lock serial {env.twin('door-2').serial} answers at address 9", retries=40)
    assert env.twin("door-1").address == 1
    entries = env.runtime.audit.query(device="door-1", text="Broadcast Set Modbus Address")
    assert len(entries) == 1 and entries[0].result == "ok" and entries[0].new == "9"
    assert "2 known locks" in entries[0].action


async def test_broadcast_refused_when_two_known_locks_would_take_it(env: Env):
    user = env.user
    await env.polled("door-1", "door-2", point="LockStatus")
    await user.open("/device/door-1")
    await user.should_see("HD-Lock door-1")
    writes: list[tuple[int, int]] = []
    for name in ("door-1", "door-2"):
        original = env.twin(name).write
        env.twin(name).write = lambda a, v, original=original: (writes.append((a, v)), original(a, v))[1]

    fill(user, "bc-address", 9)  # P1 = P2 = 0: no condition, every lock would take it
    by_testid(user, "bc-send").click()

    await user.should_see("door-1 and door-2 would all take address 9", retries=10)
    await user.should_not_see("Up to 2 locks on line1 may take address 9")
    assert writes == []
    assert (env.twin("door-1").address, env.twin("door-2").address) == (1, 2)


async def test_set_address_from_the_page_reports_the_outcome_from_the_new_address(env: Env):
    """The lock stays silent on the command write (the twin's default): the page says so and reports success."""
    user = env.user
    await env.polled("door-1", point="LockStatus")
    assert env.twin("door-1").answers_address_command is False
    await user.open("/device/door-1")
    await user.should_see("HD-Lock door-1")

    number = next(e for e in user.client.elements.values() if isinstance(e, ui.number) and e.props.get("label") == "New address"
                  and "data-testid" not in e.props)
    number.value = 8  # P1 = P2 = 0: no condition
    user.find(kind=ui.button, content="Send Set Modbus Address").click()
    await user.should_see("Change the Modbus address to 8?", retries=10)
    dialog_send = {e for e in user.client.elements.values() if isinstance(e, ui.button) and e.props.get("label") == "Send"}
    UserInteraction(user, dialog_send, None).click()

    await user.should_see("the lock answers at address 8 now (no answer to the command at address 1, as expected)", retries=60)
    assert env.twin("door-1").address == 8
    assert env.state("door-1").live("Modbus address").value == 8
    entries = env.runtime.audit.query(device="door-1", text="Set Modbus Address 8")
    assert entries and entries[0].result == "ok" and entries[0].old == "1" and entries[0].new == "8"
