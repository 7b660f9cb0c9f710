"""Pages, JSON API and the worker's life cycle on the NiceGUI app."""

from __future__ import annotations

import csv
import inspect
import io
import ipaddress
import json
import logging
import re
import secrets
import socket
import time
import uuid
import weakref
from pathlib import Path
from collections.abc import Callable
from typing import Any
from urllib.parse import parse_qs, quote, urlsplit

from fastapi import HTTPException, Query, Request
from fastapi.responses import JSONResponse, PlainTextResponse, RedirectResponse, Response
from nicegui import Client, app, core, ui
from pydantic import BaseModel, Field, create_model
from socketio import exceptions as socketio_exceptions

from app import host
from app import runtime as rt
from app.assets import AssetCache, preload_links, tailwind_style
from app.browser import BEAT_ASK_JS, BEAT_EVENT, safe_redirect, session_token
from app.runtime import Runtime
from app.state import HISTORY_SECONDS
from devices.live import json_fields as live_json_fields

log = logging.getLogger(__name__)

OPEN_PATHS = {"/login", "/login/complete", "/logout"}
LOOPBACK_NAMES = ("127.0.0.1", "localhost", "::1")
WILDCARD_HOSTS = ("0.0.0.0", "::", "")


def storage_secret(data_dir: Path) -> str:
    """A per-installation secret for the session cookies, made once and kept in the data folder."""
    path = Path(data_dir) / "session-secret"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(secrets.token_urlsafe(32))
    host.protect_file(path)  # POSIX 0600; Windows: the user profile's ACL (docs/windows-macos.md)
    return path.read_text().strip()


def allowed_host_names(host: str, extra: tuple[str, ...] | list[str] = ()) -> tuple[set[str], bool]:
    """Host names the server answers to, and whether any IP address literal is accepted.

    Loopback names always; the ``--host`` address and every ``--allowed-host``. Served on a
    wildcard address, any IP literal and this machine's name are accepted too: a page on a
    foreign site that rebinds its DNS name to this machine still sends its own name as Host.
    """
    names = {n.lower() for n in LOOPBACK_NAMES}
    names |= {normalise_host(h) for h in extra if h}
    any_ip = host in WILDCARD_HOSTS
    if any_ip:
        machine = socket.gethostname().lower()
        names |= {machine, f"{machine}.local"}
    else:
        names.add(normalise_host(host))
    return names, any_ip


def normalise_host(value: str) -> str:
    """``Host`` header or name -> lower-case name without port or IPv6 brackets."""
    value = value.strip().lower()
    if value.startswith("["):
        return value[1:value.find("]")] if "]" in value else value
    if value.count(":") == 1:
        return value.split(":", 1)[0]
    return value


class HostOriginGuard:
    """Refuse requests for foreign Host names (DNS rebinding) and cross-origin requests,
    HTTP and websocket alike (socket.io would otherwise answer any Origin)."""

    def __init__(self, asgi_app, names: set[str], any_ip: bool):
        self.app = asgi_app
        self.names = names
        self.any_ip = any_ip

    def host_ok(self, host: str) -> bool:
        name = normalise_host(host)
        if name in self.names:
            return True
        if self.any_ip:
            try:
                ipaddress.ip_address(name)
                return True
            except ValueError:
                return False
        return False

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        headers = {k.lower(): v for k, v in scope.get("headers", [])}
        host = headers.get(b"host", b"").decode("latin-1")
        why = ""
        if not self.host_ok(host):
            why = f"host {host!r} is not served here (start with --allowed-host NAME to add a name)"
        else:
            origin = headers.get(b"origin")
            if origin is not None:
                parts = urlsplit(origin.decode("latin-1"))
                scheme = "https" if scope.get("scheme") in ("https", "wss") else "http"
                if parts.scheme != scheme or parts.netloc.lower() != host.lower():
                    why = "cross-origin request refused"
        if not why:
            return await self.app(scope, receive, send)
        log.warning("refused %s %s: %s", scope["type"], scope.get("path", ""), why)
        if scope["type"] == "websocket":
            await send({"type": "websocket.close", "code": 1008})
            return None
        return await PlainTextResponse(why, status_code=403)(scope, receive, send)


class AuthMiddleware:
    """Beyond the loopback address every page and API call needs a logged-in session.

    Plain ASGI (not Starlette's BaseHTTPMiddleware, which runs every request in a task of its own
    and passes the answer through a stream): on the loopback address it costs nothing at all.
    """

    def __init__(self, asgi_app, runtime: Runtime):
        self.app = asgi_app
        self.runtime = runtime

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or not self.runtime.auth_required:
            return await self.app(scope, receive, send)
        request = Request(scope)
        path = request.url.path
        if not path.startswith("/_nicegui") and path not in OPEN_PATHS:
            public_plant_view = path == "/plant" and self.runtime.plant.plant_view.public
            if not public_plant_view and self.runtime.session_user(session_token(request)) is None:
                if path.startswith("/api/"):
                    refusal = JSONResponse({"detail": "log in first"}, status_code=401)
                else:
                    refusal = RedirectResponse(f"/login?redirect_to={quote(path)}")
                return await refusal(scope, receive, send)
        return await self.app(scope, receive, send)


# -- socket events: only from a socket admitted to the client they name ----------------------------

SOCKET_EVENTS = ("handshake", "event", "javascript_response", "ack", "log")
LOG_LEVELS = ("debug", "info", "warning", "error")
#: how long a page whose connection dropped may take to come back before it is gone for good (NiceGUI's
#: ``reconnect_timeout``; it also sets the socket's ping: every 8 s, answered within 4 s). NiceGUI's 3 s dropped the
#: connection of a browser busy for 2 s (a device page drawing its chart on a loaded laptop) and reloaded the page when
#: it came back later than 3 s: what was typed and the page's poll windows were lost. Motion and mains outputs do not
#: wait for it: they stop at once when the connection drops and within 0.5 s of the page's last beat (dead-man rule);
#: only idle control of a page that is gone is released this much later.
RECONNECT_S = 10.0
REFUSAL_LOG_PERIOD_S = 10.0  # refused or malformed socket events: one warning per period, the rest counted
_GUARDS: weakref.WeakSet[Callable] = weakref.WeakSet()  # the handlers a guard installed: never wrapped again


class SocketEventGuard:
    """NiceGUI hands a socket event to whichever client its message names (``client_id``), and
    the page code runs as the browser that built that client. Here an event reaches a client only
    from a socket its handshake admitted (the socket is in the client's room), a handshake is
    admitted only from the browser whose cookie built the page, and a malformed message is
    refused and counted instead of raising in the handler.
    """

    def __init__(self) -> None:
        self.refused = 0  # events naming a client their socket does not belong to
        self.malformed = 0  # messages of the wrong form
        self._logged_at: dict[str, float] = {}  # kind of refusal -> when it was last logged
        self._unlogged: dict[str, int] = {}

    def install(self) -> None:
        handlers = core.sio.handlers.setdefault("/", {})
        for name in SOCKET_EVENTS:
            inner = handlers.get(name)
            if inner is None or inner in _GUARDS:
                continue
            core.sio.on(name, self._wrap(name, inner))
        connect = handlers.get("connect")
        if connect is not None and connect not in _GUARDS:
            core.sio.on("connect", self._wrap_connect(connect))

    def _wrap_connect(self, inner):
        """The implicit handshake (client id and tab id in the socket's query) passes the same check."""
        async def handler(sid: str, environ: dict, *rest):
            query = parse_qs((environ or {}).get("QUERY_STRING", ""))
            client_id = (query.get("client_id") or [""])[0]
            implicit = (query.get("implicit_handshake") or [""])[0] == "true"
            if implicit and not all(query.get(k) for k in ("client_id", "tab_id", "document_id")):
                self.malformed += 1
                self._note("malformed", "malformed (implicit handshake without its ids)", sid, "connect")
                raise socketio_exceptions.ConnectionRefusedError("malformed handshake")
            if implicit and not _same_browser(environ, client_id):
                self.refused += 1
                self._note("handshake", "another browser's", sid, "connect")
                raise socketio_exceptions.ConnectionRefusedError("not this browser's page")
            result = inner(sid, environ, *rest)
            if inspect.isawaitable(result):
                result = await result
            return result

        _GUARDS.add(handler)
        return handler

    def _note(self, kind: str, what: str, sid: str, name: str) -> None:
        """One warning per kind of refusal and period; the ones between are counted in the next."""
        now = time.monotonic()
        if now - self._logged_at.get(kind, -REFUSAL_LOG_PERIOD_S) < REFUSAL_LOG_PERIOD_S:
            self._unlogged[kind] = self._unlogged.get(kind, 0) + 1
            return
        more = self._unlogged.pop(kind, 0)
        log.warning("socket %s: %s %r event refused%s", sid, what, name, f" ({more} more since the last warning)" if more else "")
        self._logged_at[kind] = now

    def _wrap(self, name: str, inner):
        async def handler(sid: str, *args):
            msg = args[0] if len(args) == 1 else None
            problem = _malformed(name, msg)
            if problem:
                self.malformed += 1
                self._note("malformed", f"malformed ({problem})", sid, name)
                return False if name == "handshake" else None
            if name == "handshake":
                if not sid.startswith("test-") and not _same_browser(_environ(sid), msg["client_id"]):
                    self.refused += 1
                    self._note("handshake", "another browser's", sid, name)
                    return False
            elif not sid.startswith("test-") and msg["client_id"] not in core.sio.rooms(sid):
                self.refused += 1
                self._note("foreign", "foreign client id in a", sid, name)
                return None
            try:
                result = inner(sid, msg)
            except KeyError:
                if name != "event":
                    raise
                # NiceGUI finds the listener of an event by its id: one its element does not have is refused here
                self.malformed += 1
                self._note("malformed", "malformed (unknown listener)", sid, name)
                return None
            if inspect.isawaitable(result):
                result = await result
            return result

        _GUARDS.add(handler)
        return handler


def _malformed(name: str, msg: Any) -> str:
    """Why a socket message cannot be handled ("" when it can)."""
    if not isinstance(msg, dict) or not isinstance(msg.get("client_id"), str):
        return "no client id"
    if name == "handshake":
        if not all(isinstance(msg.get(k), str) for k in ("tab_id", "document_id")):
            return "no tab or document id"
        if msg.get("old_tab_id") is not None and not isinstance(msg["old_tab_id"], str):
            return "bad old tab id"
        if msg.get("next_message_id") is not None and not isinstance(msg["next_message_id"], int):
            return "bad message id"
    elif name == "event":
        args = msg.get("args", [])
        if not isinstance(msg.get("id"), int) or not isinstance(msg.get("listener_id"), str) or not isinstance(args, list):
            return "no element, listener or arguments"
        for arg in args:
            if arg is not None:
                if not isinstance(arg, str):
                    return "arguments not JSON text"
                try:
                    json.loads(arg)
                except ValueError:
                    return "arguments not JSON"
    elif name == "javascript_response":
        if not isinstance(msg.get("request_id"), str):
            return "no request id"
    elif name == "ack":
        if not isinstance(msg.get("next_message_id"), int):
            return "no message id"
    elif name == "log":
        if msg.get("level") not in LOG_LEVELS or not isinstance(msg.get("message"), str):
            return "no level or message"
    return ""


def _environ(sid: str) -> dict:
    try:
        return core.sio.get_environ(sid) or {}
    except (KeyError, ValueError):
        return {}


def _same_browser(environ: dict, client_id: str) -> bool:
    """Whether a socket (its ``environ``) comes from the browser (session cookie) whose request built the client."""
    client = Client.instances.get(client_id)
    if client is None:
        return True  # NiceGUI refuses an unknown client itself
    request = client.request
    if request is None or "session" not in request.scope:
        return True  # no session cookies on this app (the read-only site view)
    page_browser = request.session.get("id")
    scope = environ.get("asgi.scope") or {}
    socket_browser = (scope.get("session") or {}).get("id")
    return bool(page_browser) and socket_browser == page_browser


SOCKET_GUARD = SocketEventGuard()


# -- uploads ------------------------------------------------------------------------------------

UPLOAD_PATH = re.compile(r"^/_nicegui/client/([^/]+)/upload/(\d+)$")  # NiceGUI's route of each ui.upload
UPLOAD_MAX_BYTES = 32 * 1024 * 1024  # an upload whose element names no max-file-size (a recording to replay)
UPLOAD_FORM_OVERHEAD = 64 * 1024  # multipart headers around the file


def upload_limit(element: Any) -> int:
    """Bytes an upload to ``element`` may carry: the size its page states (``max_file_size``), else
    :data:`UPLOAD_MAX_BYTES`; either with the form's overhead."""
    stated = element.props.get("max-file-size") if element is not None else None
    limit = int(stated) if isinstance(stated, int | float) and stated > 0 else UPLOAD_MAX_BYTES
    return min(limit, UPLOAD_MAX_BYTES) + UPLOAD_FORM_OVERHEAD


class UploadGuard:
    """Every upload route (``/_nicegui/client/ID/upload/N``, one per ui.upload of every page) takes
    a file only from the browser whose request built the page, logged in where logging in is
    needed, and no larger than the page says: the length is checked before a byte of the body is
    read, and the body is counted while it is read (a request that lies about it is cut off).
    """

    def __init__(self, asgi_app, runtime: Runtime):
        self.app = asgi_app
        self.runtime = runtime

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or not scope.get("path", "").startswith("/_nicegui/client/"):
            return await self.app(scope, receive, send)
        match = UPLOAD_PATH.match(scope["path"])
        if match is None:
            return await self.app(scope, receive, send)
        client = Client.instances.get(match.group(1))
        element = client.elements.get(int(match.group(2))) if client is not None else None
        why, status = self.refusal(scope, client, element)
        if not why:
            headers = {k.lower(): v for k, v in scope.get("headers", [])}
            limit = upload_limit(element)
            try:
                length = int(headers.get(b"content-length", b"-1"))
            except ValueError:
                length = -1
            if length < 0:
                why, status = "an upload must state its length", 411
            elif length > limit:
                why, status = f"the file is too large: at most {(limit - UPLOAD_FORM_OVERHEAD) / 1e6:.1f} MB", 413
        if why:
            log.warning("upload to %s refused: %s", scope["path"], why)
            return await PlainTextResponse(why, status_code=status)(scope, receive, send)  # the body is never read
        received = 0

        async def counted():
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit:
                    log.warning("upload to %s cut off: more than its stated length", scope["path"])
                    return {"type": "http.disconnect"}
            return message

        return await self.app(scope, counted, send)

    def refusal(self, scope, client, element) -> tuple[str, int]:
        if client is None or element is None:
            return "no such upload", 404
        request = client.request
        session = scope.get("session")
        if self.runtime.auth_required:
            token = (session or {}).get("auth")
            if self.runtime.session_user(token) is None:
                return "log in first", 401
        if request is not None and "session" in request.scope and session is not None:
            if not request.session.get("id") or session.get("id") != request.session.get("id"):
                return "this upload belongs to another browser's page", 403
        return "", 200


def serve_assets_from_memory() -> None:
    """NiceGUI's files from memory (app/assets.py), inside the host guard; every page preloads
    what it would otherwise ask for late and carries the pages' Tailwind rules, compiled beforehand."""
    app.add_middleware(AssetCache)
    head = preload_links() + "\n" + tailwind_style()
    if head not in Client.shared_head_html:
        ui.add_head_html(head, shared=True)


def register(runtime: Runtime, pages: Callable[[], None], *, host: str = "127.0.0.1",
             allowed_hosts: tuple[str, ...] | list[str] = ()) -> None:
    """Serve ``runtime``: middleware, login, the JSON API, and start/stop it with the app.

    :param pages: registers the page routes (the composition root, server/, passes them: app/ imports no page)
    :param host: the address the server listens on (its name is accepted as Host)
    :param allowed_hosts: further names or addresses browsers use to reach it
    """
    rt.set_current(runtime)
    app.on_startup(runtime.start)
    app.on_shutdown(runtime.stop)
    app.on_disconnect(lambda client: runtime.worker.session_closed(client.id))  # stops motion and outputs at once
    app.on_delete(lambda client: runtime.worker.session_deleted(client.id))  # releases control: the page did not come back
    app.add_middleware(AuthMiddleware, runtime=runtime)
    app.add_middleware(UploadGuard, runtime=runtime)
    serve_assets_from_memory()
    names, any_ip = allowed_host_names(host, allowed_hosts)
    app.add_middleware(HostOriginGuard, names=names, any_ip=any_ip)

    def on_beat(sid: str, *args) -> None:
        """A page's sign of life (dead-man rule); only counted from the socket of that page."""
        msg = args[0] if len(args) == 1 else None
        client_id = msg.get("client_id") if isinstance(msg, dict) else None
        if isinstance(client_id, str) and client_id in core.sio.rooms(sid):
            runtime.worker.heartbeat(client_id, msg.get("t"))  # the browser's own time of the beat

    core.sio.on(BEAT_EVENT, on_beat)

    def ask_beat(session: str, on: bool) -> None:
        """The dead-man supervisor asks the page of ``session`` to beat (it holds something, or its connection
        came back) or to stop (it held nothing for a while); a page that holds nothing sends no beats."""
        client = Client.instances.get(session)
        if client is not None and not client.is_deleted:
            client.run_javascript(BEAT_ASK_JS % ("true" if on else "false"))

    runtime.worker.on_beat_ask(ask_beat)
    app.on_connect(lambda client: runtime.worker.session_connected(client.id))  # a page back: asked to beat once more
    SOCKET_GUARD.install()

    @app.get("/login/complete", include_in_schema=False)
    def login_complete(request: Request, ticket: str = "", redirect_to: str = "/"):
        """Turn a checked login into a new session: a new cookie id and a new token (no fixation)."""
        token = runtime.sessions.redeem(ticket, request.session.get("id", ""))
        if token is None:
            return RedirectResponse("/login?expired=1", status_code=303)
        request.session.clear()
        request.session["id"] = str(uuid.uuid4())
        request.session["auth"] = token
        return RedirectResponse(safe_redirect(redirect_to), status_code=303)

    @app.get("/logout", include_in_schema=False)
    def logout(request: Request):
        runtime.sessions.logout(session_token(request))
        request.session.clear()
        request.session["id"] = str(uuid.uuid4())
        return RedirectResponse("/login", status_code=303)

    pages()  # the page routes, from the composition root (server/), before the API

    # the JSON API is described at /docs (Swagger UI), /redoc and /openapi.json, behind the same login
    app.docs_url, app.redoc_url, app.openapi_url = "/docs", "/redoc", "/openapi.json"
    app.setup()

    @app.get("/api/devices", response_model=list[DeviceSummary])
    def api_devices() -> list[dict]:
        """Every device of the plant: status and counters, without values."""
        return [_summary(s) for s in runtime.store.devices.values()]

    @app.get("/api/devices/{name}", response_model=DeviceDetail)
    def api_device(name: str) -> dict:
        """One device with every known value, keyed by the device document's names."""
        state = _device(runtime, name)
        return {**_summary(state), "values": state.values_json()}

    @app.get(
        "/api/devices/{name}/history",
        response_model=History,
        responses={200: {"content": {"text/csv": {"schema": {"type": "string"}}},
                         "description": "the samples as JSON, or as CSV with ?format=csv (one column per series)"}},
    )
    def api_history(name: str, seconds: float = Query(60.0, gt=0, le=HISTORY_SECONDS),
                    format: str = Query("json", pattern="^(json|csv)$")):
        """The recorded time series of the last ``seconds`` (the data the device page's charts show)."""
        state = _device(runtime, name)
        samples = state.history_since(seconds)
        series = _series(samples)
        if format == "csv":
            return Response(_history_csv(series, samples), media_type="text/csv",
                            headers={"Content-Disposition": f'attachment; filename="{name}-history.csv"'})
        return {"name": name, "seconds": seconds, "series": series,
                "samples": [{"time": t, "values": values} for t, values in samples]}


def register_view(store, pages: Callable[[], None], *, host: str = "127.0.0.1",
                  allowed_hosts: tuple[str, ...] | list[str] = ()) -> None:
    """``commission view``: the plant-wide read-only view of ``store`` (an app.site_view.SiteStore).

    :param pages: registers the view's page (the composition root, server/, passes it)

    No plant, no buses, no worker: nothing on these routes can write, and MQTT carries no commands.
    """
    app.on_startup(store.start)
    app.on_shutdown(store.stop)
    serve_assets_from_memory()
    names, any_ip = allowed_host_names(host, allowed_hosts)
    app.add_middleware(HostOriginGuard, names=names, any_ip=any_ip)

    pages()  # the page of the view, from the composition root (server/)

    app.docs_url, app.redoc_url, app.openapi_url = "/docs", "/redoc", "/openapi.json"
    app.setup()

    @app.get("/api/site")
    def api_site() -> dict:
        """Every site, instance and device heard on the broker, with live values and the view's status
        (``view_status``: the device's own status, or ``stale``, ``stopped``, ``vanished``)."""
        return store.snapshot()


# -- JSON API response models (documented at /docs) ---------------------------------------------


class DeviceSummary(BaseModel):
    name: str
    type: str
    bus: str
    online: bool
    status: str = Field(description='"online", "stale", "offline" or "unknown" (never asked)')
    last_seen: float | None = Field(description="Unix time of the last answer or frame")
    counters: dict[str, int]
    last_error: str
    drift: dict | None = Field(None, description='parameters changed since the approved set: {"approved": bool, "changed": [...]}')


# one value, a live point or a register parameter: the JSON form of devices.live.LiveValue, declared there once
Value = create_model("Value", __doc__="One value: a live point or a register parameter (devices.live.LiveValue).",
                     **{key: (typ, Field(default, description=doc)) for key, typ, default, doc in live_json_fields()})


class DeviceDetail(DeviceSummary):
    values: dict[str, Value]


class Sample(BaseModel):
    time: float
    values: dict[str, float | int | bool | None]


class History(BaseModel):
    name: str
    seconds: float
    series: list[str] = Field(description="every series name that occurs, in order of first appearance")
    samples: list[Sample]


def _device(runtime: Runtime, name: str):
    state = runtime.store.devices.get(name)
    if state is None:
        raise HTTPException(status_code=404, detail=f"no device named {name!r}")
    return state


def _series(samples: list[tuple[float, dict]]) -> list[str]:
    names: dict[str, None] = {}
    for _t, values in samples:
        for key in values:
            names.setdefault(key)
    return list(names)


def _history_csv(series: list[str], samples: list[tuple[float, dict]]) -> str:
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(["time", *series])
    for t, values in samples:
        writer.writerow([f"{t:.3f}", *("" if values.get(k) is None else values[k] for k in series)])
    return out.getvalue()


def _summary(state) -> dict:
    s = state.summary()
    return {
        "name": s["name"],
        "type": s["type"],
        "bus": s["bus"],
        "online": s["online"],
        "status": s["status"],
        "last_seen": s["last_seen"],
        "counters": s["counters"],
        "last_error": s["last_error"],
        "drift": state.drift,  # the commissioning record: changed since approved (app/record.py)
    }
