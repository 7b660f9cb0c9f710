"""The SCU page's cards of data read on demand: the data directory (any data ID or group ID, section 4.3), the
settings of the parameter model as the unit answered them, and the service table. Each reads when the engineer
asks (RG), while the unit answers and, unless it answers RG without one, the remote session is open."""

from __future__ import annotations

import time

from nicegui import ui

from app.i18n import N_
from app.message import said
from devices.scu import facts
from devices.scu import params as p
from devices.scu.adapter import SERVICE_IDS, WATCH_RG
from devices.scu.model import LIMIT_FIELDS, SESSION, VOLATILE, params_for
from pages.cards import DrawnCard, titled_card
from pages.command_client import enable_unless
from pages.frame import fmt_time
from pages.scu_view import Access, ScuView
from pages.widgets import columns, quality_note

DIRECTORY_COLUMNS = [{"name": k, "label": label, "field": k, "align": "left"} for k, label in
                     (("id", N_("Id")), ("name", N_("Name")), ("type", N_("Type")), ("unit", N_("Unit")),
                      ("access", N_("Access")), ("comment", N_("Comment")))]
SETTINGS_COLUMNS = [{"name": k, "label": label, "field": k, "align": "left"} for k, label in
                    (("id", N_("Data ID")), ("name", N_("Name")), ("value", N_("Value")), ("kind", N_("Kind")),
                     ("read", N_("Read")))]
SERVICE_COLUMNS = [{"name": k, "label": label, "field": k, "align": "left"} for k, label in
                   (("id", N_("Id")), ("name", N_("Name")), ("value", N_("Value")), ("read", N_("Read")))]


def item_name(entry: p.DataItem, gettext) -> str:
    """An item of the data directory by its name: the document's own (``Strom A1``), a group's in the page's language."""
    return gettext(entry.name) if entry.members else entry.name


def _read_gate(view: ScuView, access: Access) -> str:
    """Reads wait for a unit that answers, and for an open session unless the unit answers RG without one."""
    return access.role or access.offline or (access.lost if view.fact(facts.P_WATCH) != WATCH_RG else "")


class DirectoryCard(DrawnCard):
    """The data directory (section 4.3): read any data ID or group ID, its value and raw bytes."""

    view: ScuView

    def build(self) -> None:
        _ = self.view.lang.gettext
        with titled_card(_("Data directory (section 4.3): read any data ID or group ID")):
            rows = [{"id": e.key, "name": item_name(e, _), "type": e.type_name, "unit": self.view.lang.unit(e.unit), "access": e.access.value,
                     "comment": _(e.comment) if e.comment else ""} for e in p.DIRECTORY.values()]
            table = ui.table(columns=columns(DIRECTORY_COLUMNS, self.view.lang),
                             rows=rows, row_key="id", selection="single", pagination=10).classes("w-full text-caption")
            table.props("dense wrap-cells")
            with ui.row().classes("items-center gap-4"):
                self.pick = ui.select({e.data_id: f"{e.key} {item_name(e, _)}" for e in p.DIRECTORY.values()}, value=0x0010,
                                      label=_("Data ID"), with_input=True).classes("w-96").props("data-testid=data-id")
                table.on("selection", lambda e: self.pick.set_value(int(e.args["rows"][0]["id"], 16))
                         if e.args.get("rows") else None)
                self.button = ui.button(_("Read (RG)"), on_click=self.read).props("data-testid=read-data")
            self.shown = ui.label().classes("mono text-body2").props("data-testid=data-value")
            self.raw = ui.label().classes("mono text-caption text-grey-8").props("data-testid=data-raw")

    async def read(self) -> None:
        ok, result = await self.view.act("read data", {"data_id": self.pick.value})
        if ok:
            lang = self.view.lang
            name = item_name(p.DIRECTORY[result["data_id"]], lang.gettext)
            self.shown.set_text(f"{result['key']} {name} ({result['type']}): {lang.numbers_in(said(result['text'] or result['error'], lang))}")
            self.raw.set_text(lang.gettext("raw: {raw}").format(raw=result["raw"] or lang.gettext("(no data)")))

    def inputs(self, access: Access) -> tuple:
        return access, self.view.fact(facts.P_WATCH)

    def draw(self, access: Access) -> None:
        enable_unless(self.button, _read_gate(self.view, access))


class SettingsCard(DrawnCard):
    """The parameter model (devices/scu/model.py) as the unit answered it: the settings (remote speeds and positions,
    written with RT and read back with RG by restore, the project and a batch) and, for reference, the read-only
    values of its configuration and the plant file."""

    view: ScuView

    def build(self) -> None:
        self.params = params_for(len(self.view.scales))
        lang = self.view.lang
        _ = lang.gettext
        with titled_card(_("Settings (parameter model)")):
            self.table = ui.table(columns=columns(SETTINGS_COLUMNS, lang), rows=[], row_key="key").classes("w-full text-caption")
            self.table.props("dense wrap-cells data-testid=settings-table")
            self.button = ui.button(_("Read settings (RG)"), on_click=self.read).props("outline data-testid=read-settings")
            ui.label(_("Remote speeds and positions are the settings: a backup lists them with their names and units, and "
                       "restore, the project and a batch write them with RT and read each back with RG, refused while a "
                       "function runs; {volatile}. Conversion factors and virtual limits are the unit's configuration "
                       "(RT writes only data IDs 3xxx, table 3); the Safety_ID is the plant file's.").format(volatile=_(VOLATILE))).classes(
                "text-caption text-grey-8")

    async def read(self) -> None:
        await self.view.act("read parameters")

    @staticmethod
    def _id(q) -> str:
        if q.space == SESSION:
            return "RO"
        return f"0x{q.address:04X}" + (f" {LIMIT_FIELDS[q.space]}" if q.space in LIMIT_FIELDS else "")

    def inputs(self, access: Access) -> tuple:
        return access, self.view.readings(self.params)

    def draw(self, access: Access) -> None:
        enable_unless(self.button, _read_gate(self.view, access))
        state = self.view.state
        rows = []
        for q in self.params:
            raw = state.raw(q)
            read = state.read_time(q)
            _ = self.view.lang.gettext
            rows.append({"key": q.key, "id": self._id(q), "name": q.name,
                         "value": "-" if raw is None else self.view.lang.numbers_in(q.display(raw)),
                         "kind": _("setting") if q.setting else _("read-only"), "read": "-" if read is None else fmt_time(read)})
        if rows != self.table.rows:
            self.table.rows = rows
            self.table.update()


class ServiceCard(DrawnCard):
    """The service data read on demand, each row with the time of its reading."""

    view: ScuView

    def build(self) -> None:
        _ = self.view.lang.gettext
        with titled_card(_("Service table")):
            self.table = ui.table(columns=columns(SERVICE_COLUMNS, self.view.lang), rows=[], row_key="id") \
                .classes("w-full text-caption")
            self.table.props('dense wrap-cells data-testid=service-table :table-row-class-fn="row => row.quality_class"')
            self.button = ui.button(_("Read service data (RG)"), on_click=self.read).props("outline data-testid=read-service")
            ui.label(_("Backup: the Backup page writes the settings of the parameter model (remote speeds and positions, "
                       "with the conversion factors, virtual limits and Safety_ID for reference) and a record of identity, "
                       "counters and error history. Restore, the project and a batch write the settings back with RT and "
                       "read each back with RG; {volatile}.").format(volatile=_(VOLATILE))).classes("text-caption text-grey-8")

    async def read(self) -> None:
        out = []
        for data_id in list(SERVICE_IDS) + [0x2000 + s.number for s in self.view.scales]:
            ok, result = await self.view.act("read data", {"data_id": data_id})
            if not ok:
                break
            out.append({"id": result["key"], "name": item_name(p.DIRECTORY[result["data_id"]], self.view.lang.gettext),
                        "value": self.view.lang.numbers_in(said(result["text"] or result["error"], self.view.lang)),
                        "time": time.time(), "read": "", "quality_class": ""})
        self.table.rows = out
        self.ages()

    def ages(self) -> None:
        """The rows with the time of their reading; greyed with their age while the unit does not answer."""
        quality = "offline" if self.view.state.status == "offline" else "good"
        now = time.time()
        rows = [{**row, "read": quality_note(quality, now - row["time"], self.view.lang) if quality == "offline" else fmt_time(row["time"]),
                 "quality_class": "q-offline" if quality == "offline" else ""} for row in self.table.rows]
        if rows != self.table.rows:
            self.table.rows = rows
            self.table.update()

    def inputs(self, access: Access) -> tuple:
        return access, self.view.fact(facts.P_WATCH), self.view.state.status, len(self.table.rows)

    def draw(self, access: Access) -> None:
        enable_unless(self.button, _read_gate(self.view, access))
        self.ages()


__all__ = ["DirectoryCard", "ServiceCard", "SettingsCard"]
