"""HD-Lock writes and system commands as declared commands (issue 26): the page, the API and a restore
ask the same send policy (devices/hdlock/policy.py) through the worker's gate."""

from __future__ import annotations

import json

import pytest
from conftest import modbus_plant, wait_for

from app import backup, gate
from app.runtime import Runtime
from devices.commands import WRITE_PARAMETER
from devices.hdlock import policy
from devices.hdlock.params import PARAMS
from devices.params import Accepted
from devices.sendpolicy import Verdict

pytestmark = pytest.mark.timeout(60)
POLICY_RISK = "policy: 250 ms is a value the plant's safety review asks about"


@pytest.fixture
async def lock(tmp_path):
    runtime = Runtime(modbus_plant(locks=(("door-1", 1),)), simulate=True, data_dir=tmp_path / "data")
    await runtime.start()
    try:
        assert await wait_for(lambda: runtime.store.devices["door-1"].value("LockStatus") is not None, timeout=10)
        yield runtime
    finally:
        await runtime.stop()


@pytest.fixture
def stricter(monkeypatch):
    """The lock's send policy asks about LockRequestDelay = 250 and refuses SettingsDirection = 1."""
    real = policy.write_verdict

    def verdict(accepted: Accepted) -> Verdict:
        address, value = accepted.param.address, accepted.raw
        if address == 3000 and value == 250:
            return Verdict(confirm=(POLICY_RISK,), name="LockRequestDelay")
        if address == 3003 and value == 1:
            return Verdict(refused="policy: SettingsDirection 1 refused", name="SettingsDirection")
        return real(accepted)

    monkeypatch.setattr(policy, "write_verdict", verdict)


def _edited(document: dict, key: str, value) -> dict:
    copy = json.loads(json.dumps(document))
    entry = next(e for e in copy["parameters"] if e["key"] == key)
    entry.update(value=value, raw=value)
    return copy


async def test_restore_writes_through_the_declared_write_and_its_send_policy(lock, stricter, tmp_path):
    runtime = lock
    twin = runtime.twins["door-1"]
    document = backup.load_document((await backup.backup_device(runtime, "door-1", tmp_path)).read_bytes())
    plan = await backup.plan_restore(runtime, "door-1", _edited(_edited(document, "holding:3000", 250), "holding:3003", 1))
    delay = next(r for r in plan.rows if r.key == "holding:3000")
    direction = next(r for r in plan.rows if r.key == "holding:3003")
    # the question shown beside the row is the one the page's write asks: the gate's, from the policy
    assert delay.risk == POLICY_RISK == runtime.worker.gate.question("door-1", WRITE_PARAMETER,
                                                                     {"param": "holding:3000", "value": 250})
    assert "SettingsDirection 1 refused" in direction.error
    report = await backup.execute_restore(runtime, plan, {delay.key, direction.key})
    assert report.refused and twin.holding[3000] == 200 and twin.holding[3003] == 0
    report = await backup.execute_restore(runtime, plan, {delay.key}, confirmed={delay.key})
    assert report.written == ["LockRequestDelay"] and twin.holding[3000] == 250
    row = next(e for e in runtime.audit.query(device="door-1") if e.action == "restore" and e.parameter)
    assert (row.parameter, row.old, row.new, row.result) == ("LockRequestDelay", "200 ms", "250 ms", "ok")


async def test_api_write_asks_the_policy_and_refuses_what_it_refuses(lock, stricter):
    runtime = lock
    worker, twin = runtime.worker, runtime.twins["door-1"]
    with pytest.raises(gate.NeedsConfirmation) as asked:
        await worker.gate.invoke("door-1", WRITE_PARAMETER, {"param": "LockRequestDelay", "value": 250}, user="anna",
                                 role="engineer")
    assert asked.value.question == POLICY_RISK and twin.holding[3000] == 200
    with pytest.raises(ValueError, match="SettingsDirection 1 refused"):
        await worker.gate.invoke("door-1", WRITE_PARAMETER, {"param": "holding:3003", "value": 1}, user="anna", role="engineer")
    with pytest.raises(ValueError, match="outside"):
        await worker.gate.invoke("door-1", WRITE_PARAMETER, {"param": "holding:3000", "value": 70000}, user="anna",
                                 role="engineer")
    await worker.gate.invoke("door-1", WRITE_PARAMETER, {"param": "holding:3000", "value": 250}, user="anna",
                             role="engineer", confirmed=True)
    assert twin.holding[3000] == 250 and PARAMS.by_key["holding:3000"].key in runtime.store.devices["door-1"].unsaved
    results = [(e.action, e.result) for e in runtime.audit.query(device="door-1")]
    assert ("write LockRequestDelay", "ok") in results
    assert any(r.startswith("refused: policy: SettingsDirection 1 refused") for _, r in results)


async def test_save_settings_audit_lists_what_became_permanent(lock):
    runtime = lock
    worker = runtime.worker
    await worker.gate.invoke("door-1", WRITE_PARAMETER, {"param": "MaximumTimeUnlock", "value": 1234}, user="anna",
                             role="engineer")
    await worker.gate.invoke("door-1", "Save-Settings", {}, user="anna", role="engineer")
    row = next(e for e in runtime.audit.query(device="door-1") if e.action == "Save-Settings")
    assert row.result == "ok" and "MaximumTimeUnlock (holding 1003) = 1234" in row.new
