"""Shared live widgets: charts send only new samples and thin long windows; entries keep what was typed;
the header is built once and changed in place; counters go out once a second."""

from __future__ import annotations

import asyncio
import time

import pytest
from nicegui import ui
from plants import can_bus, device, plant_text
from webutil import eventually, lone_m3io_user, simulated_user

from app.plant import parse_plant
from app.runtime import Runtime

pytestmark = pytest.mark.timeout(40)

@pytest.fixture
async def user_runtime():
    async with lone_m3io_user() as env:
        yield env


async def charts_on_page(user, path: str, *makes) -> list:
    """Open a page at ``path`` that builds one chart per callable in ``makes``; the charts, in order."""
    charts: list = []

    @ui.page(path)
    def page() -> None:
        charts.extend(make() for make in makes)

    await user.open(path)
    return charts


async def test_chart_sends_only_new_samples_and_thins_long_windows(user_runtime):
    from pages.charts import HistoryChart

    user, runtime = user_runtime
    state = runtime.store.devices["io"]
    now = time.time()
    for i in range(6000):  # ten minutes at 10 samples/s
        state.add_history({"T": float(i)}, now=now - 600 + i * 0.1)
    chart, = await charts_on_page(user, "/chart-test", lambda: HistoryChart(state, ["T"], window_s=300, windows=(30, 300)))
    drawn = chart.figure["data"][0]["x"]
    assert 0 < len(drawn) <= HistoryChart.MAX_POINTS  # 3000 samples in the window, thinned
    assert chart.sent_points == len(drawn)
    for i in range(5):
        state.add_history({"T": 1.0}, now=now + 0.5 + i * 0.5)
    chart.update()
    assert chart.sent_points == len(drawn)  # within MIN_PERIOD_S of the drawing: kept for the next round
    chart.sent_at -= HistoryChart.MIN_PERIOD_S
    chart.update()
    assert chart.sent_points == len(drawn) + 5  # the new samples only, not the window again
    chart.sent_at -= HistoryChart.MIN_PERIOD_S
    chart.update()
    assert chart.sent_points == len(drawn) + 5  # nothing new, nothing sent
    chart.set_window(30)
    assert chart.sent_points <= 301 and chart.window_s == 30


async def test_empty_chart_says_no_data_yet(user_runtime):
    from pages.charts import HistoryChart

    user, runtime = user_runtime
    state = runtime.store.devices["io"]
    chart, = await charts_on_page(user, "/chart-empty", lambda: HistoryChart(state, ["T"]))
    layout = chart.figure["layout"]
    assert layout["annotations"][0]["text"] == "no data yet"
    assert layout["xaxis"]["range"][0] > "2026"  # the last minutes, not an axis at 1970 or 2000


async def test_range_entry_keeps_what_was_typed_and_refuses_with_the_range(user_runtime):
    from pages.widgets import range_number
    from pages.command_client import checked_value

    user, runtime = user_runtime
    fields = []

    @ui.page("/entry-test")
    def page() -> None:
        fields.append(range_number("Address", 1, 254, integer=True))

    await user.open("/entry-test")
    field = fields[0]
    field.value = 300
    with user.client:
        assert await checked_value(field, "io", "set address") is None
    assert field.value == 300  # not clamped to 254
    assert "1 .. 254" in field.error
    rows = await runtime.audit.aquery()
    assert any(r.result.startswith("refused: 300") and "1 .. 254" in r.result for r in rows)
    field.value = 12
    with user.client:
        assert await checked_value(field, "io", "set address") == 12


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


TWO = plant_text(can_bus(device("io", "m3io", "can9", variant="HM", sw1=0x1A), device("io2", "m3io", "can9", variant="HM", sw1=0x1B),
                         name="can9", channel_name="widgets-live-two", simulate=None), name="w2")


async def test_tile_counters_of_a_page_move_together_once_a_second():
    """The counters of every tile of a page go to the browser together on the page's one-second tick (one
    message), not each on its own device's round; they move once a second however often frames come."""
    runtime = Runtime(parse_plant(TWO), simulate=False)
    async with simulated_user(runtime) as user:
        await user.open("/")
        cards = {e.props["data-device"]: e for e in user.client.elements.values() if "data-device" in e.props}
        labels = {next(d for d in cards[n].descendants() if "data-tile-counters" in d.props).id: n for n in ("io", "io2")}
        sent: list[tuple[float, str]] = []
        outbox = user.client.outbox
        enqueue = outbox.enqueue_update

        def recorded(element) -> None:
            if element.id in labels:
                sent.append((time.monotonic(), labels[element.id]))
            enqueue(element)

        outbox.enqueue_update = recorded
        states = [runtime.store.devices[n] for n in ("io", "io2")]
        end = time.monotonic() + 2.6
        while time.monotonic() < end:  # frames ten times a second on both devices
            for state in states:
                state.counters.responses += 1
                state.touch()  # a frame: what every write ends with
            await asyncio.sleep(0.1)
        rounds: list[list[tuple[float, str]]] = []
        for t, name in sent:
            if rounds and t - rounds[-1][-1][0] < 0.03:
                rounds[-1].append((t, name))
            else:
                rounds.append([(t, name)])
        assert len(rounds) >= 2, sent
        for one in rounds:
            assert sorted(name for _t, name in one) == ["io", "io2"], f"not together: {rounds}"
        starts = [one[0][0] for one in rounds]
        assert all(b - a > 0.8 for a, b in zip(starts, starts[1:])), f"more often than once a second: {starts}"
        for label_id, name in labels.items():  # and they say what was counted
            count = runtime.store.devices[name].counters.responses
            await eventually(lambda: f"frames heard {count}" in user.client.elements[label_id].text, 2.0)


async def test_a_changed_value_reaches_the_tile_at_once(user_runtime):
    """Only counters and ages wait for the page's tick: a new value is pushed as it comes."""
    user, runtime = user_runtime
    await user.open("/")
    card = next(e for e in user.client.elements.values() if e.props.get("data-device") == "io")
    texts = lambda: [d.text for d in card.descendants() if isinstance(d, ui.label)]  # noqa: E731
    await asyncio.sleep(0.5)  # the page's first rounds are over before the new value comes
    state = runtime.store.devices["io"]
    state.publish("TEMP1", 21.5, "°C", text="21.5 °C")
    sent = time.monotonic()
    await eventually(lambda: any("T1\u00a021.5" in t for t in texts()), 1.0)
    assert time.monotonic() - sent < 0.5


async def test_every_chart_axis_is_titled_with_its_unit(user_runtime):
    from pages.charts import HistoryChart

    user, runtime = user_runtime
    state = runtime.store.devices["io"]
    charts = await charts_on_page(
        user, "/chart-units",
        lambda: HistoryChart(state, ["TEMP1 [°C]", "TEMP2 [°C]"]),
        lambda: HistoryChart(state, ["Position [mm]", "Current [mA]"], axes={"Current [mA]": "y2"}),
        lambda: HistoryChart(state, ["Position [mm]", "state"]),
    )
    one, two, mixed = (c.figure["layout"] for c in charts)
    assert one["yaxis"]["title"]["text"] == "°C"
    assert (two["yaxis"]["title"]["text"], two["yaxis2"]["title"]["text"]) == ("mm", "mA")
    assert "title" not in mixed["yaxis"]  # a series without a unit: no title that would leave it out


async def test_stacked_rows_share_one_time_axis_each_titled_with_its_unit(user_runtime):
    """Rows of series one above the other in one figure (one drawing for all), each on its own y axis."""
    from pages.charts import HistoryChart

    user, runtime = user_runtime
    state = runtime.store.devices["io"]
    chart, = await charts_on_page(user, "/chart-rows", lambda: HistoryChart(
        state, rows=[["Position [mm]", "Target [mm]"], ["Current [A]"], ["Speed [mm/s]"]], row_heights=(2, 1, 1)))
    figure = chart.figure
    layout = figure["layout"]
    assert [t["yaxis"] for t in figure["data"]] == ["y", "y", "y2", "y3"]
    axes = [layout["yaxis"], layout["yaxis2"], layout["yaxis3"]]
    assert [a["title"]["text"] for a in axes] == ["mm", "A", "mm/s"]
    domains = [a["domain"] for a in axes]
    assert domains[0][1] == 1.0 and domains[-1][0] >= 0.0
    assert all(upper[0] > lower[1] for upper, lower in zip(domains, domains[1:]))  # top to bottom, apart
    heights = [d[1] - d[0] for d in domains]
    assert abs(heights[0] - 2 * heights[1]) < 1e-9 and abs(heights[1] - heights[2]) < 1e-9
    assert all("overlaying" not in a for a in axes)
    assert layout["xaxis"]["anchor"] == "y3"  # the time axis under the lowest row
    with pytest.raises(ValueError):
        HistoryChart(state, ["T"], rows=[["T"]])


async def test_register_table_is_built_once_in_the_once_a_second_round(user_runtime):
    from devices.hdlock.params import INPUT, PARAMS
    from pages.widgets import RegisterTable

    user, runtime = user_runtime
    state = runtime.store.devices["io"]
    builds: list[bool] = []

    class Counted(RegisterTable):
        def update(self, times: bool = False) -> None:
            builds.append(times)
            super().update(times)

    @ui.page("/table-rounds")
    def page() -> None:
        Counted(state, PARAMS.space(INPUT))

    await user.open("/table-rounds")
    store = runtime.store
    store._aged = {name: time.monotonic() + 1e9 for name in store.devices}  # no once-a-second round for now
    builds.clear()
    state.touch()  # a write: the store is told (not only the version moved)
    await eventually(lambda: builds, timeout=15.0, what="the table drawn after a change")  # a loaded machine: late, not never
    # a change: values only (pushed as it comes, so a write of the starting runtime may add one more)
    assert builds and set(builds) == {False}
    builds.clear()
    store._aged = {name: 0.0 for name in store.devices}  # the next round is the once-a-second round
    state.touch()  # a write: the store is told (not only the version moved)
    await eventually(lambda: builds, timeout=15.0, what="the table drawn in the once-a-second round")
    assert builds[0] is True and builds.count(True) == 1  # a change in the once-a-second round: one build with the read times


async def test_a_frame_that_changes_nothing_shown_redraws_no_tile_or_row(user_runtime, monkeypatch):
    """Most frames bring the same values (only counters move): they cost the open pages a comparison, not a
    redraw of every tile and table row; a new value redraws them."""
    from pages.overview import DeviceTile, GlanceRow

    user, runtime = user_runtime
    await user.open("/")
    pushed: list[str] = []
    for cls in (DeviceTile, GlanceRow):
        def counted(self, ticked: bool = False, _refresh=cls.refresh, _name=cls.__name__) -> None:
            if not ticked:
                pushed.append(_name)
            _refresh(self, ticked)
        monkeypatch.setattr(cls, "refresh", counted)
    state = runtime.store.devices["io"]
    await asyncio.sleep(0.3)  # the page's first rounds are over before counting
    pushed.clear()
    for _ in range(8):
        state.counters.responses += 1
        state.touch()
        await asyncio.sleep(0.1)
    assert pushed == []
    state.publish("TEMP2", 30.0, "°C", text="30.0 °C")
    await eventually(lambda: sorted(set(pushed)) == ["DeviceTile", "GlanceRow"], 1.0)


def _tile_elements(user, prop: str, name: str) -> list:
    card = next(e for e in user.client.elements.values() if e.props.get(prop) == name)
    return list(card.descendants())


async def test_tiles_are_light_and_seldom_shown_marks_are_built_when_needed(user_runtime, monkeypatch):
    """A tile builds what it shows: no hidden badges, notes or bars waiting; a table row is one element.
    A mark needed later is built in its place (below the device's kind, above its values)."""
    user, runtime = user_runtime
    await user.open("/")
    state = runtime.store.devices["io"]
    elements = _tile_elements(user, "data-device", "io")
    assert len(elements) <= 12, [type(e).__name__ for e in elements]
    assert not any("data-drift" in e.props or "data-replaced" in e.props for e in elements)
    row = next(e for e in user.client.elements.values() if e.props.get("data-glance") == "io")
    assert list(row.descendants()) == []
    monkeypatch.setattr(runtime.record, "check_drift", lambda device: [])  # the drift below stays as set
    state.drift = {"changed": [{"key": "holding:3000", "name": "Delay", "approved": "200 ms", "now": "350 ms"}]}
    state.touch()  # a write: the store is told (not only the version moved)
    await eventually(lambda: any("data-drift" in e.props for e in _tile_elements(user, "data-device", "io")), 2.0)
    card = next(e for e in user.client.elements.values() if e.props.get("data-device") == "io")
    order = [("drift" if "data-drift" in e.props else "values" if "data-tile-values" in e.props else
              "kind" if getattr(e, "text", "").startswith("CAN-M3IO") else "") for e in card.default_slot.children]
    assert [o for o in order if o] == ["kind", "drift", "values"], order
    assert "Changed since approved: Delay 200 ms → 350 ms" in row.content
    await user.open("/plant")
    elements = _tile_elements(user, "data-plant-tile", "io")
    assert len(elements) <= 11, [type(e).__name__ for e in elements]
