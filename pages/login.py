"""Login, needed when the GUI listens beyond the loopback address."""

from __future__ import annotations

import asyncio
from urllib.parse import quote

from nicegui import context, ui

from app import i18n
from app import runtime as rt
from app.auth import LOGIN_PASSWORD_MAX, shown_name
from app.browser import safe_redirect
from pages.session import client_address


def content(redirect_to: str = "/", expired: str = "") -> None:
    runtime = rt.current()
    redirect_to = safe_redirect(redirect_to)
    if not runtime.auth_required:
        ui.navigate.to(redirect_to)
        return
    lang = i18n.page_language()
    _ = lang.gettext
    request = context.client.request
    browser = request.session.get("id", "") if request is not None and "session" in request.scope else ""
    address = client_address() or "unknown address"  # the audit log's words (records stay in one language)

    async def refused(account: str, result: str) -> None:
        """An audit row for a refused login, within the rows allowed per client (the rest are counted)."""
        skipped = runtime.login_throttle.rows.take(address)
        if skipped is None:
            return
        if skipped:
            result += f"; {skipped} more refused from this address not written one by one"
        await runtime.audit.arecord(user=account or "?", role="", device="", action="login", result=result)

    async def attempt() -> None:
        typed = (name.value or "").strip()
        account = shown_name(typed)  # a 64 KiB name is no account: kept short in the throttle and the audit
        keys = (f"user:{account}", f"client:{address}")
        wait = runtime.login_throttle.wait_s(*keys)
        if wait > 0:
            message.set_text(_("Too many wrong passwords: try again in {seconds} s.").format(seconds=lang.number(round(wait))))
            await refused(account, f"refused: throttled ({wait:.0f} s) from {address}")
            return
        # counted as a failure before the check: an attempt cut off half-way still counts
        failures = runtime.login_throttle.failed(*keys)
        secret = password.value or ""
        user = None
        if account == typed and len(secret) <= LOGIN_PASSWORD_MAX:
            button.disable()
            try:
                # argon2 takes tens of milliseconds on purpose: never on the event loop
                user = await asyncio.to_thread(runtime.users.verify, typed, secret)
            finally:
                button.enable()
        if user is None:
            await refused(account, f"failed: wrong user name or password from {address} ({failures} in a row)")
            message.set_text(_("Wrong user name or password"))
            ui.notify(_("Wrong user name or password"), type="negative")
            password.set_value("")
            return
        runtime.login_throttle.succeeded(*keys)  # this one was right after all
        await runtime.audit.arecord(user=user.name, role=user.role, device="", action="login", result=f"ok from {address}")
        ticket = runtime.sessions.issue_ticket(user.name, browser)
        ui.navigate.to(f"/login/complete?ticket={ticket}&redirect_to={quote(redirect_to)}")

    ui.page_title(_("Log in - commission"))
    with ui.card().classes("absolute-center w-80"):
        with ui.row().classes("w-full items-center no-wrap"):
            ui.label("commission").classes("text-h5")
            ui.space()
            i18n.language_switch(lang, dark=False)
        ui.label(_("plant {plant}").format(plant=runtime.plant.name)).classes("text-caption text-grey-8")
        name = ui.input(_("User")).props("outlined autofocus maxlength=64").classes("w-full").on("keydown.enter", attempt)
        password = ui.input(_("Password"), password=True, password_toggle_button=True).props("outlined").classes("w-full").on(
            "keydown.enter", attempt
        )
        button = ui.button(_("Log in"), on_click=attempt).classes("w-full")
        message = ui.label(_("The login took too long: log in again.") if expired else "").classes("text-negative text-body2")
