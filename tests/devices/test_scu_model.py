"""The SCU's parameter model (devices/scu/model.py) and its paths through app/: backup with names and units,
restore, the offline project and `commission check`, batch apply with identity gates, drift and the replacement
assistant, each against the twin (two simulated units on their own RS232 lines); the twin's strict modes for what a
real unit does differently (refused data IDs, a reset that loses the volatile remote data)."""

from __future__ import annotations

import asyncio

import pytest
from conftest import alive, running_plant, wait_for
from plants import SCU_ACTUATORS, bus, device, free_port, plant, plant_text

from app import backup, batch, project, replace
from app.plant import parse_plant
from app.gate import PermissionDenied
from app.runtime import Runtime
from devices.commands import WRITE_PARAMETER
from devices.params import Access
from devices.scu.model import PARAMS, SAFETY_ID, SETTINGS, params_for

pytestmark = pytest.mark.timeout(120)

SPEED_F1 = PARAMS.by_name["Remote Speed F1"]
SPEED_F2 = PARAMS.by_name["Remote Speed F2"]
POSITION_A1 = PARAMS.by_name["Remote Position A1"]


# -- the model (pure) ----------------------------------------------------------------------------------------------
def test_the_model_names_the_writable_remote_data_as_settings_and_the_rest_read_only():
    assert len(PARAMS.params) == 35  # 10 speeds, 6 positions, 6 factors, 12 virtual limits, Safety_ID
    assert [q.name for q in SETTINGS] == [f"Remote Speed F{n}" for n in range(1, 11)] + [
        f"Remote Position A{n}" for n in range(1, 7)]
    assert SPEED_F1.key == "data:12305" and SPEED_F1.unit == "% or counts/s" and SPEED_F1.limits() == (0, 1000)
    assert POSITION_A1.writable and POSITION_A1.setting and POSITION_A1.limits() == (-(2 ** 31), 2 ** 31 - 1)
    assert POSITION_A1.display(POSITION_A1.validate(-250)) == "-250 counts"
    factor = PARAMS.by_name["Conversion factor A1"]
    assert factor.access is Access.RO and not factor.setting and factor.display(factor.encode(12.5)) == "12.5 counts/mm"
    limit = PARAMS.by_name["Position_Virtual_Limit_Out A2"]
    assert limit.key == "limit_out:8194" and not limit.writable
    assert not SAFETY_ID.writable and SAFETY_ID.display(2) == "stop remote (2)"
    assert all("0x3001" not in q.description for q in PARAMS)  # the cyclic objects are the tool's own, no setting
    with pytest.raises(ValueError, match="outside 0 .. 1000"):
        SPEED_F1.validate(1001)
    with pytest.raises(ValueError, match="cannot be written"):
        factor.validate(10)
    assert len(params_for(2)) == 10 + 2 * 4 + 1  # the speeds of every function, the values of two actuators


# -- against the twin ------------------------------------------------------------------------------------------------
def _unit(name: str, bus_name: str, **options) -> str:
    """A simulated SCU with two actuators on an RS232 line of its own (``options``: the device's)."""
    return bus(bus_name, "serial", device(name, "scu", bus_name, actuators=list(SCU_ACTUATORS), **options),
               port=f"socket://127.0.0.1:{free_port()}", timeout=0.3, poll_period=0.2, simulate=True)


def _two_units(project_a: str = "") -> str:
    a = _unit("lift-a", "rs-a", serial="A-1001")
    if project_a:
        a = a.replace('serial = "A-1001"', f'serial = "A-1001"\nproject = {{ {project_a} }}')
    return plant_text(a, _unit("lift-b", "rs-b", serial="B-1002"), name="lifts")


@pytest.fixture
async def lifts(tmp_path):
    path = tmp_path / "plant.toml"
    path.write_text(_two_units('"Remote Speed F1" = 60'))
    from app.plant import load_plant

    async with running_plant(load_plant(path), tmp_path / "data", ready=("lift-a", "lift-b"), within_s=20) as runtime:
        yield runtime


async def test_backup_names_every_value_and_restore_writes_the_settings_back_read_back(lifts, tmp_path):
    runtime = lifts
    twin = runtime.twins["lift-a"]
    document = backup.load_document((await backup.backup_device(runtime, "lift-a", tmp_path)).read_bytes())
    entries = {e["key"]: e for e in document["parameters"]}
    assert {k: entries["data:12305"][k] for k in ("name", "raw", "text", "writable", "setting")} == {
        "name": "Remote Speed F1", "raw": 100, "text": "100 % or counts/s", "writable": True, "setting": True}
    assert entries["data:4113"]["name"] == "Conversion factor A1" and not entries["data:4113"]["writable"]
    assert entries["limit_out:8194"]["text"] == "3750 counts"  # A2: 300 mm stroke at 12.5 counts/mm
    assert entries["session:0"]["text"] == "stop all (1)"
    assert "data:12323" not in entries  # A3 is not configured on this unit
    assert entries["0x0001"]["text"].startswith("SCU V2B3")  # the record entries stay, never written
    assert document["identity"]["serial"] == "A-1001"
    assert document["identity"]["configuration"].startswith("SCP11")

    adapter = runtime.worker.adapters["lift-a"]
    await runtime.worker.gate.run(lambda: runtime.worker.adapters["lift-a"].write_param(SPEED_F2, 40),
                                  device="lift-a", user="anna", describe="write", role="engineer")
    await runtime.worker.gate.run(lambda: runtime.worker.adapters["lift-a"].write_param(POSITION_A1, 1234),
                                  device="lift-a", user="anna", describe="write", role="engineer")
    assert twin.remote_speed[1] == 40 and twin.remote_position[0] == 1234
    assert adapter.state.raw(SPEED_F2) == 40 and adapter.state.raw(POSITION_A1) == 1234

    plan = await backup.plan_restore(runtime, "lift-a", document)
    changed = {r.name: (r.current_text, r.backup_text) for r in plan.rows if r.changed}
    assert changed == {"Remote Speed F2": ("40 % or counts/s", "100 % or counts/s"),
                       "Remote Position A1": ("1234 counts", "600 counts")}
    assert not plan.warnings and {r.name for r in plan.rows} == {q.name for q in params_for(2) if q.setting}
    report = await backup.execute_restore(runtime, plan, {r.key for r in plan.rows}, user="anna", role="engineer")
    assert report.ok and sorted(report.written) == ["Remote Position A1", "Remote Speed F2"], report.summary()
    assert report.saved is None  # volatile remote data: nothing to save (table 7)
    assert twin.remote_speed[1] == 100 and twin.remote_position[0] == 600  # Memory 1 of User 1
    rows = await runtime.audit.aquery(limit=20)
    assert any(r.action == "restore" and r.parameter == "Remote Speed F2" and r.new == "100 % or counts/s" for r in rows)


async def test_a_write_is_refused_beyond_the_speed_select_while_a_function_runs_and_for_a_refused_data_id(lifts):
    runtime = lifts
    twin, adapter = runtime.twins["lift-a"], runtime.worker.adapters["lift-a"]
    with pytest.raises(Exception, match="above 100 %: the unit's speed select is relative"):
        await adapter.write_param(SPEED_F1, 500)
    assert twin.remote_speed[0] == 100
    # a function runs: a remote speed would change its motion (section 4.6)
    async with alive(runtime.worker, "s1"):  # the browser of s1 is alive (the worker's dead-man supervisor)
        await runtime.worker.gate.invoke("lift-a", "take control", session="s1", user="anna", role="engineer")
        await runtime.worker.gate.invoke("lift-a", "jog (RE)", {"function": 0, "direction": 1, "ramp": 1}, session="s1",
                                         user="anna", role="engineer")
        with pytest.raises(Exception, match="F1 .* runs or its stop is owed"):
            await adapter.write_param(SPEED_F1, 50)
        await runtime.worker.gate.invoke("lift-a", "jog stop (RS)", {"function": 0}, session="s1", user="anna", role="engineer")
        await runtime.worker.gate.invoke("lift-a", "release control", session="s1", user="anna", role="engineer")
    assert twin.remote_speed[0] == 100
    # strict mode: the unit's parametrisation has no F2 (its remote speed answers PDE)
    twin.strict.refused_ids = {0x3012}
    with pytest.raises(Exception, match="PDE"):
        await adapter.write_param(SPEED_F2, 50)
    entries = {e["key"] for e in await adapter.backup_read()}  # the group read refused: member by member
    assert SPEED_F1.key in entries and SPEED_F2.key not in entries
    assert adapter.settings.refused[SPEED_F2.key] == "PDE: the unit refuses RG 0x3012"
    twin.strict.refused_ids = set()
    twin.strict.single_ids_only = True  # groups refused (the document describes 0x0010 alone): read member by member
    entries = {e["key"]: e for e in await adapter.backup_read()}
    assert entries[SPEED_F2.key]["raw"] == 100 and entries["limit_out:8194"]["raw"] == 3750


async def test_project_check_and_the_page_diff_apply_per_row(lifts, tmp_path):
    runtime = lifts
    twin = runtime.twins["lift-a"]
    assert project.check_plant(runtime.plant) == []
    [entry] = project.entries(runtime.plant, "lift-a")
    assert (entry.name, entry.param.key, entry.error) == ("Remote Speed F1", "data:12305", "")
    wrong = parse_plant(_two_units('"Remote Speed F1" = 1200, "Conversion factor A1" = 10'))
    problems = " ".join(project.check_plant(wrong))
    assert "outside 0 .. 1000" in problems and "Conversion factor A1" in problems
    assert [p.name for p in project.editable(runtime.plant, "lift-b")] == [q.name for q in SETTINGS]

    plan = await backup.plan_restore(runtime, "lift-a", project.document(runtime, "lift-a"))
    [row] = [r for r in plan.rows if r.changed]
    assert (row.name, row.current_text, row.backup_text) == ("Remote Speed F1", "100 % or counts/s", "60 % or counts/s")
    report = await backup.execute_restore(runtime, plan, {row.key}, user="anna", role="engineer")
    assert report.ok and twin.remote_speed[0] == 60


async def test_batch_sets_one_setting_on_both_units_and_reports_each(lifts, tmp_path):
    runtime = lifts
    adapter = runtime.worker.adapters["lift-a"]
    await adapter.write_param(SPEED_F2, 35)
    plan = await batch.plan_batch(runtime, ["lift-a", "lift-b"], "device:lift-a")
    assert plan.ready, [d.error for d in plan.devices]
    assert [(d.device, [r.name for r in d.changed]) for d in plan.devices] == [
        ("lift-a", []), ("lift-b", ["Remote Speed F2"])]
    assert all(d.check.ok for d in plan.devices)
    results = await batch.apply_batch(runtime, plan, user="anna", role="engineer")
    assert [(r.device, r.status) for r in results] == [("lift-a", batch.UNCHANGED), ("lift-b", batch.WRITTEN)]
    assert runtime.twins["lift-b"].remote_speed[1] == 35


async def test_drift_after_a_reset_and_the_replacement_assistant_writes_the_approved_set_back(lifts):
    runtime = lifts
    twin, state = runtime.twins["lift-a"], runtime.store.devices["lift-a"]
    await runtime.worker.adapters["lift-a"].write_param(SPEED_F2, 55)
    await runtime.record.approve("lift-a", user="anna", role="engineer")
    assert state.drift == {"approved": True, "changed": []}
    twin.reset()  # the unit's remote data are back at their defaults (table 7): the poll's reads in turn see it
    assert await wait_for(lambda: state.drift["changed"], 30)
    assert state.drift["changed"] == [{"key": "data:12306", "name": "Remote Speed F2", "approved": "55 % or counts/s",
                                       "now": "100 % or counts/s"}]
    rp = await replace.plan_replacement(runtime, "lift-a")
    assert rp.check.ok and [r.name for r in rp.plan.rows if r.changed] == ["Remote Speed F2"]
    report = await replace.execute_replacement(runtime, rp, {r.key for r in rp.plan.rows if r.changed}, user="anna",
                                               role="engineer")
    assert report.ok and twin.remote_speed[1] == 55
    assert await wait_for(lambda: not state.drift["changed"], 30)


async def test_the_declared_write_goes_through_the_gate_for_a_viewer_it_is_refused(lifts):
    runtime = lifts
    with pytest.raises(PermissionDenied):
        await runtime.worker.gate.invoke("lift-a", WRITE_PARAMETER, {"param": SPEED_F1.key, "value": 20}, user="tab",
                                         role="viewer")
    await runtime.worker.gate.invoke("lift-a", WRITE_PARAMETER, {"param": SPEED_F1.key, "value": 20}, user="anna",
                                     role="engineer")
    assert runtime.twins["lift-a"].remote_speed[0] == 20


def test_serial_is_a_known_key():
    assert plant(_unit("lift", "rs1", serial=7)).devices["lift"].options["serial"] == 7


def test_commission_check_names_an_scu_project_entry_the_model_refuses(tmp_path):
    import json
    import subprocess
    import sys

    from devices.params import backup_entry

    # a parameter file in the backup format (a backup of another unit will do): its read-only entries are ignored
    entries = [backup_entry(q, q.validate(70) if q.name == "Remote Speed F2" else q.encode(0)) for q in params_for(2)]
    document = backup.make_document("lifts", "lift-b", "scu", "rs-b", {"serial": "B-1002"}, entries)
    (tmp_path / "lift-b.json").write_text(json.dumps(document, indent=2))
    bad = _two_units('"Remote Speed F1" = 1200, "Position_Virtual_Limit_In A1" = 10')
    bad = bad.replace('serial = "B-1002"', 'serial = "B-1002"\nproject = "lift-b.json"')
    path = tmp_path / "plant.toml"
    path.write_text(bad)
    out = subprocess.run([sys.executable, "-m", "app.cli", "check", "--plant", str(path)], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 1, out.stdout + out.stderr
    assert "device 'lift-a': Remote Speed F1: 1200 is outside 0 .. 1000 % or counts/s" in out.stdout
    assert "device 'lift-a': Position_Virtual_Limit_In A1 is RO and cannot be written" in out.stdout
    path.write_text(bad.replace('"Remote Speed F1" = 1200, "Position_Virtual_Limit_In A1" = 10', '"Remote Speed F1" = 80'))
    from app.plant import load_plant

    good = load_plant(path)
    assert project.check_plant(good) == []  # the parameter file and the inline table alike
    assert [(e.name, e.value) for e in project.entries(good, "lift-b") if e.value != 0] == [("Remote Speed F2", 70)]


async def test_on_the_demo_plant_lift_1s_project_differs_applies_and_a_reset_shows_as_drift(tmp_path):
    from webutil import private_endpoints

    from app.plant import DEMO_PLANT, load_plant

    demo = private_endpoints(load_plant(DEMO_PLANT), tmp_path.name)
    assert project.check_plant(demo) == []
    runtime = Runtime(demo, simulate=True, data_dir=tmp_path / "data")
    await runtime.start()
    try:
        twin, state = runtime.twins["lift-1"], runtime.store.devices["lift-1"]
        assert await wait_for(lambda: state.status == "online", timeout=20)
        plan = await backup.plan_restore(runtime, "lift-1", project.document(runtime, "lift-1"))
        assert [(r.name, r.current_text, r.backup_text) for r in plan.rows if r.changed] == [
            ("Remote Speed F1", "100 % or counts/s", "60 % or counts/s")]
        report = await backup.execute_restore(runtime, plan, {r.key for r in plan.rows}, user="anna", role="engineer")
        assert report.ok and twin.remote_speed[0] == 60
        await runtime.record.approve("lift-1", user="anna", role="engineer")
        twin.reset()
        assert await wait_for(lambda: state.drift["changed"], 30)
        assert [(r["name"], r["approved"], r["now"]) for r in state.drift["changed"]] == [
            ("Remote Speed F1", "60 % or counts/s", "100 % or counts/s")]
    finally:
        await asyncio.wait_for(runtime.stop(), 5)


def test_the_twins_strict_modes_refused_data_ids_a_reset_and_the_speed_select():
    from devices.scu import codec
    from devices.scu import params as p
    from devices.scu.sim import ScuTwin

    twin = ScuTwin("lift", 2)

    def ask(frame: bytes) -> codec.Answer:
        return codec.decode_answer(twin.handle(codec.decode_request(frame), now=1.0), frame[:2])

    assert ask(codec.encode_ro(codec.SafetyId.STOP_ALL)).ok and ask(codec.KEEP_ALIVE).ok
    assert ask(p.rt_frame(0x3012, 40)).ok and twin.remote_speed[1] == 40
    assert ask(p.rt_frame(0x3012, 101)).status == codec.Status.PDE  # relative: 0 .. 100 % (table 7)
    assert ask(p.rt_frame(0x3023, 5)).status == codec.Status.PDE  # A3: no such actuator on this unit
    twin.strict.refused_ids = {0x3012}  # the unit's parametrisation has no F2
    assert ask(codec.encode_rg(0x3012)).status == codec.Status.PDE
    assert ask(codec.encode_rg(0x3010)).status == codec.Status.PDE  # a group holding it too
    assert ask(p.rt_frame(0x3012, 50)).status == codec.Status.PDE and twin.remote_speed[1] == 40
    assert p.rg_value(0x3011, ask(codec.encode_rg(0x3011))) == 100
    twin.reset()  # volatile remote data back at their defaults, remote mode ended (table 7)
    assert twin.remote_speed[1] == 100 and twin.remote_position == [600, 600] and not twin.remote
    assert ask(codec.encode_rg(0x3011)).status == codec.Status.PE
    absolute = ScuTwin("lift", 1, speed_select="absolute")
    absolute.remote, absolute.rc_seen = True, True
    assert absolute.write(0x3011, (1000).to_bytes(2, "little")) == codec.Status.ACK and absolute.remote_speed[0] == 1000


async def test_a_unit_watched_with_rg_alone_gets_a_session_for_the_write_and_closes_it_after(lifts):
    runtime = lifts
    twin, adapter = runtime.twins["lift-b"], runtime.worker.adapters["lift-b"]
    twin.strict.rg_outside_session = True  # it answers RG outside remote mode: watched with RG, no session while idle
    adapter.watch = None  # asked again at the next poll
    assert await wait_for(lambda: adapter.watch == "rg" and adapter.session == "closed", 20), adapter.session
    assert {e["key"] for e in await adapter.backup_read()} >= {q.key for q in params_for(2)}  # read without a session
    assert adapter.session == "closed"
    await runtime.worker.gate.invoke("lift-b", WRITE_PARAMETER, {"param": SPEED_F2.key, "value": 45}, user="anna",
                                     role="engineer")
    assert twin.remote_speed[1] == 45
    assert await wait_for(lambda: adapter.session == "closed" and not twin.remote, 20)  # RA once nobody needs it
