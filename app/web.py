"""Pages, JSON API and the worker's life cycle on the NiceGUI app."""

from __future__ import annotations

import importlib

from fastapi import HTTPException
from nicegui import app, ui

from app import runtime as rt
from app.runtime import Runtime


def session_role_of(client) -> str:
    """Served on loopback without login: every browser is an engineer."""
    return "engineer"


def register(runtime: Runtime) -> None:
    """Register every route for ``runtime`` and start/stop it with the app."""
    rt.set_current(runtime)
    app.on_startup(runtime.start)
    app.on_shutdown(runtime.stop)
    app.on_connect(lambda client: runtime.worker.session_opened(client.id, session_role_of(client)))
    app.on_disconnect(lambda client: runtime.worker.session_closed(client.id))

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
