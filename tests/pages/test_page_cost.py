"""What an open page costs per push: a register table sends only the cells that changed (and nothing while
its tab is not shown), tiles are reused while their points hold the same values, the header's menu names
the buses in words."""

from __future__ import annotations

import asyncio

import pytest
from nicegui import ui
from webutil import eventually, lone_m3io_user


pytestmark = pytest.mark.timeout(40)

@pytest.fixture
async def user_runtime():
    async with lone_m3io_user() as env:
        yield env


def sent_js(client) -> list[str]:
    """Every script the page sends from now on (collected, and sent as before)."""
    sent: list[str] = []
    original = client.run_javascript

    def run_javascript(code: str, *args, **kwargs):
        sent.append(code)
        return original(code, *args, **kwargs)

    client.run_javascript = run_javascript
    return sent


async def test_register_table_sends_only_the_changed_cells_and_shows_what_the_store_holds(user_runtime):
    from devices.hdlock.params import INPUT, PARAMS
    from pages.widgets import RegisterTable

    user, runtime = user_runtime
    state = runtime.store.devices["io"]
    params = PARAMS.space(INPUT)
    state.online = True
    state.update_registers(INPUT, 0, [0] * (max(p.address + p.words for p in params)))
    tables: list = []

    @ui.page("/table-cells")
    def page() -> None:
        tables.append(RegisterTable(state, params))

    await user.open("/table-cells")
    table = tables[0]
    sent = sent_js(table.table.client)
    first = params[0]
    state.update_registers(INPUT, first.address, [1] * first.words)
    shown = lambda: next(r for r in table.table.rows if r["key"] == first.key)["value"]  # noqa: E731
    await eventually(lambda: shown() == first.display(state.raw(first)), what="the new value in the table")
    patches = [code for code in sent if "mounted_app.elements" in code]
    assert patches, "the change goes out as a patch of the table's cells"
    assert first.key in patches[-1]
    assert (first.description or "").strip() == "" or first.description not in patches[-1]  # not the whole row
    for p in params:  # every row shows what the store holds
        row = next(r for r in table.table.rows if r["key"] == p.key)
        raw = state.raw(p)
        assert row["value"] == ("-" if raw is None else p.display(raw))


async def test_register_table_in_a_hidden_tab_waits_for_its_tab(user_runtime):
    from devices.hdlock.params import HOLDING, INPUT, PARAMS
    from pages.widgets import RegisterTable

    user, runtime = user_runtime
    state = runtime.store.devices["io"]
    state.online = True
    holding = PARAMS.space(HOLDING)
    target = holding[0]
    tables: list = []

    @ui.page("/table-tabs")
    def page() -> None:
        with ui.tabs() as tabs:
            t_in = ui.tab("in")
            t_hold = ui.tab("hold")
        with ui.tab_panels(tabs, value=t_in) as panels:
            with ui.tab_panel(t_in):
                tables.append(RegisterTable(state, PARAMS.space(INPUT)))
            with ui.tab_panel(t_hold):
                tables.append(RegisterTable(state, holding))
        tables.append(panels)

    await user.open("/table-tabs")
    _, hidden, panels = tables
    row = lambda: next(r for r in hidden.table.rows if r["key"] == target.key)  # noqa: E731
    before = dict(row())
    state.update_registers(HOLDING, target.address, [7] * target.words)
    await asyncio.sleep(0.4)  # several pushes
    assert row() == before  # its tab is not shown: nothing built, nothing sent
    panels.set_value("hold")
    await eventually(lambda: row()["value"] == target.display(state.raw(target)), what="the hidden table brought up to date")


async def test_tile_is_reused_while_its_points_hold_the_same_values(user_runtime):
    from pages.plant_view import plant_tile

    _user, runtime = user_runtime
    state = runtime.store.devices["io"]
    first = plant_tile(state)
    state.counters.responses += 1
    state.version += 1  # a frame with the same values (counters moved)
    assert plant_tile(state) is first
    state.online = not state.online  # a change the tile shows
    state.version += 1
    assert plant_tile(state) is not first


async def test_header_menu_names_every_bus_in_words_and_links_fleet(user_runtime):
    user, runtime = user_runtime
    await user.open("/backup")  # any page with the header
    items = [e for e in user.client.elements.values() if "data-bus-item" in e.props]
    assert [e.props["data-bus-item"] for e in items] == list(runtime.store.buses)
    links = [e for e in user.client.elements.values() if e.props.get("href") == "/fleet"]
    assert links, "Fleet is among the page links"
    bus = runtime.store.buses["can9"]
    item = next(e for e in items if e.props["data-bus-item"] == "can9")
    words = lambda: item.default_slot.children[0].content  # noqa: E731 - icon, name and state: one element
    bus.connected = False
    await eventually(lambda: "can9</span>" in words() and ">not connected</span>" in words(), timeout=5, what="the bus's state in words")
    bus.connected = True
    await eventually(lambda: ">connected</span>" in words(), timeout=5, what="connected again in words")
    chip = next(e for e in user.client.elements.values() if e.props.get("data-bus") == "can9")
    assert chip.props["aria-label"].startswith("can9: ")
