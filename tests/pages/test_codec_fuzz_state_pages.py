"""Issue 14, item 12: a recovered device shows no old error, readable discovery log lines, the
'simulated devices' badge only with a simulated bus, and an unread chart without a year-2000 axis."""

from __future__ import annotations

import logging
from datetime import datetime

import can
import pytest
from conftest import modbus_plant
from plants import can_bus, hdlock_can, modbus_line, plant_text
from nicegui import ui
from nicegui.testing import User

from app import runtime as rt
from app.plant import parse_plant
from app.runtime import Runtime
from app.worker import Worker
from devices.hdlock import codec as hdlock
from devices.live import DeviceState

pytestmark = pytest.mark.timeout(30)


def test_recovered_device_clears_last_error_and_the_log_keeps_it():
    state = DeviceState("door-1", "hdlock", "line1")
    state.mark_seen()
    state.mark_offline("unit 1: no answer within 0.2 s")
    assert state.last_error == "unit 1: no answer within 0.2 s"
    state.mark_seen()
    assert state.status == "online"
    assert state.last_error == "" and state.summary()["last_error"] == ""
    assert any("no answer within 0.2 s" in e.text for e in state.events)


def test_error_while_online_stays_until_the_device_recovers():
    state = DeviceState("door-1", "hdlock", "line1")
    state.mark_seen()
    state.error("write refused", log=False)
    state.mark_seen()  # still online: nothing recovered, the error stays for the engineer
    assert state.last_error == "write refused"


def test_discovery_log_line_is_readable(caplog):
    plant = parse_plant(plant_text(can_bus(hdlock_can("gate", 660100), channel_name="fuzz-state-1", simulate=None),
                                   name=None))
    w = Worker(plant)
    status = hdlock.encode_status(hdlock.StatusFrame(0x0200, 0, 100, 4))
    caplog.set_level(logging.INFO, logger="app.worker")
    for t in (1_700_000_000.0, 1_700_000_001.0, 1_700_000_002.0):
        w._discover_frame("can1", can.Message(arbitration_id=660102, data=status, is_extended_id=True, timestamp=t))
    lines = [r.getMessage() for r in caplog.records if "discovered" in r.getMessage()]
    assert len(lines) == 1, lines
    assert "(True, 660102)" not in lines[0]
    assert "0xA1286" in lines[0] and "29-bit" in lines[0], lines[0]


REAL_LINE = parse_plant(plant_text(modbus_line(port="/dev/ttyUSB7", timeout=None, retries=None, poll_period=None,
                                               simulate=None), name=None))


def _page(runtime: Runtime, state: DeviceState | None = None):
    from pages.frame import frame
    from pages.charts import HistoryChart

    rt.set_current(runtime)
    charts: list[HistoryChart] = []

    @ui.page("/")
    def page():
        with frame("Test"):
            if state is not None:
                charts.append(HistoryChart(state, ["position"]))

    return charts


async def test_no_simulated_badge_without_a_simulated_bus(user: User):
    _page(Runtime(REAL_LINE, simulate=True))
    await user.open("/")
    await user.should_see("plant:")
    await user.should_not_see("simulated devices")


async def test_simulated_badge_with_a_simulated_bus(user: User):
    _page(Runtime(modbus_plant(), simulate=True))
    await user.open("/")
    await user.should_see("simulated devices")


async def test_unread_chart_has_no_axis_in_the_year_2000(user: User):
    state = DeviceState("door-1", "hdlock", "line1")
    charts = _page(Runtime(REAL_LINE, simulate=False), state)
    await user.open("/")
    layout = charts[0].figure["layout"]
    assert [a["text"] for a in layout.get("annotations", [])] == ["no data yet"]
    start, end = (datetime.fromisoformat(x) for x in layout["xaxis"]["range"])
    assert start.year == end.year == datetime.now().year and start < end
    state.add_history({"position": 12.5})
    charts[0].update()
    assert not layout.get("annotations") and "range" not in layout["xaxis"]
    assert charts[0].figure["data"][0]["y"] == [12.5]
