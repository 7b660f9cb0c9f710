"""OPC UA logins checked like the web login (issue 41, item 1): the password hash is checked in a
thread (the event loop goes on), wrong passwords are throttled by the same throttle as the web
login and written to the audit log within the same bounded rows, and user-name tokens are offered
only when anonymous sessions are off."""

from __future__ import annotations

import asyncio
import threading
import time

import pytest
from asyncua import Client, ua
from conftest import free_port

from app.audit import AuditLog
from app.auth import REFUSAL_ROWS_PER_CLIENT, LoginThrottle
from app.opcua_server import OpcuaServer
from app.plant import parse_plant
from app.state import StateStore
from app.users import UserStore
from devices.live import DeviceState

pytestmark = pytest.mark.timeout(90)
HASH_S = 0.6  # the time one password check takes here (argon2 is tuned to take a noticeable time)


class SlowUsers:
    """The accounts, with a password check that takes HASH_S and is counted (and where it ran)."""

    def __init__(self, users: UserStore):
        self.users, self.checks, self.threads = users, 0, set()

    def verify(self, name: str, password: str):
        self.checks += 1
        self.threads.add(threading.current_thread().name)
        time.sleep(HASH_S)  # a slow password hash, as argon2 is on a small machine
        return self.users.verify(name, password)


def _server(tmp_path, anonymous: bool, users=None, throttle=None, audit=None):
    port = free_port()
    flag = "true" if anonymous else "false"
    plant = parse_plant(f'name = "p"\n[opcua]\nendpoint = "opc.tcp://127.0.0.1:{port}"\nanonymous = {flag}\n')
    store = StateStore()
    store.add(DeviceState("pump", "hdlock", "line1"))
    server = OpcuaServer(plant.opcua, store, plant, users=users, audit=audit, throttle=throttle)
    return server, f"opc.tcp://127.0.0.1:{port}"


async def test_user_name_tokens_offered_only_when_anonymous_is_off(tmp_path):
    users = UserStore(tmp_path / "users.toml")
    for anonymous, expected in ((True, {ua.UserTokenType.Anonymous}), (False, {ua.UserTokenType.UserName})):
        server, url = _server(tmp_path, anonymous, users=users)
        await server.start()
        try:
            client = Client(url, timeout=5)
            endpoints = await client.connect_and_get_server_endpoints()
            offered = {policy.TokenType for endpoint in endpoints for policy in endpoint.UserIdentityTokens}
            assert offered == expected, (anonymous, offered)
        finally:
            await server.stop()


async def _login(url: str, user: str, password: str) -> bool:
    client = Client(url, timeout=5)
    client.set_user(user)
    client.set_password(password)
    try:
        await client.connect()
    except (ua.UaStatusCodeError, ua.UaError, asyncio.TimeoutError, OSError):
        return False
    await client.disconnect()
    return True


async def test_wrong_passwords_checked_off_the_loop_throttled_and_audited(tmp_path):
    accounts = UserStore(tmp_path / "users.toml")
    accounts.add("tablet", "viewer", "pass-word-1")
    users = SlowUsers(accounts)
    throttle = LoginThrottle()  # the runtime's, shared with the web login
    audit = AuditLog(tmp_path / "audit.sqlite")
    server, url = _server(tmp_path, False, users=users, throttle=throttle, audit=audit)
    await server.start()
    stalls: list[float] = []
    stop = asyncio.Event()

    async def ticker():
        last = time.monotonic()
        while not stop.is_set():
            await asyncio.sleep(0.005)
            now = time.monotonic()
            stalls.append(now - last)
            last = now

    tick = asyncio.create_task(ticker())
    try:
        results = [await _login(url, "tablet", f"guess-{i}") for i in range(6)]
        assert results == [False] * 6
        assert max(stalls) < HASH_S * 0.75, f"the loop stood still {max(stalls) * 1000:.0f} ms during a password check"
        assert users.checks == 3, "after three wrong passwords the next are refused without checking them"
        assert "MainThread" not in users.threads
        assert throttle.wait_s("user:tablet") > 0, "the web login's throttle knows of the OPC UA failures"
        rows = [r for r in audit.query(limit=100) if r.action == "login"]
        # the web login's bound: five rows per client address and minute, the rest counted
        assert len(rows) == REFUSAL_ROWS_PER_CLIENT and all("opcua" in r.result for r in rows), [r.result for r in rows]
        assert sum("throttled" in r.result for r in rows) == 2
        # anonymous is off: a session without a user is refused, and nothing is hashed for it
        checks = users.checks
        with pytest.raises(ua.UaStatusCodeError):
            async with Client(url, timeout=5):
                pass
        assert users.checks == checks
    finally:
        stop.set()
        await tick
        await server.stop()
        audit.close()


async def test_right_password_logs_in_and_is_audited(tmp_path):
    accounts = UserStore(tmp_path / "users.toml")
    accounts.add("tablet", "viewer", "pass-word-1")
    audit = AuditLog(tmp_path / "audit.sqlite")
    server, url = _server(tmp_path, False, users=SlowUsers(accounts), throttle=LoginThrottle(), audit=audit)
    await server.start()
    try:
        assert await _login(url, "tablet", "pass-word-1")
        rows = [r for r in audit.query(limit=10) if r.action == "login"]
        assert rows and rows[0].user == "tablet" and rows[0].result.startswith("ok") and "opcua" in rows[0].result
    finally:
        await server.stop()
        audit.close()
