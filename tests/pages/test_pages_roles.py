"""Roles on the pages, with NiceGUI's simulated user, on loopback (every 127.* address is a local engineer) and with
accounts required (issue 42 items 2, 8, 9 and 12):

- an engineer keeps M3IO control buttons and the project card's Apply/Update enabled after the store's rounds
  redraw them (they worked the role out without the page's session and showed "read-only session");
- a viewer sees the write buttons disabled with the reason before any click (Discover locks, Back up selected,
  Compare a backup with the device, Record on a bus monitor, the M3IO's control);
- the M3IO header names the DigOut period it sends at; a whole-plant backup downloads at once.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from nicegui import ui
from nicegui.testing import User
from nicegui.testing.user_interaction import UserInteraction
from plants import bus, can_bus, channel, device, free_port, m3io_can, plant_text
from test_auth import login
from webutil import by_testid, eventually, simulated_user

from app.plant import load_plant
from app.runtime import Runtime
from app.users import UserStore
from pages.command_client import VIEWER_REASON

pytestmark = pytest.mark.timeout(90)



def _plant_text() -> str:
    """Two HD-Locks (door-1 with a project) on a simulated RTU line and an M3IO HM heater on a CAN bus."""
    locks = (device("door-1", "hdlock", "line1", address=1, project={"LockRequestDelay": 350}),
             device("door-2", "hdlock", "line1", address=2))
    return plant_text(
        bus("line1", "modbus-rtu", *locks, port=f"socket://127.0.0.1:{free_port()}", timeout=0.3, retries=0,
            poll_period=0.2, simulate=True),
        can_bus(m3io_can("heater-hm", "can3", master="always"), name="can3", channel_name=channel("roles"), bitrate=500000),
        name="roles")

ENGINEER, VIEWER = ("anna", "correct horse"), ("tablet", "battery staple")


@dataclass
class Env:
    user: User
    runtime: Runtime


async def _env(tmp_path: Path, accounts: bool, who: tuple[str, str]) -> AsyncIterator[Env]:
    path = tmp_path / "plant.toml"
    path.write_text(_plant_text())
    store = UserStore(tmp_path / "users.toml")
    store.add(*ENGINEER[:1], "engineer", ENGINEER[1])
    store.add(*VIEWER[:1], "viewer", VIEWER[1])
    runtime = Runtime(load_plant(path), simulate=True, data_dir=tmp_path, auth_required=accounts)
    async with simulated_user(runtime) as user:
        if accounts:
            await login(user, *who)
        for name in ("door-1", "door-2", "heater-hm"):
            await eventually(lambda n=name: runtime.store.devices[n].status == "online", timeout=15, what=f"{name} online")
        yield Env(user, runtime)


@pytest.fixture(params=["loopback", "accounts"])
async def engineer(request, tmp_path: Path) -> AsyncIterator[Env]:
    """An engineer: on loopback (no login) and logged in with accounts required."""
    async for env in _env(tmp_path, request.param == "accounts", ENGINEER):
        yield env


@pytest.fixture
async def viewer(tmp_path: Path) -> AsyncIterator[Env]:
    """A viewer's account (accounts required: on loopback everybody is the local engineer)."""
    async for env in _env(tmp_path, True, VIEWER):
        yield env


def reason_of(element: ui.element) -> str:
    """Why ``element`` is disabled ("" while it is enabled)."""
    return "" if element.enabled else element.props.get("data-disabled-reason", "disabled without a reason")


async def store_rounds(env: Env, device: str, rounds: int = 2) -> None:
    """Wait until the store's once-a-second round of ``device`` ran ``rounds`` times for the page's watchers (it
    redraws the page's cards there, outside the page's own context)."""
    seen: list[bool] = []
    store = env.runtime.store
    watch = store.watch(device, lambda: seen.append(True) if store.age_round else None, group=env.user.client.id)
    try:
        await eventually(lambda: len(seen) >= rounds, timeout=5, what=f"{rounds} rounds of the store")
    finally:
        watch.cancel()


async def test_an_engineer_keeps_the_m3io_control_and_the_header_names_the_period(engineer: Env):
    user, runtime = engineer.user, engineer.runtime
    await user.open("/device/heater-hm")
    take, release = by_testid(user, "take-control"), by_testid(user, "release-control")
    card = next(c for c in user.client.elements.values() if isinstance(c, ui.label) and c.text.startswith("watchdog "))
    assert "DigOut every 500 ms" in card.text  # served with every output off: the idle period
    await store_rounds(engineer, "heater-hm")
    assert reason_of(take) == "" and reason_of(release) == "you do not control the module"
    UserInteraction(user, {take}, None).click()
    adapter = runtime.worker.adapters["heater-hm"]
    await eventually(lambda: adapter.controller is not None, timeout=5, what="control taken")
    await eventually(lambda: "DigOut every 100 ms" in card.text, timeout=5, what="the period while controlled")
    await store_rounds(engineer, "heater-hm")
    assert reason_of(release) == "" and reason_of(take) == "you control the module"


async def test_an_engineer_may_apply_the_project_after_the_automatic_compare(engineer: Env):
    user = engineer.user
    await user.open("/device/door-1")
    await user.should_see("1 of 1 project entry differs from the device", retries=100)
    table = next(t for t in user.client.elements.values() if isinstance(t, ui.table) and t.rows and "can_write" in t.rows[0])
    assert all(row["can_write"] for row in table.rows), table.rows


async def test_a_viewer_sees_write_buttons_disabled_with_the_reason(viewer: Env):
    user = viewer.user
    await user.open("/device/heater-hm")
    await store_rounds(viewer, "heater-hm")
    assert reason_of(by_testid(user, "take-control")) == VIEWER_REASON
    assert reason_of(by_testid(user, "release-control")) == VIEWER_REASON
    await user.open("/device/door-1")
    await user.should_see("1 of 1 project entry differs from the device", retries=100)
    table = next(t for t in user.client.elements.values() if isinstance(t, ui.table) and t.rows and "can_write" in t.rows[0])
    assert not any(row["can_write"] for row in table.rows)
    await user.open("/")
    assert reason_of(by_testid(user, "discover-locks")) == VIEWER_REASON
    await user.open("/backup")
    await user.should_see("Back up selected")
    assert reason_of(by_testid(user, "backup-start")) == VIEWER_REASON
    await user.open("/monitor/can3")
    await user.should_see("Recording")
    record = next(e for e in user.client.elements.values() if isinstance(e, ui.button) and e.text == "Record")
    assert reason_of(record) == VIEWER_REASON


async def test_a_whole_plant_backup_downloads_as_one_archive_at_once(engineer: Env):
    user = engineer.user
    await user.open("/backup")
    await user.should_see("Back up selected")
    downloads = len(user.download.http_responses)
    UserInteraction(user, {by_testid(user, "backup-start")}, None).click()
    await user.should_see("backup file(s) written", retries=200)
    await eventually(lambda: len(user.download.http_responses) > downloads, timeout=5, what="the archive downloaded")


@pytest.fixture
async def local(tmp_path: Path) -> AsyncIterator[Env]:
    """The local engineer on loopback (what is tested is not a role)."""
    async for env in _env(tmp_path, False, ENGINEER):
        yield env


async def test_the_fleet_page_warns_only_about_what_is_true(local: Env):
    """A set of door-1 applied to door-2: door-2's serial and door-1's name are what a batch means (issue 42 item 5)."""
    user, runtime = local.user, local.runtime
    await runtime.record.approve("door-1", user="anna", role="engineer")
    await user.open("/fleet")
    source = by_testid(user, "fleet-source")
    await eventually(lambda: source.value == "approved:door-1", timeout=5, what="the approved set as the source")
    UserInteraction(user, {by_testid(user, "fleet-compare")}, None).click()
    await user.should_see("ready:", retries=200)
    card = next(e for e in user.client.elements.values() if e.props.get("data-fleet-result") == "door-2")
    words = " ".join(getattr(e, "text", "") for e in card.descendants())
    assert "serial number" not in words and "taken from device" not in words and "⚠" not in words, words
    line = by_testid(user, "fleet-source-line").text
    assert "approved set of door-1" in line and "taken from door-1" in line, line


async def test_the_overview_shows_unsaved_changes(local: Env):
    """door-1 written and not saved: its tile and its table row say so (issue 42 item 7)."""
    user, runtime = local.user, local.runtime
    state = runtime.store.devices["door-1"]
    param = state.params.by_name["LockRequestDelay"]
    await runtime.worker.adapters["door-1"].write_param(param, 420)
    assert state.unsaved
    await user.open("/")
    await user.should_see("1 unsaved change", retries=100)
    badge = next(e for e in user.client.elements.values() if e.props.get("data-unsaved") == "door-1")
    assert badge.visible and badge.text == "1 unsaved change" and "LockRequestDelay" in badge.props["title"]
    row = next(e for e in user.client.elements.values() if e.props.get("data-glance") == "door-1")
    assert 'data-glance-unsaved="door-1"' in row.content and "1 unsaved change" in row.content
    await runtime.worker.adapters["door-1"].save_step()
    await eventually(lambda: not badge.visible, timeout=5, what="the badge gone after Save")


async def test_approve_is_offered_only_for_a_device_with_a_parameter_set(local: Env):
    """An M3IO HM in simple mode keeps no parameters: Approve and Snapshot say so instead of failing (item 8)."""
    user = local.user
    await user.open("/record/heater-hm")
    approve = next(iter(user.find(marker="record-approve").elements))
    snapshot = next(iter(user.find(marker="record-snapshot").elements))
    await eventually(lambda: ":" in reason_of(approve), timeout=5, what="the adapter's reason")
    assert reason_of(approve).startswith("heater-hm has no parameter set to approve or keep: ")
    assert reason_of(snapshot) == reason_of(approve)
    await user.open("/record/door-1")
    assert reason_of(next(iter(user.find(marker="record-approve").elements))) == ""


async def test_every_device_page_that_keeps_parameters_links_the_replacement_assistant(local: Env):
    """Not only once a swap was detected (item 10)."""
    user = local.user
    for name in ("door-1", "door-2"):
        await user.open(f"/device/{name}")
        link = by_testid(user, "replace-link")
        assert link.props["href"] == f"/replace/{name}"
    await user.open("/device/heater-hm")  # simple mode: no parameters to put into a new module
    await user.should_see("watchdog")
    assert not [e for e in user.client.elements.values() if e.props.get("data-testid") == "replace-link"]


async def test_a_question_answered_with_cancel_is_no_refusal_and_names_the_parameter(local: Env):
    """SettingsRemoveMagnet = 1 asked and cancelled: an information, audited as cancelled under the name (item 12)."""
    user, runtime = local.user, local.runtime
    await user.open("/device/door-1")
    entry = next(e for e in user.client.elements.values() if e.props.get("data-param") == "SettingsRemoveMagnet")
    entry.value = 1
    UserInteraction(user, {next(e for e in user.client.elements.values()
                                if e.props.get("data-write") == "SettingsRemoveMagnet")}, None).click()
    await user.should_see("Cancel")
    user.find(kind=ui.button, content="Cancel").click()

    async def audited():
        rows = [r for r in await runtime.audit.aquery(limit=50) if r.device == "door-1" and "not confirmed" in r.result]
        assert rows, "no audit row"
        return rows[-1]

    await eventually(audited, timeout=5, what="the cancel audited")
    row = await audited()
    assert row.result == "cancelled: not confirmed" and row.parameter == "SettingsRemoveMagnet", row
    assert runtime.twins["door-1"].holding[3005] == 0
    event = next(e for e in reversed(runtime.store.devices["door-1"].events) if "not confirmed" in e.text)
    assert event.level == "info" and "cancelled" in event.text, event


async def test_the_lock_page_marks_measured_values(local: Env):
    """MaximumTimeLock/Unlock are the lock's measurements, marked as such in the parameter table (item 4)."""
    user = local.user
    await user.open("/device/door-1")
    await user.should_see("LockRequestDelay")
    marked = {e.props["data-measured"] for e in user.client.elements.values() if e.props.get("data-measured")}
    assert marked == {"MaximumTimeLock", "MaximumTimeUnlock"}, marked
