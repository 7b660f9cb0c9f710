"""SCU page with NiceGUI's simulated user, against the SCU twin on a socket:// line."""

from __future__ import annotations

import time

import asyncio
from collections.abc import AsyncIterator

import pytest
from nicegui import ui
from nicegui.testing import User
from nicegui.testing.user_interaction import UserInteraction
from plants import plant, scu_line
from webutil import by_testid, eventually, push_the_same_values, refresh_on_the_round, user_on

from app.runtime import Runtime
from devices.scu import codec
from devices.scu import params as p

pytestmark = pytest.mark.timeout(40)


@pytest.fixture
async def env() -> AsyncIterator[tuple[User, Runtime]]:
    async with user_on(plant(scu_line())) as env:
        yield env


async def take_control(user, adapter) -> None:
    """Open the lift's page once its remote session is open, and take control (Go is enabled then)."""
    await eventually(lambda: adapter.session == "open", timeout=10)
    await user.open("/device/lift")
    user.find("Take control").click()
    await eventually(lambda: by_testid(user, "go").enabled, timeout=3)


async def test_scu_page_shows_session_positions_and_drives_with_re_rs(env):
    user, runtime = env
    adapter = runtime.worker.adapters["lift"]
    await eventually(lambda: adapter.session == "open" and "A1 position" in adapter.state.points, timeout=10)
    await user.open("/device/lift")
    await user.should_see("remote session: open")
    await user.should_see("DTR and RTS are switched on")
    await user.should_see("Release the SCU (RA)")
    await user.should_see("STOP")
    await eventually(lambda: "counts" in by_testid(user, "pos-A1").text, timeout=3)
    user.find("Take control").click()
    await eventually(lambda: adapter.controller is not None and adapter.controller.session == user.client.id, timeout=3)
    await eventually(lambda: by_testid(user, "set-pos-A1").enabled, timeout=2)  # enabled for the holder only
    by_testid(user, "remote-pos-A1").set_value(50)
    UserInteraction(user, {by_testid(user, "set-pos-A1")}, None).click()
    await eventually(lambda: (adapter.state.point("A1 remote position") or {}).get("value") == 500, timeout=3, what=str(user.notify.messages))
    user.find("Go (RE)").click()
    await user.should_see("Check that the area is clear")  # Go starts motion only after the area-clear question
    await user.should_see("F1 drives A1")
    user.find("The area is clear: Go").click()
    await eventually(lambda: adapter.holders() == {user.client.id}, timeout=3)
    user.find("Stop (RS)").click()
    await eventually(lambda: adapter.holders() == set(), timeout=3)
    # the data directory browser reads a group ID and shows value and raw bytes
    user.find("Read (RG)").click()
    await eventually(lambda: "0x0010" in by_testid(user, "data-value").text, timeout=3)
    assert "raw:" in by_testid(user, "data-raw").text


async def test_scu_dead_man_sends_rs_when_the_session_goes_away(env):
    user, runtime = env
    adapter = runtime.worker.adapters["lift"]
    await eventually(lambda: adapter.session == "open", timeout=10)
    twin = runtime.twins["lift"]
    await runtime.worker.gate.invoke("lift", "take control", {"user": "anna"}, user="anna", role="engineer", session="browser-x")
    await runtime.worker.gate.invoke("lift", "go (RE)", {"function": 0, "motion": 2, "ramp": 1}, user="anna", role="engineer",
                                     session="browser-x", confirmed=True)
    assert adapter.holders() == {"browser-x"} and twin.actuators[0].moving
    # the session never sends a heartbeat: the worker trips it DEADMAN_TIMEOUT_S after it holds something
    await eventually(lambda: adapter.holders() == set(), timeout=1.0)
    assert not twin.actuators[0].moving and ("RS", 0) in twin.function_log
    await eventually(lambda: adapter.controller is None, timeout=2.0)
    assert any("dead-man" in e.text for e in adapter.state.events)


async def test_go_asks_area_clear_and_cancel_sends_no_re(env):
    user, runtime = env
    adapter = runtime.worker.adapters["lift"]
    twin = runtime.twins["lift"]
    await take_control(user, adapter)
    user.find("Go (RE)").click()
    await user.should_see("The area is clear: Go")
    user.find("Cancel").click()
    await asyncio.sleep(0.3)  # time for a cancelled Go to reach the unit: it may not
    assert not any(cmd == "RE" for cmd, _ in twin.function_log) and adapter.holders() == set()


async def test_a_target_of_another_actuator_is_warned_about(env):
    """Issue 32.5: A2's remote position set, F1 selected (drives A1 only): the page says A2 will not move."""
    user, runtime = env
    adapter = runtime.worker.adapters["lift"]
    await eventually(lambda: adapter.session == "open", timeout=10)
    await user.open("/device/lift")
    await user.should_see("F1 drives A1")
    user.find("Take control").click()
    await eventually(lambda: by_testid(user, "set-pos-A2").enabled, timeout=3)
    by_testid(user, "remote-pos-A2").set_value(150)
    UserInteraction(user, {by_testid(user, "set-pos-A2")}, None).click()
    await eventually(lambda: "A2 will not move" in by_testid(user, "target-warning").text, timeout=3,
                     what=str(user.notify.messages))
    user.find("Go (RE)").click()
    await user.should_see("The area is clear: Go")
    await user.should_see("Check that the area is clear")
    assert any("A2 will not move" in (getattr(e, "text", "") or "") and "area is clear" in e.text
               for e in user.client.elements.values())  # the confirmation repeats it
    user.find("Cancel").click()
    by_testid(user, "function").set_value(1)  # F2 drives A2: no warning
    await eventually(lambda: by_testid(user, "target-warning").text == "", timeout=3)


async def test_drive_controls_are_off_with_the_reason_while_the_session_is_lost(env):
    """Issue 32.1: a lost session disables Go, jog and the writes, saying why; stops stay on."""
    user, runtime = env
    adapter = runtime.worker.adapters["lift"]
    twin = runtime.twins["lift"]
    await take_control(user, adapter)
    twin.drop_line(True)
    await eventually(lambda: adapter.session != "open", timeout=5)
    await eventually(lambda: not by_testid(user, "go").enabled, timeout=3)
    reason = by_testid(user, "go").props.get("data-disabled-reason", "")
    assert "remote session is lost" in reason, reason
    assert not by_testid(user, "jog-out").enabled
    assert by_testid(user, "stop").enabled and by_testid(user, "big-stop").enabled
    twin.drop_line(False)
    await eventually(lambda: adapter.session == "open", timeout=10)
    await eventually(lambda: by_testid(user, "go").enabled, timeout=5)


async def test_the_shared_sim_card_acts_on_the_scu_twin_through_the_gate(env):
    """The twin's declared controls (ScuTwin.controls) on the shared card: an actuator error is tripped through
    the gate and audited, and the page shows the error bit the unit then reports."""
    user, runtime = env
    twin = runtime.twins["lift"]
    await user.open("/device/lift")
    await user.should_see("Simulated SCU (demo)")
    by_testid(user, "sim-actuator").value = "2"
    UserInteraction(user, {by_testid(user, "sim-actuator-error")}, None).click()
    await eventually(lambda: twin.actuators[1].errors == 1, timeout=3, what=str(user.notify.messages))
    assert await runtime.audit.aquery(device="lift", text="simulation: actuator error actuator=2")
    await eventually(lambda: (runtime.store.devices["lift"].point("Error code") or {}).get("value"), timeout=5)
    UserInteraction(user, {by_testid(user, "sim-on-battery")}, None).click()  # the switch goes on
    await eventually(lambda: not twin.io.mains, timeout=3)


def _props_texts(user, prop: str, value: str) -> str:
    """The texts of the labels inside the element whose ``prop`` is ``value`` (one line of a card), an element of
    its own or drawn in the text of one that holds several (lamps, I/O lines)."""
    boxes = [e for e in user.client.elements.values() if e.props.get(prop) == value]
    if boxes:
        (box,) = boxes
        return " | ".join(e.text for e in box.descendants() if isinstance(e, ui.label))
    found = [texts for e in user.client.elements.values() if isinstance(e, ui.html)
             for texts in _drawn_parts(e.content, prop, value)]
    assert len(found) == 1, f"{len(found)} parts with {prop}={value!r}"
    return " | ".join(found[0])


def _drawn_parts(content: str, prop: str, value: str) -> list[list[str]]:
    """The texts of the child tags of each tag whose attribute ``prop`` is ``value`` in ``content``."""
    from html.parser import HTMLParser

    found: list[list[str]] = []

    class Parts(HTMLParser):
        depth, inside = 0, None

        def handle_starttag(self, tag, attrs):
            self.depth += 1
            if self.inside is None and dict(attrs).get(prop) == value:
                self.inside = self.depth
                found.append([])
            elif self.inside is not None and self.depth == self.inside + 1:
                found[-1].append("")

        def handle_endtag(self, tag):
            if self.inside == self.depth:
                self.inside = None
            self.depth -= 1

        def handle_data(self, data):
            if self.inside is not None and self.depth > self.inside and found[-1]:
                found[-1][-1] += data

    Parts().feed(content)
    return [[t for t in texts if t] for texts in found]


async def test_errors_and_io_are_named_as_the_document_names_them_with_the_raw_code_beside(env):
    user, runtime = env
    adapter, twin = runtime.worker.adapters["lift"], runtime.twins["lift"]
    await eventually(lambda: adapter.session == "open" and all(
        k in adapter.state.points for k in ("Error code", "Error history 4", "Binary Output Status", "LED HS", "Benutzer")),
        timeout=10)
    await user.open("/device/lift")
    # Error_Code 0 is "no error", the raw code stays beside it for the vendor (section 4.5)
    await eventually(lambda: _props_texts(user, "data-error", "Error code") == "Error code (last): no error | 0x00000000",
                     timeout=3, what="Error code shown as no error")
    assert _props_texts(user, "data-error", "Error history 4") == "Error history 4 (oldest): no error | 0x00000000"
    # bit outputs by name, not 0x0; the document's short names explained (LED HS = hand switch, Benutzer = user)
    assert _props_texts(user, "data-io", "Binary Output Status") == "Binary outputs: output 1 off, output 2 off | 0x00"
    assert _props_texts(user, "data-io", "LED HS").startswith("Hand switch LEDs (LED HS): LED1 ")
    assert _props_texts(user, "data-io", "Benutzer") == "Active user (Benutzer): user 1 | raw 1"
    await user.should_not_see("0x0: none")
    # status flags in words, each lamp still keyed by its point
    assert _props_texts(user, "data-lamp", "A1 limit_in_out") == "Limit in/out signal (limit_in_out)"
    # an error: its cause from table 10 on the line, the code beside it; the old code moves into the history
    twin.raise_error(codec.ERROR_BITS[14].mask)
    await eventually(lambda: _props_texts(user, "data-error", "Error code").startswith(
        "Error code (last): total current exceeded | 0x00002000"), timeout=5, what="the error's cause")
    await user.should_see("bit 14: total current exceeded — condition: while moving")


def test_bit_fields_and_error_codes_in_words():
    assert p.flags_text(0x0110, 0b10) == "output 1 off, output 2 on"
    assert p.flags_text(0x0130, 0) == "all off" and p.flags_text(0x0130, 0b101) == "LED1, LED3 on"
    assert p.flags_text(0x0162, 0b11) == "F1, F2 locked"
    assert p.flags_text(0x0120, 0x80) == "LED1 off, LED2 off; undocumented bits set: 7"
    assert p.user_text(3) == "user 3" and p.item(0x0166).title == "Active user (Benutzer)"
    assert codec.error_text(0) == "no error" and codec.error_hex(0) == "0x00000000"
    assert codec.error_text(1 << 21 | 1 << 8) == "bit 22: remote communication timeout; bit 9: not in table 10"


# -- what an open page costs per push (issue 34) ------------------------------------------------------------------



async def test_a_poll_with_the_same_values_draws_nothing_and_the_round_draws_ages(env, monkeypatch):
    from pages.scu import STATUS_BITS

    user, runtime = env
    state = runtime.store.devices["lift"]
    lamp = f"A1 {next(iter(STATUS_BITS))}"
    drawn = ("A1 position", lamp, "Binary Output Status", "Error code")
    await eventually(lambda: all(n in state.points for n in drawn), timeout=10)
    view, read = await push_the_same_values(user, runtime, "lift", monkeypatch)  # read again, the same values
    now = time.time()
    assert not [n for n in read if n in drawn], read  # nothing drawn again (no flags worded again)
    refresh_on_the_round(runtime.store, view)  # the once-a-second round: ages and stale marks drawn
    assert set(drawn) <= set(read)
    read.clear()  # a new value is drawn on the push that brings it
    state.publish_telegram(now, {"Binary Output Status": state.points["Binary Output Status"]._replace(value=2, raw=2)})
    view.refresh()
    assert _props_texts(user, "data-io", "Binary Output Status") == "Binary outputs: output 1 off, output 2 on | 0x02"


async def test_the_page_is_built_from_a_bounded_number_of_elements(env):
    """Server memory grows with every element of every open page (some 5 KB each): lamps and lines are drawn as
    few elements as they can be, with the same words and data attributes."""
    user, runtime = env
    adapter = runtime.worker.adapters["lift"]
    await eventually(lambda: adapter.session == "open" and "Benutzer" in adapter.state.points, timeout=10)
    await user.open("/device/lift")
    await user.should_see("remote session: open")
    assert len(user.client.elements) <= 280, len(user.client.elements)
