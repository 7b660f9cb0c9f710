"""The CAN-M3IO page on its parameter model (NiceGUI's simulated user, the twin on python-can's virtual bus): the
project's differences (a customer record and P2) on the device page, applied per row, P2's question naming what
it switches off, the records as read, and the P2 switch asking the same question."""

from __future__ import annotations

import pytest
from nicegui import ui
from test_m3io_params import _plant_file
from test_backup_page import emit
from webutil import dialog_button, eventually, project_card_table, switch_starting, user_on

from app.plant import load_plant
from app.runtime import Runtime
from devices.m3io import codec
from devices.m3io.params import record_param

pytestmark = pytest.mark.timeout(60)


async def _read(runtime: Runtime, *names: str) -> None:
    for name in names:
        await eventually(lambda n=name: runtime.store.devices[n].status == "online"
                         and runtime.store.devices[n].raw(record_param(15)) is not None, timeout=15, what=f"{name} read")


async def test_the_project_differs_on_the_page_and_is_applied_per_row_with_p2_asked(tmp_path):
    path = _plant_file(tmp_path, project_a='"Customer data 3" = "01 02 03", P2 = 1')
    async with user_on(load_plant(path), data_dir=tmp_path / "data") as (user, runtime):
        await _read(runtime, "io-a")
        twin = runtime.twins["io-a"]
        await user.open("/device/io-a")
        await user.should_see("2 of 2 project entries differ from the device", retries=100)
        await user.should_see(" 3: ff ff ff ff ff ff")  # the records as read
        table = project_card_table(user)
        assert sorted((r["name"], r["backup"], r["current"]) for r in table.rows) == [
            ("Customer data 3", "01 02 03 ff ff ff", "ff ff ff ff ff ff"),
            ("P2", "two-phase load (P2) (1)", "three-phase load (0)")]
        emit(table, "apply", "customer:3")
        await user.should_see("Write Customer data 3 = 01 02 03 ff ff ff to io-a?")
        dialog_button(user, "Write").click()
        await user.should_see("1 of 2 project entries differs from the device", retries=100)
        assert twin.customer[3] == bytes.fromhex("010203ffffff")
        emit(project_card_table(user), "apply", "cfg:7")
        await user.should_see("Write P2 = two-phase load (P2) (1) to io-a?")
        dialog_button(user, "Write").click()
        await user.should_see("a three-phase load that lost one phase", retries=50)  # the question names it
        dialog_button(user, "Write anyway").click()
        await user.should_see("device and project agree (2 project entries)", retries=100)
        assert twin.cfg & codec.P2 and load_plant(path).devices["io-a"].options["p2"] is True
        rows = await runtime.audit.aquery(limit=50)
        assert any(r.device == "io-a" and r.action == "restore" and r.parameter == "P2" for r in rows)


async def test_the_p2_switch_asks_and_stays_off_when_cancelled(tmp_path):
    async with user_on(load_plant(_plant_file(tmp_path)), data_dir=tmp_path / "data") as (user, runtime):
        await _read(runtime, "io-b")
        await user.open("/device/io-b")
        await user.should_see("Three-phase output loaded on two phases only (P2)", retries=100)
        switch = switch_starting(user, "Three-phase output")
        await eventually(lambda: switch.enabled, timeout=10, what="the P2 switch enabled")
        switch.set_value(True)
        await user.should_see("Switch P2 on?", retries=50)
        await user.should_see("a three-phase load that lost one phase")
        dialog_button(user, "Cancel").click()
        await eventually(lambda: switch.value is False, timeout=5, what="the switch back off")
        assert not runtime.twins["io-b"].cfg & codec.P2 and not runtime.worker.adapters["io-b"].two_phase


async def test_the_project_editor_takes_records_as_hex_bytes_and_p2_by_name(tmp_path):
    path = _plant_file(tmp_path)
    async with user_on(load_plant(path), data_dir=tmp_path / "data") as (user, runtime):
        await user.open("/project/io-a")
        await user.should_see("Edited on the CAN-M3IO parameter model without the device")
        await user.should_see("allowed: 1 to 6 bytes as hex, e.g. 01 02 0a (padded with ff to 6 bytes)")
        fields = {e.props.get("data-project-field"): e for e in user.client.elements.values()
                  if e.props.get("data-project-field")}
        assert set(fields) == {*(f"customer:{i}" for i in range(1, 16)), "cfg:7"}  # settings only: no SW1, no area 2
        fields["customer:2"].set_value("01 02 03 04 05 06 07")
        user.find(kind=ui.button, content="Save project").click()
        await user.should_see("Not saved: Customer data 2: a customer record holds 6 bytes, 7 given")
        fields["customer:2"].set_value("aa")
        fields["cfg:7"].set_value("1")
        user.find(kind=ui.button, content="Save project").click()
        await user.should_see("Saved: Customer data 2 - -> aa ff ff ff ff ff; P2 - -> 1")
        assert load_plant(path).devices["io-a"].project == {"Customer data 2": "aa ff ff ff ff ff", "P2": 1}
        await user.open("/project/io-a")  # reloaded from the file
        fields = {e.props.get("data-project-field"): e for e in user.client.elements.values()
                  if e.props.get("data-project-field")}
        assert fields["customer:2"].value == "aa ff ff ff ff ff" and fields["cfg:7"].value == "1"
