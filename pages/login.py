"""Login, needed when the GUI listens beyond the loopback address."""

from __future__ import annotations

from nicegui import app, ui

from app import runtime as rt


def content(redirect_to: str = "/") -> None:
    runtime = rt.current()
    if not redirect_to.startswith("/") or redirect_to.startswith("//"):
        redirect_to = "/"
    if not runtime.auth_required:
        ui.navigate.to(redirect_to)
        return

    def attempt() -> None:
        user = runtime.users.verify(name.value or "", password.value or "")
        if user is None:
            ui.notify("Wrong user name or password", type="negative")
            password.set_value("")
            return
        app.storage.user.update({"authenticated": True, "user": user.name, "role": user.role})
        ui.navigate.to(redirect_to)

    ui.page_title("Log in - commission")
    with ui.card().classes("absolute-center w-80"):
        ui.label("commission").classes("text-h5")
        ui.label(f"plant {runtime.plant.name}").classes("text-caption text-grey-8")
        name = ui.input("User").props("outlined autofocus").classes("w-full").on("keydown.enter", attempt)
        password = ui.input("Password", password=True, password_toggle_button=True).props("outlined").classes("w-full").on(
            "keydown.enter", attempt
        )
        ui.button("Log in", on_click=attempt).classes("w-full")
