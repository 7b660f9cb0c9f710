"""The poll window's count follows the chosen function (Modbus application protocol 6.1-6.4: 01/02 read 1..2000
bits, 03/04 read 1..125 registers): the window states the range of the function chosen and refuses a count outside
it in the field, before anything is sent (issue 42 item 11: it said "allowed 1..2000", then refused 200 for 03)."""

from __future__ import annotations

import pytest
from nicegui import ui
from nicegui.testing.user_interaction import UserInteraction
from webutil import eventually, simulated_user

from app import modbus_poll as mp
from app.runtime import Runtime
from tests.conftest import free_port, modbus_plant

pytestmark = pytest.mark.timeout(60)


@pytest.mark.parametrize(("function", "limit"), [(1, 2000), (2, 2000), (3, 125), (4, 125)])
def test_the_count_range_of_each_read_function(function: int, limit: int):
    assert mp.count_range(function) == (1, limit)
    mp.PollSpec(1, function, 0, limit).check()
    with pytest.raises(mp.PollError, match=f"1..{limit}"):
        mp.PollSpec(1, function, 0, limit + 1).check()


def _in(card: ui.element, kind: type, label: str = "", testid: str = "") -> ui.element:
    return next(e for e in card.descendants() if isinstance(e, kind)
                and (not label or e.props.get("label") == label) and (not testid or e.props.get("data-testid") == testid))


async def test_the_window_states_the_count_range_of_the_chosen_function_and_refuses_before_sending(tmp_path):
    runtime = Runtime(modbus_plant(free_port(), locks=(("door-1", 1),), poll_period=0.2), simulate=True, data_dir=tmp_path)
    async with simulated_user(runtime) as user:
        await eventually(lambda: runtime.store.devices["door-1"].status == "online", timeout=10)
        await user.open("/monitor/line1/poll")
        await user.should_see("Window 1")
        card = next(e for e in user.client.elements.values() if e.props.get("data-testid") == "poll-window-1")
        function, count = _in(card, ui.select, "Function"), _in(card, ui.number, "Count")
        function.value = 3
        assert count.props.get("hint") == "allowed 1 .. 125", count.props.get("hint")
        count.value = 200
        assert count.validate() is False and "1 .. 125" in (count.error or ""), count.error
        requests = len(runtime.store.buses["line1"].transactions)
        UserInteraction(user, {_in(card, ui.button, testid="poll-start")}, None).click()
        assert not any(t.request.startswith("poll ") for t in list(runtime.store.buses["line1"].transactions)[requests:])
        await user.should_not_see("count 200 is outside")  # the field said it; no refusal after a click
        function.value = 1  # coils: 200 is fine, the range says so
        assert count.props.get("hint") == "allowed 1 .. 2000", count.props.get("hint")
        assert count.validate() is True
