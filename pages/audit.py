"""Audit log page: every write, command and restore, with filters and CSV export."""

from __future__ import annotations

import sqlite3
from datetime import datetime

from nicegui import ui

from app import i18n
from app import runtime as rt
from app.audit import to_csv
from app.i18n import N_
from pages.frame import frame
from pages.widgets import column, columns

COLUMNS = [
    column("time", N_("Time"), sortable=True),
    *(column(name, label) for name, label in (("user", N_("User")), ("role", N_("Role")), ("device", N_("Device")),
                                              ("action", N_("Action")), ("parameter", N_("Parameter")),
                                              ("old", N_("Old")), ("new", N_("New")))),
    # the whole result, wrapped inside the screen (a refusal's reason is the point of the row)
    column("result", N_("Result"), style="white-space: normal; overflow-wrap: break-word; min-width: 14rem",
           classes="audit-result"),
]
for _column in COLUMNS:  # old and new values (a restored setting's text) wrap too
    if _column["name"] in ("action", "parameter", "old", "new"):
        _column["style"] = "white-space: normal; overflow-wrap: break-word"


def content() -> None:
    runtime = rt.current()
    audit = runtime.audit
    lang = i18n.page_language()
    _ = lang.gettext
    with frame(N_("Audit log")):
        ui.label(_("Stored in {path}; survives restarts.").format(path=audit.path)).classes("text-caption text-grey-8")
        with ui.row().classes("items-end gap-3"):
            # every device, no blank entry: "any device" is the cleared field
            anyone = _("any device")
            device = ui.select(sorted(runtime.plant.devices), value=None, label=_("Device")).props(
                f'dense outlined clearable placeholder="{anyone}"'
            ).classes("w-48")
            user = ui.input(_("User")).props("dense outlined clearable").classes("w-36")
            text = ui.input(_("Text (action, parameter, values, result)")).props("dense outlined clearable").classes("w-64")
            # the rows' results are the log's own words (records are not translated): the filter names them so
            result = ui.select({"": _("any result"), "ok": "ok", "failed": "failed", "refused": "refused"}, value="",
                               label=_("Result")).props("dense outlined").classes("w-36")
            ui.button("CSV", icon="download", on_click=lambda: download()).props("outline")
        count = ui.label().classes("text-caption")
        problem = ui.label().classes("text-negative text-body2")
        table = ui.table(columns=columns(COLUMNS, lang), rows=[], row_key="id", pagination=50).classes("w-full reg-table")
        table.props("dense flat bordered")

    async def entries():
        return await audit.aquery(device=device.value or "", user=user.value or "", text=text.value or "",
                                  result=result.value or "", limit=5000)

    async def download() -> None:
        ui.download(to_csv(await entries(), lang).encode(), f"audit-{datetime.now():%Y%m%d-%H%M%S}.csv", "text/csv")

    async def refresh() -> None:
        try:
            found = await entries()
            known = sorted(set(runtime.plant.devices) | set(await audit.adevices()))
        except (OSError, sqlite3.Error) as exc:  # a locked or unreadable database is shown, not raised
            problem.set_text(_("The audit log cannot be read: {error}").format(error=exc))
            return
        problem.set_text("")
        known = [name for name in known if name]  # plant-wide rows (accounts, files) have no device
        if known != device.options:
            device.set_options(known, value=device.value if device.value in known else None)
        rows = [
            {"id": e.id, "time": datetime.fromtimestamp(e.time).strftime("%Y-%m-%d %H:%M:%S"), "user": e.user, "role": e.role,
             "device": e.device, "action": e.action, "parameter": e.parameter, "old": e.old, "new": e.new, "result": e.result}
            for e in found
        ]
        count.set_text(_("{n} entries").format(n=len(rows))
                       + (" " + _("(newest 5000)") if len(rows) == 5000 else ""))
        if rows != table.rows:
            table.rows = rows
            table.update()

    for element in (device, user, text, result):
        element.on_value_change(refresh)
    ui.timer(0, refresh, once=True)
    ui.timer(2.0, refresh)
