"""The composition root: the server of app/web.py (middleware, login, the JSON API) with the
routes of the pages, the one place that knows both. Imports run server -> pages -> app -> devices;
``commission`` (app/cli.py) hands over to it when it starts serving.

Each route imports its page module when it is first served, so starting the server loads no page.
"""

from __future__ import annotations

import importlib

from nicegui import ui

from app import i18n, web
from app.i18n import N_
from app.runtime import Runtime

BUS_TOOLS = ("transmit", "poll", "replay")  # pages/bus_<tool>.py, linked from the bus monitor


def register(runtime: Runtime, *, host: str = "127.0.0.1", allowed_hosts: tuple[str, ...] | list[str] = ()) -> None:
    """Register every route for ``runtime`` and start/stop it with the app.

    :param host: the address the server listens on (its name is accepted as Host)
    :param allowed_hosts: further names or addresses browsers use to reach it
    """
    web.register(runtime, lambda: register_pages(runtime), host=host, allowed_hosts=allowed_hosts)


def register_view(store, *, host: str = "127.0.0.1", allowed_hosts: tuple[str, ...] | list[str] = ()) -> None:
    """``commission view``: the plant-wide read-only view of ``store`` (an app.site_view.SiteStore)."""

    def view_page() -> None:
        @ui.page("/")
        def site_page() -> None:
            from pages import site_view

            site_view.content(store)

    web.register_view(store, view_page, host=host, allowed_hosts=allowed_hosts)


def register_pages(runtime: Runtime) -> None:
    """The page routes of ``runtime``'s GUI."""

    @ui.page("/login")
    def login_page(redirect_to: str = "/", expired: str = "") -> None:
        from pages import login

        login.content(redirect_to, expired)

    @ui.page("/plant")
    def plant_page() -> None:
        from pages import plant_view

        plant_view.content()

    @ui.page("/backup")
    def backup_page() -> None:
        from pages import backup

        backup.content()

    @ui.page("/record")
    @ui.page("/record/{name}")
    def record_page(name: str = "") -> None:
        from pages import record

        record.content(name or None)

    @ui.page("/replace/{name}")
    def replace_page(name: str) -> None:
        from pages import replace

        replace.content(name)

    @ui.page("/fleet")
    def fleet_page() -> None:
        from pages import fleet

        fleet.content()

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
            _ = i18n.page_language().gettext
            with frame(N_("Unknown device")):
                ui.label(_("The plant has no device named '{name}'.").format(name=name))
                ui.link(_("Back to the overview"), "/")
            return
        importlib.import_module(f"pages.{state.type}").content(name)
        from pages.project import device_card
        from pages.replace import notice

        notice(name)  # "replaced?" with old and new identity, whatever the device type
        device_card(name)  # the plant file's project against the device, whatever the device type

    @ui.page("/project/{name}")
    def project_page(name: str) -> None:
        from pages import project

        project.content(name)

    @ui.page("/monitor/{bus}")
    def monitor_page(bus: str) -> None:
        from pages import monitor
        from pages.frame import frame

        if bus not in runtime.store.buses:
            _ = i18n.page_language().gettext
            with frame(N_("Unknown bus")):
                ui.label(_("The plant has no bus named '{bus}'.").format(bus=bus))
            return
        monitor.content(bus)

    @ui.page("/monitor/{bus}/{tool}")
    def bus_tool_page(bus: str, tool: str) -> None:
        """An engineer's bus tool (transmit list, Modbus poll, replay): ``pages.bus_<tool>.content(bus)``."""
        from pages.frame import frame

        if bus not in runtime.store.buses or tool not in BUS_TOOLS:
            _ = i18n.page_language().gettext
            with frame(N_("Unknown page")):
                ui.label(_("There is no tool '{tool}' for a bus named '{bus}'.").format(tool=tool, bus=bus))
                ui.link(_("Back to the overview"), "/")
            return
        importlib.import_module(f"pages.bus_{tool}").content(bus)
