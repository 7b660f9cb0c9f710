"""Bus monitor.

Request/answer lines: the transaction log of the worker (bounded ring buffer), each transaction decoded
once, with the device that answered it, exported as CSV. Each kind of line has its own filters and
decoding: a Modbus line by unit, function and address, decoded through the device's parameter model
(signed, scaled, enum names, units); an SCU's RS232 line by command letters and data ID, and a LogiTed
line (MO 64) by telegram type, both in the words of their device pages (:mod:`app.recording.lines`).
CAN buses have a monitor of their own (pages/can_monitor.py); :func:`content` shows the one a bus needs.

The table is refreshed by a timer twice a second, never once per transaction, and shows at
most ``SHOWN`` transactions.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime

from nicegui import ui

from app import i18n
from app import recording as rec
from app import runtime as rt
from app.can_bus import CanBusState
from app.csvfile import csv_text
from app.i18n import N_, Lang
from app.message import said
from app.recording import lines
from pages.can_monitor import CanMonitor
from pages.frame import frame
from pages.monitor_common import CSS, SHOWN, tool_links
from pages.widgets import columns as shown_columns

# -- Modbus / serial lines: transaction log ----------------------------------------------------------

COLUMNS = [  # widths in % of a fixed-layout table: hex wraps between bytes (never cut), the decoded text shows
    # two lines with the whole of it on hover, so a transaction takes one or two lines and a screen holds many
    {"name": "time", "label": N_("Time"), "field": "time", "align": "left", "headerStyle": "width: 7%"},
    {"name": "device", "label": N_("Device"), "field": "device", "align": "left", "headerStyle": "width: 9%"},
    {"name": "request", "label": N_("Request"), "field": "request", "align": "left", "headerStyle": "width: 11%"},
    {"name": "tx", "label": N_("Request hex"), "field": "tx", "align": "left", "headerStyle": "width: 14%"},
    {"name": "rx", "label": N_("Response hex"), "field": "rx", "align": "left", "headerStyle": "width: 24%"},
    {"name": "decoded", "label": N_("Decoded"), "field": "decoded", "align": "left", "headerStyle": "width: 22%"},
    {"name": "rtt", "label": N_("RTT ms"), "field": "rtt_text", "align": "right", "headerStyle": "width: 5%"},
    {"name": "error", "label": N_("Error"), "field": "error", "align": "left", "headerStyle": "width: 7%"},
]
# a line worded like its device page: the request is a name ("RG 0x0011 Actual_Position Actuator 1"), so it gets the
# room the hex of a short SCU or LogiTed request does not need
# the plant file's bus types in words, the type itself beside them (what the plant file says)
BUS_TYPES = {"modbus-rtu": N_("Modbus RTU line"), "serial": N_("RS232 line"), "logited-rs485": N_("LogiTed RS485 line"),
             "logited-tcp": N_("LogiTed TCP connection")}
WORDED_WIDTHS = {"time": 9, "device": 10, "request": 16, "tx": 11, "rx": 19, "decoded": 25, "rtt": 5, "error": 5}
WORDED_COLUMNS = [{**c, "headerStyle": f"width: {WORDED_WIDTHS[c['name']]}%"} for c in COLUMNS]
CUT_SLOT = '<q-td :props="props" :class="\'cut \' + (props.col.name === \'error\' ? \'text-negative\' : \'\')" :title="props.value">{{ props.value }}</q-td>'
HEX_SLOT = '<q-td :props="props" class="mono hex">{{ props.value }}</q-td>'
WRAP_SLOT = '<q-td :props="props" class="clamp" :title="props.value"><div>{{ props.value }}</div></q-td>'
FIRST_SHOWN = 40  # rows in the page's first answer (more than a screen holds): the rest follow with the first refresh
FUNCTIONS = {1: N_("01 read coils"), 2: N_("02 read discrete inputs"), 3: N_("03 read holding registers"),
             4: N_("04 read input registers"), 5: N_("05 write coil"), 6: N_("06 write register"), 15: N_("15 write coils"),
             16: N_("16 write registers")}
CSV_HEADER = [N_("time"), N_("device"), N_("unit"), N_("function"), N_("request"), N_("request hex"), N_("response hex"),
              N_("decoded"), N_("rtt ms"), N_("error")]
CSV_FIELDS = ("date", "device", "unit", "function", "request", "tx", "rx", "decoded", "rtt", "error")
# the filters the device types declare for their lines (devices/scu/linewords.py, devices/mo64/linewords.py): their
# labels, hints and choices, shown in the page's language (an answer's choice "answer 0x0C Gate state" by its parts)
LINE_FILTER_WORDS = (
    N_("Command"), N_("Data ID (hex)"), N_("0011 or 0010"),
    N_("A group ID (0x0010) also finds its members and the cyclic objects that carry them"),
    N_("RO open remote mode"), N_("RC keep-alive / cyclic object"), N_("RG read data"), N_("RT write remote data"),
    N_("RE start a function"), N_("RS stop a function"), N_("RA end remote mode"),
    N_("Telegram"), N_("operating commands"), N_("queries"), N_("settings"), N_("ack, nak, busy, syn"), N_("answers"),
    N_("unsolicited (change monitoring)"), N_("another master's"), N_("token"),
)


def transaction_function(t) -> int | None:
    """The Modbus function code of a transaction's request (its frame's second byte), or None."""
    parts = t.request_hex.split(maxsplit=2)
    try:
        return int(parts[1], 16) if len(parts) > 1 else None
    except ValueError:
        return None


def filter_word(text: str, lang: Lang) -> str:
    """A label, hint or choice of a line's filter (:data:`LINE_FILTER_WORDS`) in ``lang``; an answer's choice
    ``answer 0x0C Gate state`` with the name its device page gives the value."""
    head, _sep, rest = text.partition(" ")
    code, _sep, name = rest.partition(" ")
    if head == "answer" and code.startswith("0x") and name:
        return lang.gettext("answer {type} {name}").format(type=code, name=lang.phrase(name))
    return lang.gettext(text)


def parse_unit(text: str) -> int | None:
    """A unit filter: blank for every unit, else 0 ... 247."""
    text = (text or "").strip()
    if not text:
        return None
    unit = int(text, 0)
    if not 0 <= unit <= 247:
        raise ValueError("a unit is 0 ... 247")
    return unit


def parse_address(text: str) -> tuple[int, int] | None:
    """An address filter: blank, ``3000`` or ``3000-3010`` (first and last register, both included)."""
    text = (text or "").strip()
    if not text:
        return None
    first, _, last = text.partition("-")
    low = int(first.strip(), 0)
    high = int(last.strip(), 0) if last.strip() else low
    if not 0 <= low <= high <= 0xFFFF:
        raise ValueError("an address is 0 ... 65535, a range first-last")
    return low, high


def _parsed(field: ui.input, parse: Callable[[str], object], rule: str):
    """``parse(field.value)``, the field's error mark cleared; a ValueError marks the field with ``rule`` and is
    raised on."""
    try:
        value = parse(field.value)
    except ValueError:
        field.props(f'error error-message="{rule}"')
        raise
    field.props(remove="error")
    return value


def transaction_matches(t, unit: int | None, function: int | None, address: tuple[int, int] | None) -> bool:
    """Whether a transaction passes the filters: its unit, its function, and any register it asked for in the range."""
    if unit is not None and t.unit != unit:
        return False
    if function is not None and transaction_function(t) != function:
        return False
    if address is not None:
        if t.address is None:
            return False
        first, last = t.address, t.address + max(1, len(t.values)) - 1
        if last < address[0] or first > address[1]:
            return False
    return True


def _csv_value(key: str, value: object) -> object:
    """A row's cell for the CSV: the round trip as a number (written the language's way by :func:`app.csvfile.cell`),
    any other cell as text a spreadsheet shows and never runs."""
    from app.audit import csv_cell

    if key == "rtt" and value != "-":
        return float(str(value))
    return csv_cell(str(value))


def transactions_csv(rows: list[dict], lang: Lang | None = None) -> str:
    """The shown rows as CSV as ``lang``'s spreadsheets read it (:mod:`app.csvfile`: headings in the language, in
    German a semicolon between cells and decimal commas; English when None); times ISO, the line's texts as written."""
    return csv_text(CSV_HEADER, ([_csv_value(k, r[k]) for k in CSV_FIELDS] for r in rows), lang)


def content(bus: str) -> None:
    if isinstance(rt.current().store.buses.get(bus), CanBusState):
        CanMonitor(bus)
    else:
        modbus_content(bus)


def modbus_content(bus: str) -> None:
    """The monitor of a request/answer line, with the filters and decoding of its kind."""
    lang = i18n.page_language()
    with frame(lang.gettext("Bus monitor {bus}").format(bus=bus)):
        ui.add_css(CSS)
        words = lines.line_words(rt.current().worker, bus)
        if words is not None:
            TaggedMonitor(bus, lang, words)
        elif rt.current().store.buses[bus].type == "modbus-rtu":
            ModbusMonitor(bus, lang)
        else:
            LineMonitor(bus, lang)


class LineMonitor:
    """The transactions of one line, filtered, each decoded once, updated twice a second; without filters of
    its own kind (a line this monitor knows no decoding for): subclasses add them."""

    columns = COLUMNS
    clamped = ("decoded",)  # columns shown in two lines, the whole on hover

    def __init__(self, bus: str, lang: Lang):
        runtime = rt.current()
        self.bus = bus
        self.lang = lang
        self.bus_state = runtime.store.buses[bus]
        self._build()
        self.decoder = rec.TransactionDecoder(runtime.worker, bus)
        self.made: dict[int, tuple[object, dict]] = {}  # id(transaction) -> (transaction, row): each decoded once
        self.shown_key = None
        for control in (*self.filter_controls(), self.errors_only):
            control.on_value_change(self.refilter)
        self.export.on_click(self.download)
        self.update(FIRST_SHOWN)  # the first answer carries the newest rows, the rest come with the first refresh
        ui.timer(0.5, self.update)

    def _build(self) -> None:
        bus_state = self.bus_state
        _ = self.lang.gettext
        with ui.row().classes("items-center gap-3 w-full"):
            kind = _(BUS_TYPES[bus_state.type]) + f" ({bus_state.type})" if bus_state.type in BUS_TYPES else bus_state.type
            ui.label(f"{kind} · {bus_state.endpoint}").classes("text-caption text-grey-8")
            if bus_state.type == "modbus-rtu":
                tool_links(self.bus, [(_("Modbus poll"), "poll", "table_rows")])
        with ui.row().classes("items-center gap-3"):
            self.paused = ui.switch(_("Pause"))
            self.errors_only = ui.switch(_("Errors only"))
            self.build_filters()
            self.export = ui.button(_("Export CSV"), icon="download").props("flat dense no-caps data-monitor=export")
            self.summary = ui.label().classes("text-body2")
        with ui.element("div").classes("w-full monitor-scroll monitor-fill").props("data-monitor=transactions-box"):
            table = ui.table(columns=shown_columns(self.columns, self.lang), rows=[], row_key="id", pagination=0).classes(
                "w-full reg-table")
        table.props("dense flat bordered hide-bottom data-monitor=transactions")
        for name in ("time", "device", "request", "rtt", "error"):
            if name not in self.clamped:
                table.add_slot(f"body-cell-{name}", CUT_SLOT)
        table.add_slot("body-cell-tx", HEX_SLOT)
        table.add_slot("body-cell-rx", HEX_SLOT)
        for name in self.clamped:
            table.add_slot(f"body-cell-{name}", WRAP_SLOT)
        table.mark("transactions")
        self.table = table

    # -- what a kind of line filters on and how it words a transaction -----------------------------------
    def build_filters(self) -> None:
        """The filter controls of this kind of line (none here)."""

    def filter_controls(self) -> tuple:
        return ()

    def filters(self) -> tuple | None:
        """The filters as entered, or None while one of them is not valid (it says why)."""
        return ()

    def matches(self, t, chosen: tuple) -> bool:
        return True

    def words(self, t) -> tuple[str, str, str]:
        """``(request, decoded, function)`` of a transaction: the request and the answer in words, and what the
        CSV's function column says."""
        return t.request, t.decoded, ""

    def row_of(self, t) -> dict:
        made, decoder = self.made, self.decoder
        cached = made.get(id(t))
        if cached is not None and cached[0] is t:
            return cached[1]
        request, decoded, function = self.words(t)
        request, decoded = said(request, self.lang), said(decoded, self.lang)  # what app/ words itself, in the page's language
        row = {
            "id": id(t),
            # a narrow column breaks before the milliseconds, not inside a number (a zero-width space there)
            "time": datetime.fromtimestamp(t.time).strftime("%H:%M:%S\u200b.%f")[:-3],
            "date": datetime.fromtimestamp(t.time).strftime("%Y-%m-%d %H:%M:%S.%f")[:-3],
            "device": said(decoder.device(t.unit), self.lang),
            "unit": t.unit,
            "function": function,
            "request": request,
            "tx": t.request_hex,
            "rx": t.response_hex,
            "decoded": decoded,
            "rtt": "-" if t.rtt_ms is None else f"{t.rtt_ms:.1f}",  # the CSV's number; the table shows rtt_text
            "rtt_text": "-" if t.rtt_ms is None else self.lang.number(t.rtt_ms, 1, group=False),
            "error": said(t.error, self.lang),  # the line's diagnosis (app/modbus_line.py) in the page's language
        }
        if len(made) > 4 * SHOWN:  # the log's ring buffer dropped the oldest: forget rows no longer listed
            live = {id(x) for x in self.bus_state.transactions}
            for key in [k for k in made if k not in live]:
                del made[key]
        made[id(t)] = (t, row)
        return row

    def refresh_decoders(self) -> None:
        self.decoder.refresh()

    def update(self, limit: int = SHOWN) -> None:
        bus_state = self.bus_state
        log = list(bus_state.transactions)
        errors = sum(1 for t in log if t.error)
        cycle = bus_state.cycle_s
        conflicts = bus_state.address_conflicts
        lang = self.lang
        _ = lang.gettext
        parts = [_("{n} transactions buffered, {errors} with errors").format(n=len(log), errors=errors)]
        if cycle:
            parts.append(_("line cycle {cycle} s (every device polled once)").format(cycle=lang.number(cycle, 2, group=False)))
        if conflicts:
            parts.append(_("{n} answers from another unit: address conflict on the line?").format(n=conflicts))
        self.summary.set_text(" · ".join(parts))
        if self.paused.value:
            return
        chosen = self.filters()
        if chosen is None:
            return
        self.refresh_decoders()
        matches, errors_only = self.matches, self.errors_only.value
        selected = [t for t in reversed(log) if (not errors_only or t.error) and matches(t, chosen)][:limit]
        key = (tuple(id(t) for t in selected[:1]), len(selected), chosen, errors_only)
        if key == self.shown_key:
            return  # nothing new on the line: nothing sent to the browser
        self.shown_key = key
        self.table.rows = [self.row_of(t) for t in selected]
        self.table.update()

    def refilter(self) -> None:
        self.shown_key = None
        self.update()

    def download(self) -> None:
        ui.download(transactions_csv(self.table.rows, self.lang).encode(),
                    f"{self.bus}-transactions-{datetime.now():%Y%m%d-%H%M%S}.csv", "text/csv")


class ModbusMonitor(LineMonitor):
    """A Modbus line: filtered by unit, function and any register asked; decoded through the parameter model."""

    def build_filters(self) -> None:
        _ = self.lang.gettext
        self.unit_filter = ui.input(self.lang.pgettext("Modbus", "Unit"), placeholder=_("any")).props(
            "dense clearable data-monitor=filter-unit").classes("w-24")
        functions = {0: _("any function"), **{code: _(text) for code, text in FUNCTIONS.items()}}
        self.function_filter = ui.select(functions, value=0, label=_("Function")) \
            .props("dense data-monitor=filter-function").classes("w-56")
        self.address_filter = ui.input(_("Address"), placeholder=_("3000 or 3000-3010")) \
            .props("dense clearable data-monitor=filter-address").classes("w-44")

    def filter_controls(self) -> tuple:
        return self.unit_filter, self.function_filter, self.address_filter

    def matches(self, t, chosen: tuple) -> bool:
        return transaction_matches(t, *chosen)

    def words(self, t) -> tuple[str, str, str]:
        function = transaction_function(t)
        named = FUNCTIONS.get(function) if function is not None else None
        return t.request, self.decoder.decoded(t), "" if function is None else self.lang.gettext(named) if named else f"{function:02d}"

    def filters(self) -> tuple[int | None, int | None, tuple[int, int] | None] | None:
        try:
            unit = _parsed(self.unit_filter, parse_unit, "0 ... 247")
            address = _parsed(self.address_filter, parse_address, self.lang.gettext("0 ... 65535 or first-last"))
        except ValueError:
            return None
        return unit, (self.function_filter.value or None), address


class TaggedMonitor(LineMonitor):
    """A line whose device type words its telegrams like its device page and declares the filters that fit them
    (:mod:`app.recording.lines`): an SCU's RS232 line by command letters and data ID, a LogiTed line by telegram
    type."""

    columns = WORDED_COLUMNS
    clamped = ("request", "decoded")

    def __init__(self, bus: str, lang: Lang, words: lines.LineWords):
        self.line_words = words
        self.filter_fields: list[tuple[lines.LineFilter, ui.element]] = []
        super().__init__(bus, lang)

    def build_filters(self) -> None:
        lang = self.lang
        for spec in self.line_words.filters:
            if spec.choices:
                choices = {key: filter_word(text, lang) for key, text in spec.choices.items()}
                control = ui.select({"": lang.gettext("any"), **choices}, value="", label=filter_word(spec.label, lang)) \
                    .props(f"dense data-monitor=filter-{spec.key}").classes("w-60")
            else:
                placeholder = filter_word(spec.placeholder, lang) if spec.placeholder else spec.placeholder
                control = ui.input(filter_word(spec.label, lang), placeholder=placeholder) \
                    .props(f"dense clearable data-monitor=filter-{spec.key}").classes("w-40")
            if spec.hint:
                control.tooltip(filter_word(spec.hint, lang))
            self.filter_fields.append((spec, control))

    def filter_controls(self) -> tuple:
        return tuple(control for _spec, control in self.filter_fields)

    def filters(self) -> tuple[str | None, ...] | None:
        chosen: list[str | None] = []
        for spec, control in self.filter_fields:
            text = (control.value or "").strip()
            if spec.choices or not text:
                chosen.append(text or None)
                continue
            try:
                chosen.append(spec.parse(text))
                control.props(remove="error")
            except ValueError as exc:
                problem = str(exc) or self.lang.gettext("not valid")
                control.props(f'error error-message="{problem}"')
                return None
        return tuple(chosen)

    def refresh_decoders(self) -> None:
        super().refresh_decoders()
        self.line_words.refresh()

    def words(self, t) -> tuple[str, str, str]:
        text = self.line_words.text(t)
        return text.request, text.decoded, ", ".join(sorted(text.tags))

    def matches(self, t, chosen: tuple) -> bool:
        if not any(chosen):
            return True
        tags = self.line_words.text(t).tags
        return all(want is None or want in tags for want in chosen)
