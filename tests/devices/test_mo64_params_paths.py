"""MO 64 settings on the parameter model, on every path against the twins: the project's difference on the device
page applied per row, restore with names and the question a safety flag names, batch apply to the demo plant's two
barriers on one RS485 line (each reported), drift of a changed setting in /api/devices, the page's question when
force monitoring is cleared (NiceGUI's simulated user) and the replacement assistant."""

from __future__ import annotations

import asyncio
import json

import pytest
from nicegui.testing.user_interaction import UserInteraction
from plants import mo64_tcp, plant_text
from recordutil import demo_plant
from test_backup_page import emit
from webutil import by_testid, dialog_button, eventually, project_card_table, simulated_user, user_on

from app import backup, batch, project, replace
from app.plant import load_plant, parse_plant
from app.runtime import Runtime
from devices.mo64.params import KRAFT_RISK, PARAMS

pytestmark = pytest.mark.timeout(60)
KRAFT = PARAMS.by_name["Kraftüberwachung"]
T_OPEN = PARAMS.by_name["t_offen"]


def _force_bits(twin) -> int:
    return twin.settings["config_flags"]["konfig2"] >> 11 & 0b11


async def _online(runtime: Runtime, *names: str, settings: bool = True) -> None:
    """Each device answers, and (``settings``) its start-up reads brought the settings into the store."""
    for name in names:
        await eventually(lambda n=name: runtime.store.devices[n].status == "online"
                         and (not settings or runtime.store.devices[n].raw(KRAFT) is not None), timeout=20,
                         what=f"{name} read")


def _changed(document: dict, **values) -> dict:
    """``document`` with the entries named (by the model's name) set to ``values`` (decoded), as a file holds them."""
    for entry in document["parameters"]:
        param = PARAMS.by_key.get(entry["key"])
        if param is not None and param.name in values:
            raw = param.validate(values[param.name])
            entry.update(value=param.decode(raw), raw=raw, text=param.display(raw))
    return document


async def test_the_project_differs_on_the_device_page_and_is_applied_per_row(tmp_path):
    path = tmp_path / "plant.toml"
    path.write_text(plant_text(mo64_tcp("gate", device_options={"project": {"t_offen": 12.5}}), name="gates"))
    bad = parse_plant(plant_text(mo64_tcp("gate", device_options={"project": {"t_offen": 700, "multi7": 1}})))
    named = parse_plant(plant_text(mo64_tcp("gate", device_options={"project": {"LS-Test": "aus"}})))
    assert not project.check_plant(named)  # a choice by its name
    (entry,) = project.entries(named, "gate")
    assert (entry.key, entry.raw) == ("config_flags:48", 0)
    problems = project.check_plant(bad)  # commission check: without the device
    assert any("t_offen: 700 is outside 0 .. 655" in p for p in problems), problems
    assert any("unknown parameter 'multi7'" in p for p in problems), problems
    async with user_on(load_plant(path), data_dir=tmp_path / "data") as (user, runtime):
        await _online(runtime, "gate")
        twin = runtime.twins["gate"]
        await user.open("/device/gate")
        await user.should_see("1 of 1 project entry differs from the device", retries=100)
        table = project_card_table(user)
        assert [(r["name"], r["backup"], r["current"], r["changed"]) for r in table.rows] == [
            ("t_offen", "12.5 s", "10 s", True)]
        emit(table, "apply", "t_open:0")
        await user.should_see("Write t_offen = 12.5 s to gate?")
        dialog_button(user, "Write").click()
        await user.should_see("device and project agree (1 project entry)", retries=100)
        assert twin.settings["t_open"] == 1250 and twin.setting_writes == {"t_open": 1}  # written and read back
        rows = await runtime.audit.aquery(limit=50)
        assert any(r.device == "gate" and r.action == "restore" and r.parameter == "t_offen" for r in rows)


async def test_restore_names_each_setting_and_asks_before_force_monitoring_is_cleared(tmp_path):
    runtime = Runtime(parse_plant(plant_text(mo64_tcp("gate"))), simulate=True, data_dir=tmp_path / "data")
    await runtime.start()
    try:
        await _online(runtime, "gate")
        twin = runtime.twins["gate"]
        path = await backup.backup_device(runtime, "gate")
        document = _changed(json.loads(path.read_text()), Kraftüberwachung="ohne", t_offen=12)
        plan = await backup.plan_restore(runtime, "gate", document)
        changed = {r.name: r for r in plan.rows if r.changed}
        assert set(changed) == {"Kraftüberwachung", "t_offen"}
        assert (changed["Kraftüberwachung"].current_text, changed["Kraftüberwachung"].backup_text) == (
            "Stopp und öffnen (1)", "ohne (0)")
        assert KRAFT_RISK in changed["Kraftüberwachung"].risk and not changed["t_offen"].risk
        keys = {r.key for r in changed.values()}
        report = await backup.execute_restore(runtime, plan, keys, user="anna", role="engineer")
        assert report.written == ["t_offen"] and [n for n, _ in report.refused] == ["Kraftüberwachung"]
        assert "Kraftüberwachung" in report.refused[0][1] and _force_bits(twin) == 1  # not written
        plan = await backup.plan_restore(runtime, "gate", document)
        report = await backup.execute_restore(runtime, plan, {KRAFT.key}, user="anna", role="engineer",
                                              confirmed={KRAFT.key})
        assert report.ok and report.written == ["Kraftüberwachung"], report.summary()
        assert _force_bits(twin) == 0 and twin.settings["t_open"] == 1200
    finally:
        await asyncio.wait_for(runtime.stop(), 15)


async def test_a_batch_sets_one_setting_on_both_rs485_barriers_and_asks_for_force_monitoring(tmp_path):
    # the demo plant's two barriers on its shared RS485 line (another master passes the token)
    runtime = Runtime(demo_plant(("barrier-out-1", "barrier-out-2")), simulate=True, data_dir=tmp_path / "data")
    await runtime.start()
    try:
        await _online(runtime, "barrier-out-1", "barrier-out-2", settings=False)  # the backup reads them
        path = await backup.backup_device(runtime, "barrier-out-1")
        source = tmp_path / "set.json"
        source.write_text(json.dumps(_changed(json.loads(path.read_text()), t_offen=12.5)))
        plan = await batch.plan_batch(runtime, ["barrier-out-1", "barrier-out-2"], str(source))
        assert plan.ready, [d.error for d in plan.devices]
        assert [[r.name for r in d.changed] for d in plan.devices] == [["t_offen"], ["t_offen"]]
        seen = []
        results = await batch.apply_batch(runtime, plan, user="anna", role="engineer", on_device=seen.append)
        assert [(r.device, r.status) for r in results] == [("barrier-out-1", "written"), ("barrier-out-2", "written")], \
            [r.text for r in results]
        assert seen == results and all("1 written" in r.text for r in results)
        assert all(runtime.twins[n].settings["t_open"] == 1250 for n in ("barrier-out-1", "barrier-out-2"))

        source.write_text(json.dumps(_changed(json.loads(path.read_text()), t_offen=12.5, Kraftüberwachung="ohne")))
        plan = await batch.plan_batch(runtime, ["barrier-out-1", "barrier-out-2"], str(source))
        rows = [r for d in plan.devices for r in d.changed]
        assert [r.name for r in rows] == ["Kraftüberwachung", "Kraftüberwachung"] and all(KRAFT_RISK in r.risk for r in rows)
        results = await batch.apply_batch(runtime, plan, user="anna", role="engineer")
        assert [r.status for r in results] == ["failed", "skipped"] and "Kraftüberwachung" in results[0].text
        assert _force_bits(runtime.twins["barrier-out-1"]) == 1
        plan = await batch.plan_batch(runtime, ["barrier-out-1", "barrier-out-2"], str(source))
        results = await batch.apply_batch(runtime, plan, user="anna", role="engineer", confirmed={"Kraftüberwachung"})
        assert [r.status for r in results] == ["written", "written"], [r.text for r in results]
        assert all(_force_bits(runtime.twins[n]) == 0 for n in ("barrier-out-1", "barrier-out-2"))
    finally:
        await asyncio.wait_for(runtime.stop(), 15)


async def test_drift_of_a_changed_setting_and_the_page_asks_before_force_monitoring_is_cleared(tmp_path):
    runtime = Runtime(parse_plant(plant_text(mo64_tcp("gate"))), simulate=True, data_dir=tmp_path / "data")
    async with simulated_user(runtime) as user:
        await _online(runtime, "gate")
        state, twin = runtime.store.devices["gate"], runtime.twins["gate"]
        await runtime.record.approve("gate", user="anna", role="engineer")

        async def drift() -> dict:
            return next(d for d in (await user.http_client.get("/api/devices")).json() if d["name"] == "gate")["drift"]
        assert (await drift()) == {"approved": True, "changed": []}
        await runtime.worker.gate.run(lambda: runtime.worker.adapters["gate"].write_param(T_OPEN, 12.5),
                                      device="gate", user="anna", describe="write", role="engineer")
        await eventually(lambda: state.drift["changed"], timeout=5, what="drift")
        assert (await drift())["changed"] == [{"key": "t_open:0", "name": "t_offen", "approved": "10 s", "now": "12.5 s"}]

        await user.open("/device/gate")
        await eventually(lambda: by_testid(user, "piece-write").enabled, timeout=10, what="Write enabled")
        by_testid(user, "piece-param").value = KRAFT.key
        by_testid(user, "piece-value").value = "ohne"
        UserInteraction(user, {by_testid(user, "piece-write")}, None).click()
        await user.should_see("Kraftüberwachung (force monitoring) = ohne switches the force monitoring off")
        assert _force_bits(twin) == 1  # asked first, nothing sent
        dialog_button(user, "Write anyway").click()
        await eventually(lambda: _force_bits(twin) == 0, timeout=10, what="force monitoring off in the barrier")
        await eventually(lambda: any(r["key"] == KRAFT.key for r in state.drift["changed"]), timeout=5,
                         what="drift of the flag")

        # the replacement assistant: the approved set against the unit, by name, the flag's question included
        rp = await replace.plan_replacement(runtime, "gate")
        assert rp.check.ok and not rp.check.lacks and not rp.check.adds
        rows = {r.name: r for r in rp.plan.rows if r.changed}
        assert set(rows) == {"t_offen", "Kraftüberwachung"}
        assert (rows["t_offen"].current_text, rows["t_offen"].backup_text) == ("12.5 s", "10 s")
        assert not rows["Kraftüberwachung"].risk  # back on: asks nothing
        report = await replace.execute_replacement(runtime, rp, {r.key for r in rows.values()}, user="anna",
                                                   role="engineer")
        assert report.ok and sorted(report.written) == ["Kraftüberwachung", "t_offen"], report.summary()
        assert _force_bits(twin) == 1 and twin.settings["t_open"] == 1000
        await eventually(lambda: not state.drift["changed"], timeout=5, what="no drift after the replacement")


async def test_the_demo_plants_barriers_name_a_project_whose_difference_is_applied(tmp_path):
    runtime = Runtime(demo_plant(("barrier-in", "barrier-out-1", "barrier-out-2")), simulate=True,
                      data_dir=tmp_path / "data")
    await runtime.start()
    try:
        await _online(runtime, "barrier-in", "barrier-out-1", "barrier-out-2", settings=False)  # the plans read them
        plan = await backup.plan_restore(runtime, "barrier-in", project.document(runtime, "barrier-in"))
        assert [(r.name, r.current_text, r.backup_text) for r in plan.rows if r.changed] == [("t_offen", "10 s", "12.5 s")]
        report = await backup.execute_restore(runtime, plan, {"t_open:0"}, user="anna", role="engineer")
        assert report.ok and runtime.twins["barrier-in"].settings["t_open"] == 1250
        # each RS485 barrier's own project, in one batch
        plan = await batch.plan_batch(runtime, ["barrier-out-1", "barrier-out-2"], "project")
        assert plan.ready, [d.error for d in plan.devices]
        assert [[r.backup_text for r in d.changed] for d in plan.devices] == [["8 s"], ["8 s"]]
        results = await batch.apply_batch(runtime, plan, user="anna", role="engineer")
        assert [r.status for r in results] == ["written", "written"], [r.text for r in results]
        assert all(runtime.twins[n].settings["t_open"] == 800 for n in ("barrier-out-1", "barrier-out-2"))
    finally:
        await asyncio.wait_for(runtime.stop(), 15)
