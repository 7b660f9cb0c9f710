"""Several Modbus poll windows on one page (issue 32 item 14), with NiceGUI's simulated user: each window has its
own request, table, counters and age; windows are added and removed; a reload of the tab brings them back."""

from __future__ import annotations

import pytest
from nicegui import ui
from nicegui.testing.user_interaction import UserInteraction
from webutil import eventually, simulated_user

from app.runtime import Runtime
from tests.conftest import free_port, modbus_plant

pytestmark = pytest.mark.timeout(60)


def window(user, number: int) -> ui.element:
    found = [e for e in user.client.elements.values() if e.props.get("data-testid") == f"poll-window-{number}"]
    assert len(found) == 1, f"window {number}: {len(found)} cards"
    return found[0]


def inside(card: ui.element, kind: type, label: str = "", testid: str = "") -> ui.element:
    for e in card.descendants():
        if isinstance(e, kind) and (not label or e.props.get("label") == label) \
                and (not testid or e.props.get("data-testid") == testid):
            return e
    raise AssertionError(f"no {kind.__name__} {label or testid} in {card.props.get('data-testid')}")


def click(user, element: ui.element) -> None:
    UserInteraction(user, {element}, None).click()


def set_request(card, *, unit: int, function: int, start: int, count: int, period: float) -> None:
    inside(card, ui.number, "Unit").value = unit
    inside(card, ui.select, "Function").value = function
    inside(card, ui.number, "Start address").value = start
    inside(card, ui.number, "Count").value = count
    inside(card, ui.number, "Period s").value = period


def status(card) -> str:
    return inside(card, ui.label, testid="poll-status").text


async def test_windows_poll_each_their_own_request_and_come_back_after_a_reload(tmp_path):
    runtime = Runtime(modbus_plant(free_port(), locks=(("door-1", 1), ("door-2", 2)), poll_period=0.2),
                      simulate=True, data_dir=tmp_path)
    async with simulated_user(runtime) as user:
        await eventually(lambda: runtime.store.devices["door-1"].status == "online", timeout=10)
        await user.open("/monitor/line1/poll")
        await user.should_see("Window 1")
        first = window(user, 1)
        click(user, next(e for e in user.client.elements.values() if e.props.get("data-testid") == "poll-add"))
        await user.should_see("Window 2")
        second = window(user, 2)
        set_request(first, unit=1, function=3, start=3000, count=2, period=0.2)
        set_request(second, unit=2, function=4, start=104, count=2, period=0.3)
        click(user, inside(first, ui.button, testid="poll-start"))
        click(user, inside(second, ui.button, testid="poll-start"))
        table1, table2 = inside(first, ui.table, testid="poll-table"), inside(second, ui.table, testid="poll-table")
        await eventually(lambda: table1.rows and table2.rows, timeout=5, what="both tables filled")
        assert table1.rows[0]["name"].startswith("door-1: ") and table1.rows[0]["address"] == 3000
        assert table2.rows[0]["name"] == "door-2: SerialNumber (word 1 of 2)" and table2.rows[0]["address"] == 104
        await eventually(lambda: " 0 errors (0 timeouts)" in status(first) and "updated just now" in status(first),
                         timeout=5, what=status(first))
        assert "unit 2 · 04 Read Input Registers · 104+2 · every 0.3 s" in inside(second, ui.label, testid="poll-summary").text
        assert len(runtime.worker.lines["line1"].state.transactions) > 0

        # a third window asks a unit nobody answers: its timeouts are counted, the others go on
        click(user, next(e for e in user.client.elements.values() if e.props.get("data-testid") == "poll-add"))
        await user.should_see("Window 3")
        third = window(user, 3)
        set_request(third, unit=9, function=3, start=0, count=1, period=0.2)
        click(user, inside(third, ui.button, testid="poll-start"))
        await eventually(lambda: "(2 timeouts" in status(third) or "(3 timeouts" in status(third), timeout=5,
                         what=status(third))
        assert inside(third, ui.label, testid="poll-error").text.startswith("unit 9: no answer")
        polls = runtime.worker.lines["line1"].tool_requests
        await eventually(lambda: runtime.worker.lines["line1"].tool_requests > polls + 4, timeout=5)

        # removing a window stops its poll
        windows = user.client.elements  # noqa: F841 - kept for the reader: the cards live in the client
        click(user, inside(third, ui.button, testid="poll-remove"))
        await user.should_not_see("Window 3")

        # a reload of the tab brings both windows back, polling what they polled
        await user.open("/monitor/line1/poll")
        await user.should_see("Window 2")
        first, second = window(user, 1), window(user, 2)
        await user.should_not_see("Window 3")
        assert inside(second, ui.number, "Start address").value == 104 and inside(second, ui.select, "Function").value == 4
        table2 = inside(second, ui.table, testid="poll-table")
        await eventually(lambda: table2.rows and "polling" in status(second), timeout=5, what=status(second))
        assert table2.rows[0]["name"] == "door-2: SerialNumber (word 1 of 2)"
        click(user, inside(first, ui.button, testid="poll-stop"))
        await eventually(lambda: status(first).startswith("stopped"), timeout=3)
