"""Offline project: intended parameters in the plant file (a table, or a parameter file in the backup
format), checked without the device with file:line, shown against the device and reconciled per row."""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys

import pytest
from conftest import running_plant
from plants import device, modbus_line, plant_text

from app import backup, project
from app.plant import load_plant
from devices.hdlock.params import PARAMS
from devices.params import backup_entry

def _files(tmp_path, delay=350, extra: dict | None = None, offset_right=7):
    entries = [backup_entry(p, p.default if p.default is not None else 0) for p in PARAMS]
    for e in entries:
        if e["name"] == "SettingsProximityOffsetRight":
            e.update(raw=offset_right, value=offset_right, text=str(offset_right))
    document = backup.make_document("offline", "door-2", "hdlock", "line1", {}, entries)
    (tmp_path / "door-2.json").write_text(json.dumps(document, indent=2))
    path = tmp_path / "plant.toml"
    door_1 = device("door-1", "hdlock", "line1", address=1,
                    project={"LockRequestDelay": delay, "SettingsProximityOffsetLeft": -5, **(extra or {})})
    door_2 = device("door-2", "hdlock", "line1", address=2, project="door-2.json")
    path.write_text(plant_text(modbus_line(locks=()) + door_1 + door_2, name="offline"))
    return path


def test_check_lists_invalid_and_unknown_entries_with_file_and_line(tmp_path):
    path = _files(tmp_path, delay=70000, extra={"LockReqDelay": 3})
    text = path.read_text().splitlines()
    line = next(i + 1 for i, t in enumerate(text) if t.startswith("project = {"))
    plant = load_plant(path)
    problems = project.check_plant(plant)
    assert any(p.startswith(f"{path}:{line}: device 'door-1': LockRequestDelay: 70000 is outside") for p in problems), problems
    assert any(p.startswith(f"{path}:{line}: device 'door-1': unknown parameter 'LockReqDelay'") for p in problems), problems
    # the parameter file: a damaged entry named with its own file and line
    data = json.loads((tmp_path / "door-2.json").read_text())
    bad = next(e for e in data["parameters"] if e["key"] == "holding:3003")
    bad["value"] = 9
    bad["raw"] = 9
    (tmp_path / "door-2.json").write_text(json.dumps(data, indent=2))
    json_line = next(i + 1 for i, t in enumerate((tmp_path / "door-2.json").read_text().splitlines()) if '"holding:3003"' in t)
    problems = project.check_plant(load_plant(path))
    assert any(p.startswith(f"{tmp_path / 'door-2.json'}:{json_line}: device 'door-2': ") for p in problems), problems
    out = subprocess.run([sys.executable, "-m", "app.cli", "check", "--plant", str(path)], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 1, out
    assert f"{path}:{line}: device 'door-1': unknown parameter 'LockReqDelay'" in out.stdout
    (tmp_path / "ok").mkdir()
    good = _files(tmp_path / "ok")
    out = subprocess.run([sys.executable, "-m", "app.cli", "check", "--plant", str(good)], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "0 invalid or unknown" in out.stdout


@pytest.fixture
async def offline(tmp_path):
    path = _files(tmp_path)
    async with running_plant(load_plant(path), tmp_path / "data", ready=("door-1", "door-2")) as runtime:
        yield runtime, path


async def test_project_against_devices_applied_and_updated_per_row(offline):
    runtime, path = offline
    # door-1: one changed parameter (LockRequestDelay 350, the lock holds 200) and one equal (-5 is not, see below)
    twin1, twin2 = runtime.twins["door-1"], runtime.twins["door-2"]
    twin1.holding[3007] = (-5) & 0xFFFF  # the offset as in the project: only LockRequestDelay differs
    twin1.flash[3007] = twin1.holding[3007]
    plan1 = await backup.plan_restore(runtime, "door-1", project.document(runtime, "door-1"))
    changed1 = [r for r in plan1.rows if r.changed]
    assert [(r.name, r.current_text, r.backup_text) for r in changed1] == [("LockRequestDelay", "200 ms", "350 ms")]
    # door-2 (parameter file): one changed parameter, SettingsProximityOffsetRight 7 against 0
    plan2 = await backup.plan_restore(runtime, "door-2", project.document(runtime, "door-2"))
    changed2 = [r for r in plan2.rows if r.changed]
    assert [(r.name, r.backup_text) for r in changed2] == [("SettingsProximityOffsetRight", "7 Inc")]

    # apply the project's value on door-1, through the gate and restore's verified write
    report = await backup.execute_restore(runtime, plan1, {changed1[0].key}, user="anna", role="engineer")
    assert report.ok and report.written == ["LockRequestDelay"], report.summary()
    assert twin1.holding[3000] == 350 and twin1.flash[3000] == 350
    rows = await runtime.audit.aquery(limit=100)
    assert any(r.device == "door-1" and r.action == "restore" and r.parameter == "LockRequestDelay" for r in rows)

    # update the project from door-2's value: the parameter file is rewritten, the diff is empty after
    entry = await asyncio.to_thread(project.update_entry, runtime.plant, "door-2", "holding:3008", 0)
    assert entry.value == 0 and not entry.error
    assert twin2.holding[3008] == 0  # nothing written to the device
    plan2 = await backup.plan_restore(runtime, "door-2", project.document(runtime, "door-2"))
    assert not [r for r in plan2.rows if r.changed]
    saved = json.loads((path.parent / "door-2.json").read_text())
    assert next(e for e in saved["parameters"] if e["key"] == "holding:3008")["raw"] == 0

    # update an inline entry: the plant file's line is rewritten, comments and the rest stay
    before = path.read_text()
    await asyncio.to_thread(project.update_entry, runtime.plant, "door-1", "holding:3007", 12)
    after = path.read_text()
    assert "SettingsProximityOffsetLeft = 12 }" in after and "LockRequestDelay = 350" in after
    assert len(after.splitlines()) == len(before.splitlines())
    assert load_plant(path).devices["door-1"].project == {"LockRequestDelay": 350, "SettingsProximityOffsetLeft": 12}
    with pytest.raises(project.ProjectError):
        await asyncio.to_thread(project.update_entry, runtime.plant, "door-1", "holding:3000", 70000)
    assert "LockRequestDelay = 350" in path.read_text()


TABLE_PLANT = """name = "tables"  # the site's plant

[[bus]]
name = "line1"
type = "modbus-rtu"
port = "socket://127.0.0.1:5999"

[[device]]
name = "door-1"
type = "hdlock"
bus = "line1"
address = 1  # left door

[device.project]
LockRequestDelay = 300  # the closer is slow
SettingOutput1 = 4

[[device]]
name = "door-2"
type = "hdlock"
bus = "line1"
address = 2
serial = 660021
# the right door, no project yet

[[device]]
name = "door-3"
type = "hdlock"
bus = "line1"
address = 3
project = "door-3.json"
"""


def test_saving_a_project_keeps_the_file_and_its_comments(tmp_path):
    path = tmp_path / "plant.toml"
    path.write_text(TABLE_PLANT)
    document = backup.make_document("tables", "door-3", "hdlock", "line1", {}, [backup_entry(PARAMS.by_key["holding:3000"], 200)])
    (tmp_path / "door-3.json").write_text(json.dumps(document, indent=2))
    plant = load_plant(path)

    # a [device.project] table: one entry changed (its comment kept), one dropped, one added
    project.save(plant, "door-1", {"holding:3000": 450, "holding:3001": None, "holding:3007": -5})
    text = path.read_text()
    assert "LockRequestDelay = 450  # the closer is slow\n" in text and "SettingOutput1" not in text
    assert (tmp_path / "plant.toml.bak").read_text() == TABLE_PLANT
    assert load_plant(path).devices["door-1"].project == {"LockRequestDelay": 450, "SettingsProximityOffsetLeft": -5}
    assert plant.devices["door-1"].project == {"LockRequestDelay": 450, "SettingsProximityOffsetLeft": -5}

    # a device without a project: a project line in its own table, before the comment that follows it
    project.save(plant, "door-2", {"holding:3003": "Always left-hinged"})  # an enum by name is kept as its number
    text = path.read_text()
    assert "serial = 660021\nproject = { SettingsDirection = 1 }\n# the right door, no project yet\n" in text
    assert load_plant(path).devices["door-2"].project == {"SettingsDirection": 1}
    assert '# the site\'s plant' in text and "address = 1  # left door" in text

    # the parameter file: an entry changed and one added, in the backup format
    entries = project.save(plant, "door-3", {"holding:3000": 275, "holding:3008": 3})
    assert {e.name: e.value for e in entries} == {"LockRequestDelay": 275, "SettingsProximityOffsetRight": 3}
    assert not [e for e in entries if e.error]
    saved = backup.load_document((tmp_path / "door-3.json").read_text())
    assert {e["key"]: e["raw"] for e in saved["parameters"]} == {"holding:3000": 275, "holding:3008": 3}
    assert json.loads((tmp_path / "door-3.json.bak").read_text()) == document

    # refused before anything is written: out of range, not a number, not writable, unknown
    before = path.read_text()
    for changes, message in (({"holding:3000": 70000}, "outside 0 .. 65535 ms"),
                             ({"holding:3000": "soon"}, "'soon' is not a number; allowed: 0 .. 65535 ms"),
                             ({"input:51": 1}, "not a writable parameter"),
                             ({"holding:3003": 7}, "is not one of: -1 Always right-hinged")):
        with pytest.raises(project.ProjectError, match=message):
            project.save(plant, "door-1", changes)
    assert path.read_text() == before
