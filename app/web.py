"""Pages, JSON API and the worker's life cycle on the NiceGUI app."""

from __future__ import annotations

import importlib
import secrets
from pathlib import Path

from fastapi import HTTPException, Request
from fastapi.responses import JSONResponse, RedirectResponse
from nicegui import app, ui
from starlette.middleware.base import BaseHTTPMiddleware

from app import runtime as rt
from app.runtime import Runtime

OPEN_PATHS = {"/login"}


def storage_secret(data_dir: Path) -> str:
    """A per-installation secret for the session cookies, made once and kept in the data folder."""
    path = Path(data_dir) / "session-secret"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(secrets.token_urlsafe(32))
        path.chmod(0o600)
    return path.read_text().strip()


class AuthMiddleware(BaseHTTPMiddleware):
    """Beyond the loopback address every page and API call needs a logged-in session."""

    def __init__(self, asgi_app, runtime: Runtime):
        super().__init__(asgi_app)
        self.runtime = runtime

    async def dispatch(self, request: Request, call_next):
        path = request.url.path
        if self.runtime.auth_required and not path.startswith("/_nicegui") and path not in OPEN_PATHS:
            public_plant_view = path == "/plant" and self.runtime.plant.plant_view.public
            if not public_plant_view and not app.storage.user.get("authenticated", False):
                if path.startswith("/api/"):
                    return JSONResponse({"detail": "log in first"}, status_code=401)
                return RedirectResponse(f"/login?redirect_to={path}")
        return await call_next(request)


def register(runtime: Runtime) -> None:
    """Register every route for ``runtime`` and start/stop it with the app."""
    rt.set_current(runtime)
    app.on_startup(runtime.start)
    app.on_shutdown(runtime.stop)
    app.on_disconnect(lambda client: runtime.worker.session_closed(client.id))
    app.add_middleware(AuthMiddleware, runtime=runtime)

    @ui.page("/login")
    def login_page(redirect_to: str = "/") -> None:
        from pages import login

        login.content(redirect_to)

    @ui.page("/plant")
    def plant_page() -> None:
        from pages import plant_view

        plant_view.content()

    @ui.page("/backup")
    def backup_page() -> None:
        from pages import backup

        backup.content()

    @ui.page("/audit")
    def audit_page() -> None:
        from pages import audit

        audit.content()

    @ui.page("/")
    def overview_page() -> None:
        from pages import overview

        overview.content()

    @ui.page("/device/{name}")
    def device_page(name: str) -> None:
        from pages.frame import frame

        state = runtime.store.devices.get(name)
        if state is None:
            with frame("Unknown device"):
                ui.label(f"The plant has no device named '{name}'.")
                ui.link("Back to the overview", "/")
            return
        importlib.import_module(f"pages.{state.type}").content(name)

    @ui.page("/monitor/{bus}")
    def monitor_page(bus: str) -> None:
        from pages import monitor
        from pages.frame import frame

        if bus not in runtime.store.buses:
            with frame("Unknown bus"):
                ui.label(f"The plant has no bus named '{bus}'.")
            return
        monitor.content(bus)

    @app.get("/api/devices")
    def api_devices() -> list[dict]:
        return [_summary(s) for s in runtime.store.devices.values()]

    @app.get("/api/devices/{name}")
    def api_device(name: str) -> dict:
        state = runtime.store.devices.get(name)
        if state is None:
            raise HTTPException(status_code=404, detail=f"no device named {name!r}")
        return {**_summary(state), "values": state.values()}


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
    }
