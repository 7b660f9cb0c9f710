"""Who is using this browser session: on loopback a local engineer, else the logged-in account."""

from __future__ import annotations

from nicegui import app

from app import runtime as rt

LOCAL = ("local", "engineer")


def current_user() -> tuple[str, str]:
    """(user name, role) of the session; ("", "") when logging in is needed and nobody did."""
    runtime = rt.current()
    if not runtime.auth_required:
        return LOCAL
    storage = app.storage.user
    if not storage.get("authenticated"):
        return "", ""
    user = runtime.users.users.get(storage.get("user", ""))
    if user is None:  # the account was removed meanwhile
        return "", ""
    return user.name, user.role


def can_write() -> bool:
    return current_user()[1] == "engineer"
