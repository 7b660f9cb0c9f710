"""What an open Electrak page costs per push (issue 34): a status telegram with the same values draws nothing; the
page's once-a-second round draws the ages and stale marks; the page is built from a bounded number of elements."""

from __future__ import annotations

import time

import pytest
from plants import channel, electrak_bus, plant
from webutil import eventually, push_the_same_values, refresh_on_the_round, simulated_user

from app.runtime import Runtime

pytestmark = pytest.mark.timeout(60)

# a network of its own name: a page reads a network's service parameters by itself once per 30 s (pages.electrak)

# what the cards draw from (each read through the device record's live/point/entry)
DRAWN = ("Position", "Current", "Speed", "Extending", "Message timeout", "Devices heard")
MAX_ELEMENTS = 264  # the whole page: header (with its language switch), cards, chart, simulation card, events, STOP bar




async def test_a_telegram_with_the_same_values_draws_nothing_and_the_round_draws_ages(tmp_path, monkeypatch):
    runtime = Runtime(plant(electrak_bus("hoist", channel_name=channel("cost"))), simulate=True, data_dir=tmp_path)
    async with simulated_user(runtime) as user:
        state = runtime.store.devices["hoist"]
        await eventually(lambda: state.status == "online" and "Position" in state.points, timeout=10)
        view, read = await push_the_same_values(user, runtime, "hoist", monkeypatch)
        assert not [n for n in read if n in DRAWN], read  # nothing drawn again
        refresh_on_the_round(runtime.store, view)  # the once-a-second round: ages and stale marks drawn
        assert set(DRAWN) <= set(read)
        # a new value is drawn on the push that brings it
        read.clear()
        state.publish_telegram(time.time(), {"Position": state.points["Position"]._replace(value=123.4)})
        view.refresh()
        assert "Position" in read
        cell = [e for e in user.client.elements.values() if e.props.get("data-testid") == "network-position"][0]
        assert cell.default_slot.children[0].text.startswith("123.4 mm")


async def test_the_page_is_built_from_a_bounded_number_of_elements(tmp_path):
    """Server memory grows with every element of every open page (some 5 KB each): lamps, numbers and lines are
    drawn as few elements as they can be, with the same words, units and data attributes."""
    runtime = Runtime(plant(electrak_bus("hoist", channel_name=channel("elements"))), simulate=True, data_dir=tmp_path)
    async with simulated_user(runtime) as user:
        state = runtime.store.devices["hoist"]
        await eventually(lambda: state.status == "online", timeout=10)
        await user.open("/device/hoist")
        await eventually(lambda: any("2 of 2 configured" in (getattr(e, "text", "") or "") for e in user.client.elements.values()),
                         timeout=5, what="the network drawn")
        assert len(user.client.elements) <= MAX_ELEMENTS, len(user.client.elements)
