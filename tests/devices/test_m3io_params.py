"""The CAN-M3IO parameter model (devices/m3io/params.py) and every generic path on it, against the twin on
python-can's virtual bus: a project's difference applied per row, batch apply to two modules, drift in
/api/devices and on the overview, backup and restore with P2's confirmation, P2 kept in the plant file across
a restart, and the twin's strict modes (a firmware before 17.0 without P2, a slow record store)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import wait_for
from plants import can_bus, device, plant_text
from webutil import simulated_user

from app import backup, batch, gate, project
from app.plant import PlantError, load_plant, parse_plant
from app.runtime import Runtime
from devices.commands import WRITE_PARAMETER
from devices.m3io import codec, policy
from devices.m3io.params import P2_PARAM, P2_RISK, PARAMS, SW1_PARAM, describe_sw1, record_param
from devices.params import ParamError, backup_entry
from devices.sendpolicy import BusDevice

pytestmark = pytest.mark.timeout(60)


# -- the model, pure ------------------------------------------------------------------------------------------


def test_the_model_names_every_setting_the_document_gives():
    settings = [p for p in PARAMS if p.setting]
    assert [p.key for p in settings] == [*(f"customer:{i}" for i in range(1, 16)), "cfg:7"]
    assert {p.key for p in PARAMS if not p.writable} == {"config:1", "config:2", "config:3", "config:15", "sw1:0"}


def test_a_customer_record_is_six_bytes_padded_with_ff():
    """7.2.4.2.4: a record written with fewer bytes is padded with 0xFF to 6; an unwritten one reads ff x 6."""
    record = record_param(3)
    raw = record.validate("01 02 0A")
    assert raw == 0x01020AFFFFFF and record.display(raw) == "01 02 0a ff ff ff" == record.decode(raw)
    assert record.validate(record.decode(raw)) == raw and record.validate(raw) == raw
    assert record.validate("0x01020a") == raw and record.validate(b"\x01\x02\x0a") == raw
    for bad, why in (("01 02 03 04 05 06 07", "holds 6 bytes"), ("zz", "not bytes as hex"), ("", "no bytes given"),
                     (True, "not bytes")):
        with pytest.raises(ParamError, match=why):
            record.validate(bad)
    assert project.allowed(record) == "1 to 6 bytes as hex, e.g. 01 02 0a (padded with ff to 6 bytes)"
    assert project.parse_value(record, "aa bb") == "aa bb ff ff ff ff"
    with pytest.raises(ParamError, match="outside 1..15"):
        record_param(16)


def test_p2_on_asks_first_and_names_what_it_switches_off():
    assert P2_PARAM.prepare_write(0) == 0 and P2_PARAM.validate("two-phase load (P2)") == 1
    with pytest.raises(ParamError, match="needs confirmation: P2 on: .* no longer switched off as a fault"):
        P2_PARAM.prepare_write(1)
    assert P2_PARAM.prepare_write(1, confirmed=True) == 1
    with pytest.raises(ParamError, match="not one of"):
        P2_PARAM.validate(2)


def test_sw1_is_shown_as_the_document_reads_it():
    """5.8.1 and 5.8.2, with the document's two examples."""
    assert describe_sw1(0x1A) == "0x1A: offset 26 (base 0x3A0 + 5 x offset), 500 kbit/s, DigOut 0x422"
    assert SW1_PARAM.display(0xCA) == ("0xCA: addressed mode, module address 10, 500 kbit/s, function IDs of S7 on, "
                                       "DigOut 0x20A")
    with pytest.raises(ParamError, match="cannot be written"):
        SW1_PARAM.validate(0x1A)


def test_a_raw_sync_that_sets_p2_asks_what_the_declared_write_asks():
    hmr = [BusDevice("io", "m3io", {"sw1": 0xCA, "variant": "HMR"})]
    ids = codec.derive_ids(0xCA)
    assert policy.check_can(ids.sync, False, b"\x80", hmr).confirm == (P2_RISK,)
    assert P2_RISK in policy.check_can(ids.sync, False, bytes([1, 15, 0x80]), hmr).confirm
    assert P2_RISK not in policy.check_can(ids.sync, False, bytes([1, 15, 0x00]), hmr).confirm
    assert policy.check_can(ids.sync, False, b"\x00", hmr).confirm == ()


def test_p2_in_the_plant_file_is_checked():
    with pytest.raises(PlantError, match="p2 = true exists on the HMR only"):
        parse_plant(plant_text(can_bus(device("io", "m3io", "can1", variant="HM", sw1=0x1A, p2=True))))
    with pytest.raises(PlantError, match="true or false"):
        parse_plant(plant_text(can_bus(device("io", "m3io", "can1", variant="HMR", sw1=0x1A, p2=1))))


def test_commission_check_names_a_bad_record_and_an_unknown_one_without_the_device():
    text = plant_text(can_bus(device("io", "m3io", "can1", variant="HMR", sw1=0xCA))).replace(
        'name = "io"', 'name = "io"\nproject = { "Customer data 3" = "zz", "Customer data 16" = "01", P2 = 2 }')
    problems = project.check_plant(parse_plant(text))
    assert any("Customer data 3: 'zz' is not bytes as hex" in p for p in problems), problems
    assert any("unknown parameter 'Customer data 16'" in p for p in problems), problems
    assert any("P2: 2 is not one of: 0 three-phase load, 1 two-phase load (P2)" in p for p in problems), problems
    assert all(p.startswith("<plant>:") or ".toml:" in p for p in problems)


def test_the_plant_file_keeps_p2_with_its_comments_and_project_table(tmp_path):
    from app.plant_options import keep_device_options, set_device_options

    path = tmp_path / "plant.toml"
    path.write_text(plant_text(can_bus(device("io", "m3io", "can1", variant="HMR", sw1=0xCA), name="can1"))
                    + '# the heater of line 2\n[device.project]\n"Customer data 1" = "01"\n')
    plant = load_plant(path)
    assert keep_device_options(plant, "io", {"p2": True}) == "p2 = true kept in the plant file plant.toml"
    assert plant.devices["io"].options["p2"] is True and keep_device_options(plant, "io", {"p2": True}) == ""
    text = path.read_text()
    assert text.index("p2 = true") < text.index("[device.project]") and "# the heater of line 2" in text
    assert load_plant(path).devices["io"].project == {"Customer data 1": "01"}
    assert set_device_options(path, "io", {"p2": False}) and "p2 = false" in path.read_text()
    assert "p2 = true" not in path.read_text()
    with pytest.raises(PlantError, match="names no device 'other'"):
        set_device_options(path, "other", {"p2": True})


# -- against the twins ------------------------------------------------------------------------------------------


def _plant_file(tmp_path: Path, project_a: str = "", **options_b) -> Path:
    """Two addressed HMR modules and a simple-mode HM on one virtual CAN bus, served by this tool (master = always)."""
    text = plant_text(can_bus(
        device("io-a", "m3io", "can1", variant="HMR", sw1=0xCA, serial=42120023, master="always"),
        device("io-b", "m3io", "can1", variant="HMR", sw1=0xCB, serial=42120024, master="always", **options_b),
        device("io-c", "m3io", "can1", variant="HM", sw1=0x1A, master="always"),
        bitrate=500_000, poll_period=0.2), name="m3io-params")
    if project_a:
        text = text.replace('name = "io-a"', f'name = "io-a"\nproject = {{ {project_a} }}', 1)
    path = tmp_path / "plant.toml"
    path.write_text(text)
    return path


async def _started(path: Path, tmp_path: Path, names=("io-a", "io-b", "io-c")) -> Runtime:
    runtime = Runtime(load_plant(path), simulate=True, data_dir=tmp_path / "data")
    await runtime.start()
    states = runtime.store.devices
    assert await wait_for(lambda: all(states[n].status == "online" for n in names), 10), {n: states[n].status for n in names}
    # addressed modules read their settings once they answer (for drift and projects)
    assert await wait_for(lambda: all(states[n].raw(record_param(15)) is not None for n in names if n != "io-c"), 10)
    return runtime


async def test_a_project_shows_its_differences_and_applies_them_per_row_and_p2_survives_a_restart(tmp_path):
    path = _plant_file(tmp_path, project_a='"Customer data 3" = "01 02 03", P2 = 1')
    assert project.check_plant(load_plant(path)) == []
    runtime = await _started(path, tmp_path)
    try:
        plan = await backup.plan_restore(runtime, "io-a", project.document(runtime, "io-a"))
        rows = {r.key: r for r in plan.rows}
        assert {k for k, r in rows.items() if r.changed} == {"customer:3", "cfg:7"}
        record, p2 = rows["customer:3"], rows["cfg:7"]
        assert (record.current_text, record.backup_text) == ("ff ff ff ff ff ff", "01 02 03 ff ff ff") and not record.risk
        assert (p2.current_text, p2.backup_text) == ("three-phase load (0)", "two-phase load (P2) (1)") and p2.risk == P2_RISK

        report = await backup.execute_restore(runtime, plan, {"customer:3"}, user="anna")  # one row
        assert report.written == ["Customer data 3"] and report.ok
        assert runtime.twins["io-a"].customer[3] == bytes.fromhex("010203ffffff")
        report = await backup.execute_restore(runtime, plan, {"cfg:7"}, user="anna")  # not confirmed: refused
        assert report.refused and "P2 on" in report.refused[0][1] and not runtime.worker.adapters["io-a"].two_phase
        report = await backup.execute_restore(runtime, plan, {"cfg:7"}, user="anna", confirmed={"cfg:7"})
        assert report.written == ["P2"], report.summary()
        assert runtime.twins["io-a"].cfg & codec.P2  # area 1 index 15, answered and compared
        after = await backup.plan_restore(runtime, "io-a", project.document(runtime, "io-a"))
        assert not any(r.changed for r in after.rows)
        assert load_plant(path).devices["io-a"].options["p2"] is True  # kept in the plant file
        assert "p2 = true" in path.read_text() and 'project = { "Customer data 3" = "01 02 03", P2 = 1 }' in path.read_text()
    finally:
        await runtime.stop()
    runtime = await _started(path, tmp_path)  # a restart: the module forgot P2 (twin reset), the tool did not
    try:
        adapter, state = runtime.worker.adapters["io-a"], runtime.store.devices["io-a"]
        assert adapter.two_phase and state.raw(P2_PARAM) == 1
        assert await wait_for(lambda: runtime.twins["io-a"].cfg & codec.P2, 5)  # sent with the DigOut period
    finally:
        await runtime.stop()


async def test_p2_on_asks_on_the_page_command_and_the_declared_write(tmp_path):
    runtime = await _started(_plant_file(tmp_path), tmp_path)
    try:
        with pytest.raises(gate.NeedsConfirmation, match="P2 on"):
            await runtime.worker.gate.invoke("io-a", "P2", {"on": 1}, user="anna", role="engineer")
        with pytest.raises(gate.NeedsConfirmation, match="P2 on"):
            await runtime.worker.gate.invoke("io-a", WRITE_PARAMETER, {"param": "cfg:7", "value": 1}, user="anna",
                                             role="engineer")
        await runtime.worker.gate.invoke("io-a", "P2", {"on": 0}, user="anna", role="engineer")  # off: no question
        with pytest.raises(Exception, match="HMR only"):
            await runtime.worker.gate.invoke("io-c", WRITE_PARAMETER, {"param": "cfg:7", "value": 0}, user="anna",
                                             role="engineer")
    finally:
        await runtime.stop()


async def test_batch_apply_sets_one_record_on_two_modules_and_reports_each(tmp_path):
    runtime = await _started(_plant_file(tmp_path), tmp_path)
    try:
        source = tmp_path / "set.json"
        param = record_param(5)
        raw = param.validate("aa bb")
        entry = backup_entry(param, raw)
        source.write_text(json.dumps(backup.make_document("m3io-params", "io-a", "m3io", "can1", {}, [entry])))
        plan = await batch.plan_batch(runtime, ["io-a", "io-b"], f"file:{source}")
        assert plan.ready, (plan.errors, [(d.device, d.error) for d in plan.devices])
        results = await batch.apply_batch(runtime, plan, user="anna", role="engineer")
        assert [(r.device, r.status) for r in results] == [("io-a", "written"), ("io-b", "written")]
        for name in ("io-a", "io-b"):
            assert runtime.twins[name].customer[5] == bytes.fromhex("aabbffffffff")
            assert runtime.store.devices[name].raw(param) == raw
        refused = await batch.plan_batch(runtime, ["io-a", "io-c"], f"file:{source}")  # HMR and HM: two variants
        assert any("variants" in e for e in refused.errors)
    finally:
        await runtime.stop()


async def test_drift_of_a_changed_record_on_the_overview_and_in_the_api(tmp_path):
    runtime = Runtime(load_plant(_plant_file(tmp_path)), simulate=True, data_dir=tmp_path / "data")
    async with simulated_user(runtime) as user:
        state = runtime.store.devices["io-a"]
        assert await wait_for(lambda: state.status == "online" and state.raw(record_param(15)) is not None, 10)
        await runtime.record.approve("io-a", user="anna", role="engineer")

        async def drift() -> dict:
            devices = (await user.http_client.get("/api/devices")).json()
            return next(d for d in devices if d["name"] == "io-a")["drift"]

        assert await drift() == {"approved": True, "changed": []}
        await runtime.worker.gate.invoke("io-a", WRITE_PARAMETER, {"param": "Customer data 7", "value": "12 34"},
                                         user="anna", role="engineer")
        assert await wait_for(lambda: state.drift["changed"], 5)
        assert (await drift())["changed"] == [{"key": "customer:7", "name": "Customer data 7",
                                               "approved": "ff ff ff ff ff ff", "now": "12 34 ff ff ff ff"}]
        await user.open("/")
        await user.should_see("changed since approved")


async def test_backup_restore_names_units_and_hm_in_simple_mode_has_nothing(tmp_path):
    runtime = await _started(_plant_file(tmp_path), tmp_path)
    try:
        path = await backup.backup_device(runtime, "io-a", tmp_path / "out")
        document = backup.load_document(path.read_bytes())
        keys = [e["key"] for e in document["parameters"]]
        assert keys[:2] == ["sw1:0", "cfg:7"] and keys[-1] == "customer:15" and len(keys) == 21
        byname = {e["key"]: e for e in document["parameters"]}
        assert byname["config:1"]["text"] == "42120023" and byname["config:2"]["text"] == "0x300A HMR01 (from 08.11.2013)"
        assert byname["customer:1"]["value"] == "ff ff ff ff ff ff" and byname["customer:1"]["setting"]
        assert not byname["config:15"]["writable"] and not byname["sw1:0"]["writable"]
        await runtime.worker.adapters["io-a"].write_param(record_param(1), "01")
        plan = await backup.plan_restore(runtime, "io-a", document)
        assert [(r.name, r.current_text, r.backup_text) for r in plan.rows if r.changed] == [
            ("Customer data 1", "01 ff ff ff ff ff", "ff ff ff ff ff ff")]
        report = await backup.execute_restore(runtime, plan, {r.key for r in plan.rows})
        assert report.written == ["Customer data 1"] and report.ok and runtime.twins["io-a"].customer[1] == b"\xff" * 6
        assert "addressed mode" in await backup.why_nothing_to_back_up(runtime, "io-c")
        # a backup made before the model kept a record's hex text as its raw value: still restored
        old = {**document, "parameters": [{"key": "customer:1", "name": "Customer data 1", "raw": "0a 0b 0c 0d 0e 0f",
                                           "value": "0a 0b 0c 0d 0e 0f", "writable": True}]}
        plan = await backup.plan_restore(runtime, "io-a", old)
        assert [(r.error, r.backup_text, r.changed) for r in plan.rows] == [("", "0a 0b 0c 0d 0e 0f", True)]
    finally:
        await runtime.stop()


async def test_strict_twin_without_p2_and_with_a_slow_store(tmp_path):
    """A firmware before 17.0 ignores area 1 index 15 (section 4.3, 7.2.4.2): the write says so; a record store slower
    than an ordinary request's wait is still awaited and verified (7.2.4.2.4)."""
    runtime = await _started(_plant_file(tmp_path, firmware=0x1000, store_s=0.8), tmp_path)
    try:
        adapter = runtime.worker.adapters["io-b"]
        with pytest.raises(Exception, match="firmware before 17.0"):
            await adapter.write_param(P2_PARAM, 1, confirmed=True)
        assert not runtime.twins["io-b"].cfg & codec.P2
        stored = await adapter.write_param(record_param(2), "0b 0c")
        assert stored == record_param(2).validate("0b 0c") and runtime.twins["io-b"].customer[2][:2] == b"\x0b\x0c"
    finally:
        await runtime.stop()


async def test_the_replacement_assistant_restores_the_approved_records_on_a_new_module(tmp_path):
    """A module exchanged (off the bus, back with another serial number and empty records, P2 forgotten): the new
    identity is read when it answers again, and the approved set is restored through restore's verified write."""
    from app import replace

    runtime = await _started(_plant_file(tmp_path), tmp_path)
    try:
        adapter, state, twin = runtime.worker.adapters["io-a"], runtime.store.devices["io-a"], runtime.twins["io-a"]
        await adapter.write_param(record_param(1), "01 02")
        await adapter.read_identity()
        await runtime.record.approve("io-a", user="anna", role="engineer")
        twin.powered = False  # taken off the bus
        assert await wait_for(lambda: state.status == "offline", 6)
        twin.serial, twin.customer, twin.powered = 42120099, {}, True  # the new module
        twin.power_cycle()
        assert await wait_for(lambda: getattr(state, "replaced", None), 10)
        assert state.replaced["differs"] == ["serial"]
        assert await wait_for(lambda: state.raw(record_param(1)) == record_param(1).validate("ff"), 5)  # read again
        rp = await replace.plan_replacement(runtime, "io-a")
        assert rp.check.ok and any("serial number 42120023 -> 42120099" in n for n in rp.check.notes), rp.check.notes
        changed = [r for r in rp.plan.rows if r.changed]
        assert [(r.name, r.current_text, r.backup_text) for r in changed] == [
            ("Customer data 1", "ff ff ff ff ff ff", "01 02 ff ff ff ff")]
        report = await replace.execute_replacement(runtime, rp, {r.key for r in changed}, user="anna", role="engineer")
        assert report.ok and report.written == ["Customer data 1"] and twin.customer[1] == bytes.fromhex("0102ffffffff")
    finally:
        await runtime.stop()


async def test_p2_switched_off_while_not_served_is_sent_off_when_served_again(tmp_path):
    """Simple mode (no read-back): the module holds P2 until a reset (7.2.4), so P2 off set while this tool did not
    serve it goes out as cfg 0 once it does, or the module would go on accepting two loaded phases."""
    path = tmp_path / "plant.toml"
    path.write_text(plant_text(can_bus(device("io", "m3io", "can1", variant="HMR", sw1=0x1B), name="can1",
                                       bitrate=500_000, poll_period=0.2), name="simple"))
    runtime = Runtime(load_plant(path), simulate=True, data_dir=tmp_path / "data")
    await runtime.start()
    try:
        adapter, twin = runtime.worker.adapters["io"], runtime.twins["io"]
        await adapter.take_control("s1", "anna")
        await adapter.write_param(P2_PARAM, 1, confirmed=True)
        assert await wait_for(lambda: twin.cfg & codec.P2, 3)
        adapter.release_control("s1")
        await adapter.write_param(P2_PARAM, 0)
        assert twin.cfg & codec.P2  # not served: nothing sent, the module still holds it
        await adapter.take_control("s1", "anna")
        assert await wait_for(lambda: not twin.cfg & codec.P2, 3)
        assert load_plant(path).devices["io"].options.get("p2") is None  # a direct adapter call: no gate, no file
    finally:
        await runtime.stop()


async def test_on_the_demo_plant_heater_hmrs_project_differs_applies_and_a_change_shows_as_drift(tmp_path):
    from webutil import private_endpoints

    from app.plant import DEMO_PLANT

    demo = private_endpoints(load_plant(DEMO_PLANT), tmp_path.name)
    assert project.check_plant(demo) == []
    for name in [n for n in demo.devices if demo.devices[n].bus != "can3"]:
        del demo.devices[name]
    demo.buses["can3"].options["poll_period"] = 0.2  # the settings are read at the first polls once it answers
    runtime = Runtime(demo, simulate=True, data_dir=tmp_path / "data")
    async with simulated_user(runtime) as user:
        twin, state = runtime.twins["heater-hmr"], runtime.store.devices["heater-hmr"]
        assert await wait_for(lambda: state.status == "online" and state.raw(record_param(15)) is not None, 15)
        plan = await backup.plan_restore(runtime, "heater-hmr", project.document(runtime, "heater-hmr"))
        assert [(r.name, r.current_text, r.backup_text) for r in plan.rows if r.changed] == [
            ("Customer data 1", "ff ff ff ff ff ff", "01 02 03 ff ff ff")]
        report = await backup.execute_restore(runtime, plan, {r.key for r in plan.rows}, user="anna", role="engineer")
        assert report.ok and twin.customer[1] == bytes.fromhex("010203ffffff")
        await runtime.record.approve("heater-hmr", user="anna", role="engineer")
        await runtime.worker.gate.invoke("heater-hmr", WRITE_PARAMETER, {"param": "customer:1", "value": "04"},
                                         user="anna", role="engineer")
        assert await wait_for(lambda: state.drift["changed"], 5)
        devices = (await user.http_client.get("/api/devices")).json()
        drift = next(d for d in devices if d["name"] == "heater-hmr")["drift"]
        assert [(r["name"], r["approved"], r["now"]) for r in drift["changed"]] == [
            ("Customer data 1", "01 02 03 ff ff ff", "04 ff ff ff ff ff")]
        await user.open("/")
        await user.should_see("changed since approved")
