"""Batch apply: one set to both demo HD-Locks over Modbus, identity check and dry run per device,
device by device, stopping at the first failure; from the CLI with the restore's confirmations."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from conftest import modbus_plant, running_plant
from plants import modbus_line, plant_text

from app import backup, batch
from app.runtime import Runtime
from devices.hdlock.params import PARAMS
from devices.params import backup_entry


def _source(tmp_path, delay=420, magnet=0):
    entries = [backup_entry(p, p.default if p.default is not None else 0) for p in PARAMS]
    for e in entries:
        if e["name"] == "LockRequestDelay":
            e.update(raw=delay, value=delay, text=f"{delay} ms")
        if e["name"] == "SettingsRemoveMagnet":
            e.update(raw=magnet, value=magnet)
    document = backup.make_document("demo", "door-1", "hdlock", "line1", {"serial": 1}, entries)
    path = tmp_path / "set.json"
    path.write_text(json.dumps(document))
    return path


@pytest.fixture
async def locks(tmp_path):
    async with running_plant(modbus_plant(locks=(("door-1", 1), ("door-2", 2))), tmp_path / "data",
                             ready=("door-1", "door-2")) as runtime:
        yield runtime


async def test_batch_stops_at_the_first_failure_and_says_so(locks, tmp_path):
    runtime = locks
    source = str(_source(tmp_path))
    plan = await batch.plan_batch(runtime, ["door-1", "door-2"], source)
    assert plan.ready, [d.error for d in plan.devices]
    for entry in plan.devices:  # each its own identity check and dry-run diff
        assert entry.check.ok
        # the set is door-1's: its serial against door-1's is a replacement; door-2's own serial is no news
        assert any("serial number 1 ->" in n for n in entry.check.notes) == (entry.device == "door-1")
        assert [r.name for r in entry.changed] == ["LockRequestDelay"]
    assert runtime.twins["door-1"].holding[3000] == 200  # a dry run writes nothing

    runtime.twins["door-1"].refuse_writes = True  # the first lock refuses every write
    seen = []
    results = await batch.apply_batch(runtime, plan, user="anna", role="engineer", on_device=seen.append)
    assert [(r.device, r.status) for r in results] == [("door-1", "failed"), ("door-2", "skipped")]
    assert "LockRequestDelay" in results[0].text and "stopped at door-1" in results[1].text
    assert seen == results
    assert runtime.twins["door-2"].holding[3000] == 200  # never reached
    rows = await runtime.audit.aquery(limit=100)
    assert any(r.action == "batch apply" and "door-1 failed" in r.result and "door-2 skipped" in r.result for r in rows)

    runtime.twins["door-1"].refuse_writes = False
    plan = await batch.plan_batch(runtime, ["door-1", "door-2"], source)
    results = await batch.apply_batch(runtime, plan, user="anna", role="engineer")
    assert [(r.device, r.status) for r in results] == [("door-1", "written"), ("door-2", "written")]
    assert all(runtime.twins[n].flash[3000] == 420 for n in ("door-1", "door-2"))  # written, read back, saved
    plan = await batch.plan_batch(runtime, ["door-1", "door-2"], "device:door-1")  # a sibling as the source
    results = await batch.apply_batch(runtime, plan, user="anna", role="engineer")
    assert [r.status for r in results] == ["unchanged", "unchanged"]


async def test_mixed_types_and_viewers_are_refused(tmp_path):
    from app.plant import DEMO_PLANT, load_plant
    from webutil import private_endpoints

    plant = private_endpoints(load_plant(DEMO_PLANT), tmp_path.name)
    runtime = Runtime(plant, simulate=False, data_dir=tmp_path / "data")
    plan = await batch.plan_batch(runtime, ["door-1", "heater-hm"], str(_source(tmp_path)))
    assert not plan.ready and "types" in plan.errors[0]
    plan = await batch.plan_batch(runtime, ["heater-hm", "heater-hmr"], str(_source(tmp_path)))
    assert not plan.ready and "variants" in plan.errors[0]


async def test_viewer_cannot_apply(locks, tmp_path):
    runtime = locks
    plan = await batch.plan_batch(runtime, ["door-2"], str(_source(tmp_path)))
    results = await batch.apply_batch(runtime, plan, user="tablet", role="viewer")
    assert results[0].status == "failed" and runtime.twins["door-2"].holding[3000] == 200


def test_cli_apply_confirmations_and_stop(tmp_path):
    plant = tmp_path / "plant.toml"
    plant.write_text(plant_text(modbus_line(locks=(("door-1", 1), ("door-2", 2))), name="cli"))
    source = _source(tmp_path, delay=430, magnet=1)
    cmd = [sys.executable, "-m", "app.cli", "apply", "--plant", str(plant), "--from", str(source), "--devices", "door-1,door-2",
           "--data-dir", str(tmp_path / "data"), "--yes"]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL)
    assert out.returncode == 2, out.stdout + out.stderr
    assert "SettingsRemoveMagnet needs a confirmation" in out.stderr and "nothing written" in out.stderr
    assert "door-1:\n" in out.stdout and "LockRequestDelay: 200 ms -> 430 ms" in out.stdout
    out = subprocess.run(cmd + ["--accept-risk", "SettingsRemoveMagnet"], capture_output=True, text=True, timeout=120,
                         stdin=subprocess.DEVNULL)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "door-1: written:" in out.stdout and "door-2: written:" in out.stdout
