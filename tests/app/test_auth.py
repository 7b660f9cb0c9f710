"""Users and roles: accounts with argon2 hashes, the start-up refusal, login, and a viewer who cannot write."""

from __future__ import annotations

import contextlib
import io
from collections.abc import AsyncIterator
from pathlib import Path

import pytest
from conftest import modbus_plant, wait_for
from nicegui import ui
from nicegui.testing import User
from webutil import simulated_user

from app.cli import main
from app.runtime import Runtime
from app.users import UserError, UserStore, is_loopback

pytestmark = pytest.mark.timeout(40)


def test_a_name_nobody_has_is_checked_against_a_hash_made_at_the_first_miss(tmp_path):
    """A miss takes as long as a wrong password (a real argon2 check), but the hash it is checked against is not made
    when the module is imported: every process that starts a plant imports it, most never check a password."""
    import subprocess
    import sys

    from app import users

    fresh = subprocess.run([sys.executable, "-c", "import app.runtime, app.users as u; print(u._dummy_hash.cache_info().currsize)"],
                           capture_output=True, text=True, check=True, cwd=Path(__file__).resolve().parents[2])
    assert fresh.stdout.strip() == "0"
    assert UserStore(tmp_path / "users.toml").verify("nobody", "x" * 8) is None
    assert users._dummy_hash().startswith("$argon2id$")


def test_accounts_store_salted_hashes(tmp_path):
    store = UserStore(tmp_path / "users.toml")
    store.add("anna", "engineer", "correct horse")
    store.add("tablet", "viewer", "battery staple")
    text = (tmp_path / "users.toml").read_text()
    assert "correct horse" not in text and "$argon2id$" in text
    again = UserStore(tmp_path / "users.toml")
    assert again.verify("anna", "correct horse").role == "engineer"
    assert again.verify("anna", "wrong") is None and again.verify("nobody", "x" * 8) is None
    assert again.has_engineer()
    again.add("anna2", "engineer", "correct horse")
    first, second = again.users["anna"].password_hash, again.users["anna2"].password_hash
    assert first != second  # salted
    with pytest.raises(UserError):
        again.add("bad name!", "engineer", "long enough")
    with pytest.raises(UserError):
        again.add("x", "admin", "long enough")
    with pytest.raises(UserError):
        again.add("x", "viewer", "short")


def test_loopback():
    assert is_loopback("127.0.0.1") and is_loopback("localhost") and is_loopback("::1")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.0.2.7")


def test_user_add_command(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("sys.stdin", io.StringIO("s3cret-pass\n"))
    assert main(["user", "add", "anna", "--role", "engineer", "--password-stdin", "--data-dir", str(tmp_path)]) == 0
    assert UserStore(tmp_path / "users.toml").verify("anna", "s3cret-pass")
    assert main(["user", "list", "--data-dir", str(tmp_path)]) == 0
    assert "anna\tengineer" in capsys.readouterr().out


def test_refuses_to_listen_beyond_loopback_without_engineer(tmp_path, capsys):
    assert main(["--host", "0.0.0.0", "--data-dir", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "refusing to listen on 0.0.0.0" in err and "commission user add NAME --role engineer" in err
    store = UserStore(tmp_path / "users.toml")
    store.add("tablet", "viewer", "battery staple")  # a viewer alone is not enough
    assert main(["--host", "0.0.0.0", "--data-dir", str(tmp_path)]) == 2


@contextlib.asynccontextmanager
async def secured_app(tmp_path, public_plant_view: bool = False) -> AsyncIterator[tuple[User, Runtime]]:
    """The app as served beyond loopback: login required; accounts anna (engineer), tablet (viewer)."""
    plant = modbus_plant(locks=(("door-1", 1),))
    plant.plant_view.public = public_plant_view
    store = UserStore(tmp_path / "users.toml")
    store.add("anna", "engineer", "correct horse")
    store.add("tablet", "viewer", "battery staple")
    runtime = Runtime(plant, simulate=True, data_dir=tmp_path, auth_required=True)
    async with simulated_user(runtime) as user:
        yield user, runtime


@pytest.fixture
async def secured(tmp_path) -> AsyncIterator[tuple[User, Runtime]]:
    async with secured_app(tmp_path) as app_:
        yield app_


async def login(user: User, name: str, password: str, succeeds: bool = True) -> None:
    await user.open("/login")
    user.find("User").type(name)
    user.find("Password").type(password)
    user.find("Log in").click()
    if succeeds:
        await user.should_see("Overview", retries=50)  # the login page sends the browser on to / (argon2 takes a while)


async def test_pages_need_login(secured):
    user, _runtime = secured
    response = await user.http_client.get("/", follow_redirects=False)
    assert response.status_code in (302, 307) and "/login" in response.headers["location"]
    assert (await user.http_client.get("/api/devices")).status_code == 401


async def test_wrong_password(secured):
    user, _runtime = secured
    await login(user, "anna", "nope nope", succeeds=False)
    await user.should_see("Wrong user name or password", retries=50)  # argon2 on a loaded machine


async def _delay_300_typed(user, runtime) -> ui.button:
    """door-1's LockRequestDelay, once read, typed as 300 on the open page: its write button."""
    state = runtime.store.devices["door-1"]
    assert await wait_for(lambda: state.value("LockRequestDelay") is not None, timeout=5)
    delay = next(e for e in user.find(ui.number).elements if e.props.get("data-param") == "LockRequestDelay")
    delay.set_value(300)
    return next(e for e in user.find(ui.button).elements if e.props.get("data-write") == "LockRequestDelay")


async def test_viewer_reads_but_cannot_write(secured):
    user, runtime = secured
    await login(user, "tablet", "battery staple")
    await user.open("/device/door-1")
    await user.should_see("HD-Lock door-1")
    await user.should_see("tablet (viewer)")
    await user.should_see("Read-only session (viewer)")
    write = await _delay_300_typed(user, runtime)
    # a viewer sees the write control disabled ...
    assert not write.enabled or write.props.get("disable")
    # ... and the refusal itself comes from the worker's gate, whatever the page shows: the same
    # declared write invoked as this account (a crafted event) is refused, audited and sends nothing
    from app.worker import PermissionDenied

    with pytest.raises(PermissionDenied, match="viewer role and may not write"):
        await runtime.worker.gate.invoke("door-1", "write parameter", {"param": "holding:3000", "value": 300},
                                         user="tablet", role="engineer")  # the gate takes the account's role, not the caller's
    assert runtime.twins["door-1"].holding[3000] == 200
    entry = runtime.audit.query(device="door-1")[0]
    assert entry.user == "tablet" and entry.role == "viewer" and entry.result.startswith("refused")


async def test_engineer_can_write(secured):
    user, runtime = secured
    await login(user, "anna", "correct horse")
    await user.open("/device/door-1")
    await user.should_see("anna (engineer)")
    write = await _delay_300_typed(user, runtime)
    from nicegui.testing.user_interaction import UserInteraction

    UserInteraction(user, {write}, None).click()
    await user.should_see("written and read back")
    assert runtime.twins["door-1"].holding[3000] == 300
    entry = runtime.audit.query(device="door-1")[0]
    assert (entry.user, entry.parameter, entry.old, entry.new, entry.result) == ("anna", "LockRequestDelay", "200 ms", "300 ms", "ok")


async def test_public_plant_view(tmp_path):
    async with secured_app(tmp_path, public_plant_view=True) as (user, _runtime):
        await user.open("/plant")
        await user.should_see("door-1")
        await user.should_not_see(kind=ui.button)  # read-only by construction
        response = await user.http_client.get("/", follow_redirects=False)
        assert "/login" in response.headers["location"]
