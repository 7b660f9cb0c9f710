"""Security: foreign Host and Origin (DNS rebinding, cross-site websockets), session fixation,
removed accounts, the login throttle, viewer paths, the audit log failing closed, and the
data folder's permissions.

Host and Origin are tried against the app in its own process with real HTTP and websocket
requests; the login flows use NiceGUI's simulated user on the same app code.
"""

from __future__ import annotations

import asyncio
import os
import stat
import subprocess
import sys
import time

import httpx
import pytest
import websockets
from conftest import free_port, wait_for
from nicegui.testing.user_interaction import UserInteraction
from test_auth import login, secured_app
from webutil import DEMO_PLANT, demo_plant_text, wait_http

from app import backup
from app.audit import BUSY_TIMEOUT_MS
from app.runtime import Runtime, remove_stale_parts
from app.users import UserStore
from app.worker import AuditUnavailable, PermissionDenied
from pages.command_client import gate_reason

pytestmark = pytest.mark.timeout(90)


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    """The GUI on the demo plant in its own process, loopback, with its own data folder."""
    folder = tmp_path_factory.mktemp("served")
    plant = folder / "plant.toml"
    plant.write_text(demo_plant_text(free_port()))
    port = free_port()
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    for key in ("NICEGUI_USER_SIMULATION", "PYTEST_CURRENT_TEST", "NICEGUI_STORAGE_PATH"):
        env.pop(key, None)
    with open(folder / "app.log", "wb") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "app.cli", "--plant", str(plant), "--port", str(port), "--data-dir", str(folder / "data"),
             "--allowed-host", "commission.plant.local"],
            cwd=folder, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True,
        )
    try:
        wait_http(f"http://127.0.0.1:{port}/", proc, timeout=30)
        yield port, folder
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()


def test_foreign_host_is_refused(served):
    port, _folder = served
    base = f"http://127.0.0.1:{port}"
    with httpx.Client() as client:
        assert client.get(f"{base}/").status_code == 200
        assert client.get(f"{base}/", headers={"Host": f"localhost:{port}"}).status_code == 200
        assert client.get(f"{base}/", headers={"Host": f"commission.plant.local:{port}"}).status_code == 200  # --allowed-host
        # a site that rebinds its DNS name to 127.0.0.1 still sends its own name
        for host in (f"attacker.example:{port}", "attacker.example", f"127.0.0.1.attacker.example:{port}"):
            response = client.get(f"{base}/", headers={"Host": host})
            assert response.status_code == 403 and "not served here" in response.text, host
        assert client.get(f"{base}/api/devices", headers={"Host": f"attacker.example:{port}"}).status_code == 403


def test_files_from_memory_still_pass_the_host_guard(served):
    """NiceGUI's files are answered from memory (app/assets.py), compressed, and only to hosts served here."""
    from app.assets import PREFIX

    port, _folder = served
    base = f"http://127.0.0.1:{port}"
    script = f"{base}{PREFIX}static/quasar.umd.prod.js"
    with httpx.Client() as client:
        page = client.get(f"{base}/plant").text
        assert f'<link rel="modulepreload" href="{PREFIX}static/dompurify.mjs">' in page
        assert 'rel="preload" as="font"' in page
        for _ in range(2):  # the first fills the cache, the second is answered from it
            answer = client.get(script, headers={"accept-encoding": "gzip"})
            assert answer.status_code == 200 and answer.headers["content-encoding"] == "gzip"
            assert b"Quasar" in answer.content[:2000]
        refused = client.get(script, headers={"Host": f"attacker.example:{port}"})
        assert refused.status_code == 403 and "not served here" in refused.text


def test_cross_origin_http_and_socketio_polling_are_refused(served):
    port, _folder = served
    base = f"http://127.0.0.1:{port}"
    polling = f"{base}/_nicegui_ws/socket.io/?EIO=4&transport=polling"
    with httpx.Client() as client:
        same = client.get(polling, headers={"Origin": base})
        assert same.status_code == 200 and same.text.startswith("0{")  # the engine.io open packet
        for origin in ("http://attacker.example", f"http://attacker.example:{port}", "null", f"https://127.0.0.1:{port}"):
            response = client.get(polling, headers={"Origin": origin})
            assert response.status_code == 403 and "access-control-allow-origin" not in response.headers, origin
        assert client.get(f"{base}/api/devices", headers={"Origin": "http://attacker.example"}).status_code == 403


async def test_cross_origin_websocket_is_refused(served):
    port, _folder = served
    url = f"ws://127.0.0.1:{port}/_nicegui_ws/socket.io/?EIO=4&transport=websocket"
    async with websockets.connect(url, origin=f"http://127.0.0.1:{port}", open_timeout=5) as ws:
        assert (await asyncio.wait_for(ws.recv(), 5)).startswith("0{")  # same origin: the handshake opens
    with pytest.raises(websockets.exceptions.InvalidStatus):
        async with websockets.connect(url, origin="http://attacker.example", open_timeout=5):
            pass
    with pytest.raises((websockets.exceptions.InvalidStatus, websockets.exceptions.InvalidHandshake)):
        async with websockets.connect(url, additional_headers={"Host": "attacker.example"}, open_timeout=5):
            pass


def test_state_stays_in_the_data_folder_owner_only(served):
    port, folder = served
    data = folder / "data"
    assert stat.S_IMODE(data.stat().st_mode) == 0o700
    for name in ("audit.sqlite", "session-secret"):
        assert stat.S_IMODE((data / name).stat().st_mode) == 0o600, name
    httpx.get(f"http://127.0.0.1:{port}/", timeout=10)
    assert not (folder / ".nicegui").exists()  # NiceGUI's per-browser storage is not in the working folder
    for path in data.rglob("*"):
        assert stat.S_IMODE(path.stat().st_mode) & 0o077 == 0, path  # nothing in the data folder for others


# -- sessions and accounts (simulated user) -----------------------------------------------------


async def test_a_cookie_planted_before_login_is_worthless_after_it(tmp_path):
    async with secured_app(tmp_path) as (user, _runtime):
        await user.open("/login")
        planted = dict(user.http_client.cookies)  # what an attacker would have set in the victim's browser
        assert planted
        await login(user, "anna", "correct horse")
        assert dict(user.http_client.cookies) != planted
        assert (await user.http_client.get("/api/devices")).status_code == 200  # the victim is logged in
        async with httpx.AsyncClient(transport=user.http_client._transport, base_url="http://test", cookies=planted) as attacker:
            assert (await attacker.get("/api/devices")).status_code == 401
        # and logging out ends the session for every copy of the new cookie
        logged_in = dict(user.http_client.cookies)
        await user.open("/logout")
        async with httpx.AsyncClient(transport=user.http_client._transport, base_url="http://test", cookies=logged_in) as copy:
            assert (await copy.get("/api/devices")).status_code == 401


async def test_removed_account_loses_its_rights_at_once(tmp_path):
    async with secured_app(tmp_path) as (user, runtime):
        await login(user, "anna", "correct horse")
        assert (await user.http_client.get("/api/devices")).status_code == 200
        UserStore(tmp_path / "users.toml").remove("anna")  # `commission user remove anna` in another process
        assert await wait_for(lambda: "anna" not in runtime.users.users, timeout=5)
        assert (await user.http_client.get("/api/devices")).status_code == 401
        await user.open("/device/door-1")
        await user.should_see("Log in")


async def test_downgraded_account_cannot_write_any_more(tmp_path):
    async with secured_app(tmp_path) as (user, runtime):
        await login(user, "anna", "correct horse")
        await user.open("/backup")
        await user.should_see("anna (engineer)")
        other = UserStore(tmp_path / "users.toml")
        other.add("anna", "viewer", "correct horse")  # role changed from the command line
        assert await wait_for(lambda: runtime.users.users["anna"].role == "viewer", timeout=5)
        UserInteraction(user, {e for e in user.find("Back up selected").elements}, None).click()
        await user.should_see("viewer role and may not write")
        entry = next(e for e in runtime.audit.query() if e.action == "backup")
        assert (entry.user, entry.role) == ("anna", "viewer") and entry.result.startswith("refused")
        assert not runtime.backups_dir.exists() or not list(runtime.backups_dir.glob("*.json"))


async def test_repeated_wrong_passwords_are_slowed_down_and_audited(tmp_path):
    async with secured_app(tmp_path) as (user, runtime):
        for n in range(3):
            await login(user, "anna", "wrong guess!", succeeds=False)
            assert await wait_for(lambda n=n: sum(e.action == "login" for e in runtime.audit.query()) == n + 1)
        await user.should_see("Wrong user name or password")
        await login(user, "anna", "wrong guess!", succeeds=False)  # the 4th comes too soon
        await user.should_see("Too many wrong passwords")
        assert await wait_for(lambda: sum(e.action == "login" for e in runtime.audit.query()) == 4)
        await login(user, "anna", "correct horse", succeeds=False)  # even the right one waits
        await user.should_see("Too many wrong passwords")
        assert await wait_for(lambda: sum(e.action == "login" for e in runtime.audit.query()) == 5)
        rows = [e for e in runtime.audit.query() if e.action == "login"]
        assert sum(e.result.startswith("failed") for e in rows) == 3
        assert sum(e.result.startswith("refused: throttled") for e in rows) == 2
        runtime.login_throttle._failures.clear()  # the wait is over
        await login(user, "anna", "correct horse")


async def test_viewer_paths_that_change_files_or_the_plant_are_refused_in_the_worker(tmp_path):
    async with secured_app(tmp_path) as (user, runtime):
        await login(user, "tablet", "battery staple")
        await user.open("/backup")
        buttons = user.find("Back up selected").elements
        assert buttons and all(gate_reason(b) for b in buttons), "a viewer sees Back up selected enabled"
        UserInteraction(user, buttons, None).click()  # a click on the disabled button does nothing
        assert not runtime.backups_dir.exists() or not list(runtime.backups_dir.glob("*.json"))
        worker = runtime.worker
        for describe, action in (
            ("scan line", lambda: worker.discover("line1", 1, 3)),
            ("backup", lambda: backup.backup_device(runtime, "door-1", tmp_path / "b", user="tablet", role="viewer")),
        ):
            with pytest.raises(PermissionDenied):
                if describe == "backup":
                    await action()
                else:
                    await worker.gate.run(action, user="tablet", role="viewer", describe=describe, device="line1", kind="write")
        refused = [e for e in runtime.audit.query(user="tablet") if e.result.startswith("refused")]
        assert {e.action for e in refused} >= {"backup", "scan line"}


# -- the audit log fails closed -------------------------------------------------------------------

LOCKER = """
import sqlite3, sys, time
db = sqlite3.connect(sys.argv[1], isolation_level=None)
db.execute("BEGIN EXCLUSIVE")
print("locked", flush=True)
time.sleep(float(sys.argv[2]))
"""


async def test_write_is_refused_while_another_process_locks_the_audit_log(tmp_path):
    from conftest import modbus_plant

    runtime = Runtime(modbus_plant(locks=(("door-1", 1),)), simulate=True, data_dir=tmp_path)
    await runtime.start()
    try:
        state = runtime.store.devices["door-1"]
        assert await wait_for(lambda: state.value("LockRequestDelay") is not None, timeout=8)
        param = state.params.by_name["LockRequestDelay"]
        locker = subprocess.Popen([sys.executable, "-c", LOCKER, str(runtime.audit.path), "6"], stdout=subprocess.PIPE, text=True)
        try:
            assert locker.stdout.readline().strip() == "locked"
            lags_before = len(runtime.worker.loop_health.lags_ms)
            started = time.monotonic()
            with pytest.raises(AuditUnavailable, match="audit log cannot be written"):
                await runtime.worker.gate.run(lambda: runtime.worker.adapters["door-1"].write_param(param, 321),
                                              device="door-1", describe="write LockRequestDelay", user="local", role="engineer")
            assert time.monotonic() - started < 5
            assert runtime.twins["door-1"].holding[3000] == 200  # nothing was sent
            assert runtime.audit.problem  # shown in the header
            # waiting for the lock (BUSY_TIMEOUT_MS, in the audit's thread) never blocked the loop: no lag in the
            # meantime came near it (a loaded machine's own stalls of a few hundred ms are no such wait)
            lags = list(runtime.worker.loop_health.lags_ms)[lags_before:]
            assert max(lags, default=0.0) < BUSY_TIMEOUT_MS / 2, lags
            # a stop is not a write: it goes through even without an audit row
            await runtime.worker.gate.run(lambda: asyncio.sleep(0), device="door-1", role="engineer", user="local",
                                          describe="stop", kind="stop")
        finally:
            locker.kill()
            locker.wait()
        await runtime.worker.gate.run(lambda: runtime.worker.adapters["door-1"].write_param(param, 321),
                                      device="door-1", describe="write LockRequestDelay", user="local", role="engineer")
        assert runtime.twins["door-1"].holding[3000] == 321 and not runtime.audit.problem
    finally:
        await asyncio.wait_for(runtime.stop(), 10)


async def test_unwritable_audit_log_is_reported_at_start_and_refuses_writes(tmp_path, caplog):
    (tmp_path / "audit.sqlite").mkdir()  # not a database file at all (as good as a broken disk, even for root)
    from conftest import modbus_plant

    runtime = Runtime(modbus_plant(locks=(("door-1", 1),)), simulate=True, data_dir=tmp_path)
    await runtime.start()
    try:
        assert runtime.audit.problem and "audit log cannot be written" in caplog.text
        state = runtime.store.devices["door-1"]
        assert await wait_for(lambda: state.value("LockRequestDelay") is not None, timeout=8)
        param = state.params.by_name["LockRequestDelay"]
        with pytest.raises(AuditUnavailable):
            await runtime.worker.gate.run(lambda: runtime.worker.adapters["door-1"].write_param(param, 321),
                                          device="door-1", describe="write LockRequestDelay", user="local", role="engineer")
        assert runtime.twins["door-1"].holding[3000] == 200
    finally:
        await asyncio.wait_for(runtime.stop(), 10)


def test_stale_temporary_files_are_removed_at_start(tmp_path):
    backups = tmp_path / "backups"
    backups.mkdir()
    stale = backups / ".door-1-20261122-101500.json.abc123.part"
    stale.write_text("{")
    old = time.time() - 3600
    os.utime(stale, (old, old))
    fresh = backups / ".door-2.json.def456.part"  # another instance may be writing it right now
    fresh.write_text("{")
    kept = backups / "door-1-20261122-101500.json"
    kept.write_text("{}")
    Runtime(_plant(), simulate=False, data_dir=tmp_path)
    assert not stale.exists() and fresh.exists() and kept.exists()
    assert remove_stale_parts(tmp_path, older_than_s=-1) == [fresh]


def _plant():
    from app.plant import load_plant

    return load_plant(DEMO_PLANT)

