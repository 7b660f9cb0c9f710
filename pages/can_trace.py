"""The frames of the CAN bus monitor, live and in a recorded file alike: how they are named (the device codecs
of the bus, :class:`BusDecoding`) and filtered (:class:`FilterCard`), the frame table (its columns, its rows from
:class:`app.can_bus.FrameRecord`) and one frame's full decoding in a dialog."""

from __future__ import annotations

import re
from collections.abc import Callable

from nicegui import ui

from app import recording as rec
from app import runtime as rt
from app.can_bus import FrameRecord
from app.i18n import N_, Lang
from app.message import said
from pages.widgets import columns as shown_columns

SCROLL_HEIGHT = "max-height: 56vh; overflow-y: auto"  # each table scrolls inside its box: the page height stays bounded
FRAME_COLUMNS = [
    {"name": "time", "label": N_("Time"), "field": "time", "align": "left", "classes": "mono"},
    {"name": "dir", "label": N_("Dir"), "field": "dir", "align": "center"},
    {"name": "id", "label": "ID", "field": "id", "align": "left", "classes": "mono"},
    {"name": "device", "label": N_("Device"), "field": "device", "align": "left"},
    {"name": "dt", "label": "Δt ms", "field": "dt", "align": "right", "classes": "mono nowrap"},
    {"name": "dlc", "label": "DLC", "field": "dlc", "align": "right"},
    {"name": "data", "label": N_("Data"), "field": "data", "align": "left", "classes": "mono bytes"},
    {"name": "decoded", "label": N_("Decoded"), "field": "decoded", "align": "left"},
]
DECODED_SLOT = (
    '<q-td :props="props" class="decoded" :class="props.row.err ? \'text-negative text-weight-bold\' : '
    "(props.row.unknown ? 'text-grey-6' : '')\">{{ props.value }}</q-td>"
)
# the decoder's own words for a frame no codec names (app/recording): shown in the page's language
DECODER_WORDS = {rec.UNKNOWN: N_("unknown"), "error frame": N_("error frame")}


def decoded_text(text: str, lang: Lang) -> str:
    """A frame's decoded text as shown: the codecs' words as they are, the decoder's own in ``lang``."""
    word = DECODER_WORDS.get(text)
    return lang.gettext(word) if word else said(text, lang)
ROW_CLASS_FN = ":table-row-class-fn"  # Quasar: a JS function (row) -> class


def frame_table(mark: str, lang: Lang, time_label: str = N_("Time")) -> ui.table:
    """The frame list's table in ``lang``, its first column's label ``time_label`` (marked ``N_``)."""
    columns = [dict(c) for c in FRAME_COLUMNS]
    columns[0]["label"] = time_label
    table = ui.table(columns=shown_columns(columns, lang), rows=[], row_key="k", pagination=0).classes("w-full can-table")
    table.props("dense flat bordered hide-bottom")
    table.props(f'{ROW_CLASS_FN}="row => row.err ? \'row-error\' : \'\'"')
    table.add_slot("body-cell-decoded", DECODED_SLOT)
    table.mark(mark)
    table.props(f"data-monitor={mark}")
    return table


def frame_rows(frames: list[FrameRecord], decoder: rec.FrameDecoder, lang: Lang, relative_to: float | None = None,
               first_key: int = 0) -> list[dict]:
    """The table's rows of ``frames``: times, IDs and bytes as the bus has them, the words in ``lang``; the decoded
    text is the codecs' (the documents' names of messages and fields)."""
    _ = lang.gettext
    error_frame, remote = _("error frame"), _("remote")
    rows = []
    for i, f in enumerate(frames):
        decoded = decoder.record(f)
        rows.append({
            "k": first_key + i,
            "time": rec.format_time(f.time, relative_to),
            "dir": f.direction,
            "id": error_frame if f.is_error_frame else rec.format_id(f.arbitration_id, f.is_extended_id),
            "device": decoder.record_device(f),
            "dt": _ms(f.dt, lang),
            "dlc": f.dlc,
            "data": remote if f.is_remote_frame else rec.format_data(f.data),
            "decoded": decoded_text(decoded, lang),
            "unknown": decoded == rec.UNKNOWN,
            "err": f.is_error_frame,
        })
    return rows


def _ms(seconds: float | None, lang: Lang) -> str:
    return "-" if seconds is None else lang.number(seconds * 1000, 1, group=False)


_FIELD_SPLIT = re.compile(r";\s+|,\s+(?![^\[]*\])")


def decoded_fields(text: str) -> tuple[str, list[str]]:
    """The message name and its fields from a decoded text (``name: field, field; field``)."""
    head, sep, rest = text.partition(": ")
    if not sep:
        return text, []
    return head, [part for part in _FIELD_SPLIT.split(rest) if part]


BYTE_COLUMNS = [{"name": c, "label": label, "field": c, "align": "left"}
                for c, label in (("byte", N_("Byte")), ("hex", N_("Hex")), ("dec", N_("Dec")), ("bin", N_("Bin")))]


def show_frame_details(f: FrameRecord, decoder: rec.FrameDecoder, relative_to: float | None, lang: Lang) -> None:
    """A dialog with one frame's full decoding: its device, message, fields and bytes (its words in ``lang``)."""
    _ = lang.gettext
    text = decoder.record(f)
    name, fields = decoded_fields(text)
    with ui.dialog() as dialog, ui.card().classes("q-pa-md").style("min-width: 520px; max-width: 90vw") as card:
        card.props("data-monitor=frame-details")
        ident = _("error frame") if f.is_error_frame else rec.format_id(f.arbitration_id, f.is_extended_id)
        ui.label(f"{ident} · "
                 f"{f.direction} · {rec.format_time(f.time, relative_to)}").classes("text-h6 mono")
        data = _("remote frame") if f.is_remote_frame else (rec.format_data(f.data) or _("(none)"))
        dt = _("first heard") if f.dt is None else f"{lang.number(f.dt * 1000, 1, group=False)} ms"
        facts = [  # (label, value, in the bytes' typeface)
            (_("Device"), decoder.record_device(f) or _("not a device of this bus"), False),
            (_("Message"), decoded_text(name, lang), False),
            ("DLC", str(f.dlc), False),
            (_("Data"), data, True),
            (_("Δt to the previous frame of this ID"), dt, False),
        ]
        with ui.grid(columns="auto 1fr").classes("gap-x-4 gap-y-1"):
            for label, value, mono in facts:
                ui.label(label).classes("text-grey-8")
                ui.label(value).classes("mono" if mono else "")
        if fields:
            ui.label(_("Fields")).classes("text-subtitle2 q-mt-sm")
            with ui.column().classes("gap-0").props("data-monitor=frame-fields"):
                for item in fields:
                    ui.label(item).classes("text-body2")
        if f.data and not f.is_remote_frame:
            ui.label(_("Bytes")).classes("text-subtitle2 q-mt-sm")
            ui.table(columns=shown_columns(BYTE_COLUMNS, lang),
                     rows=[{"byte": i, "hex": f"{b:02X}", "dec": b, "bin": f"{b:08b}"} for i, b in enumerate(f.data)],
                     row_key="byte").props("dense flat bordered hide-bottom").classes("mono")
        ui.button(_("Close"), on_click=dialog.close).props("flat")
    dialog.on("hide", dialog.delete)
    dialog.open()


def clicked_key(event) -> int | None:
    """The row key of a table's ``rowClick`` event (its second argument is the row)."""
    row = event.args[1] if len(event.args) > 1 else {}
    key = row.get("k") if isinstance(row, dict) else None
    return key if isinstance(key, int) else None


def set_deltas(frames: list[FrameRecord]) -> None:
    """Each frame's time since the previous frame of its ID (a recorded file's Δt column)."""
    last: dict[tuple[bool, int], float] = {}
    for f in frames:
        key = (f.is_extended_id, f.arbitration_id)
        previous = last.get(key)
        f.dt = None if previous is None else f.time - previous
        last[key] = f.time


class BusDecoding:
    """How the frames of one CAN bus are named: the device codecs of the types on the bus (in the plant
    and discovered), the IDs of its devices and which device owns a frame (through app.recording)."""

    def __init__(self, bus: str):
        runtime = rt.current()
        self.bus = bus
        self.worker = runtime.worker
        self.plant = runtime.plant
        self.decoder = rec.FrameDecoder(self.worker.known_ids(bus), self.describers(), self.owners())

    def types(self) -> list[str]:
        """Device types in the plant on this bus and discovered on it: their codecs decode first."""
        types = [d.type for d in self.plant.devices_on(self.bus)]
        types += [entry.get("type", "") for entry in self.worker.discovered.get(self.bus, {}).values()]
        return types

    def describers(self):
        return rec.describers(self.worker, self.bus, self.types())

    def owners(self):
        return rec.device_owners(self.worker, self.bus)

    def owner(self, device: str):
        """The frame test of ``device``: the same ownership as the Device column (adapter, else the type's CAN IDs)."""
        return dict(self.owners()).get(device) or rec.owner_of(None)

    def refresh(self) -> None:
        """Devices adopted or discovered since: the live decoder names them too."""
        self.decoder.set_known_ids(self.worker.known_ids(self.bus))
        self.decoder.set_codecs(self.describers())
        self.decoder.set_owners(self.owners())

    def for_file(self, known: set) -> rec.FrameDecoder:
        """A decoder for a recorded file, which also knows the device IDs found in it (``known``)."""
        return rec.FrameDecoder(self.worker.known_ids(self.bus) | known, self.describers(), self.owners())


class FilterCard:
    """ID range, device, error frames only, and pause: the filters of the live lists and of an opened file.

    :param on_change: called after the filter changed (:attr:`filter`, :attr:`version`)
    :param on_pause: called after pause was switched (:attr:`paused`)
    """

    def __init__(self, devices: list[str], decoding: BusDecoding, on_change: Callable[[], None],
                 on_pause: Callable[[], None], lang: Lang):
        self.lang = lang
        self.devices = devices
        self.decoding = decoding
        self.on_change = on_change
        self.on_pause = on_pause
        self.filter = rec.FrameFilter()
        self.version = 0  # counts the changes: a list built with an older filter is built again

    def build(self) -> None:
        _ = self.lang.gettext
        with ui.row().classes("items-end gap-3 w-full"):
            self.id_from = ui.input(_("ID from (hex)"), on_change=self.changed).props("dense outlined clearable").classes("w-36 mono")
            self.id_to = ui.input(_("ID to (hex)"), on_change=self.changed).props("dense outlined clearable").classes("w-36 mono")
            self.id_from.mark("id-from")
            self.id_to.mark("id-to")
            options = {"": _("all devices"), **{name: name for name in self.devices}}
            self.device = ui.select(options, value="", label=_("Device"), on_change=self.changed).props("dense outlined").classes("w-44")
            self.device.mark("device")
            self.errors_only = ui.switch(_("Error frames only"), on_change=self.changed)
            self.pause = ui.switch(_("Pause"), on_change=self.on_pause).mark("pause")
            self.pause.props("data-monitor=pause")
            self.filter_info = ui.label().classes("text-caption text-grey-8")

    @property
    def paused(self) -> bool:
        return bool(self.pause.value)

    def changed(self) -> None:
        problems = []
        bounds = []
        for field_input in (self.id_from, self.id_to):
            try:
                bounds.append(rec.parse_id(field_input.value))
                field_input.props(remove="error")
            except ValueError:
                bounds.append(None)
                problems.append(self.lang.gettext("'{value}' is not a hex CAN ID").format(value=field_input.value))
                field_input.props("error")
        owner = self.decoding.owner(self.device.value) if self.device.value else None
        self.filter = rec.FrameFilter(bounds[0], bounds[1], owner, bool(self.errors_only.value))
        self.version += 1
        self.filter_info.set_text("; ".join(problems))
        self.filter_info.classes(replace="text-caption " + ("text-negative" if problems else "text-grey-8"))
        self.on_change()


__all__ = ["BusDecoding", "DECODED_SLOT", "decoded_text", "FilterCard", "FRAME_COLUMNS", "SCROLL_HEIGHT", "clicked_key", "decoded_fields", "frame_rows", "frame_table", "set_deltas", "show_frame_details"]
