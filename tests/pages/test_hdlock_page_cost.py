"""What an open HD-Lock page costs per push: a card whose values did not change does nothing, a register table
compares its words and builds only the rows whose words changed, and the page is built of few elements."""

from __future__ import annotations

import gc
import json
import time

import pytest
from nicegui import ui
from plants import modbus_line, plant
from webutil import eventually, user_on

from devices.hdlock.params import HOLDING, INPUT, PARAMS
from pages.device_page import DeviceView
from pages.hdlock import LampsCard
from pages.widgets import RegisterTable

pytestmark = pytest.mark.timeout(40)

# the HD-Lock page was 388 elements (the header's ~100 among them): lamps of one element, value cells of one
HDLOCK_PAGE_ELEMENTS = 350


def page_view(runtime, name: str) -> DeviceView:
    """The view of the open page of ``name`` (the one whose refresh follows the store)."""
    (view,) = [w.callback.__self__ for w in runtime.store._watches[name]
               if getattr(w.callback, "__func__", None) is DeviceView.pushed]
    return view


def reread(state, space: str, address: int) -> None:
    """The device answered again with the same word: a new read time (and a new version), the same value."""
    state.update_registers(space, address, [state.registers[(space, address)][0]])


@pytest.fixture
async def door_page():
    async with user_on(plant(modbus_line(locks=(("door-1", 1),)))) as (user, runtime):
        state = runtime.store.devices["door-1"]
        await eventually(lambda: state.status == "online" and state.value("SerialNumber") is not None
                         and all(state.raw(p) is not None for p in PARAMS.space(INPUT)), timeout=10)
        await user.open("/device/door-1")
        await user.should_see("HD-Lock door-1")
        yield user, runtime, state


async def test_a_card_whose_values_did_not_change_draws_nothing_until_they_change_or_the_ages_are_due(door_page):
    user, runtime, state = door_page
    view = page_view(runtime, "door-1")
    (lamps,) = [card for card in view.cards if isinstance(card, LampsCard)]
    drawn = []
    for name, lamp in lamps.lamps.items():
        lamp.show = lambda entry, value=None, name=name: drawn.append(name)  # noqa: B023 - recorded, not drawn

    # a poll that read the same words, counters counting: no card draws (no record built, no element touched)
    state.counters.requests += 1
    reread(state, HOLDING, 1000)
    view.pushed()
    assert drawn == []

    # the once-a-second round: nothing drawn while the qualities are as drawn; a value turned stale is drawn stale
    def round_() -> None:
        runtime.store.age_round = True
        try:
            view.pushed()
        finally:
            runtime.store.age_round = False

    round_()
    assert drawn == []
    word, read = state.registers[(HOLDING, 1000)]
    state.registers[(HOLDING, 1000)] = (word, read - 60)  # LockStatus not read for a minute
    round_()
    assert len(drawn) == len(lamps.lamps) and lamps.aging
    drawn.clear()
    state.registers[(HOLDING, 1000)] = (word, time.time())  # read again, the same word: the stale mark clears
    view.pushed()
    assert len(drawn) == len(lamps.lamps) and not lamps.aging

    # a new LockStatus word is drawn on the push that brings it
    drawn.clear()
    state.update_registers(HOLDING, 1000, [state.registers[(HOLDING, 1000)][0] ^ 0x0001])
    view.pushed()
    assert len(drawn) == len(lamps.lamps)

    # the device going silent changes what every card shows at once (not at the next round)
    drawn.clear()
    state.mark_offline("test: no answer")
    view.pushed()
    assert len(drawn) == len(lamps.lamps)


async def test_a_register_table_builds_only_the_rows_whose_words_changed_and_sends_only_their_cells(door_page):
    user, runtime, state = door_page
    (table,) = [o for o in gc.get_objects() if isinstance(o, RegisterTable) and o.state is state
                and o.params[0].space == INPUT]  # the input registers: the tab shown
    table.update(times=True)
    sent: list[str] = []
    table.table.client.run_javascript = lambda code, *a, **k: sent.append(code)
    read: list[str] = []
    raw = type(state).raw
    state.raw = lambda p: (read.append(p.key), raw(state, p))[1]  # type: ignore[method-assign]
    try:
        # a poll that read the same words: one comparison of the words, no row looked at, nothing sent
        for p in table.params:
            reread(state, p.space, p.address)
        table.update()
        assert read == [] and sent == []

        # one word changed: that row alone is built, and only its changed cells go to the browser
        changed = PARAMS.by_name["LockState"]
        state.update_registers(INPUT, changed.address, [state.registers[(INPUT, changed.address)][0] ^ 0x0001])
        table.update()
        assert read == [changed.key]
        (code,) = sent
        patch = json.loads(code[code.index(",{") + 1:code.rindex(")")])
        assert list(patch) == [changed.key] and {"value", "raw"} <= set(patch[changed.key])

        # the once-a-second round: a good row read again changes its Read cell alone
        sent.clear()
        for p in table.params:
            state.registers[(p.space, p.address)] = (state.registers[(p.space, p.address)][0],
                                                     state.registers[(p.space, p.address)][1] + 5)
        table.update(times=True)
        (code,) = sent
        patch = json.loads(code[code.index(",{") + 1:code.rindex(")")])
        assert patch and all(set(cells) == {"age"} for cells in patch.values())
    finally:
        del state.raw


async def test_the_hdlock_page_is_built_of_few_elements(door_page):
    user, runtime, state = door_page
    elements = list(user.client.elements.values())
    assert len(elements) <= HDLOCK_PAGE_ELEMENTS, len(elements)
    lamps = [e for e in elements if "data-lamp" in e.props]
    assert len(lamps) == 10
    for lamp in lamps:  # one element and its tooltip, with its name, state and quality
        assert isinstance(lamp, ui.label) and [type(e) for e in lamp.descendants()] == [ui.tooltip]
        assert lamp.text and lamp.props["data-on"] in ("0", "1") and lamp.props["data-quality"] == "good"
    cells = [e for e in elements if isinstance(e, ui.html) and '<div class="mono">' in e.content]
    assert len(cells) == len([p for p in PARAMS.space(HOLDING) if p.writable])  # each current value: one element

    # the "unsaved" mark of a parameter is built when it is first needed, beside the parameter's name
    badges = lambda: [e for e in user.client.elements.values() if isinstance(e, ui.badge) and e.text == "unsaved"]  # noqa: E731
    assert badges() == []
    delay = PARAMS.by_name["LockRequestDelay"]
    state.unsaved.add(delay.key)
    state.touch()
    page_view(runtime, "door-1").pushed()
    (badge,) = badges()
    assert badge.visible and badge.parent_slot.parent.default_slot.children[0].props["data-param-name"] == "LockRequestDelay"
    state.unsaved.discard(delay.key)
    page_view(runtime, "door-1").pushed()
    assert not badge.visible
