"""Backup page and backup files (issue 15 items 5 and 13), with NiceGUI's simulated user.

A plant of one HD-Lock on Modbus RTU, an M3IO in unaddressed mode (nothing to back up) and a
Bauer MO 64 over TCP (its parameter model names the values).
"""

from __future__ import annotations

import json
import time
from collections.abc import AsyncIterator
from pathlib import Path

import pytest
from nicegui import ui
from nicegui.testing import User
from plants import can_bus, device, modbus_line, mo64_tcp, plant
from webutil import PageEnv, eventually, pages_on

from app import backup
from app.plant import Plant
from devices.hdlock.params import PARAMS
from devices.params import backup_entry

pytestmark = pytest.mark.timeout(60)

def backup_plant() -> Plant:
    """An HD-Lock on an RTU line, an M3IO HM in unaddressed mode and an MO 64 on TCP."""
    # master "always": no PLC here, the tool serves the module's watchdog, so it answers
    heater = device("heater-hm", "m3io", "can3", variant="HM", sw1=0x1A, master="always")
    return plant(modbus_line(baudrate=19200, parity="E", timeout=0.5, poll_period=0.5, retries=None),
                 can_bus(heater, name="can3", bitrate=500000),
                 mo64_tcp("barrier-in", "gate-tcp", travel_s=None, timeout=None, poll_period=None), name="bp")


Env = PageEnv


@pytest.fixture
async def env(tmp_path: Path) -> AsyncIterator[Env]:
    async with pages_on(backup_plant(), tmp_path) as env:
        yield env


def _elements(user: User, kind):
    return [e for e in user.client.elements.values() if isinstance(e, kind)]


def _magnet_document() -> dict:
    """A door-1 backup (factory values) whose SettingsRemoveMagnet is 1: a security risk to restore."""
    entries = []
    for p in PARAMS:
        raw = 1 if p.name == "SettingsRemoveMagnet" else (p.default if p.default is not None else 0)
        entries.append(backup_entry(p, raw))
    return backup.make_document("bp", "door-1", "hdlock", "line1", {"serial": 660020, "FirmwareVersion": 57}, entries,
                                user="anna", role="engineer")


async def test_a_device_with_nothing_to_back_up_is_named_with_the_reason(env: Env):
    await env.user.open("/backup")
    await env.user.should_see("heater-hm (m3io): nothing to back up")
    await env.user.should_see("addressed mode")  # the M3IO's own reason: SW1 switch 8
    boxes = [b.text for b in _elements(env.user, ui.checkbox)]
    assert any(t.startswith("door-1") for t in boxes) and not any(t.startswith("heater-hm") for t in boxes), boxes


async def test_the_uploader_has_no_size_placeholder(env: Env):
    await env.user.open("/backup")
    uploads = _elements(env.user, ui.upload)
    assert len(uploads) == 1
    assert "header" in uploads[0].slots  # Quasar's own header prints "0.0B / 0.00%" before any file
    assert "Restore from a file" in uploads[0].slots["header"].template


async def test_a_backup_is_credited_to_who_started_it(env: Env):
    path = await backup.backup_device(env.runtime, "door-1", user="anna", role="engineer")
    document = json.loads(path.read_text())
    assert document["taken_by"] == {"user": "anna", "role": "engineer"}
    assert backup.taken_by(document) == "anna (engineer)"
    row = next(e for e in env.runtime.audit.query(device="door-1") if e.action == "backup")
    assert (row.user, row.role, row.result) == ("anna", "engineer", "ok")

    # from the page: the session's user, in the file, the audit log and the file list
    await env.user.open("/backup")
    for box in _elements(env.user, ui.checkbox):
        box.value = box.text.startswith("door-1")
    env.user.find("Back up selected").click()
    await env.user.should_see("1 backup file(s) written")
    files = sorted(env.runtime.backups_dir.glob("door-1-*.json"))
    documents = [json.loads(p.read_text()) for p in files]
    assert any(d["taken_by"] == {"user": "local", "role": "engineer"} for d in documents)
    table = next(t for t in _elements(env.user, ui.table) if any(c["name"] == "by" for c in t.columns))
    await eventually(lambda: {r["by"] for r in table.rows} == {"anna (engineer)", "local (engineer)"}, what="the By column")


def test_backup_times_are_shown_in_local_time(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv("TZ", "Europe/Berlin")
    time.tzset()
    try:
        assert backup.local_time("2024-01-15T12:00:00+00:00") == "2024-01-15 13:00:00 CET"
        assert backup.local_time("2024-07-15T12:00:00+00:00") == "2024-07-15 14:00:00 CEST"
        assert backup.local_time("not a time") == "not a time"
    finally:
        monkeypatch.delenv("TZ")
        time.tzset()


async def test_restore_rows_name_enums_units_and_the_risk(env: Env):
    directory = env.runtime.backups_dir
    directory.mkdir(parents=True, exist_ok=True)
    document = _magnet_document()
    (directory / "door-1-magnet.json").write_text(json.dumps(document))
    await env.user.open("/backup")
    files = next(t for t in _elements(env.user, ui.table) if any(c["name"] == "by" for c in t.columns))
    await eventually(lambda: [r["name"] for r in files.rows] == ["door-1-magnet.json"], what="the file listed")
    row = files.rows[0]
    assert row["by"] == "anna (engineer)"
    assert row["time"] == backup.local_time(document["time"])
    emit(files, "restore", "door-1-magnet.json")  # the row's Restore button
    await env.user.should_see("Restore from door-1-magnet.json")
    await env.user.should_see("by anna (engineer)")
    await env.user.should_see("identity: serial 660020, FirmwareVersion 57")  # in words, not as JSON (issue 42 item 13)
    env.user.find("Compare with the device").click()
    table = await _wait_table(env.user)
    rows = {r["name"]: r for r in table.rows}
    magnet = rows["SettingsRemoveMagnet"]
    assert magnet["backup"] == "Retract when magnet removed (1)", magnet  # by name, with its number
    assert magnet["risk"] is True and "risk" in magnet["state"] and "unlocked from outside" in magnet["state"], magnet
    assert rows["LockRequestDelay"]["backup"] == "200 ms"  # the unit with the value
    assert rows["LockRequestDelay"]["risk"] is False
    assert "body-cell-state" in table.slots  # the risk is drawn in red with a warning sign


async def test_rows_of_the_mo64_carry_its_models_names_and_units(env: Env):
    path = await backup.backup_device(env.runtime, "barrier-in")
    document = json.loads(path.read_text())
    for entry in document["parameters"]:
        if entry["key"] == "t_open:0":  # t_offen, by the MO 64's parameter model (devices/mo64/params.py)
            entry["value"] = entry["value"] + 1
            entry["raw"] = entry["raw"] + 100
    plan = await backup.plan_restore(env.runtime, "barrier-in", document)
    rows = {r.key: r for r in plan.rows}
    t_open = rows["t_open:0"]
    assert t_open.changed and t_open.name == "t_offen" and t_open.backup_text == "11 s", t_open.backup_text  # in seconds
    assert t_open.current_text == "10 s", t_open.current_text
    relays = rows["multi_relays:0"]
    assert not relays.changed and relays.name == "multi1" and relays.backup_text == relays.current_text == "fault (1)"


def emit(element: ui.element, event: str, args) -> None:
    """The browser's ``$emit(event, args)`` on ``element`` (a table's slot button)."""
    listeners = [key for key, listener in element._event_listeners.items() if listener.type == event]
    assert listeners, f"nothing listens to {event!r}"
    for key in listeners:
        element._handle_event({"listener_id": key, "args": args})


async def _wait_table(user: User) -> ui.table:
    found: list[ui.table] = []

    def check() -> bool:
        found[:] = [t for t in _elements(user, ui.table) if any(c["name"] == "backup" for c in t.columns) and t.visible and t.rows]
        return bool(found)

    await eventually(check, timeout=10, what="the restore diff")
    return found[0]



async def test_the_restore_confirmation_names_every_unsaved_change_the_save_makes_permanent(env: Env):
    """Issue 32 items 4 and 13: a value written earlier and not saved (SettingOutput1 = 5),
    deselected in the diff, is made permanent by the restore's Save-Settings: the confirmation names
    it beside the restored row, and counts in words ("1 parameter", not "1 parameters")."""
    output = PARAMS.by_name["SettingOutput1"]  # a setting (a measured maximum is never restored: issue 42 item 4)
    await env.runtime.worker.gate.run(lambda: env.runtime.worker.adapters["door-1"].write_param(output, 5),
                                      device="door-1", describe="write", user="local", role="engineer")
    assert output.key in env.runtime.store.devices["door-1"].unsaved
    entries = []
    for p in PARAMS:
        raw = p.default if p.default is not None else 0
        raw = 250 if p.name == "LockRequestDelay" else raw
        entries.append(backup_entry(p, raw))
    document = backup.make_document("bp", "door-1", "hdlock", "line1", {}, entries)
    directory = env.runtime.backups_dir
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "door-1-delay.json").write_text(json.dumps(document))
    await env.user.open("/backup")
    files = next(t for t in _elements(env.user, ui.table) if any(c["name"] == "by" for c in t.columns))
    await eventually(lambda: [r["name"] for r in files.rows] == ["door-1-delay.json"], what="the file listed")
    emit(files, "restore", "door-1-delay.json")
    await env.user.should_see("Restore from door-1-delay.json")
    env.user.find("Compare with the device").click()
    table = await _wait_table(env.user)
    names = {r["name"] for r in table.selected}
    assert {"LockRequestDelay", "SettingOutput1"} <= names, names
    table.selected = [r for r in table.rows if r["name"] == "LockRequestDelay"]  # SettingOutput1 deselected
    env.user.find("Write selected").click()
    await env.user.should_see("Write 1 parameter to door-1?")
    await env.user.should_see("LockRequestDelay 200 ms -> 250 ms")
    await env.user.should_see(f"SettingOutput1 (holding 3001) = {output.display(5)}")  # the unrelated unsaved change, named
    await env.user.should_not_see("Write 1 parameters")
    env.user.find(marker="restore-confirm-ok").click()
    await env.user.should_see("1 written", retries=100)

    def save_row():
        rows = env.runtime.audit.query(device="door-1", text="SettingOutput1")
        assert any(e.action == "restore: save step" for e in rows), rows  # what the save made permanent is searchable

    await eventually(save_row, what="the save step's audit row naming SettingOutput1")
