"""CAN-M3IO page: inputs, SSR channels with fuse/triac/load, temperatures, watchdog, addressed data.

Reads only the live store (the points and records :mod:`devices.m3io.adapter` publishes) and invokes the
declared commands (devices/m3io/policy.py) through the worker's gate. Each card is a small class with
``build()`` (in the page's layout) and ``refresh()`` (on every change the store pushes)."""

from __future__ import annotations

import html

from nicegui import ui

from app import i18n
from app.i18n import N_, NP_
from app.message import Message, said
from app.state import LiveValue
from app.worker import DEADMAN_BOUND_S
from devices.m3io import adapter as facts
from devices.m3io import codec
from devices.m3io.codec import Variant
from devices.m3io.params import P2_PARAM, RECORD_PARAMS
from devices.commands import WRITE_PARAMETER
from pages.cards import DrawnCard, titled_card
from pages.device_page import DeviceView, StatusRow, device_page
from pages.frame import fmt_age
from pages.session import current_user
from pages.simcontrols import sim_card
from pages.widgets import entry_age, Lamp, mark_quality, quality_note
from pages.command_client import checked_value, WriteGuard
from pages.charts import HistoryChart
from pages.widgets import range_number, stop_bar
from pages.command_client import enable_unless, refuse, viewer_reason

STATE_COLOR = {"ok": "positive", "present": "positive", "blown": "negative", "defective": "negative"}
VARIANT_COLOR = {"ok": "text-positive", "mismatch": "text-negative text-weight-medium", "unchecked": "text-grey-8", "not possible": "text-warning"}
TAKE_CONTROL = N_("take control of the module first")
# the channels' states (section 7.2.3: Last, Si, Triac) and the badges' titles, as the adapter publishes them
CUSTOMER_DATA_WORDS = (NP_("customer data", "Record"), NP_("customer data", "Read"))  # a record and reading it
CHANNEL_WORDS = (N_("none (no load, no supply, or a triac with a permanent short circuit)"), N_("not checked (off)"), N_("ok"), N_("present"), N_("blown"), N_("defective"), N_("unknown"), N_("load"), N_("fuse"), N_("triac"))
# The temperature chart's legend under the time axis, at the foot of the figure: above the plot it lay where
# plotly's mode bar appears (top right), which covered the last channels' names.
CHART_HEIGHT = 300
LEGEND_MARGIN_B = 80  # the time axis with its date line, then one or two rows of legend
MODE_BAR_MARGIN_T = 30  # the mode bar's own row above the plot, clear of the lines
LEGEND_BELOW = {"orientation": "h", "x": 0, "xanchor": "left", "y": 0, "yanchor": "bottom", "yref": "container"}
STOP_RULE = N_(
    "Outputs belong to the page that switched them on: they go off at once when that page is closed or reloaded, "
    "or within {bound} s when it stops confirming that it is alive (frozen tab, sleeping laptop, lost network). "
    "Another open tab does not keep them on. While you control the module this tool serves its 2 s watchdog, "
    "and it switches the outputs off by itself if the program stalls."
)


def temp_text(variant: Variant, channel: int, word: codec.TempWord, lang=None) -> str:
    """``21.5 °C`` or ``out of range (-5.0 °C)``: the reading in the bus monitor's words (codec.describe_temp, 7.2.2),
    in ``lang`` when given."""
    text = codec.describe_temp(variant, channel, word).split(" · ", 1)[0].split(" ", 1)[1]
    if lang is None:
        return text
    if word.in_range:
        return lang.numbers_in(text)
    return lang.gettext("out of range ({value} °C)").format(value=lang.number(word.celsius, 1))


def variant_text(check: LiveValue, view: M3ioView) -> str:
    """The variant check's words (devices/m3io/codec.py check_variant) in the page's language."""
    return said(check.text, view.lang) if isinstance(check.text, Message) else view.lang.gettext(check.text)


def _p2_words(text: str, lang) -> str:
    """What the module's P2 check says (devices/m3io/adapter.py) in ``lang``."""
    if isinstance(text, Message):
        return said(text, lang)
    return lang.gettext(text) if text else ""  # gettext("") would be the catalog's header


def _quality(value: LiveValue | None) -> str:
    return "unknown" if value is None else value.quality


def _age_note(value: LiveValue | None, lang=None) -> str:
    quality = _quality(value)
    return quality_note(quality, entry_age(value), lang) if quality in ("stale", "offline") else ""


class M3ioView(DeviceView):
    """What every card of one page shares: the module's live record, its variant and addressing, and its
    declared commands (devices/m3io/policy.py). Outputs switched on here belong to this page session."""

    def __init__(self, name: str):
        super().__init__(name)
        self.variant = Variant(self.fact(facts.P_VARIANT))
        self.addressing: facts.Addressing = self.fact(facts.P_ADDRESSING)

    def controls(self) -> bool:
        """Whether this page session controls the module (display only: the gate decides)."""
        control = self.fact(facts.P_CONTROL)
        return control is not None and control.session == self.tag

    def switch_reason(self, on: bool) -> str:
        """Why an output's switch is off here ("" when it may be used): the module silent or a viewer (the page's
        guard), or switching on without control. Switching an output off is never refused for want of control."""
        reason = self.guard.reason if self.guard is not None else ""
        if reason or on or self.controls():
            return reason
        control = self.fact(facts.P_CONTROL)
        _ = self.lang.gettext
        return _(TAKE_CONTROL) if control is None else _("{user} controls the module").format(user=control.user)


def _aging(value: LiveValue | None) -> bool:
    return _quality(value) in ("stale", "offline")


class ModuleCard(DrawnCard):
    """Status, watchdog, counters, SW1 and the CAN IDs, the variant check, control of the module."""

    view: M3ioView
    POINTS = (facts.P_WATCHDOG, facts.P_OTHER_MASTER, facts.P_CONTROL, facts.P_VARIANT_CHECK)

    def build(self) -> None:
        view, a = self.view, self.view.addressing
        _ = view.lang.gettext
        # the session's role, worked out here in the page's context: the store's round redraws without it
        self.read_only = viewer_reason(view.lang)
        self.status = StatusRow(view.state, lambda c: _("frames in {responses} · requests {requests} · timeouts {timeouts} "
                                                        "· malformed {malformed} · write errors {write_errors}").format(
            responses=c.responses, requests=c.requests, timeouts=c.timeouts, malformed=c.malformed,
            write_errors=c.write_errors), view.lang)
        with ui.card().classes("w-full"):
            with self.status.build():
                self.watchdog = ui.label().classes("text-body2")
            ui.label(f"SW1 0x{a.sw1:02X} ({a.sw1:08b}): " + (_("addressed mode (S8 on), ") if a.addressed else _("S8 off, "))
                     + f"{a.bitrate // 1000} kbit/s · " + " · ".join(f"{k} 0x{v:03X}" for k, v in a.ids)).classes("text-body2 mono")
            self.variant = ui.label().classes("text-body2").props("data-testid=variant-check")
            # the module is a slave: this tool serves its watchdog (DigOut) only while an engineer controls it
            with ui.row().classes("items-center gap-3"):
                self.take_button = ui.button(_("Take control"), icon="sports_esports", on_click=self.take) \
                    .props("data-testid=take-control")
                self.take_button.tooltip(_("Listens for another master (a PLC sending DigOut {id}) first; refused if "
                                           "there is one").format(id=f"0x{a.dig_out:03X}"))
                self.release = ui.button(_("Release"), icon="logout", on_click=lambda: view.act("release control")) \
                    .props("outline data-testid=release-control")
                self.holder = ui.label().classes("text-body2").props("data-testid=controller")
            if view.fact(facts.P_BITRATE_CHECK) == "mismatch":
                ui.label(_("SW1 sets {module} kbit/s, but the bus runs at {bus} kbit/s: the module cannot be reached. Fix SW1 "
                           "or the bus bit rate in the plant file.").format(module=a.bitrate // 1000,
                                                                            bus=(a.bus_bitrate or 0) // 1000)).classes("text-negative text-body1")

    async def take(self) -> None:
        await self.view.act("take control", {"user": current_user()[0] or "local engineer"},
                            success=self.view.lang.gettext("you control the module: DigOut serves its watchdog"))

    def draw(self) -> None:
        view, state = self.view, self.view.state
        _ = view.lang.gettext
        self.status.refresh()
        served = bool(view.fact(facts.P_WATCHDOG))
        other = view.fact(facts.P_OTHER_MASTER)
        foreign = other is not None and other.active
        self.watchdog.set_text(_("watchdog {state} · last answer {age}").format(state=view.lang.phrase(view.text(facts.P_WATCHDOG)),
                                                                                age=fmt_age(state.age, view.lang)))
        self.watchdog.classes(replace="text-body2 " + ("text-positive" if served else "text-warning" if foreign else "text-grey-8"))
        control = view.fact(facts.P_CONTROL)
        self.holder.set_text((_("you control the module") if control.session == view.tag
                              else _("{user} controls the module").format(user=control.user))
                             if control else _("nobody controls the module"))
        mine = view.controls()
        enable_unless(self.take_button, self.read_only or (_("you control the module") if mine else ""))
        enable_unless(self.release, self.read_only or ("" if mine else _("you do not control the module")))
        check = view.live(facts.P_VARIANT_CHECK)
        self.variant.set_text(_("Variant {variant}: {text}").format(variant=view.variant.value, text=variant_text(check, view)))
        self.variant.classes(replace="text-body2 " + VARIANT_COLOR.get(check.value, "text-grey-8"))


class OutputsCard(DrawnCard):
    """Inputs E1-E6, the stop rule, the LED, one row per SSR output and (HMR) P2."""

    def __init__(self, view: M3ioView):
        super().__init__(view)
        self.rows = [ChannelRow(view, view.guard, output, channels) for output, channels in facts.ssr_groups(view.variant)]
        self.POINTS = (facts.P_VARIANT_CHECK, facts.P_CONTROL, facts.P_OWNERS, facts.P_LOAD_CHECK, facts.P_P2,
                       facts.P_P2_CHECK, "LED", *(f"E{i}" for i in range(1, 7)), *(row.output for row in self.rows),
                       *(f"SSR{c} {what}" for row in self.rows for c in row.channels for what in ("Last", "Si", "Triac")))

    def build(self) -> None:
        _ = self.view.lang.gettext
        with titled_card(_("Digital inputs"), "col-xs-12 col-md"):
            with ui.row().classes("gap-5"):
                self.lamps = {f"E{i}": Lamp(f"E{i}") for i in range(1, 7)}
            ui.separator()
            with ui.row().classes("items-center w-full"):
                ui.label(_("Outputs")).classes("text-subtitle1")
                ui.space()
                ui.label(_("All off: in the bar at the bottom, always in sight")).classes("text-caption text-grey-8")
            with ui.row().classes("items-start gap-1 no-wrap").props("data-testid=stop-rule"):
                ui.icon("front_hand", size="xs").classes("text-grey-8 q-mt-xs")
                ui.label(_(STOP_RULE).format(bound=f"{DEADMAN_BOUND_S:g}")).classes("text-caption text-grey-8")
            self.refused = ui.label().classes("text-negative text-body2")
            self.no_control = ui.label(_("Switches: {reason} (Take control above)").format(reason=_(TAKE_CONTROL))).classes(
                "text-caption text-grey-8").props("data-testid=switch-reason")
            self.led = ui.switch(_("LED (Bereit)"), on_change=lambda e: switch(self.view, "LED", e)).props("data-output=LED")
            with ui.column().classes("w-full gap-1"):
                for row in self.rows:
                    row.build()
            self.p2 = self.p2_check = None
            if self.view.variant is Variant.HMR:
                with ui.row().classes("items-center"):
                    self.p2 = ui.switch(_("Three-phase output loaded on two phases only (P2)"), on_change=self.set_p2)
                    self.guard.add(self.p2)
                    ui.label(_("not stored in the module: sent with every DigOut period, so a reset cannot lose it, and "
                               "kept in the plant file (p2), so a restart does not assume three phases")).classes(
                        "text-caption text-grey-8")
                self.p2_check = ui.label().classes("text-caption").props("data-testid=p2-check")

    async def set_p2(self, event) -> None:
        """The model's write of P2 (on asks what it switches off, devices/m3io/params.py); back if refused."""
        if bool(event.value) == bool(self.view.fact(facts.P_P2)):
            return
        words = self.view.lang.gettext
        ok, _ = await self.view.act(WRITE_PARAMETER, {"param": P2_PARAM.key, "value": int(bool(event.value))},
                                    title=words("Switch P2 on?") if event.value else "", ok=words("Switch P2 on"))
        if not ok:
            event.sender.set_value(bool(self.view.fact(facts.P_P2)))

    def draw(self) -> bool:
        view = self.view
        _ = view.lang.gettext
        check = view.live(facts.P_VARIANT_CHECK)
        may_switch = check is None or bool(check.raw)
        self.refused.set_text("" if may_switch else _("Switching on is refused: {text}").format(text=variant_text(check, view)))
        self.refused.set_visibility(not may_switch)
        good = True
        for key, lamp in self.lamps.items():
            value = view.live(key)
            lamp.show(value)
            good = good and (value is None or value.quality not in ("stale", "offline"))
        self.no_control.set_visibility(not view.controls() and not (view.guard and view.guard.reason))
        self.led.set_value(bool(view.fact("LED")))
        enable_unless(self.led, view.switch_reason(bool(view.fact("LED"))))
        for row in self.rows:
            good = row.refresh() and good
        if self.p2 is not None:
            self.p2.set_value(bool(view.fact(facts.P_P2)))
            p2_check = view.live(facts.P_P2_CHECK)
            self.p2_check.set_text("" if p2_check is None else _("P2 in the module: {text}").format(
                text=_p2_words(p2_check.shown, view.lang)))
            self.p2_check.classes(replace="text-caption " + ("text-negative" if p2_check and p2_check.value == "mismatch"
                                                             else "text-grey-8"))
        return good


async def switch(view: M3ioView, output: str, event) -> None:
    """A switch moved: the declared "<output> on/off" (an SSR asks its mains risk first); back if refused."""
    value = bool(event.value)
    if value == bool(view.fact(output)):
        return  # the refresh set it to what the module has
    words = view.lang.gettext
    ok, _ = await view.act(f"{output} {'on' if value else 'off'}", title=words("Switch {output} on?").format(output=output),
                           ok=words("Switch on"))
    if not ok:
        event.sender.set_value(bool(view.fact(output)))


class ChannelRow:
    """One SSR output with the load, fuse and triac of each channel it drives (HMR SSR1-3: three)."""

    def __init__(self, view: M3ioView, guard: WriteGuard, output: str, channels: tuple[int, ...]):
        self.view, self.guard, self.output, self.channels = view, guard, output, channels
        self.shown: object = None

    def build(self) -> None:
        output = self.output
        with ui.row().classes("items-center w-full gap-3 no-wrap") as row:
            row.props(f'data-channel="{output}"')
            self.switch = ui.switch(output, on_change=lambda e: switch(self.view, output, e)).classes("w-32")
            self.switch.props(f'data-output="{output}"')
            # the channels' badges and advice: drawn as the text of one element when they change
            self.details = ui.html("", sanitize=False).classes("nicegui-column gap-1 col")
            self.age = ui.label().classes("q-age")
        if output == "SSR1-3":
            ui.label(self.view.lang.gettext("Three-phase output: a fault on one of SSR1, SSR2, SSR3 switches all three off.")).classes("text-caption text-grey-8")

    def _channel(self, channel: int) -> tuple[str, str, str, bool]:
        view = self.view
        last = view.live(f"SSR{channel} Last")
        return (view.text(f"SSR{channel} Last", "unknown"), view.fact(f"SSR{channel} Si", "unknown"),
                view.fact(f"SSR{channel} Triac", "unknown"), last is not None)

    def refresh(self) -> bool:
        """The output's switch and its channels as the store has them; False when their status is stale or offline."""
        view, output = self.view, self.output
        on = bool(view.fact(output))
        self.switch.set_value(on)
        enable_unless(self.switch, view.switch_reason(on))
        owners = {o.output: o.session for o in view.fact(facts.P_OWNERS, ())}
        foreign = on and output in owners and owners[output] != view.tag
        group = view.live(facts.P_LOAD_CHECK) if output == "SSR1-3" else None
        group_fault = group.text if group is not None and group.value == "fault" else None
        shown = (foreign, group_fault, tuple(self._channel(c) for c in self.channels))
        entry = view.live(f"SSR{self.channels[0]} Last")
        mark_quality(self.details, _quality(entry))  # greyed, with the age of its status, while stale or offline
        self.age.set_text(_age_note(entry, view.lang))
        if shown != self.shown:  # drawn again only when it changed
            self.shown = shown
            parts = []
            if foreign:
                parts.append(_text_html(view.lang.gettext("switched on from another page: it goes off when that page goes away"),
                                        "text-caption text-warning"))
            if group_fault:
                parts.append(_text_html(said(group_fault, view.lang), "text-negative text-body2"))
            for channel, (load, fuse, triac, heard) in zip(self.channels, shown[2]):
                parts.append(self._show(channel, load, fuse, triac, heard))
            self.details.set_content("".join(parts))
        return not _aging(entry)

    def _show(self, channel: int, load: str, fuse: str, triac: str, heard: bool) -> str:
        """One channel's load, fuse and triac as badges (Quasar's), with what to do about a fault."""
        _ = self.view.lang.gettext
        parts = ['<div class="nicegui-row row items-center gap-2">']
        if len(self.channels) > 1:
            parts.append(_text_html(f"SSR{channel}", "text-caption mono"))
        for title, value in (("load", load), ("fuse", fuse), ("triac", triac)):
            text = html.escape(f"{_(title)}: {_(value)}", quote=True)
            parts.append(f'<div class="q-badge flex inline items-center no-wrap q-badge--multi-line '
                         f'bg-{STATE_COLOR.get(value, "grey")}" role="status" aria-label="{text}" '
                         f'data-{title}="{html.escape(value, quote=True)}">{text}</div>')
        if not heard:
            parts.append(_text_html(_("no status yet"), "text-caption text-grey-8"))
        parts.append("</div>")
        if fuse == "blown":
            fuse_name, hmr, hm = codec.FUSES[channel]  # codec.fuse_advice, in the page's language
            parts.append(_text_html(_("replace fuse {fuse} ({rating}, fast-acting 5x20 mm)").format(
                fuse=fuse_name, rating=hmr if self.view.variant is Variant.HMR else hm), "text-negative text-body2"))
        if triac == "defective":
            parts.append(_text_html(_("triac defective: it does not conduct while switched on"), "text-negative text-body2"))
        return "".join(parts)


def _text_html(text: str, classes: str) -> str:
    """A label's tag and classes, in the text of the element that holds it."""
    return f'<div class="{classes}">{html.escape(text)}</div>'


class TemperatureCard(DrawnCard):
    """The Pt100 temperatures (section 7.2.2) and their chart."""

    view: M3ioView

    def build(self) -> None:
        view = self.view
        self.labels: dict[int, tuple[ui.label, ui.label]] = {}
        with titled_card(view.lang.gettext("Pt100 temperatures (0.1 °C)"), "col-xs-12 col-md"):
            with ui.row().classes("gap-6"):
                for channel in facts.temp_channels(view.variant):
                    with ui.column().classes("gap-0"):
                        ui.label(f"TEMP{channel}" + (" (SSR1-3)" if view.variant is Variant.HMR and channel == 1 else "")) \
                            .classes("text-caption text-grey-8")
                        self.labels[channel] = (ui.label("-").classes("text-h6").props(f'data-temp="{channel}"'),
                                                ui.label().classes("q-age q-ml-none"))
            self.POINTS = tuple(f"TEMP{channel}" for channel in self.labels)
            chart = HistoryChart(view.state, list(facts.history_points(view.variant)), window_s=600, height=CHART_HEIGHT,
                                 lang=view.lang)
            chart.figure["layout"]["legend"] = LEGEND_BELOW  # the mode bar (top right) covered the legend above the plot
            chart.figure["layout"]["margin"].update(t=MODE_BAR_MARGIN_T, b=LEGEND_MARGIN_B)
            chart.plot.update()

    def draw(self) -> bool:
        good = True
        for channel, (label, note) in self.labels.items():
            value = self.view.live(f"TEMP{channel}")
            good = good and not _aging(value)
            word = None if value is None or value.raw is None else codec.TempWord(value.raw)
            label.set_text("-" if word is None else temp_text(self.view.variant, channel, word, self.view.lang))
            label.classes(replace="text-h6 " + ("" if word is None or word.in_range else "text-warning"))
            mark_quality(label, _quality(value))
            note.set_text(_age_note(value, self.view.lang))
        return good


class AddressedCard(DrawnCard):
    """Addressed mode (SW1 switch 8 on, 7.2.4.2): identity, the 15 customer-data records, the actual load data."""

    view: M3ioView
    POINTS = (facts.P_IDENTITY, *(f"SSR{i} load data" for i in range(1, 7)), *(p.name for p in RECORD_PARAMS))

    def build(self) -> None:
        _ = self.view.lang.gettext
        with titled_card(_("Addressed data (SW1 switch 8 on)")):
            self.identity = ui.label(_("not read")).classes("text-body2").props("data-testid=identity")
            self.guard.add(ui.button(_("Read identity"), icon="badge", on_click=lambda: self.view.act("read identity"))
                           .props("outline dense"))
            ui.label(_("Software version: assumed decoding ({assumption}).").format(assumption=_(codec.VERSION_ASSUMPTION))).classes("text-caption text-grey-8")
            ui.separator()
            ui.label(_("Customer data (15 records of 6 bytes)")).classes("text-body2 text-weight-medium")
            with ui.row().classes("items-center"):
                # records 1-15 of 6 bytes (section 7.2.4.2, areas 3 and 4)
                self.index = range_number(self.view.lang.pgettext("customer data", "Record"), 1, 15, integer=True, value=1, lang=self.view.lang).classes("w-32").props("data-testid=record")
                self.data = ui.input(_("Bytes (hex, up to 6)"), placeholder="01 02 03",
                                     validation=lambda text: _bytes_check(text, self.view.lang)).props(
                    "dense outlined data-testid=record-bytes").classes("w-56 mono")
                self.record = ui.label().classes("mono")
                self.guard.add(ui.button(self.view.lang.pgettext("customer data", "Read"), on_click=self.read_record).props("outline dense"),
                               ui.button(_("Write"), on_click=self.write_record).props("dense data-testid=record-write"))
            # the records as last read (the parameter model's values: projects, backups and drift compare these)
            with ui.element("div").classes("mono text-body2").style(
                    "display: grid; grid-template-columns: repeat(auto-fill, minmax(13rem, 1fr)); gap: 0 16px").props(
                    "data-testid=records"):
                self.records = [ui.label() for _ in RECORD_PARAMS]
            ui.separator()
            self.loads = ui.label().classes("text-body2 mono")
            self.guard.add(ui.button(_("Read actual load data SSR1-6"), on_click=lambda: self.view.act("read load data"))
                           .props("outline dense"))

    async def read_record(self) -> None:
        view = self.view
        number = await checked_value(self.index, view.name, "read customer data", parameter="Customer data")
        if number is not None:
            ok, _ = await view.act("read customer data", {"index": int(number)})
            if ok:
                self.record.set_text(view.lang.gettext("record {n}: {text}").format(
                    n=int(number), text=view.text(f"Customer data {int(number)}")))

    async def write_record(self) -> None:
        view = self.view
        number = await checked_value(self.index, view.name, "write customer data", parameter="Customer data")
        reason = _bytes_check(self.data.value)
        if reason is not None:
            self.data.validate()
            await refuse(view.name, "write customer data", f"{self.data.value!r}: {reason}", parameter="Customer data",
                         new=self.data.value)
        if number is None or reason is not None:
            return
        ok, _ = await view.act("write customer data", {"index": int(number), "payload": self.data.value or ""},
                               success=view.lang.gettext("written and verified"))
        if ok:
            self.record.set_text(view.lang.gettext("record {n}: {text} (verified)").format(
                n=int(number), text=view.text(f"Customer data {int(number)}")))

    def draw(self) -> None:
        view = self.view
        _ = view.lang.gettext
        identity = view.live(facts.P_IDENTITY)
        self.identity.set_text(_("not read") if identity is None else said(identity.shown, view.lang) if identity.shown else "")
        for label, param in zip(self.records, RECORD_PARAMS):
            raw = view.state.raw(param)
            label.set_text(f"{param.address:>2}: {_('not read') if raw is None else param.display(raw)}")
        loads = [(i, view.live(f"SSR{i} load data")) for i in range(1, 7)]
        self.loads.set_text(" · ".join(f"SSR{i}: {v.shown}" for i, v in loads if v is not None and v.value is not None))


def content(name: str) -> None:
    view = M3ioView(name)
    _ = view.lang.gettext

    def all_off() -> None:
        stop_bar(_("Switches every output off at once; anyone may, also without writing rights."), _("All off"), "power_off",
                 lambda: view.act("all off"), "off-bar", "all-off")

    with device_page(view, _("CAN-M3IO {name} ({variant})").format(name=name, variant=view.variant.value), stop=all_off):
        view.guard = WriteGuard(view.state, lang=view.lang)  # switches and commands, disabled with the reason while the module does not answer
        view.add(ModuleCard(view))
        # side by side from 1024 px; one above the other on a tablet, where the chart would get a third of the width
        with ui.row().classes("w-full items-start gap-4"):
            view.add(OutputsCard(view))
            if view.variant is not Variant.KM:
                view.add(TemperatureCard(view))
        sim_card(name)  # the twin's declared controls, in simulation only
        if view.addressing.addressed:
            view.add(AddressedCard(view))


def _bytes_check(text, lang=None) -> str | None:
    """Customer data: up to 6 bytes as hex (section 7.2.4.2: 6 data bytes per record); the reason in ``lang``
    (English by default: the audit row's)."""
    _ = (lang or i18n.get("en")).gettext
    try:
        payload = bytes.fromhex(text or "")
    except ValueError:
        return _("bytes as hex, e.g. 01 02 0A")
    return None if len(payload) <= 6 else _("at most 6 bytes ({n} entered)").format(n=len(payload))


__all__ = ["content", "temp_text"]
