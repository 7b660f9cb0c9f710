"""Audit page and audit trail (issue 15 items 5 and 14), with NiceGUI's simulated user.

The device filter, refusals in the log, the whole result text, and motion commands of the
Electrak page recorded with their target, speed and current limit.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import pytest
from nicegui import ui
from nicegui.testing import User
from plants import ELECTRAK_ACTUATORS, electrak_bus, modbus_line, plant
from webutil import PageEnv, eventually, pages_on

from app.plant import Plant

pytestmark = pytest.mark.timeout(60)

def audit_plant() -> Plant:
    """An HD-Lock on an RTU line and an Electrak network of one actuator."""
    return plant(modbus_line(baudrate=19200, parity="E", timeout=0.5, poll_period=0.5, retries=None),
                 electrak_bus(actuators=ELECTRAK_ACTUATORS[:1], simulate=True), name="ap")


LONG = ("refused: SettingsRemoveMagnet = 1 needs a confirmation: Security risk: with SettingsRemoveMagnet = 1 the bolt "
        "retracts as soon as the magnetic field of the strike plate weakens, even while locking is requested (END)")


Env = PageEnv


@pytest.fixture
async def env(tmp_path: Path) -> AsyncIterator[Env]:
    async with pages_on(audit_plant(), tmp_path) as env:
        yield env


def _one(user: User, kind, test=lambda e: True):
    found = [e for e in user.client.elements.values() if isinstance(e, kind) and test(e)]
    assert len(found) == 1, f"{len(found)} {kind.__name__}"
    return found[0]


async def test_device_filter_lists_every_device_and_no_blank_entry(env: Env):
    # a plant-wide row (no device) and a row of a device that left the plant
    await env.runtime.audit.arecord(user="admin", role="engineer", device="", action="add user", result="ok")
    await env.runtime.audit.arecord(user="anna", role="engineer", device="old-door", action="write", result="ok")
    await env.user.open("/audit")
    select = _one(env.user, ui.select, lambda e: e.props.get("label") == "Device")
    await eventually(lambda: "old-door" in select.options, what="devices of the log in the filter")
    assert select.options == ["door-1", "lift", "old-door"], select.options
    assert "" not in select.options and None not in select.options
    assert select.value is None  # "any device" is the cleared field

    table = _one(env.user, ui.table)
    await eventually(lambda: len(table.rows) == 2, what="both rows shown")
    select.value = "old-door"
    await eventually(lambda: [r["device"] for r in table.rows] == ["old-door"], what="filtered by device")
    select.value = None
    await eventually(lambda: len(table.rows) == 2, what="every row again")


async def test_refusals_are_in_the_log_with_the_whole_reason(env: Env):
    await env.runtime.worker.gate.refused(device="door-1", user="local", role="engineer", describe="write SettingsRemoveMagnet",
                                          reason=LONG.removeprefix("refused: "), parameter="SettingsRemoveMagnet", new=1)
    await env.user.open("/audit")
    table = _one(env.user, ui.table)
    await eventually(lambda: len(table.rows) == 1, what="the refusal listed")
    assert table.rows[0]["result"] == LONG[:500]  # the whole text, not cut
    assert table.rows[0]["result"].endswith("(END)")
    result = next(c for c in table.columns if c["name"] == "result")
    assert "white-space: normal" in result.get("style", ""), result  # wrapped, never cut off with an ellipsis
    kind = _one(env.user, ui.select, lambda e: e.props.get("label") == "Result")
    kind.value = "refused"
    await eventually(lambda: len(table.rows) == 1, what="the refused filter")


async def test_motion_commands_record_target_speed_and_limit(env: Env):
    await env.user.open("/device/lift")
    adapter = env.runtime.worker.adapters["lift"]
    env.user.find(marker=None, content="Take control").click()
    await eventually(lambda: adapter.controller is not None, timeout=10, what="control taken")

    def number(prefix: str) -> ui.number:
        return _one(env.user, ui.number, lambda e: str(e.props.get("label", "")).startswith(prefix))

    number("Target position").value = 120.5
    number("Speed").value = 20
    number("Current limit").value = 4.5
    go_button = _one(env.user, ui.button, lambda e: e.props.get("data-testid") == "go")
    await eventually(lambda: go_button.enabled, what="Go enabled for the holder of control")
    env.user.find(marker=None, content="Go", kind=ui.button).click()
    await env.user.should_see("The area is clear: Go")  # Go asks that the area is clear
    env.user.find(marker=None, content="The area is clear: Go", kind=ui.button).click()

    def actions() -> list[str]:
        return [e.action for e in env.runtime.audit.query(device="lift")]

    # the go's row, not the drive's enable: this page sends no beats (no browser), so the dead-man rule ends the
    # motion within its bound, and a loaded machine could look at the enable only after that (2026-11-29)
    await eventually(lambda: any(a.startswith("go:") for a in actions()), timeout=15, what="the go row")
    env.user.find("Stop").click()
    found = actions()
    target = next(a for a in found if a.startswith("set target"))
    assert target == "set target: position 120.5 mm, speed 20 mm/s, current limit 4.5 A", found
    go = next(a for a in found if a.startswith("go:"))
    assert go == "go: target 120.5 mm, speed 20 mm/s, current limit 4.5 A", found
