"""The offline project in the pages (issue 30, section 2), with NiceGUI's simulated user: the device page's
project card (the differing row, applied through the gate) and the project editor on a device that never
answered (edited on its type's parameter model, saved into the plant file, invalid entries and viewers refused).

One simulated HD-Lock (door-1, with a project) and one on a line nothing listens on (door-9: not yet wired).
"""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from nicegui import ui
from nicegui.testing import User
from plants import bus, device, free_port, modbus_line, mo64_tcp, plant_text
from test_auth import login
from test_backup_page import emit
from webutil import dialog_button, eventually, project_card_table, simulated_user, user_on

from app import project
from app.plant import load_plant
from app.runtime import Runtime
from app.users import UserStore
from app.gate import PermissionDenied

pytestmark = pytest.mark.timeout(60)

def project_plant_text() -> str:
    """door-1 with a project on a simulated line, door-9 on a line nothing answers on (not wired yet); each
    with a comment that saving the project must keep."""
    door_1 = device("door-1", "hdlock", "line1", address=1, project={"LockRequestDelay": 350})
    return plant_text(
        bus("line1", "modbus-rtu", door_1.rstrip("\n") + "  # the door closer needs longer\n",
            port=f"socket://127.0.0.1:{free_port()}", timeout=0.3, retries=0, poll_period=0.2, simulate=True),
        modbus_line((("door-9", 9),), name="line9", timeout=0.2, poll_period=0.5, simulate=None)
        + "# the lock of the second door\n",
        name="pp")


def plant_file(folder: Path) -> Path:
    """:func:`project_plant_text` in ``folder``'s plant.toml."""
    path = folder / "plant.toml"
    path.write_text(project_plant_text())
    return path


@dataclass
class Env:
    user: User
    runtime: Runtime
    path: Path


@pytest.fixture
async def env(tmp_path: Path) -> AsyncIterator[Env]:
    path = plant_file(tmp_path)
    async with user_on(load_plant(path), data_dir=tmp_path / "data") as (user, runtime):
        await eventually(lambda: runtime.store.devices["door-1"].status == "online", timeout=15, what="door-1 online")
        yield Env(user, runtime, path)



async def test_device_page_shows_the_differing_entry_and_applies_it_through_the_gate(env: Env):
    twin = env.runtime.twins["door-1"]
    await env.user.open("/device/door-1")
    await env.user.should_see("1 of 1 project entry differs from the device", retries=100)
    table = project_card_table(env.user)
    assert [(r["name"], r["backup"], r["current"], r["changed"]) for r in table.rows] == [
        ("LockRequestDelay", "350 ms", "200 ms", True)]
    emit(table, "apply", "holding:3000")
    await env.user.should_see("Write LockRequestDelay = 350 ms to door-1?")
    dialog_button(env.user, "Write").click()
    await env.user.should_see("device and project agree (1 project entry)", retries=100)
    assert twin.holding[3000] == 350 and twin.flash[3000] == 350  # written, read back and saved
    rows = await env.runtime.audit.aquery(limit=50)
    assert any(r.device == "door-1" and r.action == "restore" and r.parameter == "LockRequestDelay" for r in rows)


async def test_project_of_a_device_that_never_answered_is_edited_on_the_parameter_model(env: Env):
    assert env.runtime.store.devices["door-9"].status != "online"
    await env.user.open("/device/door-9")
    await env.user.should_see("The plant file names no project for this device.")
    await env.user.open("/project/door-9")
    await env.user.should_see("Edited on the HD-Lock parameter model without the device")
    await env.user.should_see("allowed: 0 .. 65535 ms (whole numbers)")  # what LockRequestDelay allows
    fields = {e.props.get("data-project-field"): e for e in env.user.client.elements.values()
              if e.props.get("data-project-field")}
    assert "holding:3000" in fields and "input:51" not in fields  # writable parameters only
    fields["holding:3000"].set_value("70000")
    env.user.find(kind=ui.button, content="Save project").click()
    await env.user.should_see("Not saved: LockRequestDelay: 70000 is outside 0 .. 65535 ms")
    fields["holding:3000"].set_value("abc")
    env.user.find(kind=ui.button, content="Save project").click()
    await env.user.should_see("'abc' is not a number; allowed: 0 .. 65535 ms (whole numbers)")
    before = env.path.read_text()
    assert "project" not in before.split("name = \"door-9\"")[1]
    fields["holding:3000"].set_value("420")
    fields["holding:3001"].set_value("5")  # SettingOutput1: Bolt retracted
    env.user.find(kind=ui.button, content="Save project").click()
    await env.user.should_see("Saved: LockRequestDelay - -> 420; SettingOutput1 - -> 5")
    text = env.path.read_text()
    assert "# the lock of the second door" in text and "# the door closer needs longer" in text
    assert (env.path.parent / "plant.toml.bak").read_text() == before
    assert load_plant(env.path).devices["door-9"].project == {"LockRequestDelay": 420, "SettingOutput1": 5}
    row = next(r for r in await env.runtime.audit.aquery(limit=20) if r.action == "edit project")
    assert (row.device, row.user, row.result) == ("door-9", "local", "ok") and "LockRequestDelay - -> 420" in row.new

    await env.user.open("/project/door-9")  # reloaded: the saved values, from the file
    fields = {e.props.get("data-project-field"): e for e in env.user.client.elements.values()
              if e.props.get("data-project-field")}
    assert fields["holding:3000"].value == "420" and fields["holding:3001"].value == "5"
    fields["holding:3000"].set_value("")  # emptied: dropped from the project
    env.user.find(kind=ui.button, content="Save project").click()
    await env.user.should_see("Saved: LockRequestDelay 420 -> -")
    assert load_plant(env.path).devices["door-9"].project == {"SettingOutput1": 5}
    await env.user.open("/device/door-9")  # its page now shows the project, to be compared once the lock answers
    await env.user.should_see("1 project entry; the device does not answer: compared when it does")


async def test_a_viewer_sees_the_project_read_only_and_the_worker_refuses_the_save(tmp_path: Path):
    path = plant_file(tmp_path)
    UserStore(tmp_path / "users.toml").add("tablet", "viewer", "battery staple")
    runtime = Runtime(load_plant(path), simulate=True, data_dir=tmp_path, auth_required=True)
    async with simulated_user(runtime) as user:
        await login(user, "tablet", "battery staple")
        await user.open("/project/door-1")
        await user.should_see("read-only session")
        fields = [e for e in user.client.elements.values() if e.props.get("data-project-field")]
        assert fields and all(not f.enabled for f in fields)
        assert not next(iter(user.find(kind=ui.button, content="Save project").elements)).enabled
        # past the page: the worker refuses a viewer's save (and audits the refusal); the file is not touched
        before = path.read_text()
        with pytest.raises(PermissionDenied):
            await runtime.worker.gate.run(
                lambda: asyncio.to_thread(project.save, runtime.plant, "door-1", {"holding:3000": 1}), user="tablet",
                role="viewer", describe="edit project", device="door-1", kind="write")
        assert path.read_text() == before
        row = next(r for r in await runtime.audit.aquery(limit=20) if r.action == "edit project")
        assert row.user == "tablet" and row.result.startswith("refused")


async def test_the_mo64_project_is_edited_on_its_parameter_model(tmp_path: Path):
    path = tmp_path / "plant.toml"
    path.write_text(plant_text(mo64_tcp("barrier-in", "gate-tcp", travel_s=None, timeout=None, poll_period=None, simulate=None),
                               name="gates"))
    async with user_on(load_plant(path), data_dir=tmp_path / "data") as (user, runtime):
        await user.open("/project/barrier-in")  # every family has a parameter model now (devices/mo64/params.py)
        await user.should_see("Kraftüberwachung")
        assert [e for e in user.client.elements.values() if e.props.get("data-project-field")]
        await user.open("/device/barrier-in")
        await user.should_see("barrier-in")
        assert [e for e in user.client.elements.values() if e.props.get("data-testid") == "project-none"]
