"""The Electrak page's service parameters and control holder with NiceGUI's simulated user (issue 32 items 6 and 7).

The fields start at the actuators' values, Enter writes as the Write button does, the field shows the value read
back after a write, a fraction or a finer step than the parameter's unit is refused on the field with what is
allowed; control is taken in the logged-in account's name, shown to the other browsers and audited under it.
"""

from __future__ import annotations

import re

import pytest
from nicegui import ui
from nicegui.testing.user_interaction import UserInteraction
from plants import channel, electrak_bus, plant
from test_auth import login
from webutil import by_testid, eventually, simulated_user

from app.runtime import Runtime
from app.users import UserStore
from devices.electrak import codec
from devices.electrak.params import PARAMS, password_of

pytestmark = pytest.mark.timeout(60)


def lift_plant():
    return plant(electrak_bus(channel_name=channel("entries")), name="entries")


def interact(user, element) -> UserInteraction:
    return UserInteraction(user, {element}, None)


async def refused(runtime: Runtime, *words: str) -> bool:
    return any(r.device == "lift" and r.result.startswith("refused") and all(w in r.result for w in words)
               for r in await runtime.audit.aquery())


async def cancelled(runtime: Runtime, parameter: str) -> bool:
    """A question answered with Cancel: audited as cancelled (no refusal), under the parameter's name."""
    return any(r.device == "lift" and r.result == "cancelled: not confirmed" and parameter in r.parameter
               for r in await runtime.audit.aquery())


async def test_service_fields_start_at_the_value_enter_writes_and_bad_entries_are_refused_on_the_field(tmp_path):
    runtime = Runtime(lift_plant(), simulate=True, data_dir=tmp_path)
    soft_start, soft_stop = PARAMS.get("service", 0x01), PARAMS.get("service", 0x02)
    async with simulated_user(runtime) as user:
        await eventually(lambda: runtime.store.devices["lift"].status == "online", timeout=10, what="lift online")
        twins = runtime.twins["lift"].actuators
        await user.open("/device/lift")
        start_entry, stop_entry = by_testid(user, "entry-01"), by_testid(user, "entry-02")
        # the page reads the service parameters once by itself: the fields start at the actuators' values
        state = runtime.store.devices["lift"]
        await eventually(lambda: all(state.raw(p) is not None for p in PARAMS), timeout=10, what="service parameters read")
        await eventually(lambda: start_entry.value == soft_start.decode(state.raw(soft_start)), timeout=3,
                         what=f"soft start field at the actuators' value, not {start_entry.value!r}")
        await eventually(lambda: stop_entry.value == soft_stop.decode(state.raw(soft_stop)), timeout=3)

        # 12.5 where whole milliseconds are asked: kept as typed, refused on the field with what is allowed
        start_entry.value = 12.5
        interact(user, start_entry).trigger("keydown.enter")
        await eventually(lambda: start_entry.error, timeout=3, what="12.5 marked on the field")
        assert start_entry.value == 12.5 and "whole numbers only" in start_entry.error and "0 .. 65535 ms" in start_entry.error
        assert not user.notify.messages  # said on the field, not in a toast (nor only in the Events)
        await eventually(lambda: refused(runtime, "12.5"), timeout=5, what="refusal audited")
        # a finer step than the parameter's 0.1 mm
        stop_entry.value = 1.25
        interact(user, by_testid(user, "write-02")).click()
        await eventually(lambda: stop_entry.error, timeout=3, what="1.25 mm marked on the field")
        assert "steps of 0.1 mm" in stop_entry.error and stop_entry.value == 1.25

        # Enter writes (with the read-back), and the field then shows the value read back
        start_entry.value = 321
        interact(user, start_entry).trigger("keydown.enter")
        await eventually(lambda: all(a.service.values.get(0x01) == 321 for a in twins), timeout=5,
                         what="soft start 321 ms written to every actuator")
        await eventually(lambda: state.raw(soft_start) == 321 and not start_entry.error, timeout=3)
        # the field follows the actuators' value afterwards (it holds the read-back, not a typed text of its own)
        await runtime.worker.adapters["lift"].write_param(soft_start, 400)
        await eventually(lambda: start_entry.value == 400, timeout=3, what=f"field follows the device: {start_entry.value}")
        # Enter asks the same question as the Write button where the parameter wants one (a Timeout above 250 ms)
        timeout_entry = by_testid(user, "entry-06")
        timeout_entry.value = 300
        interact(user, timeout_entry).trigger("keydown.enter")
        await user.should_see("keep moving for that long")
        assert all(a.service.values.get(0x06) == 250 for a in twins)  # nothing sent before the answer
        user.find(kind=ui.button, content="Cancel").click()
        await eventually(lambda: cancelled(runtime, "Timeout"), timeout=5, what="unconfirmed write audited as cancelled")
        assert all(a.service.values.get(0x06) == 250 for a in twins)
        # what the engineer typed and did not write stays until written
        start_entry.value = 555
        await runtime.worker.adapters["lift"].write_param(soft_start, 410)
        await eventually(lambda: state.raw(soft_start) == 410, timeout=3)
        assert start_entry.value == 555


async def test_control_is_taken_in_the_logged_in_account_name(tmp_path):
    store = UserStore(tmp_path / "users.toml")
    store.add("anna", "engineer", "correct horse")
    runtime = Runtime(lift_plant(), simulate=True, data_dir=tmp_path, auth_required=True)
    async with simulated_user(runtime) as user:
        await login(user, "anna", "correct horse")
        await eventually(lambda: runtime.store.devices["lift"].status == "online", timeout=10, what="lift online")
        await user.open("/device/lift")
        interact(user, by_testid(user, "take-control")).click()
        adapter = runtime.worker.adapters["lift"]
        await eventually(lambda: adapter.controller is not None, timeout=5, what="control taken")
        await user.should_see("you hold control as anna")
        control = runtime.store.devices["lift"].live("Control").value
        assert control.user == "anna"
        rows = [r for r in await runtime.audit.aquery() if r.device == "lift" and "take control" in r.action]
        assert rows and rows[-1].user == "anna", rows


async def test_no_password_is_shown_the_specifier_column_says_what_the_parameter_is(tmp_path):
    runtime = Runtime(lift_plant(), simulate=True, data_dir=tmp_path)
    async with simulated_user(runtime) as user:
        await eventually(lambda: runtime.store.devices["lift"].status == "online", timeout=10, what="lift online")
        await user.open("/device/lift")
        await user.should_see("Service parameters (0x0A / 0x0B)")
        texts = " ".join((getattr(e, "text", "") or "") + (getattr(e, "content", "") or "")  # labels and drawn text
                         for e in user.client.elements.values())
        for p in PARAMS:  # the passwords of the document's table: keys, not data
            password = password_of(p)
            assert f"{password:08X}" not in texts.upper() and str(password) not in texts, p.name
        (cell,) = [e for e in user.client.elements.values() if e.props.get("data-specifier") == "01"]
        assert re.findall(r">([^<]+)<", cell.content) == ["0x01", "2 bytes, ms, password-protected"]
    # the bus monitor names a password telegram without decoding its value
    text = codec.describe_frame(codec.SERVICE_REQUEST_ID, False, codec.password_request(password_of(PARAMS.get("service", 1)))
                                .encode(), {(False, codec.STATUS_ID)})
    assert text == "Electrak service WRITE_REQUEST 0xFF len 4 (password: not shown)"


async def test_the_chart_axes_do_not_run_below_zero(tmp_path):
    """Position, current and speed are unsigned (status 0x07): an idle network's axes start at 0, not at -1."""
    runtime = Runtime(lift_plant(), simulate=True, data_dir=tmp_path)
    async with simulated_user(runtime) as user:
        await user.open("/device/lift")
        await user.should_see("Service parameters (0x0A / 0x0B)")
        (chart,) = [e for e in user.client.elements.values() if isinstance(e, ui.plotly)]
        layout = chart.figure["layout"]
        assert [layout[a]["rangemode"] for a in ("yaxis", "yaxis2", "yaxis3")] == ["nonnegative"] * 3
