"""Who is using this browser session: on loopback a local engineer, else the logged-in account."""

from __future__ import annotations

from nicegui import context

from app import runtime as rt
from app.browser import session_token

LOCAL = ("local", "engineer")


def current_user() -> tuple[str, str]:
    """(user name, role) of the session; ("", "") when logging in is needed and nobody did.

    Looked up at every call: a logout, a removed account or a changed role takes effect at once.
    """
    runtime = rt.current()
    if not runtime.auth_required:
        return LOCAL
    try:
        request = context.client.request
    except RuntimeError:  # no page context (e.g. a background task)
        return "", ""
    user = runtime.session_user(session_token(request))
    if user is None:
        return "", ""
    return user.name, user.role


def client_address() -> str:
    """The browser's address as the server sees it (for the login throttle and the audit log)."""
    try:
        request = context.client.request
    except RuntimeError:
        return ""
    return request.client.host if request is not None and request.client is not None else ""


def can_write() -> bool:
    return current_user()[1] == "engineer"
