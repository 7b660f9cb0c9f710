"""The SCU's parameter model in the pages, with NiceGUI's simulated user against the twin: the project's differing
setting on the device page, applied per row through the gate; a changed setting as drift on the overview and in
/api/devices; the project editor on the model's settings."""

from __future__ import annotations

from pathlib import Path

import pytest
from nicegui import ui
from plants import SCU_ACTUATORS, bus, device, free_port, plant_text
from test_backup_page import emit
from webutil import dialog_button, eventually, project_card_table, user_on

from app.plant import load_plant

pytestmark = pytest.mark.timeout(120)


def _plant(tmp_path: Path) -> Path:
    line = bus("rs-a", "serial", device("lift-a", "scu", "rs-a", actuators=list(SCU_ACTUATORS), serial="A-1001"),
               port=f"socket://127.0.0.1:{free_port()}", timeout=0.3, poll_period=0.2, simulate=True)
    line = line.replace('serial = "A-1001"', 'serial = "A-1001"\nproject = { "Remote Speed F1" = 60, "Remote Position A1" = 600 }')
    path = tmp_path / "plant.toml"
    path.write_text(plant_text(line, name="lifts"))
    return path



async def test_project_difference_applied_per_row_on_the_page_and_drift_on_the_overview_and_in_the_api(tmp_path: Path):
    async with user_on(load_plant(_plant(tmp_path)), data_dir=tmp_path / "data") as (user, runtime):
        twin, state = runtime.twins["lift-a"], runtime.store.devices["lift-a"]
        await eventually(lambda: state.status == "online", timeout=30, what="lift-a online")
        await user.open("/device/lift-a")
        await user.should_see("1 of 2 project entries differs from the device", retries=300)  # A1 is at 600 already
        table = project_card_table(user)
        assert [(r["name"], r["backup"], r["current"]) for r in table.rows] == [
            ("Remote Speed F1", "60 % or counts/s", "100 % or counts/s")]
        emit(table, "apply", "data:12305")
        await user.should_see("Write Remote Speed F1 = 60 % or counts/s to lift-a?")
        dialog_button(user, "Write").click()
        await user.should_see("device and project agree (2 project entries)", retries=300)
        assert twin.remote_speed[0] == 60  # written with RT and read back with RG
        rows = await runtime.audit.aquery(limit=50)
        assert any(r.device == "lift-a" and r.action == "restore" and r.parameter == "Remote Speed F1" for r in rows)

        # drift: approved as it is, then the unit is reset (its remote data are volatile, table 7)
        # the model on the page: settings and the read-only values, as the unit answered them
        user.find(kind=ui.button, content="Read settings (RG)").click()
        settings = next(e for e in user.client.elements.values()
                        if isinstance(e, ui.table) and e.props.get("data-testid") == "settings-table")
        await eventually(lambda: any(r["value"] == "12.5 counts/mm" for r in settings.rows), timeout=30)
        rows = {r["name"]: r for r in settings.rows}
        assert (rows["Remote Speed F1"]["id"], rows["Remote Speed F1"]["value"], rows["Remote Speed F1"]["kind"]) == (
            "0x3011", "60 % or counts/s", "setting")
        assert rows["Conversion factor A2"]["kind"] == "read-only" and rows["Safety_ID"]["value"] == "stop all (1)"
        assert rows["Position_Virtual_Limit_Out A2"]["id"] == "0x2002 Position_Virtual_Limit_Out"

        await runtime.record.approve("lift-a", user="anna", role="engineer")
        api = await user.http_client.get("/api/devices")
        assert next(d for d in api.json() if d["name"] == "lift-a")["drift"] == {"approved": True, "changed": []}
        twin.reset()
        await eventually(lambda: state.drift["changed"], timeout=30, what="drift of lift-a")
        changed = [{"key": "data:12305", "name": "Remote Speed F1", "approved": "60 % or counts/s",
                    "now": "100 % or counts/s"}]
        api = await user.http_client.get("/api/devices")
        assert next(d for d in api.json() if d["name"] == "lift-a")["drift"] == {"approved": True, "changed": changed}
        await user.open("/")
        await user.should_see("changed since approved", retries=300)


async def test_the_project_editor_offers_the_settings_of_the_model(tmp_path: Path):
    async with user_on(load_plant(_plant(tmp_path)), data_dir=tmp_path / "data") as (user, runtime):
        await user.open("/project/lift-a")
        await user.should_see("Edited on the Ewellix SCU parameter model")
        fields = {e.props.get("data-project-field"): e for e in user.client.elements.values()
                  if e.props.get("data-project-field")}
        assert "data:12305" in fields and "data:4113" not in fields  # settings only: no conversion factor
        fields["data:12306"].set_value("2000")
        user.find(kind=ui.button, content="Save project").click()
        await user.should_see("Remote Speed F2: 2000 is outside 0 .. 1000 % or counts/s")
