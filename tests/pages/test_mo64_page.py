"""MO 64 page with NiceGUI's simulated user, against the MO 64 twin on a LogiTed TCP port."""

from __future__ import annotations

from collections.abc import AsyncIterator

import pytest
from conftest import alive
from nicegui import ui
from nicegui.testing import User
from nicegui.testing.user_interaction import UserInteraction
from plants import mo64_tcp, plant
from webutil import by_testid, eventually, user_on

from app.runtime import Runtime
from devices.mo64 import codec

pytestmark = pytest.mark.timeout(40)


@pytest.fixture
async def env() -> AsyncIterator[tuple[User, Runtime]]:
    async with user_on(plant(mo64_tcp())) as env:
        yield env


def twin(runtime):
    return runtime.twins["gate"]


async def test_mo64_page_shows_the_gate_and_opens_after_the_confirmation(env):
    user, runtime = env
    adapter = runtime.worker.adapters["gate"]
    await eventually(lambda: "Gate state" in adapter.state.points and "Serial number" in adapter.state.points, timeout=10)
    await user.open("/device/gate")
    await user.should_see("gate state: closed")
    await user.should_see("RAM only")
    await user.should_see("Assumptions beyond the manual")
    await user.should_see("loop A occupied")
    await user.should_see("Serial number: 6400001")  # the twin's serial number, as the identity card shows it
    await user.should_see("Baum ab = boom off")  # the status bits are explained
    UserInteraction(user, {by_testid(user, "pulse-open")}, None).click()
    await user.should_see("nobody stands under it (the area is clear)")  # the declared risk, asked by the gate
    assert twin(runtime).position_pct == 0  # nothing sent before the answer
    user.find("Send").click()
    await eventually(lambda: "open pulse: ack" in by_testid(user, "reply").text, timeout=3, what=str(user.notify.messages))
    await eventually(lambda: "gate state: open" == by_testid(user, "gate-state").text, timeout=6)
    await eventually(lambda: by_testid(user, "position").text == "position: 100 %", timeout=3)
    # the second motion of the session asks again (issue 42 item 6: the close went out unasked)
    UserInteraction(user, {by_testid(user, "activate-close")}, None).click()
    await user.should_see("nobody stands under it (the area is clear)")
    assert adapter.holders() == set()  # nothing sent before the answer
    user.find("Send").click()
    await eventually(lambda: adapter.holders() == {user.client.id}, timeout=3, what=str(user.notify.messages))
    await eventually(lambda: "close (dead-man)" in by_testid(user, "levels").text, timeout=2)
    UserInteraction(user, {by_testid(user, "clear-levels")}, None).click()
    await user.should_see("An open level released lets the boom close")  # asks the declared risk first, once
    assert adapter.holders() == {user.client.id}
    user.find("Send").click()
    await eventually(lambda: adapter.holders() == set(), timeout=3)
    assert not twin(runtime).levels[2]  # the close level is off in the barrier


async def test_a_viewer_cannot_clear_levels_or_release_the_connection(env, monkeypatch):
    user, runtime = env
    # what is under test is the viewer's refusal, not the dead-man (tests/safety): the engineer's hold must not lapse
    # because this process starves on a loaded machine (0.4 s without a beat ends it, as it should)
    monkeypatch.setattr("app.worker.deadman.DEADMAN_TIMEOUT_S", 10.0)
    monkeypatch.setattr("app.worker.deadman.SILENCE_LIMIT_S", 10.0)
    adapter = runtime.worker.adapters["gate"]
    adapter.core.lease_s = 10.0  # the barrier's own dead-man lease (devices/mo64/control.py), likewise
    await eventually(lambda: "Gate state" in adapter.state.points, timeout=10)
    async with alive(runtime.worker, "engineer-1", period_s=0.05):  # the engineer's browser stays alive for this test
        await runtime.worker.gate.invoke("gate", "close activate", user="anna", role="engineer", session="engineer-1",
                                         confirmed=True)
        await user.open("/device/gate")
        monkeypatch.setattr("pages.session.current_user", lambda: ("tablet", "viewer"))
        # the page's write guard holds the buttons disabled while the barrier's answers are late (a loaded machine)
        await eventually(lambda: by_testid(user, "clear-levels").enabled, timeout=15, what="clear levels enabled")
        UserInteraction(user, {by_testid(user, "clear-levels")}, None).click()  # refused by the gate before any question
        await eventually(lambda: any("refused for tablet: clear levels: the viewer role may not" in e.text for e in adapter.state.events),
                         timeout=10)
        assert adapter.holders() == {"engineer-1"} and twin(runtime).levels[2]  # still active in the barrier
        await eventually(lambda: by_testid(user, "release").enabled, timeout=15, what="release enabled")
        UserInteraction(user, {by_testid(user, "release")}, None).click()
        await eventually(lambda: any("refused for tablet: release the connection: the viewer role may not" in e.text for e in adapter.state.events),
                         timeout=10)
        assert not runtime.worker.lines["gate-bus"].released


async def test_every_reading_beyond_the_manual_is_shown_as_an_assumption(env):
    from devices.mo64 import codec

    user, runtime = env
    await user.open("/device/gate")
    import html
    import re

    # one element holds them all (static text), one line (div) each
    (block,) = [e for e in user.client.elements.values() if isinstance(e, ui.html) and "Assumption: " in e.content]
    shown = [html.unescape(line) for line in re.findall(r'<div class="text-caption">(.*?)</div>', block.content)]
    for text in codec.ASSUMPTIONS:  # among them the short commands' one byte and the error memory's level byte
        assert f"Assumption: {text}" in shown
    assert f"Assumption: {codec.ASSUMED_SHORT_COMMAND}" in shown
    assert f"Assumption: {codec.ASSUMED_ERROR_MEMORY_LEVEL}" in shown


async def test_mo64_dead_man_deactivates_the_close_level_of_a_silent_session(env):
    user, runtime = env
    adapter = runtime.worker.adapters["gate"]
    await eventually(lambda: "Gate state" in adapter.state.points, timeout=10)
    await runtime.worker.gate.run(lambda: runtime.worker.adapters["gate"].command("browser-x", 2, 1, confirmed=True),
                                  device="gate", user="local", role="engineer")
    assert adapter.holders() == {"browser-x"}
    # the session never sends a heartbeat: the worker trips it 0.3 s after it holds something
    await eventually(lambda: adapter.holders() == set(), timeout=1.0)
    assert any("dead-man" in e.text for e in adapter.state.events)


async def test_the_shared_sim_card_acts_on_the_twin_through_the_gate(env, monkeypatch):
    """The twin's declared controls (Mo64Twin.controls) on the shared card: each action through the gate,
    audited; a viewer gets the note instead of the controls."""
    user, runtime = env
    await user.open("/device/gate")
    await user.should_see("Simulated barrier (demo)")
    by_testid(user, "sim-flags").value = "0x4"
    UserInteraction(user, {by_testid(user, "sim-raise-fault")}, None).click()
    await eventually(lambda: twin(runtime).error_flags == 0x4, timeout=3, what=str(user.notify.messages))
    rows = await runtime.audit.aquery(device="gate", text="simulation: raise fault flags=0x4")
    assert rows, "the action is audited"
    UserInteraction(user, {by_testid(user, "sim-light-barrier")}, None).click()  # the switch goes on
    await eventually(lambda: twin(runtime).light_barrier, timeout=3)
    await eventually(lambda: (runtime.store.devices["gate"].point("LS") or {}).get("value") is True, timeout=5)
    by_testid(user, "sim-flags").value = "0x1FFFFFFFF"  # out of range: refused before the gate, nothing changes
    UserInteraction(user, {by_testid(user, "sim-raise-fault")}, None).click()
    await eventually(lambda: any("outside" in str(m) for m in user.notify.messages), timeout=3)
    assert twin(runtime).error_flags == 0x4
    monkeypatch.setattr("pages.command_client.viewer_reason", lambda *_: "the viewer role may not write")
    await user.open("/device/gate")
    await user.should_see("Simulation controls change the simulated plant: engineers only.")


async def test_error_memory_rows_say_what_each_level_means_with_the_raw_flags_beside(env):
    user, runtime = env
    adapter = runtime.worker.adapters["gate"]
    await eventually(lambda: "Gate state" in adapter.state.points, timeout=10)
    twin(runtime).raise_fault(0x04)
    twin(runtime).clear_fault()
    await user.open("/device/gate")
    UserInteraction(user, {user.find(kind=ui.button, content="Read again").elements.pop()}, None).click()
    table = by_testid(user, "error-memory")

    def rows() -> list[tuple]:
        return [(r["level"], r["meaning"], r["raw"]) for r in table.rows]

    # chapter 5.1.23: level 0 the newest change (the flags cleared), level 1 the one before (flag 2 set)
    await eventually(lambda: len(rows()) == 10 and rows()[:2] == [("0 (newest)", "no error (flag 2 cleared)", "0x00000000"),
                                                                 ("1", "error flag 2 set", "0x00000004")],
                     timeout=10, what="the error memory in words, all ten levels read")
    assert rows()[2] == ("2", "empty: no change stored", "0x00000000")  # a level no change has reached yet
    assert rows()[-1][0] == "9 (oldest)"
    assert all(r["time"].endswith(" h") for r in table.rows)  # the operating hours at the change
    await user.should_see("level 0 the newest, level 9 the oldest")


def test_error_flags_in_words():
    assert codec.error_flags_text(0) == "no error"
    assert codec.error_flags_text(0x88, older=0x08) == "error flags 3, 7 set (7 new)"
    assert codec.error_flags_text(0x08, older=0x18) == "error flag 3 set (4 cleared)"
    assert codec.error_level_text(0) == "0 (newest)" and codec.error_level_text(9) == "9 (oldest)"
    assert codec.error_level_meaning(0, 0) == "empty: no change stored"
    assert codec.error_level_meaning(0, 12, older=0x10) == "no error (flag 4 cleared)"


async def test_the_mo64_page_is_built_of_few_elements(env):
    """Lamps of one element (and their tooltips), each value with its quality and age in one element: the page
    was 453 elements (the header's ~100 among them)."""
    user, runtime = env
    state = runtime.worker.adapters["gate"].state
    await eventually(lambda: "Serial number" in state.points and "Gate state" in state.points, timeout=10)
    await user.open("/device/gate")
    await user.should_see("Serial number: 6400001")
    elements = list(user.client.elements.values())
    assert len(elements) <= 340, len(elements)
    lamps = [e for e in elements if "data-lamp" in e.props]
    from pages.mo64 import HIDDEN_BITS

    assert len(lamps) == len([b for names in codec.STATUS_GROUPS.values() for b in names if b not in HIDDEN_BITS])
    for lamp in lamps:
        assert isinstance(lamp, ui.label) and [type(e) for e in lamp.descendants()] == [ui.tooltip]
    (serial,) = [e for e in elements if isinstance(e, ui.html) and "Serial number: 6400001" in e.content]
    await eventually(lambda: serial.props.get("data-quality") == "good", timeout=5)
    assert not list(serial.descendants())
