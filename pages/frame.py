"""Shared page frame: header with plant name, navigation and bus connection state."""

from __future__ import annotations

import time
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path

from nicegui import ui

from app import runtime as rt
from pages.session import current_user

CSS = (Path(__file__).resolve().parent.parent / "static" / "commission.css").read_text()
STATUS_ICON = {"online": "check_circle", "stale": "schedule", "offline": "error", "unknown": "help"}


def fmt_age(seconds: float | None) -> str:
    if seconds is None:
        return "never"
    if seconds < 1:
        return "just now"
    if seconds < 120:
        return f"{seconds:.0f} s ago"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min ago"
    return f"{seconds / 3600:.1f} h ago"


def fmt_time(t: float | None) -> str:
    return "-" if t is None else datetime.fromtimestamp(t).strftime("%H:%M:%S")


def _logout() -> None:
    from nicegui import app

    app.storage.user.clear()
    ui.navigate.to("/login")


def notify_error(message: str) -> None:
    ui.notify(message, type="negative", multi_line=True, close_button="OK", timeout=0)


@contextmanager
def frame(title: str):
    """Header, navigation and a content column; yields inside the column."""
    runtime = rt.current()
    ui.add_css(CSS)
    ui.page_title(f"{title} - commission")
    with ui.header().classes("items-center bg-blue-grey-9 q-py-xs"):
        ui.link("commission", "/").classes("text-h6 text-white no-underline")
        ui.label(f"plant: {runtime.plant.name}").classes("text-caption text-grey-4")
        if runtime.sim is not None:
            ui.badge("simulated devices", color="purple-3").classes("text-black")
        ui.space()
        with ui.row().classes("items-center gap-2") as buses:
            pass
        ui.link("Overview", "/").classes("text-white")
        ui.link("Plant view", "/plant").classes("text-white")
        ui.link("Backup", "/backup").classes("text-white")
        ui.link("Audit", "/audit").classes("text-white")
        user, role = current_user()
        if runtime.auth_required:
            ui.label(f"{user} ({role})").classes("text-caption text-grey-4")
            ui.button("Log out", on_click=_logout).props("flat dense color=white")
        elif role:
            ui.label("local engineer").classes("text-caption text-grey-4").tooltip(
                "Served on the loopback address only: no login, full rights"
            )
    client = ui.context.client
    runtime.worker.session_opened(client.id, role or "none")

    def refresh_buses() -> None:
        buses.clear()
        with buses:
            for bus in runtime.store.buses.values():
                color = "green" if bus.connected else "red"
                chip = ui.link(f"{bus.name}", f"/monitor/{bus.name}").classes("text-white no-underline")
                with chip:
                    ui.icon("lan" if bus.connected else "link_off", color=color).classes("q-ml-xs")
                    ui.tooltip(f"{bus.type} {bus.endpoint}: " + ("connected" if bus.connected else bus.last_error or "not connected"))

    refresh_buses()
    ui.timer(2.0, refresh_buses)
    with ui.column().classes("w-full q-pa-md gap-4"):
        ui.label(title).classes("text-h5")
        if role == "viewer":
            with ui.row().classes("w-full bg-amber-1 q-pa-sm items-center"):
                ui.icon("visibility")
                ui.label("Read-only session (viewer): writes, commands and restores are refused. Log in as an engineer to change anything.")
        yield


STATUS_COLOR = {"online": "positive", "stale": "warning", "offline": "negative", "unknown": "grey"}


def status_text(status: str, age: float | None) -> str:
    return {"online": "online", "stale": f"stale ({fmt_age(age)})", "offline": "offline", "unknown": "waiting"}[status]


def set_status_badge(badge: ui.badge, status: str, age: float | None) -> None:
    badge.set_text(status_text(status, age))
    badge.props(f"color={STATUS_COLOR[status]}")


def now() -> float:
    return time.time()
