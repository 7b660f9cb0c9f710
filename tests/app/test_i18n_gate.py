"""The command gate's refusals in the reader's language (issue 47): the gate's errors carry a Message, so the parameter
model's refusal of a write, a command not declared, a role that may not write and a restore's row refused through the
gate keep their English (the audit log's and the record's) and come in German where a German page shows them."""

from __future__ import annotations

import pytest
from plants import modbus_plant

from app import backup, i18n
from app.gate import PermissionDenied
from app.message import Message, said
from app.runtime import Runtime
from devices.commands import WRITE_PARAMETER, CommandError
from devices.hdlock.params import PARAMS
from devices.message import N_
from pages.diffrows import row_state, state_text

pytestmark = pytest.mark.timeout(60)

DE = i18n.get("de")


async def test_the_gates_refusals_keep_their_english_and_come_in_german(tmp_path):
    low, high = PARAMS.by_name["LockRequestDelay"].limits()
    runtime = Runtime(modbus_plant(), simulate=True, data_dir=tmp_path)
    await runtime.start()
    try:
        gate = runtime.worker.gate
        with pytest.raises(CommandError) as outside:
            await gate.invoke("door-1", WRITE_PARAMETER, {"param": "LockRequestDelay", "value": 70000}, user="anna", role="engineer")
        assert str(outside.value) == f"LockRequestDelay: 70000 is outside {low} .. {high} ms"
        assert said(outside.value, DE) == f"LockRequestDelay: 70000 liegt außerhalb von {low} .. {high} ms"
        with pytest.raises(CommandError) as unknown:
            await gate.invoke("door-1", "fly", {}, user="anna", role="engineer")
        assert str(unknown.value) == "'fly' is not a command of door-1"
        assert said(unknown.value, DE) == "'fly' ist kein Befehl von door-1"
        with pytest.raises(CommandError) as asked:
            gate.question("door-1", "fly")
        assert said(asked.value, DE) == "'fly' ist kein Befehl von door-1"
        with pytest.raises(PermissionDenied) as denied:
            await gate.invoke("door-1", WRITE_PARAMETER, {"param": "LockRequestDelay", "value": 250}, user="vera", role="viewer")
        assert str(denied.value) == "vera has the viewer role and may not write (write parameter)"
        assert said(denied.value, DE) == "vera hat die Rolle Betrachter und darf nicht schreiben (write parameter)"
        with pytest.raises(PermissionDenied) as nobody:
            await gate.run(lambda: None, device="door-1", user="", role="", describe="backup", kind="write")
        assert str(nobody.value) == "anonymous has the no role and may not write (backup)"
        assert said(nobody.value, DE) == "anonym hat keine Rolle und darf nicht schreiben (backup)"
        results = [r.result for r in runtime.audit.query(device="door-1")]
        assert f"refused: LockRequestDelay: 70000 is outside {low} .. {high} ms" in results  # the audit log keeps the English
        assert "refused: 'fly' is not a command of door-1" in results
    finally:
        await runtime.stop()


async def test_a_restores_row_refused_by_the_gate_comes_in_german(tmp_path):
    runtime = Runtime(modbus_plant(), simulate=True, data_dir=tmp_path)
    await runtime.start()
    try:
        from tests.conftest import wait_for

        assert await wait_for(lambda: runtime.store.devices["door-1"].value("LockRequestDelay") is not None, 15)
        document = backup.make_document("plant", "door-1", "hdlock", "line1", {}, [
            {"key": PARAMS.by_name["LockRequestDelay"].key, "name": "LockRequestDelay", "value": 321, "writable": True}])
        plan = await backup.plan_restore(runtime, "door-1", document)
        row = next(r for r in plan.rows if r.name == "LockRequestDelay")
        report = await backup.execute_restore(runtime, plan, {row.key}, user="vera", role="viewer")
        (name, error), = report.failed
        assert name == "LockRequestDelay" and error == "vera has the viewer role and may not write (write parameter)"
        assert said(error, DE) == "vera hat die Rolle Betrachter und darf nicht schreiben (write parameter)"
        assert said(report.summary(), DE).startswith("0 geschrieben, 0 unverändert, 1 fehlgeschlagen")
    finally:
        await runtime.stop()


def test_a_diff_rows_refusal_in_the_pages_language():
    row = backup.DiffRow("holding:3000", "LockRequestDelay", "ms", 200, 200, None, 70000,
                         error=Message(N_("{name} is not a command of {device}"), name="'fly'", device="door-1"))
    assert row_state(row) == "not written: 'fly' is not a command of door-1"  # the row's state as the page compares it
    assert state_text(row, DE) == "nicht geschrieben: 'fly' ist kein Befehl von door-1"
