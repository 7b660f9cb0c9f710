"""Values a device measures itself (HD-Lock's MaximumTimeLock/Unlock, "longest time measured so far") are not
settings: never restored, applied in a batch, preselected when a device is replaced, or counted as drift.
One function of the parameter model (``Param.setting``) decides for all of them (issue 42 item 4)."""

from __future__ import annotations

import json

import pytest
from conftest import identified, modbus_plant, running_plant

from app import backup, batch, record_sets, replace
from devices.hdlock.params import PARAMS
from devices.params import backup_entry

pytestmark = pytest.mark.timeout(60)

MEASURED = ("MaximumTimeLock", "MaximumTimeUnlock")


def test_the_parameter_model_says_what_is_a_setting():
    for name in MEASURED:
        param = PARAMS.by_name[name]
        assert param.writable and not param.setting  # the document's RW (to reset it), but measured by the lock
        assert backup_entry(param, 753)["setting"] is False
    assert PARAMS.by_name["LockRequestDelay"].setting
    assert not PARAMS.by_name["LockState"].setting


@pytest.fixture
async def locks(tmp_path):
    async with running_plant(modbus_plant(locks=(("door-1", 1), ("door-2", 2))), tmp_path / "data",
                             ready=("door-1", "door-2"), is_ready=identified) as runtime:
        yield runtime


def _document(delay: int, measured: int) -> dict:
    """door-1's set as the record or a backup file holds it: every parameter flagged writable as the model said."""
    entries = []
    for p in PARAMS:
        raw = p.default if p.default is not None else 0
        if p.name == "LockRequestDelay":
            raw = delay
        if p.name in MEASURED:
            raw = measured
        entry = backup_entry(p, raw)
        entry.pop("setting")  # a file written before the model said so
        entries.append(entry)
    return backup.make_document("demo", "door-1", "hdlock", "line1", {"serial": 1}, entries)


async def test_measured_maxima_are_not_restored_batched_preselected_or_drift(locks, tmp_path):
    runtime = locks
    document = _document(delay=420, measured=753)
    for twin in runtime.twins.values():
        assert twin.holding[1004] != 753
    # restore (and so the replacement assistant, whose rows are restore's plan): the measured values are no rows
    plan = await backup.plan_restore(runtime, "door-2", document)
    assert [r.name for r in plan.rows if r.changed] == ["LockRequestDelay"]
    assert not {r.name for r in plan.rows} & set(MEASURED)
    assert not any(name in w for w in plan.warnings for name in MEASURED), plan.warnings
    # a batch from a file and from the approved set
    path = tmp_path / "set.json"
    path.write_text(json.dumps(document))
    bplan = await batch.plan_batch(runtime, ["door-1", "door-2"], str(path))
    assert bplan.ready, [d.error for d in bplan.devices]
    assert [[r.name for r in d.changed] for d in bplan.devices] == [["LockRequestDelay"], ["LockRequestDelay"]]
    # the replacement's check does not list a measured value as one the set lacks a setting for
    check = await replace.check_identity(runtime, "door-2", {**document, "parameters": [
        e for e in document["parameters"] if e["name"] not in MEASURED]},
        {e["key"] for e in await runtime.worker.adapters["door-2"].backup_read()})
    assert not set(check.adds) & set(MEASURED), check.adds
    # drift: an approved set whose measured maxima differ from the device's has no drift
    state = runtime.store.devices["door-2"]
    approved = record_sets.param_set(document["parameters"])
    assert not [r for r in record_sets.drift_of(state, approved) if r["name"] in MEASURED]
    current = {k: {**v, "device_updates": record_sets.device_updated(state, k)} for k, v in record_sets.live_params(state).items()}
    verdicts = {r["name"]: r["verdict"] for r in record_sets.compare_with_approved(current, approved)}  # as the report does
    assert all(verdicts[name] != "changed" for name in MEASURED), verdicts
