"""Probes as an attacker sends them (issue 33): socket events naming another browser's client id,
handshakes into another browser's page and malformed messages (items 4 and 9); uploads without a
session, from another browser or larger than the page allows (item 6).

The GUI runs in its own process beyond loopback (``--host 0.0.0.0``, accounts anna engineer and
tablet viewer); the "browsers" are an HTTP client and a socket.io client each (tests/socket_browser.py).
"""

from __future__ import annotations

import asyncio
import contextlib
import sqlite3
from collections.abc import AsyncIterator

import pytest
from conftest import free_port
from socket_browser import SocketBrowser
from plants import modbus_line, plant_text
from webutil import eventually, serve_beyond_loopback, stop_app, wait_http

from app.users import UserStore

pytestmark = pytest.mark.timeout(120)

@pytest.fixture(scope="module")
def beyond_loopback(tmp_path_factory):
    """The GUI on 0.0.0.0 (every browser logs in) on one simulated HD-Lock; yields (base URL, data folder, log)."""
    folder = tmp_path_factory.mktemp("sockets")
    data = folder / "data"
    store = UserStore(data / "users.toml")
    store.add("anna", "engineer", "correct horse")
    store.add("tablet", "viewer", "battery staple")
    (folder / "plant.toml").write_text(plant_text(modbus_line(timeout=0.2, poll_period=0.2, retries=None), name=None))
    port = free_port()
    proc = serve_beyond_loopback(folder, port, data)
    try:
        wait_http(f"http://127.0.0.1:{port}/login", proc, timeout=40)
        yield f"http://127.0.0.1:{port}", data, folder / "app.log"
    finally:
        stop_app(proc)


def audit_rows(data, parameter: str) -> list[tuple[str, str, str, str]]:
    with sqlite3.connect(data / "audit.sqlite") as db:
        return db.execute("SELECT user, role, new, result FROM audit WHERE parameter = ? ORDER BY id", (parameter,)).fetchall()


@contextlib.asynccontextmanager
async def logged_in(base: str) -> AsyncIterator[tuple[SocketBrowser, SocketBrowser]]:
    """An engineer's (anna) and a viewer's (tablet) browser, each logged in to the app at ``base``; closed on leaving."""
    engineer, viewer = SocketBrowser(base), SocketBrowser(base)
    try:
        await engineer.login("anna", "correct horse")
        await viewer.login("tablet", "battery staple")
        yield engineer, viewer
    finally:
        await engineer.aclose()
        await viewer.aclose()


async def test_an_event_naming_another_browsers_client_does_not_run_as_that_user(beyond_loopback):
    base, data, _log = beyond_loopback
    async with logged_in(base) as (engineer, viewer):
        victim = await engineer.open("/device/door-1")
        await viewer.open("/device/door-1")
        field, write = victim.find(**{"data-param": "LockRequestDelay"}), victim.find(**{"data-write": "LockRequestDelay"})

        # the viewer cannot take over the engineer's page by a handshake of its own ...
        intruder = SocketBrowser(base)
        intruder.http.cookies = viewer.http.cookies
        try:
            assert not await intruder.connect(victim.client_id)
            assert not await intruder.connect(victim.client_id, implicit=True)
        finally:
            await intruder.aclose()
        # ... nor send events in its name over the viewer's own socket
        await viewer.set_value(field, 175, page=victim)
        await viewer.emit_event(write, "click", [], page=victim)

        # the engineer's own events still work: a write of 180 lands, the forged 175 never did
        await engineer.set_value(field, 180)
        await engineer.emit_event(write, "click", [])
        await eventually(lambda: any(row[2].startswith("180") for row in audit_rows(data, "LockRequestDelay")),
                         timeout=20, what="the engineer's own write of 180")
        rows = audit_rows(data, "LockRequestDelay")
        assert not [row for row in rows if row[2].startswith("175")], rows
        assert all(row[:2] == ("anna", "engineer") for row in rows), rows


async def test_junk_socket_events_are_refused_without_a_traceback(beyond_loopback):
    base, _data, log = beyond_loopback
    browser = SocketBrowser(base)
    try:
        await browser.login("tablet", "battery staple")
        page = await browser.open("/device/door-1")
        before = log.read_text(errors="replace").count("Traceback")
        junk = [
            ("event", {}), ("event", {"client_id": page.client_id}), ("event", "text"), ("event", [1, 2]),
            ("event", {"client_id": page.client_id, "id": 1, "listener_id": "nope", "args": ["{"]}),
            ("event", {"client_id": page.client_id, "id": 99999, "listener_id": 5, "args": 7}),
            ("handshake", {"client_id": page.client_id}), ("handshake", None),
            ("javascript_response", {"client_id": page.client_id}), ("ack", {"client_id": page.client_id}),
            ("log", {"client_id": page.client_id, "level": "critical", "message": "x"}), ("log", {}),
            ("commission_beat", "x"),
        ]
        for name, msg in junk:
            await browser.sio.emit(name, msg)
        await browser.sio.emit("event", ({"client_id": page.client_id}, "extra"))  # two arguments (a tuple is spread)
        stray = SocketBrowser(base)  # an implicit handshake in the query without its tab and document ids
        stray.http.cookies = browser.http.cookies
        try:
            await stray.sio_connect_query(f"client_id={page.client_id}&implicit_handshake=true")
        finally:
            await stray.aclose()
        # the socket still works after the junk: a real handshake-bound event is answered
        alive = await browser.sio.call("ack", {"client_id": page.client_id, "next_message_id": 0}, timeout=10)
        assert alive is None
        assert log.read_text(errors="replace").count("Traceback") == before, log.read_text(errors="replace")[-3000:]
        assert "malformed" in log.read_text(errors="replace")
    finally:
        await browser.aclose()


# -- uploads (item 6) ----------------------------------------------------------------------------


def upload_route(page) -> str:
    element = next(i for i, e in page.elements.items() if "max-file-size" in e.get("props", {}))  # the restore upload
    return f"/_nicegui/client/{page.client_id}/upload/{element}"


async def raw_post(base: str, path: str, length: int, body: bytes, cookie: str = "") -> int:
    """POST with a stated ``Content-Length`` but only ``body`` sent: the status the server answers."""
    host, port = base.removeprefix("http://").split(":")
    reader, writer = await asyncio.open_connection(host, int(port))
    try:
        head = (f"POST {path} HTTP/1.1\r\nHost: {host}:{port}\r\nContent-Type: multipart/form-data; boundary=b\r\n"
                f"Content-Length: {length}\r\n" + (f"Cookie: {cookie}\r\n" if cookie else "") + "\r\n")
        writer.write(head.encode() + body)
        await writer.drain()
        status_line = await asyncio.wait_for(reader.readline(), 20)
        return int(status_line.split()[1])
    finally:
        writer.close()


def multipart(name: str, data: bytes) -> bytes:
    return (f'--b\r\nContent-Disposition: form-data; name="file"; filename="{name}"\r\n'
            "Content-Type: application/json\r\n\r\n").encode() + data + b"\r\n--b--\r\n"


async def test_uploads_need_the_pages_own_session_and_stay_within_the_stated_size(beyond_loopback):
    base, _data, _log = beyond_loopback
    async with logged_in(base) as (engineer, viewer):
        page = await viewer.open("/backup")
        route = upload_route(page)
        cookie = "; ".join(f"{k}={v}" for k, v in viewer.http.cookies.items())
        small = multipart("x.json", b'{"schema": "commission-backup"}')
        # no cookie at all: refused before the body is read
        assert await raw_post(base, route, len(small), small) == 401
        # 60 MB announced on the page that says 5 MB: refused before the body is read
        assert await raw_post(base, route, 60_000_000, small[:100], cookie) == 413
        # another browser's session (the engineer's) on the viewer's page
        answer = await engineer.http.post(route, files={"file": ("x.json", b"{}", "application/json")})
        assert answer.status_code == 403
        # the page's own browser, within the size: taken
        answer = await viewer.http.post(route, files={"file": ("x.json", b"{}", "application/json")})
        assert answer.status_code == 200, answer.text
        too_big = await viewer.http.post(route, files={"file": ("x.json", b" " * 6_000_000, "application/json")})
        assert too_big.status_code == 413
