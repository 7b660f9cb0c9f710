"""The commissioning record: append-only storage, approved set, drift in the API, automatic
snapshot after Save-Settings, the as-left report (HTML, PDF, archive) and the sign-off."""

from __future__ import annotations

import asyncio
import io
import sqlite3
import stat
import zipfile

import pytest
from webutil import simulated_user

from app.record_store import RecordStore
from app.report import plant_content, plant_html
from app.report_archive import write_plant
from devices.hdlock.params import PARAMS
from tests.conftest import wait_for
from tests.recordutil import demo_plant

pytestmark = pytest.mark.timeout(90)


def test_records_are_append_only_and_owner_only(tmp_path):
    store = RecordStore(tmp_path / "record.sqlite")
    first = store.add(plant="p", device="d", kind="signoff", user="anna", role="engineer", data={"name": "Anna"})
    second = store.add(plant="p", device="d", kind="signoff", user="anna", role="engineer", data={"name": "Anna"}, supersedes=first)
    with pytest.raises(sqlite3.DatabaseError, match="append-only"):
        store._open().execute("UPDATE record SET data = '{}' WHERE id = ?", (first,))
    with pytest.raises(sqlite3.DatabaseError, match="append-only"):
        store._open().execute("DELETE FROM record")
    assert store.latest("p", "d", "signoff").id == second and store.get(second).supersedes == first
    assert stat.S_IMODE((tmp_path / "record.sqlite").stat().st_mode) == 0o600
    store.close()


async def test_a_session_that_ends_while_the_record_starts_is_not_missed(tmp_path):
    """The record started after the worker and followed the audit from the moment it was ready. A Save-Settings that
    ended meanwhile (the devices up, the record still reading its newest sets: a loaded machine) was never acted on,
    and the record lacked the snapshot of the set the session ended with. It follows the audit from the program's
    start now."""
    from app.runtime import Runtime

    runtime = Runtime(demo_plant(("door-1",)), simulate=True, data_dir=tmp_path / "data")
    record, written = runtime.record, []
    reading = record.store.run

    async def run(*args, **kwargs):  # the record reads its newest sets: a write session ends meanwhile
        if not written:
            row = runtime.audit.record(user="anna", role="engineer", device="door-1", action="Save-Settings", result="started")
            runtime.audit.finish(row, "ok")
            written.append(row)
        return await reading(*args, **kwargs)

    record.store.run = run
    async with simulated_user(runtime):
        assert await wait_for(lambda: written, 15), "the record read nothing at its start"
        assert await wait_for(lambda: "door-1" in record.snapshots, 30)
        assert [e.title for e in await record.timeline("door-1", ("snapshot",))] == ["after Save-Settings"]


async def test_a_save_still_running_when_the_audit_is_read_is_not_missed(tmp_path):
    """The gate writes a row before the action runs (``started``) and finishes it with the outcome. A Save-Settings
    that took a while on a busy line was read while it ran, skipped as not ok, and never read again: the record
    lacked the snapshot of the set the session ended with."""
    from app.record import AUDIT_FOLLOW_S
    from app.runtime import Runtime

    runtime = Runtime(demo_plant(("door-1",)), simulate=True, data_dir=tmp_path / "data")
    async with simulated_user(runtime):
        state = runtime.store.devices["door-1"]
        assert await wait_for(lambda: state.status == "online" and state.value("LockRequestDelay") is not None, 15)
        record = runtime.record
        row = runtime.audit.record(user="anna", role="engineer", device="door-1", action="Save-Settings", result="started")
        await asyncio.sleep(2.5 * AUDIT_FOLLOW_S)  # the audit is read twice while the save still runs
        assert "door-1" not in record.snapshots
        runtime.audit.finish(row, "ok")
        # the snapshot reads the lock anew (a loaded line: tried again up to 4 times, 3 s apart, app/record.py)
        assert await wait_for(lambda: "door-1" in record.snapshots, 30)
        assert [e.title for e in await record.timeline("door-1", ("snapshot",))] == ["after Save-Settings"]
        await asyncio.sleep(2 * AUDIT_FOLLOW_S)  # two more readings: the row is acted on once
        assert len(await record.timeline("door-1", ("snapshot",))) == 1


async def test_an_automatic_snapshot_that_fails_is_tried_again(tmp_path, monkeypatch, caplog):
    """The device still storing, a timeout on a busy line: the snapshot after Save-Settings is tried again, so the
    record holds the set the write session ended with (it was dropped until the next session's end)."""
    from app import record as record_module
    from app.runtime import Runtime
    from devices.errors import CommissionError

    monkeypatch.setattr(record_module, "SNAPSHOT_RETRY_S", 0.2)
    runtime = Runtime(demo_plant(("door-1",)), simulate=True, data_dir=tmp_path / "data")
    async with simulated_user(runtime):
        state = runtime.store.devices["door-1"]
        assert await wait_for(lambda: state.status == "online" and state.value("LockRequestDelay") is not None, 15)
        record = runtime.record
        read_set, failures = record.read_set, []

        async def busy_once(device, **kwargs):
            if not failures:
                failures.append(device)
                raise CommissionError("door-1: no answer within 0.5 s (timeout)")
            return await read_set(device, **kwargs)

        monkeypatch.setattr(record, "read_set", busy_once)
        runtime.audit.record(user="anna", role="engineer", device="door-1", action="Save-Settings", result="ok")
        # the snapshot reads the lock anew (a loaded line: tried again up to 4 times, 3 s apart, app/record.py)
        assert await wait_for(lambda: "door-1" in record.snapshots, 30)
        assert failures == ["door-1"]
        timeline = await record.timeline("door-1", ("snapshot",))
        assert [e.title for e in timeline] == ["after Save-Settings"]
        assert "automatic snapshot after Save-Settings failed (1 of 4); tried again in 0.2 s" in caplog.text


async def test_drift_in_the_api_snapshot_after_save_and_the_signed_report(tmp_path):
    from app.runtime import Runtime

    runtime = Runtime(demo_plant(("door-1",)), simulate=True, data_dir=tmp_path / "data")
    async with simulated_user(runtime) as user:
        client = user.http_client
        state = runtime.store.devices["door-1"]
        assert await wait_for(lambda: state.status == "online" and state.value("LockRequestDelay") is not None, 15)
        await runtime.record.approve("door-1", user="anna", role="engineer")
        assert (await client.get("/api/devices")).json()[0]["drift"] == {"approved": True, "changed": []}

        param = PARAMS.get("holding", 3000)
        await runtime.worker.gate.run(lambda: runtime.worker.adapters["door-1"].write_param(param, 350),
                                      device="door-1", user="anna", describe="write", role="engineer")

        async def drifted() -> dict:
            return (await client.get("/api/devices")).json()[0]["drift"]
        assert await wait_for(lambda: state.drift["changed"], 5)
        drift = await drifted()
        assert drift["changed"] == [{"key": "holding:3000", "name": "LockRequestDelay", "approved": "200 ms", "now": "350 ms"}]
        assert "changed since approved" in state.entry("Changed since approved")["text"]

        await runtime.worker.gate.run(lambda: runtime.worker.adapters["door-1"].save_settings(),
                                      device="door-1", user="anna", describe="Save-Settings", role="engineer")
        assert await wait_for(lambda: runtime.record.snapshots.get("door-1", {}).get("holding:3000", {}).get("raw") == 350, 30)
        timeline = await runtime.record.timeline("door-1")
        assert [e.kind for e in timeline][:2] == ["snapshot", "approved"] and timeline[0].title == "after Save-Settings"

        with pytest.raises(PermissionError):
            await runtime.record.approve("door-1", user="tablet", role="viewer")

        content = await plant_content(runtime, user="anna")
        runtime.users.add("anna", "engineer", "anna-password")  # a sign-off needs a named account
        await runtime.record.sign("", user="anna", role="engineer", name="Anna Berg", signer_role="commissioning engineer",
                                  comment="door-1 delay raised on site", content=content, account="anna")
        paths = await write_plant(runtime, tmp_path / "out")
        html = paths["html"].read_text()
        assert "LockRequestDelay" in html and "350 ms" in html and "changed" in html and "Anna Berg" in html

        from pypdf import PdfReader

        text = "\n".join(page.extract_text() for page in PdfReader(paths["pdf"]).pages)
        assert "door-1" in text and "LockRequestDelay" in text and "350 ms" in text and "Anna Berg" in text
        names = zipfile.ZipFile(io.BytesIO(paths["zip"].read_bytes())).namelist()
        assert {"demo-as-left.html", "demo-as-left.pdf", "backups/door-1-approved.json", "backups/door-1-snapshot.json"} <= set(names)
        assert "Changed since approved" in plant_html(await plant_content(runtime, read=False))


async def test_values_the_lock_measures_itself_and_a_running_checkout_are_not_drift(tmp_path):
    import asyncio

    from tests.recordutil import demo_runtime, run_checkout

    async with demo_runtime(tmp_path, ("door-2",)) as runtime:
        twin, state = runtime.twins["door-2"], runtime.store.devices["door-2"]
        twin.holding[1003] = twin.holding[1004] = 0  # no cycle measured yet: the checkout's cycle sets both
        maxima = (PARAMS.get("holding", 1003), PARAMS.get("holding", 1004))
        assert await wait_for(lambda: all(state.raw(p) == 0 for p in maxima), 15)
        await runtime.record.approve("door-2", user="anna", role="engineer")
        assert state.drift == {"approved": True, "changed": []}

        seen: list[dict] = []

        async def watch() -> None:
            while True:
                runtime.record.check_drift("door-2")
                seen.append(state.drift)
                await asyncio.sleep(0.1)

        watcher = asyncio.create_task(watch())
        try:
            result = await run_checkout(runtime, "door-2", act=True)
        finally:
            watcher.cancel()
        assert result["status"] == "passed", [(s["name"], s["reason"]) for s in result["steps"]]
        assert any(r["key"] == "holding:4" for d in seen for r in d.get("checkout", [])), "the checkout's own write was seen"
        assert not any(r["key"] == "holding:4" for d in seen for r in d["changed"]), "and never shown as drift"

        assert await wait_for(lambda: all(state.raw(p) for p in maxima), 10), "the lock measured its cycle"
        assert runtime.record.check_drift("door-2") == [] and state.drift == {"approved": True, "changed": []}
        assert state.entry("Changed since approved")["value"] == 0
        from app.report import device_content

        content = await device_content(runtime, "door-2", user="anna", role="engineer")
        verdicts = {r["key"]: r["verdict"] for r in content["parameters"]}
        assert verdicts["holding:1004"] == "updated by the device" and verdicts["holding:4"] == "equal"

        # a real change is still drift
        await runtime.worker.gate.run(lambda: runtime.worker.adapters["door-2"].write_param(PARAMS.get("holding", 3000), 350),
                                      device="door-2", user="anna", describe="write", role="engineer")
        assert await wait_for(lambda: [r["key"] for r in state.drift["changed"]] == ["holding:3000"], 10)


async def test_overview_marks_a_device_changed_since_approved_on_its_tile_and_in_the_table(tmp_path):
    from nicegui import ui

    from app.runtime import Runtime

    runtime = Runtime(demo_plant(("door-1",)), simulate=True, data_dir=tmp_path / "data")
    async with simulated_user(runtime) as user:
        state = runtime.store.devices["door-1"]
        assert await wait_for(lambda: state.status == "online" and state.value("LockRequestDelay") is not None, 15)
        await runtime.record.approve("door-1", user="anna", role="engineer")
        await user.open("/")
        await user.should_not_see("changed since approved")

        param = PARAMS.get("holding", 3000)
        await runtime.worker.gate.run(lambda: runtime.worker.adapters["door-1"].write_param(param, 350),
                                      device="door-1", user="anna", describe="write", role="engineer")
        assert await wait_for(lambda: state.drift["changed"], 5)
        await user.should_see("Changed since approved: LockRequestDelay 200 ms → 350 ms")  # the table's row
        badge = next(iter(user.find(kind=ui.badge, content="changed since approved (1)").elements))
        assert badge.visible and badge._props["title"] == "Changed since approved: LockRequestDelay 200 ms → 350 ms"

        await runtime.worker.gate.run(lambda: runtime.worker.adapters["door-1"].write_param(param, 200),
                                      device="door-1", user="anna", describe="write", role="engineer")
        assert await wait_for(lambda: not state.drift["changed"], 5)
        await user.should_not_see("changed since approved")
