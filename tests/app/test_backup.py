"""Backup and restore on every device twin, file checks, atomic writes, audit and roles."""

from __future__ import annotations

import json

import pytest
from conftest import running_plant, wait_for
from webutil import private_endpoints

from app import backup
from app.audit import AuditLog, to_csv
from app.plant import DEMO_PLANT, load_plant
from app.worker import PermissionDenied

DEVICES = ("door-1", "gate-1", "lift", "heater-hmr")


@pytest.fixture
async def plant_runtime(tmp_path):
    plant = private_endpoints(load_plant(DEMO_PLANT), tmp_path.name)  # own ports and CAN channels
    async with running_plant(plant, tmp_path / "data", ready=DEVICES) as runtime:
        yield runtime


async def write_raw(adapter, key: str, raw) -> None:
    """Write a raw value straight through the adapter's checked write (as a manual entry would)."""
    if key.startswith("customer:"):
        await adapter.restore_entry(key, raw)
        return
    param = adapter.state.params.by_key[key]
    await adapter.write_param(param, param.decode(int(raw)), confirmed=True)  # the engineer confirmed the risk


async def change_every_writable(runtime, name: str, entries: list[dict]) -> int:
    """Write a different value to every writable parameter, straight through the adapter."""
    adapter = runtime.worker.adapters[name]
    changed = 0
    for entry in entries:
        if not entry.get("setting", entry["writable"]):
            continue  # read-only, or measured by the device (never restored: Param.setting)
        if entry["key"].startswith("customer:"):
            new = "0a 0b 0c 0d 0e 0f"
        elif entry["key"] == "cfg:7":  # the M3IO's P2: the other of its two values (1 asks first: confirmed below)
            new = 1 - entry["raw"]
        elif entry["key"] == "service:4":  # the bit rate: changing it takes the actuators off the bus
            continue
        elif entry["key"] in ("holding:4", "holding:1002"):
            new = 0x81 if entry["raw"] != 0x81 else 0x01
        elif entry["key"] == "holding:3001" or entry["key"] == "holding:3002":
            new = 7
        elif entry["key"] == "holding:3003":
            new = 1
        elif entry["key"] == "holding:3005":
            continue  # stays 0: 1 is a security risk, covered by its own test
        else:
            new = int(entry["raw"]) + 7
        await write_raw(adapter, entry["key"], new)
        changed += 1
    return changed


@pytest.mark.parametrize("name", DEVICES)
async def test_backup_change_restore_round_trip(plant_runtime, name, tmp_path):
    runtime = plant_runtime
    path = await backup.backup_device(runtime, name, tmp_path / "out")
    document = backup.load_document(path.read_bytes())
    assert document["device"] == {"name": name, "type": runtime.store.devices[name].type, "bus": runtime.store.devices[name].bus}
    assert document["plant"] == "demo" and document["tool"]["name"] == "commission" and document["version"] == 1
    assert all({"key", "name", "raw", "value", "writable"} <= set(e) for e in document["parameters"])
    changed = await change_every_writable(runtime, name, document["parameters"])
    assert changed > 0
    plan = await backup.plan_restore(runtime, name, document)
    assert not plan.warnings
    assert sum(r.changed for r in plan.rows) == changed
    writes = []
    adapter = runtime.worker.adapters[name]
    original = getattr(adapter, "restore_entry", None)
    original_write = getattr(adapter, "write_accepted", None)  # what the declared write runs

    async def spy(key, raw):
        writes.append(key)
        return await original(key, raw)

    async def spy_write(accepted, *, confirmed=False):
        writes.append(accepted.param.key)
        return await original_write(accepted, confirmed=confirmed)

    if original is not None:
        adapter.restore_entry = spy
    if original_write is not None:
        adapter.write_accepted = spy_write
    report = await backup.execute_restore(runtime, plan, {r.key for r in plan.rows})
    assert report.ok and len(report.written) == changed and not report.failed
    read_only = {e["key"] for e in document["parameters"] if not e["writable"]}
    assert len(writes) == changed and not read_only & set(writes)  # read-only parameters are never written
    after = await backup.plan_restore(runtime, name, document)
    assert not any(r.changed for r in after.rows)  # every writable parameter is back
    if name in ("door-1", "gate-1"):
        assert report.saved == "Save-Settings" and runtime.twins[name].flash[3000] == document_value(document, "holding:3000")
    if name == "lift":
        assert report.saved.startswith("save parameters") and runtime.twins["lift"].service.saves >= 1


def document_value(document: dict, key: str):
    return next(e["raw"] for e in document["parameters"] if e["key"] == key)


async def test_restore_refuses_another_device_type(plant_runtime, tmp_path):
    path = await backup.backup_device(plant_runtime, "lift", tmp_path)
    document = backup.load_document(path.read_bytes())
    with pytest.raises(backup.BackupError, match="is a 'hdlock'"):
        await backup.plan_restore(plant_runtime, "door-1", document)


async def test_restore_warns_on_another_serial_number(plant_runtime, tmp_path):
    path = await backup.backup_device(plant_runtime, "door-1", tmp_path)
    document = backup.load_document(path.read_bytes())
    plan = await backup.plan_restore(plant_runtime, "door-2", document)  # same type, other lock
    assert any("serial number 660020" in w and "replaced device" in w for w in plan.warnings)


async def test_deselected_rows_are_skipped(plant_runtime, tmp_path):
    runtime = plant_runtime
    path = await backup.backup_device(runtime, "door-1", tmp_path)
    document = backup.load_document(path.read_bytes())
    adapter = runtime.worker.adapters["door-1"]
    await write_raw(adapter, "holding:3000", 444)
    await write_raw(adapter, "holding:3004", 65500)
    plan = await backup.plan_restore(runtime, "door-1", document)
    report = await backup.execute_restore(runtime, plan, {"holding:3004"})
    assert report.written == ["SettingsProximityThresholdUnlock"] and "LockRequestDelay" in report.skipped
    assert runtime.twins["door-1"].holding[3000] == 444


async def test_failed_write_skips_the_save_step(plant_runtime, tmp_path):
    runtime = plant_runtime
    path = await backup.backup_device(runtime, "door-1", tmp_path)
    document = backup.load_document(path.read_bytes())
    twin = runtime.twins["door-1"]
    await write_raw(runtime.worker.adapters["door-1"], "holding:3000", 444)
    await write_raw(runtime.worker.adapters["door-1"], "holding:3004", 65500)  # this one restores fine
    twin.writable.discard(3000)  # the firmware now refuses it
    saves = twin.input[101]
    plan = await backup.plan_restore(runtime, "door-1", document)
    report = await backup.execute_restore(runtime, plan, {r.key for r in plan.rows})
    assert report.written == ["SettingsProximityThresholdUnlock"]
    assert [name for name, _ in report.failed] == ["LockRequestDelay"]
    assert report.saved is None and twin.input[101] == saves  # one write failed: no Save-Settings
    assert "not saved because a write failed" in report.summary()


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ('{"schema": "commission-backup", "version": 1, "device": {"type": "hdl', "truncated or not JSON"),
        ('{"schema": "commission-backup", "version": 7, "device": {}, "parameters": []}', "version 7 is not supported"),
        ('{"schema": "something-else", "version": 1}', "not a commission backup"),
        ('{"schema": "commission-backup", "version": 1, "device": {"type": "hdlock"}}', "damaged file"),
    ],
)
def test_bad_files_are_rejected_by_name(text, words):
    with pytest.raises(backup.BackupError, match=words):
        backup.load_document(text)


def test_interrupted_write_leaves_no_partial_file(tmp_path, monkeypatch):
    target = tmp_path / "door-1.json"

    def broken_fsync(fd):
        raise OSError("disk removed")

    monkeypatch.setattr(backup.os, "fsync", broken_fsync)
    with pytest.raises(OSError):
        backup.write_atomic(target, json.dumps({"x": 1}) * 1000)
    assert not target.exists()
    assert list(tmp_path.iterdir()) == []  # the temporary file is gone too


def test_whole_plant_archive(tmp_path):
    files = [backup.write_atomic(tmp_path / f"d{i}.json", json.dumps({"i": i})) for i in range(3)]
    archive = backup.zip_files(files, tmp_path / "plant.zip")
    import zipfile

    with zipfile.ZipFile(archive) as z:
        assert sorted(z.namelist()) == ["d0.json", "d1.json", "d2.json"]


async def test_viewer_write_refused_and_audited(plant_runtime):
    runtime = plant_runtime
    with pytest.raises(PermissionDenied):
        await runtime.worker.gate.run(lambda: write_raw(runtime.worker.adapters["door-1"], "holding:3000", 300),
                                      device="door-1", role="viewer", user="tablet", describe="write LockRequestDelay")
    assert runtime.twins["door-1"].holding[3000] == 200
    entry = runtime.audit.query(device="door-1")[0]
    assert (entry.user, entry.role, entry.result) == ("tablet", "viewer", "refused: the viewer role may not write")


async def test_viewer_restore_is_refused(plant_runtime, tmp_path):
    runtime = plant_runtime
    path = await backup.backup_device(runtime, "door-1", tmp_path)
    document = backup.load_document(path.read_bytes())
    await write_raw(runtime.worker.adapters["door-1"], "holding:3000", 444)
    plan = await backup.plan_restore(runtime, "door-1", document)
    report = await backup.execute_restore(runtime, plan, {r.key for r in plan.rows}, user="tablet", role="viewer")
    assert report.failed and not report.written
    assert runtime.twins["door-1"].holding[3000] == 444


def test_audit_survives_a_restart(tmp_path):
    log = AuditLog(tmp_path / "audit.sqlite")
    log.record(user="anna", role="engineer", device="door-1", action="write LockRequestDelay", parameter="LockRequestDelay",
               old="200 ms", new="300 ms", result="ok")
    log.close()
    again = AuditLog(tmp_path / "audit.sqlite")
    entries = again.query(device="door-1")
    assert len(entries) == 1 and entries[0].new == "300 ms" and entries[0].user == "anna"
    assert again.query(user="bob") == []
    assert "LockRequestDelay" in to_csv(entries)


# -- restore writes what it shows, checked like a manual entry (issue: restore of edited files) ----


def edited(document: dict, key: str, **fields) -> dict:
    """The document with one parameter entry changed (as a hand-edited or damaged file would be)."""
    copy = json.loads(json.dumps(document))
    entry = next(e for e in copy["parameters"] if e["key"] == key)
    entry.update(fields)
    return copy


async def test_restore_writes_what_the_diff_shows_never_a_disagreeing_raw(plant_runtime, tmp_path):
    runtime = plant_runtime
    document = backup.load_document((await backup.backup_device(runtime, "door-1", tmp_path)).read_bytes())
    # raw 1 (magnet removal: a security risk) behind a shown value of 0
    plan = await backup.plan_restore(runtime, "door-1", edited(document, "holding:3005", raw=1, value=0))
    row = next(r for r in plan.rows if r.key == "holding:3005")
    assert row.error and "disagree" in row.error and not row.changed
    report = await backup.execute_restore(runtime, plan, {r.key for r in plan.rows})
    assert ("SettingsRemoveMagnet", row.error) in report.refused and not report.ok
    assert runtime.twins["door-1"].holding[3005] == 0 and runtime.twins["door-1"].flash[3005] == 0


@pytest.mark.parametrize("value, words", [
    (250.9, "not a whole number"), ("300", "not a number"), (True, "not a number"), (70000, "outside"),
])
async def test_restore_validates_each_value_like_a_manual_entry(plant_runtime, tmp_path, value, words):
    runtime = plant_runtime
    document = backup.load_document((await backup.backup_device(runtime, "door-1", tmp_path)).read_bytes())
    changed = edited(document, "holding:3000", value=value)
    del next(e for e in changed["parameters"] if e["key"] == "holding:3000")["raw"]
    plan = await backup.plan_restore(runtime, "door-1", changed)
    row = next(r for r in plan.rows if r.key == "holding:3000")
    assert words in row.error
    report = await backup.execute_restore(runtime, plan, {r.key for r in plan.rows})
    assert report.refused and runtime.twins["door-1"].holding[3000] == 200


async def test_restore_shows_and_writes_the_value_field(plant_runtime, tmp_path):
    runtime = plant_runtime
    document = backup.load_document((await backup.backup_device(runtime, "door-1", tmp_path)).read_bytes())
    plan = await backup.plan_restore(runtime, "door-1", edited(document, "holding:3000", raw=250, value=250))
    row = next(r for r in plan.rows if r.key == "holding:3000")
    assert (row.current_text, row.backup_text, row.changed) == ("200 ms", "250 ms", True)
    report = await backup.execute_restore(runtime, plan, {"holding:3000"})
    assert report.written == ["LockRequestDelay"] and runtime.twins["door-1"].holding[3000] == 250
    entry = next(e for e in runtime.audit.query(device="door-1") if e.action == "restore" and e.parameter)
    assert (entry.old, entry.new, entry.result) == ("200 ms", "250 ms", "ok")


async def test_restore_asks_the_same_confirmation_as_a_manual_write(plant_runtime, tmp_path):
    runtime = plant_runtime
    document = backup.load_document((await backup.backup_device(runtime, "door-1", tmp_path)).read_bytes())
    risky = edited(document, "holding:3005", raw=1, value=1)
    plan = await backup.plan_restore(runtime, "door-1", risky)
    row = next(r for r in plan.rows if r.key == "holding:3005")
    assert row.risk and plan.risky({row.key}) == [row]
    report = await backup.execute_restore(runtime, plan, {row.key})  # nobody confirmed
    assert report.refused and "needs a confirmation" in report.refused[0][1]
    assert runtime.twins["door-1"].holding[3005] == 0
    report = await backup.execute_restore(runtime, plan, {row.key}, confirmed={row.key})
    assert report.written == ["SettingsRemoveMagnet"] and runtime.twins["door-1"].holding[3005] == 1


async def test_electrak_restore_writes_the_shown_bit_rate(plant_runtime, tmp_path):
    runtime = plant_runtime
    document = backup.load_document((await backup.backup_device(runtime, "lift", tmp_path)).read_bytes())
    entry = next(e for e in document["parameters"] if e["key"] == "service:4")
    plan = await backup.plan_restore(runtime, "lift", edited(document, "service:4", raw=entry["raw"] + 1))
    row = next(r for r in plan.rows if r.key == "service:4")
    assert "disagree" in row.error and not row.changed  # shown 2 -> 2 but raw 3: never written


async def test_scu_backup_restores_its_volatile_remote_data(plant_runtime, tmp_path):
    runtime = plant_runtime
    assert await wait_for(lambda: runtime.store.devices["lift-1"].status == "online", timeout=10)
    path = await backup.backup_device(runtime, "lift-1", tmp_path)
    document = backup.load_document(path.read_bytes())
    assert document["device"]["type"] == "scu" and document["parameters"]
    plan = await backup.plan_restore(runtime, "lift-1", document)  # the settings of devices/scu/model.py
    assert plan.rows and not any(r.changed for r in plan.rows)
    assert "volatile remote data" in backup.restore_wear(runtime, "lift-1")
