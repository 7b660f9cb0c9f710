"""HD-Lock page with NiceGUI's simulated user: units of the proximity settings, the chart's current axis, one
``data-param`` per entry, and the counters of the lock's own bus in the header (Modbus RTU or CAN)."""

from __future__ import annotations

from collections import Counter

import pytest
from nicegui import ui
from plants import can_bus, hdlock_can, modbus_line, plant
from webutil import eventually, user_on

from devices.hdlock.params import PARAMS

pytestmark = pytest.mark.timeout(40)

PROXIMITY_SETTINGS = ("SettingsProximityThresholdUnlock", "SettingsProximityThresholdLock",
                      "SettingsProximityOffsetLeft", "SettingsProximityOffsetRight")


def header_counters(user) -> str:
    """The counter line of the first card (the line's or bus's counters, as the page shows them)."""
    (line,) = [e for e in user.client.elements.values() if "data-counters" in e.props]
    return line.text


def test_the_proximity_settings_are_in_increments_as_the_magnet_position_they_are_compared_with():
    for name in PROXIMITY_SETTINGS:  # holding 3004, 3006-3008 (sections 3.2.7, 3.2.8); input 7 and holding 1005: [Inc]
        assert PARAMS.by_name[name].unit == PARAMS.by_name["Calculated proxi (normalized)"].unit == "Inc"
    assert PARAMS.by_name["SettingsProximityThresholdLock"].display(65476) == "-60 Inc"  # factory -60, signed
    assert PARAMS.by_name["SettingsRemoveMagnet"].unit == ""  # 0/1 switch (section 3.2.6)


async def test_modbus_lock_page_units_chart_axes_unique_entries_and_modbus_counters():
    async with user_on(plant(modbus_line(locks=(("door-1", 1),)))) as (user, runtime):
        state = runtime.store.devices["door-1"]
        await eventually(lambda: state.status == "online" and state.value("SettingsProximityThresholdLock") is not None,
                         timeout=10)
        await user.open("/device/door-1")
        await user.should_see("HD-Lock door-1")
        # the Current column of the Parameters card names the unit: -60 Inc, not a bare -60
        await user.should_see("-60 Inc")
        # every entry and Write button has a key of its own: holding 4 and holding 1002 share the name LockRequestSource
        for prop in ("data-param", "data-write", "data-param-name"):
            keys = Counter(e.props[prop] for e in user.client.elements.values() if prop in e.props)
            assert keys and max(keys.values()) == 1, f"{prop}: {[k for k, n in keys.items() if n > 1]}"
            assert {"LockRequestSource (HR4)", "LockRequestSource", "LockRequestDelay"} <= set(keys), prop
        # the chart: both axes from 0, the motor current never below 0 mA and in whole mA
        (chart,) = [e for e in user.client.elements.values() if isinstance(e, ui.plotly)]
        layout = chart.figure["layout"]
        assert layout["yaxis"]["rangemode"] == "tozero"
        assert layout["yaxis2"]["rangemode"] == "nonnegative" and layout["yaxis2"]["tickformat"] == "d"
        assert layout["yaxis2"]["title"]["text"] == "mA" and layout["yaxis"]["title"]["text"] == "Inc"
        # the legend at the foot of the figure, clear of the mode bar that plotly shows top right on hover
        assert layout["legend"]["yref"] == "container" and layout["legend"]["y"] == 0 and layout["margin"]["t"] >= 30
        # Modbus RTU's own counters
        assert "CRC" in header_counters(user) and "exceptions" in header_counters(user)


async def test_can_lock_header_shows_the_can_counters_not_modbus_ones():
    async with user_on(plant(can_bus(hdlock_can("gate-1", 11)))) as (user, runtime):
        state = runtime.store.devices["gate-1"]
        await eventually(lambda: state.status == "online", timeout=10)
        await user.open("/device/gate-1")
        await user.should_see("HD-Lock gate-1")
        await eventually(lambda: "frames heard" in header_counters(user), timeout=3)
        line = header_counters(user)
        assert "malformed" in line and "CRC" not in line and "exceptions" not in line, line
        (chart,) = [e for e in user.client.elements.values() if isinstance(e, ui.plotly)]
        assert chart.figure["layout"]["yaxis2"]["rangemode"] == "nonnegative"
