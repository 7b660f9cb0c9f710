"""Bauer MO 64 page: gate state with a picture of the boom, position, the 40 status bits, identity,
counters, error memory, modes; commands, settings, change monitoring and the TCP connection.

Reads only the live store (the points and records :mod:`devices.mo64.adapter` publishes) and invokes
the declared commands (devices/mo64/policy.py) through the worker's gate. Each card is a small class
with ``build()`` (in the page's layout) and ``refresh()`` (on every change the store pushes)."""

from __future__ import annotations

import html

from nicegui import ui

from app.i18n import N_, NP_
from app.message import said
from devices.mo64 import adapter as facts
from devices.mo64 import codec
from devices.mo64.adapter import COMMAND_NAMES
from devices.mo64.control import command_words
from devices.mo64.policy import operation_name
from pages.cards import DeviceCard, titled_card
from pages.device_page import DeviceView, StatusBadge, device_page
from pages.frame import status_text
from pages.mo64_settings import SettingsCard, show_line, value_line
from pages.simcontrols import sim_card
from pages.widgets import counter_line, Lamp, mark_quality, quality_note
from pages.command_client import enable_unless, viewer_reason, WriteGuard

MOTION_WARNING = N_("the boom moves: check that nobody stands under it")
STOP_HINT = N_("a stop: anyone may stop (deactivating a close or reverse level never moves the boom)")
ALARM_BITS = {"LS", "Baum ab", "F_ereignis"}
ALARM_WORDS = {"LS": N_("light barrier interrupted"), "Baum ab": N_("boom off"), "F_ereignis": N_("fault event")}
# what the status bits mean (chapter 5.1.7, pages 16-17; SPEC-NOTES "Barrier status"); a bit the summary
# names without its function says so
BIT_MEANINGS = {
    "Funk": N_("radio (Funk): the learned radio code is being received (page 16)"),
    "BT": N_("BT: the open command input (BT = open, BZ = close, chapter 5.2.1)"),
    "BTS": N_("BTS: command input named in chapter 5.1.7; its function is not in the summary"),
    "SLZ": N_("SLZ: input named in chapter 5.1.7; its function is not in the summary"),
    "LS": N_("LS: the light barrier is interrupted (safety: a closing boom reverses)"),
    "Baum ab": N_("Baum ab: boom off - the boom is broken away or removed (safety)"),
    "F_ereignis": N_("F_ereignis: fault event - an error flag is set; see the error memory (safety)"),
    "SERVICE": N_("SERVICE: maintenance is due (maintenance counter reached the interval)"),
    "mains monitoring": N_("mains monitoring: the mains supply monitor reports"),
    "loop EXT": N_("the external loop detector reports"),
}
# a meaning with the bit's name, loop or relay in it: its text in the catalog with the field, the field's value
BIT_TEMPLATES: dict[str, tuple[str, dict]] = {}
for _name in ("BTA1", "BTA2", "BTA3", "BTZ1A", "BTZ1B", "BTZ2"):
    BIT_TEMPLATES[_name] = (N_("{name}: command input named in chapter 5.1.7; its function is not in the summary"),
                            {"name": _name})
for _loop in "ABC":
    BIT_TEMPLATES[f"adjusting loop {_loop}"] = (N_("loop {loop} is being adjusted (Abgleich Schleife {loop}, page 17)"),
                                                {"loop": _loop})
    BIT_TEMPLATES[f"loop {_loop} occupied"] = (N_("a vehicle is on loop {loop}"), {"loop": _loop})
for _n in range(1, 7):
    BIT_TEMPLATES[f"multi relay {_n}"] = (N_("multi relay {n} is switched on (Multi{n}, page 17)"), {"n": _n})
for _bit, (_text, _fields) in BIT_TEMPLATES.items():
    BIT_MEANINGS[_bit] = _text.format(**_fields)
# the lamps' names where the summary words them in English (chapter 5.1.7, pages 16-17); the others are its own
BIT_NAMES = {"mains monitoring": N_("mains monitoring"), "loop EXT": N_("loop EXT")}
BIT_NAME_TEMPLATES = {f"adjusting loop {x}": (N_("adjusting loop {loop}"), {"loop": x}) for x in "ABC"} | {
    f"loop {x} occupied": (N_("loop {loop} occupied"), {"loop": x}) for x in "ABC"} | {
    f"multi relay {n}": (N_("multi relay {n}"), {"n": n}) for n in range(1, 15)}
GROUP_NAMES = {"inputs": N_("inputs"), "safety": N_("safety"), "loops": N_("loops"), "multi relays": N_("multi relays"),
               "service": N_("service")}


def bit_meaning(bit: str, lang) -> str:
    """What a status bit means, in ``lang``."""
    if bit in BIT_TEMPLATES:
        text, fields = BIT_TEMPLATES[bit]
        return lang.gettext(text).format(**fields)
    if bit in BIT_MEANINGS:
        return lang.gettext(BIT_MEANINGS[bit])
    return lang.gettext("{bit}: named in chapter 5.1.7").format(bit=bit)


def bit_name(bit: str, lang) -> str:
    """A status bit's name on its lamp, in ``lang`` (the summary's own abbreviations stay as printed)."""
    if bit in BIT_NAME_TEMPLATES:
        text, fields = BIT_NAME_TEMPLATES[bit]
        return lang.gettext(text).format(**fields)
    return lang.gettext(BIT_NAMES[bit]) if bit in BIT_NAMES else bit


LEGEND = N_("Funk = radio code received; BT = open input; LS = light barrier interrupted; Baum ab = boom off "
            "(broken away or removed); F_ereignis = fault event (see the error memory); SERVICE = maintenance due. "
            "Hover a lamp for its meaning.")
ENTRY_WORDS = (N_("enter a value first"),)  # an entry's own reason (the others are the codec's)
ERROR_COLUMNS = [{"name": k, "label": label, "field": k, "align": "left"} for k, label in
                 (("level", NP_("error memory", "Level")), ("meaning", N_("Error flags")), ("raw", N_("Raw (for the vendor)")),
                  ("time", N_("Operating hours at the change")))]
# chapter 5.1.23 as devices/mo64/codec.py words it (ERROR_MEMORY_MEANING), marked here for the catalogs
ERROR_MEMORY_MEANING = N_("Each level is one change of the 32 error flags with the operating hours at that change "
                          "(chapter 5.1.23): level 0 the newest, level 9 the oldest. The document summary does not name "
                          "the flags: a set flag is shown by its bit number.")
# the points' names as the page labels them (the adapter publishes them under these names)
POINT_LABELS = (N_("Device code"), N_("Program version"), N_("Serial number"), N_("MAC address"), N_("Operating hours"),
                N_("Service counter"), N_("Maintenance counter"), N_("Maintenance interval"), N_("Vehicle counter"),
                N_("Loop-adjust counter A"), N_("Loop-adjust counter B"), N_("Loop-adjust counter C"),
                N_("Induction-loop modes"), N_("Direction logics"), N_("Configuration flags"), N_("Multi-relay modes"),
                N_("Status mask"), N_("Counting function"), N_("Radio code (dec_bt)"), N_("Loop periods"))
RAW_SETTING_NAMES = (N_("multi-relay modes"), N_("configuration flags"))  # codec.SETTINGS' names of the raw rows
IDENTITY_POINTS = ("Device code", "Program version", "Serial number", "MAC address", "Operating hours")
COUNTER_POINTS = ("Service counter", "Maintenance counter", "Maintenance interval", "Vehicle counter",
                  "Loop-adjust counter A", "Loop-adjust counter B", "Loop-adjust counter C")
MODE_POINTS = ("Induction-loop modes", "Direction logics", "Configuration flags", "Multi-relay modes",
               "Status mask", "Counting function", "Radio code (dec_bt)", "Loop periods")
# what the gate card and the settings card are drawn from (besides the device's status and errors)
COMMAND_WORDS = {codec.Command.OPEN: N_("open"), codec.Command.CLOSE: N_("close"), codec.Command.REVERSE: N_("reverse")}
GATE_INPUTS = ("Gate state", "Position", *sorted(ALARM_BITS), facts.P_LATE, facts.P_CONNECTION, facts.P_POLLING,
               facts.P_QUERY_FORM, facts.P_UNAVAILABLE, facts.P_LEVELS_UNAVAILABLE)
HIDDEN_BITS = frozenset(f"multi relay {n}" for n in range(7, 15))  # an MO 64 has six (5.1.25): SPEC-NOTES


def boom_svg(position: int | None) -> str:
    """A barrier post with its boom raised by ``position`` % (0 closed, horizontal; 100 open, upright)."""
    angle = 0 if position is None else -90 * max(0, min(100, position)) / 100
    colour = "#9e9e9e" if position is None else "#c62828"
    return (f'<svg width="220" height="130" viewBox="0 0 220 130" role="img" aria-label="boom">'
            f'<rect x="10" y="60" width="26" height="66" fill="#455a64"/>'
            f'<g transform="rotate({angle:.1f} 23 64)">'
            f'<rect x="23" y="58" width="190" height="12" rx="3" fill="#fff" stroke="{colour}" stroke-width="3"/>'
            + "".join(f'<rect x="{40 + 40 * i}" y="59" width="18" height="10" fill="{colour}"/>' for i in range(4))
            + '</g><circle cx="23" cy="64" r="6" fill="#263238"/></svg>')


class Mo64View(DeviceView):
    """What every card of one page shares: the device's live record and the declared commands
    (devices/mo64/policy.py)."""

    async def move(self, cmd: codec.Command, fn: codec.Function) -> None:
        words = said(command_words(cmd, fn), self.lang)  # "öffnen Impuls": the declared name is the audit's
        # the declared risk ("the area is clear") is asked by the gate for every motion, every time
        await self.act(operation_name(cmd, fn), title=f"{words}?",
                       success=self.lang.gettext("{operation}: ack").format(operation=words))


class GateCard(DeviceCard):
    """Gate state, the boom, position, alarms, the connection and the line's counters."""

    def __init__(self, view: Mo64View):
        super().__init__(view)
        self.badge = StatusBadge(view.state, view.lang)
        self.last_position: object = object()

    def build(self) -> None:
        view = self.view
        _ = view.lang.gettext
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-6 w-full no-wrap"):
                self.picture = ui.html(boom_svg(None)).props("data-testid=boom")
                with ui.column().classes("gap-1"):
                    with ui.row().classes("items-center gap-4"):
                        self.badge.build()
                        self.gate = ui.label(_("gate state: {text}").format(text="-")).classes("text-h6").props("data-testid=gate-state")
                    self.position = ui.label(_("position: {text}").format(text="-")).classes("text-h6").props("data-testid=position")
                    self.bar = ui.linear_progress(value=0, show_value=False).props("size=14px rounded").classes("w-72")
                    self.alarms = ui.label().classes("text-negative text-body1").props("data-testid=alarms")
                    self.link = ui.label().classes("text-body2").props("data-testid=connection")
                    self.error_line = ui.label().classes("text-negative text-caption")
                    self.unavailable = ui.label().classes("text-caption text-grey-8").props("data-testid=unavailable")
                    counter_line(view.state, lambda c: _("requests {requests}  answers {answers}  timeouts {timeouts}  "
                                                         "malformed {malformed}").format(
                        requests=c.requests, answers=c.responses, timeouts=c.timeouts, malformed=c.malformed))
            line = view.fact(facts.P_LINE)
            if line is not None and line.rs485:
                ui.label(_("RS485 bus address {address}, this tool is master {master}.").format(address=line.address, master=line.master)) \
                    .classes("text-caption text-grey-8")
            else:
                with ui.row().classes("items-center gap-2"):
                    ui.label(_("The MO 64 serves one TCP client at a time (chapter 3).")).classes("text-caption text-grey-8")
                    release = ui.button(_("Release the connection"), icon="link_off", on_click=lambda: view.act(
                        "release the connection", success=_("released: another client may connect"))) \
                        .props("outline dense data-testid=release")
                    resume = ui.button(_("Take it back"), icon="link", on_click=lambda: view.act("take the connection back")) \
                        .props("outline dense data-testid=resume")
                    # engineers only (declared writes); usable while the barrier is silent: that may be why
                    for button in (release, resume):
                        enable_unless(button, viewer_reason(view.lang))

    def refresh(self) -> None:
        view, state = self.view, self.view.state
        _ = view.lang.gettext
        bus = view.store.buses.get(state.bus)
        if self.unchanged((state.status, state.last_error, bus.last_error if bus is not None else None,
                           view.inputs(GATE_INPUTS)), lambda: status_text(state.status, state.age, view.lang)):
            return  # status, errors and the gate's points as drawn: the badge's age moves on the once-a-second round
        self.badge.refresh()
        self.gate.set_text(_("gate state: {text}").format(text=view.lang.phrase(view.text("Gate state"), "Gate state")))
        value = view.fact("Position")
        self.position.set_text(_("position: {text}").format(text=view.lang.numbers_in(view.text("Position"))))
        self.bar.set_value(0 if value is None else value / 100)
        if value != self.last_position:
            self.last_position = value
            self.picture.set_content(boom_svg(value))
        on = [b for b in ALARM_BITS if view.fact(b)]
        self.alarms.set_text(", ".join(_(ALARM_WORDS[b]) for b in sorted(on)))
        late = view.fact(facts.P_LATE, 0)
        words = view.lang.phrase  # the adapter's words of these points (app/device_words.py)
        self.link.set_text(_("connection: {text}").format(text=words(view.text(facts.P_CONNECTION), facts.P_CONNECTION))
                           + (f" ({bus.last_error})" if bus is not None and bus.last_error else "")
                           + _("; polling {polling}; query form: {form}").format(
                               polling=words(view.text(facts.P_POLLING), facts.P_POLLING),
                               form=words(view.text(facts.P_QUERY_FORM), facts.P_QUERY_FORM))
                           + (_("; late answers {n}").format(n=late) if late else ""))
        missing = view.fact(facts.P_UNAVAILABLE, ())
        levels_missing = view.fact(facts.P_LEVELS_UNAVAILABLE, ())
        self.unavailable.set_text((_("not available on this unit: {list}").format(list=", ".join(missing)) if missing else "")
                                  + ("; " if missing and levels_missing else "")
                                  + (_("error memory levels {levels} not available on this unit").format(
                                      levels=", ".join(map(str, levels_missing))) if levels_missing else ""))
        self.error_line.set_text(state.last_error)


class CommandsCard(DeviceCard):
    """Pulses and levels (chapter 5.2.1), the levels this tool set, the barrier's last answer."""

    view: Mo64View

    def build(self) -> None:
        view, guard = self.view, self.guard
        _ = view.lang.gettext
        with titled_card(_("Commands (chapter 5.2.1)")):
            with ui.row().classes("items-center gap-3"):
                ui.label(_("Pulse:")).classes("text-body2")
                for cmd, icon in ((codec.Command.OPEN, "arrow_upward"), (codec.Command.CLOSE, "arrow_downward"),
                                  (codec.Command.REVERSE, "swap_vert")):
                    guard.add(ui.button(_(COMMAND_WORDS[cmd]).capitalize(), icon=icon,
                                        on_click=lambda cmd=cmd: view.move(cmd, codec.Function.PULSE))
                              .props(f"data-testid=pulse-{COMMAND_NAMES[cmd]}"))
            with ui.row().classes("items-center gap-3"):
                ui.label(_("Level:")).classes("text-body2")
                for cmd in (codec.Command.OPEN, codec.Command.CLOSE, codec.Command.REVERSE):
                    with ui.button_group():
                        guard.add(ui.button(_("{command} activate").format(command=_(COMMAND_WORDS[cmd])),
                                            on_click=lambda cmd=cmd: view.move(cmd, codec.Function.ACTIVATE))
                                  .props(f"outline data-testid=activate-{COMMAND_NAMES[cmd]}"))
                        off = ui.button(_("deactivate"), on_click=lambda cmd=cmd: view.move(cmd, codec.Function.DEACTIVATE)) \
                            .props(f"outline data-testid=deactivate-{COMMAND_NAMES[cmd]}")
                        if cmd is codec.Command.OPEN:  # lets the boom close: motion (devices/mo64/control.py)
                            enable_unless(off, viewer_reason(view.lang))
                        else:  # a stop, never refused: on for every role, also while the barrier is silent
                            off.props(f'title="{html.escape(_(STOP_HINT))}"')
                clear = ui.button(_("Clear my levels"), icon="layers_clear", on_click=self.clear_levels) \
                    .props("data-testid=clear-levels")
                enable_unless(clear, viewer_reason(view.lang))  # a declared system command: engineers only
            self.levels = ui.label().classes("text-body2").props("data-testid=levels")
            self.reply = ui.label().classes("text-body2 mono").props("data-testid=reply")
            ui.label(_("A level stays active in the barrier until it is deactivated. Close and reverse levels are "
                       "deactivated when this browser closes or freezes (dead-man rule) and when the tool stops (each "
                       "acknowledged by the barrier); an open level is not, since "
                       "deactivating it would let an unattended boom close. Every motion asks for its own "
                       "confirmation ({warning}).").format(warning=_(MOTION_WARNING))).classes("text-caption text-grey-8")

    async def clear_levels(self) -> None:
        _ = self.view.lang.gettext
        if not self.view.fact(facts.P_LEVELS, ()):
            ui.notify(_("no level set by this tool is active"))
            return
        await self.view.act("clear levels", success=_("levels deactivated"))  # the gate asks the declared risk

    def refresh(self) -> None:
        if self.unchanged(self.view.inputs((facts.P_LEVELS, facts.P_LAST_REPLY)), lambda: None):
            return
        _ = self.view.lang.gettext
        mine = sorted(_(level.command) + (_(" (dead-man)") if level.dead_man else "")
                      for level in self.view.fact(facts.P_LEVELS, ()))
        self.levels.set_text(_("levels this tool set: {list}").format(list=", ".join(mine) if mine else _("none")))
        reply = said(self.view.text(facts.P_LAST_REPLY), self.view.lang)
        self.reply.set_text(_("last answer: {text}").format(text=reply))


class StatusCard(DeviceCard):
    """The 40 status bits (chapter 5.1.7) as lamps, with their meanings on hover."""

    def build(self) -> None:
        lang = self.view.lang
        _ = lang.gettext
        self.lamps: dict[str, Lamp] = {}
        with titled_card(_("Barrier status (40 bits, chapter 5.1.7)")):
            with ui.row().classes("gap-8 items-start"):
                for group, names in codec.STATUS_GROUPS.items():
                    with ui.column().classes("gap-0"):
                        ui.label(_(GROUP_NAMES.get(group, group))).classes("text-subtitle2")
                        for bit in names:
                            if bit in HIDDEN_BITS:
                                continue
                            lamp = self.lamps[bit] = Lamp(bit_name(bit, lang), "alarm" if bit in ALARM_BITS else "ok",
                                                          light=True, tooltip=bit_meaning(bit, lang))
                            lamp.row.props(f'data-lamp="{bit}"')  # the bit's name, whatever the lamp says
            ui.label(_(LEGEND)).classes("text-caption text-grey-8").props("data-testid=status-legend")

    def refresh(self) -> None:
        if self.unchanged(self.view.inputs(self.lamps), lambda: self.view.qualities(self.lamps)):
            return  # the same 40 bits, none shown stale
        aging = False
        for bit, lamp in self.lamps.items():
            value = self.view.live(bit)
            lamp.show(value)
            aging = aging or (value is not None and value.quality == "stale")
        self.aging = aging


class ValuesCard(DeviceCard):
    """Named values, each with its age while stale or offline (identity, counters, modes)."""

    def __init__(self, view: Mo64View, title: str, points: tuple[str, ...], testid: str, classes: str,
                 note: str = "", column: str = "gap-0 mono text-body2"):
        super().__init__(view)
        self.title, self.points, self.testid = title, points, testid
        self.classes, self.note, self.column = classes, note, column
        self.lines: dict[str, tuple] = {}

    def build(self) -> None:
        _ = self.view.lang.gettext
        with titled_card(_(self.title), self.classes):
            with ui.column().classes(self.column).props(f"data-testid={self.testid}"):
                self.lines = {pt: value_line() for pt in self.points}
            if self.note:
                ui.label(_(self.note)).classes("text-caption text-grey-8")

    def refresh(self) -> None:
        if self.unchanged(self.view.inputs(self.points), lambda: self.view.qualities(self.points)):
            return
        aging = False
        lang = self.view.lang
        for point, line in self.lines.items():
            aging = show_line(line, f"{lang.gettext(point)}: {lang.numbers_in(said(self.view.text(point), lang))}", self.view.live(point),
                               lang) or aging
        self.aging = aging


class ErrorMemoryCard(DeviceCard):
    """The 10 levels of the error memory (chapter 5.1.23), newest first, and a read again."""

    def build(self) -> None:
        _ = self.view.lang.gettext
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-4"):
                ui.label(_("Error memory (10 levels, newest first, chapter 5.1.23)")).classes("text-subtitle1")
                self.guard.add(ui.button(_("Read again"), on_click=lambda: self.view.act("read error memory"))
                               .props("outline dense"))
                self.age = ui.label().classes("q-age").props("data-testid=error-memory-age")
            ui.label(_(ERROR_MEMORY_MEANING)).classes("text-caption text-grey-8")
            lang = self.view.lang  # the document's Ebene, not the event log's Stufe
            self.table = ui.table(columns=[{**c, "label": lang.pgettext("error memory", c["label"]) if c["name"] == "level"
                                            else lang.gettext(c["label"])} for c in ERROR_COLUMNS],
                                  rows=[], row_key="level").classes("w-full text-caption") \
                .props("dense flat wrap-cells data-testid=error-memory")

    def refresh(self) -> None:
        state = self.view.state
        if self.unchanged((state.status, self.view.inputs((facts.P_ERROR_LEVELS,))),
                          lambda: state.status == "offline" and quality_note("offline", state.age, self.view.lang)):
            return
        lang = self.view.lang
        levels = {e.level: e for e in self.view.fact(facts.P_ERROR_LEVELS, ())}
        rows = [{"level": error_level_text(e.level, lang),
                 "meaning": error_level_meaning(e.flags, e.timestamp_h,
                                                levels[e.level + 1].flags if e.level + 1 in levels else None, lang),
                 "raw": f"0x{e.flags:08X}", "time": f"{lang.number(e.timestamp_h)} h"} for e in levels.values()]
        if rows != self.table.rows:
            self.table.rows = rows
            self.table.update()
        offline = state.status == "offline" and rows
        mark_quality(self.table, "offline" if offline else "good")
        self.age.set_text(quality_note("offline", state.age, lang) if offline else "")


def content(name: str) -> None:
    view = Mo64View(name)
    _ = view.lang.gettext
    with device_page(view, _("Bauer MO 64 {name}").format(name=name)):
        view.guard = WriteGuard(view.state, lang=view.lang)  # commands and settings, disabled with the reason while the barrier does not answer
        for card in (GateCard(view), CommandsCard(view), StatusCard(view)):
            view.add(card)
        with ui.row().classes("w-full gap-4 items-stretch"):
            view.add(ValuesCard(view, N_("Identity"), IDENTITY_POINTS, "identity", "col"))
            view.add(ValuesCard(view, N_("Counters"), COUNTER_POINTS, "counters", "col",
                                note=N_("The vehicle counter lives in RAM only: it is 0 after power-up (chapter 5.2.5).")))
        view.add(ErrorMemoryCard(view))
        view.add(ValuesCard(view, N_("Modes (decoded as far as the document names the fields, raw otherwise)"), MODE_POINTS,
                            "modes", "w-full", column="gap-0 text-body2"))
        view.add(SettingsCard(view))
        with ui.expansion(_("Assumptions beyond the manual (shown as such)")).classes("w-full") \
                .props("data-testid=assumptions"):
            # static text: one element for all of them
            assumption = _("Assumption: {text}")
            ui.html("".join(f'<div class="text-caption">{html.escape(assumption.format(text=_(text)), quote=False)}</div>'
                            for text in codec.ASSUMPTIONS),
                    sanitize=False).classes("column gap-2")
        sim_card(name)  # the twin's declared controls, in simulation only


def error_level_text(level: int, lang) -> str:
    """:func:`devices.mo64.codec.error_level_text` in ``lang``: level 0 the newest change, 9 the oldest (5.1.23)."""
    if level == 0:
        return lang.gettext("{level} (newest)").format(level=level)
    if level == codec.ERROR_MEMORY_LEVELS - 1:
        return lang.gettext("{level} (oldest)").format(level=level)
    return str(level)


def error_level_meaning(flags: int, timestamp_h: int, older: int | None, lang) -> str:
    """:func:`devices.mo64.codec.error_level_meaning` in ``lang``: the flags set, what changed against the older
    level, or a level no change has reached yet."""
    _ = lang.gettext
    if int(flags) == 0 and int(timestamp_h) == 0:
        return _("empty: no change stored")
    now = codec.error_flag_bits(int(flags))
    before = set(codec.error_flag_bits(older)) if older is not None else None

    def numbers(bits) -> str:
        return ", ".join(map(str, bits))

    def named(bits: list[int]) -> str:
        return lang.ngettext("flag {list}", "flags {list}", len(bits)).format(list=numbers(bits))

    changes = []
    if before is not None:
        new = [n for n in now if n not in before]
        gone = sorted(before - set(now))
        if new and before:
            changes.append(_("{list} new").format(list=numbers(new)))
        if gone:
            changes.append(_("{list} cleared").format(list=named(gone) if not now else numbers(gone)))
    tail = f" ({'; '.join(changes)})" if changes else ""
    return (_("no error") if not now else _("error {flags} set").format(flags=named(now))) + tail


__all__ = ["boom_svg", "content"]
