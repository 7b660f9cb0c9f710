"""Shared page frame: header with plant name, navigation and bus connection state."""

from __future__ import annotations

import sqlite3
from html import escape

import time
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path

from nicegui import ui

from app import i18n
from app import runtime as rt
from app.i18n import N_, Lang
from app.message import said
from devices.errors import CommissionError
from pages.session import current_user

CSS = (Path(__file__).resolve().parent.parent / "static" / "commission.css").read_text()
LOOP_ORANGE_MS, LOOP_RED_MS = 100, 250  # loop lag p99 worth a look; one that endangers a 250 ms keep-alive
NAV_PAGES = ((N_("Overview"), "/"), (N_("Plant view"), "/plant"), (N_("Fleet"), "/fleet"), (N_("Backup"), "/backup"),
             (N_("Audit"), "/audit"), (N_("Record"), "/record"))
STATUS_ICON = {"online": "check_circle", "stale": "schedule", "offline": "error", "unknown": "help"}


def fmt_age(seconds: float | None, lang: Lang | None = None) -> str:
    if lang is not None:
        return lang.age(seconds)
    if seconds is None:
        return "never"
    if seconds < 1:
        return "just now"
    if seconds < 120:
        return f"{seconds:.0f} s ago"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min ago"
    return f"{seconds / 3600:.1f} h ago"


def fmt_time(t: float | None, lang: Lang | None = None) -> str:
    if lang is not None:
        return "-" if t is None else lang.clock(t)
    return "-" if t is None else datetime.fromtimestamp(t).strftime("%H:%M:%S")


def _logout() -> None:
    from app.browser import session_token

    rt.current().sessions.logout(session_token(ui.context.client.request))  # every tab of it loses its rights now
    ui.navigate.to("/logout")  # and the browser gets a new session cookie


# The dead-man beat (app/worker/deadman.py). A Web Worker ticks every BEAT_PERIOD_S (timers of hidden tabs
# are throttled to 1 Hz, a worker's are not); the page sends a tick to the server, with the tick's own time
# (the browser's clock, so the server tells a beat that waited because the server was busy from a browser
# that was silent), only while it is needed:
# - while the server asks (``ask(true)``: its session holds motion, mains outputs, a transmit list, or its
#   connection came back) until it says stop (``ask(false)``, app.browser.BEAT_ASK_JS);
# - for BEAT_WINDOW_S after any user interaction (pointer, key, touch; capture phase, so before the page's
#   own handlers): the command that takes control or starts motion reaches the server after a beat.
# It sends one beat at once when it starts beating. A page that holds nothing sends nothing; a frozen, asleep
# or cut-off browser stops sending, and the worker stops what its session holds.
BEAT_JS = """
<script>
(function () {
  if (window.commissionBeat) return;
  const tick = new Worker(URL.createObjectURL(new Blob(
    ["setInterval(function () { postMessage(performance.timeOrigin + performance.now()); }, %d);"],
    {type: "text/javascript"})));
  const windowMs = %d;
  let until = -1, asked = false, beating = false;
  const send = function (t) {
    if (window.socket && window.did_handshake && window.socket.connected) {
      window.socket.emit("%s", {client_id: window.clientId, t: t});
    }
  };
  const start = function () {
    if (!beating) { beating = true; send(performance.timeOrigin + performance.now()); }
  };
  tick.onmessage = function (e) {
    beating = asked || performance.now() < until;
    if (beating) send(e.data);
  };
  const touched = function () { until = performance.now() + windowMs; start(); };
  for (const name of ["pointerdown", "keydown", "touchstart"]) {
    window.addEventListener(name, touched, {capture: true, passive: true});
  }
  tick.ask = function (on) { asked = !!on; if (asked) start(); };
  window.commissionBeat = tick;
})();
</script>
"""


# bus names give way to their icons (state and tooltip stay) when the bus list does not fit the header
# A language whose decimal sign is a comma (German): a comma typed or pasted into a number entry is its decimal
# point. The browser's own number entry drops a comma it does not expect, so "12,5" arrived as 125.
DECIMAL_COMMA_JS = """<script>
(() => {
  const number = (t) => t instanceof HTMLInputElement && t.type === 'number';
  document.addEventListener('keydown', (e) => {
    if (e.key === ',' && number(e.target) && !e.ctrlKey && !e.metaKey && !e.altKey) {
      e.preventDefault();
      document.execCommand('insertText', false, '.');
    }
  }, true);
  document.addEventListener('paste', (e) => {
    const text = e.clipboardData ? e.clipboardData.getData('text') : '';
    if (number(e.target) && /^\\s*-?\\d*,\\d+\\s*$/.test(text)) {
      e.preventDefault();
      document.execCommand('insertText', false, text.trim().replace(',', '.'));
    }
  }, true);
})();
</script>"""


HEADER_FIT_JS = """
<script>
(function () {
  if (window.commissionHeaderFit) return;
  const fit = function () {
    const buses = document.querySelector('.hdr-buses');
    if (!buses) return;
    buses.classList.remove('hdr-icons');
    if (buses.scrollWidth > buses.clientWidth + 1) buses.classList.add('hdr-icons');
  };
  window.addEventListener('resize', fit);
  window.commissionHeaderFit = setInterval(fit, 1000);
  setTimeout(fit, 50);
})();
</script>
"""


#: what a page's action says to the engineer (and goes on) instead of failing: the project's refusals (devices/errors.py:
#: a device or command refusing, a bad file or entry, a role, the audit log), and a file, folder or database that
#: cannot be read or written. Anything else is a bug: it ends the action and is logged with its traceback.
ACTION_ERRORS = (CommissionError, OSError, sqlite3.Error)


def notify_error(message: str) -> None:
    ui.notify(message, type="negative", multi_line=True, close_button="OK", timeout=0)


def _header(runtime, lang: Lang) -> tuple[ui.row, ui.row, ui.menu, str | None, str | None]:
    """The header bar; returns its empty health and bus rows and its page menu (filled by :class:`HeaderStatus`),
    user and role."""
    _ = lang.gettext
    # one line down to 1024 px: below 1360 px the page links fold into a menu and the bus names get smaller
    # (static/commission.css, .hdr-*); the bus list gives way first, never the pages or the account
    with ui.header().classes("items-center no-wrap bg-blue-grey-9 q-py-xs hdr").props("data-testid=header"):
        ui.link("commission", "/").classes("text-h6 text-white no-underline hdr-keep")
        ui.label(_("plant: {plant}").format(plant=runtime.plant.name)).classes("text-caption text-grey-4 hdr-plant")
        if runtime.sim is not None and runtime.sim.servers:  # only when some bus of the plant is simulated
            ui.badge(_("simulated devices"), color="purple-3").classes("text-black hdr-keep").tooltip(
                _("Some buses of this plant are simulated by this program"))
        ui.space()
        with ui.row().classes("items-center gap-2 no-wrap hdr-keep") as health:
            pass
        with ui.row().classes("items-center gap-2 no-wrap hdr-buses").props("data-testid=header-buses") as buses:
            pass
        with ui.row().classes("items-center gap-4 no-wrap hdr-wide").props("data-testid=nav"):
            for label, href in NAV_PAGES:
                ui.link(_(label), href).classes("text-white")
        pages = _("Pages")
        with ui.button(icon="menu").props(f'flat dense color=white aria-label="{pages}" data-testid=nav-menu') \
                .classes("hdr-narrow"):
            with ui.menu().props("data-testid=nav-menu-list") as menu:
                for label, href in NAV_PAGES:
                    ui.menu_item(_(label)).props(f'href="{href}" tag=a')
        with ui.row().classes("items-center gap-2 no-wrap hdr-keep").props("data-testid=account"):
            user, role = current_user()
            if runtime.auth_required:
                ui.label(f"{user} ({_(role) if role else role})").classes("text-caption text-grey-4")
                ui.button(_("Log out"), on_click=_logout).props("flat dense color=white")
            elif role:
                ui.label(_("local engineer")).classes("text-caption text-grey-4").tooltip(
                    _("Served on the loopback address only: no login, full rights")
                )
            i18n.language_switch(lang)
    return health, buses, menu, user, role


ROLE_WORDS = (N_("engineer"), N_("viewer"))  # the roles as the header names them


def bus_item_html(name: str, connected: bool, lang: Lang | None = None) -> str:
    """A bus in the page menu: its state's icon, its name and its state in words (a tablet has no hover)."""
    _ = (lang or i18n.get("en")).gettext
    icon = ('<i class="q-icon notranslate material-icons %s" aria-hidden="true" role="presentation" style="font-size: 20px">'
            '%s</i>') % (("text-green", "lan") if connected else ("text-red", "link_off"))
    return (f'<div class="row items-center no-wrap q-gutter-x-sm">{icon}'
            f'<span class="text-weight-medium text-no-wrap">{escape(name)}</span>'
            f'<span class="text-caption text-grey-8" data-bus-words>{_("connected") if connected else _("not connected")}</span></div>')


class HeaderStatus:
    """The header's live part: the audit log's state, the broker, the event-loop lag and the buses."""

    def __init__(self, runtime: rt.Runtime, user: str | None, lang: Lang | None = None):
        self.runtime = runtime
        self.user = user
        self.lang = lang or i18n.get("en")
        self.broker_badge = self.broker_tip = None
        self.bus_chips: dict = {}
        self.bus_items: dict = {}  # bus -> its line in the page menu (name and state in words)
        self.bus_shown: dict = {}  # bus -> (connected, words) last shown

    def build(self, health: ui.row, buses: ui.row, menu: ui.menu | None = None) -> None:
        runtime = self.runtime
        with health:
            self.problem_box = ui.row().classes("items-center gap-1 no-wrap bg-negative q-px-sm rounded-borders") \
                .props("data-testid=audit-state")
            with self.problem_box:
                ui.icon("report", color="white")
                ui.label(self.lang.gettext("audit log not writable: writes refused")).classes("text-white text-caption")
                self.problem_tip = ui.tooltip("")
            self.problem_box.set_visibility(False)
            if runtime.mqtt is not None:  # only with an [mqtt] table: the broker's state
                with ui.badge(self.lang.gettext("broker"), color="orange-4").classes("text-black").props(
                        "data-testid=broker-state") as self.broker_badge:
                    self.broker_tip = ui.tooltip("")
            with ui.label().classes("text-caption text-grey-5 hdr-loop").props("data-testid=loop-lag") as self.loop_chip:
                self.loop_tip = ui.tooltip("")
        with buses:
            for bus in runtime.store.buses.values():
                # the bus's state in words is the link's title (the browser's own tooltip: no element of its own)
                with ui.link("", f"/monitor/{bus.name}").classes("text-white no-underline hdr-bus row items-center no-wrap") \
                        .props(f'aria-label="{bus.name}" data-bus="{bus.name}"') as link:
                    ui.label(bus.name).classes("hdr-bus-name")  # left out on a narrow screen: the icon and its title stay
                    self.bus_chips[bus.name] = (ui.icon("link_off", color="red").classes("q-ml-xs"), link)
        if menu is not None and runtime.store.buses:
            # a tablet has no hover for the icons' tooltips and no room for the names: the page menu names every
            # bus with its state in words, each a link to its monitor
            with menu:
                ui.separator()
                for bus in runtime.store.buses.values():
                    with ui.menu_item().props(f'href="/monitor/{bus.name}" tag=a data-bus-item="{bus.name}"'):
                        # icon, name and state in one element (redrawn when the state changes)
                        self.bus_items[bus.name] = ui.html(bus_item_html(bus.name, False, self.lang), sanitize=False)

    def refresh(self) -> None:
        runtime = self.runtime
        lang = self.lang
        _ = lang.gettext
        if runtime.auth_required and self.user and current_user()[0] != self.user:
            ui.navigate.to("/login")  # logged out elsewhere, or the account was removed
            return
        problem = runtime.audit.problem
        self.problem_box.set_visibility(bool(problem))
        if problem:
            self.problem_tip.set_text(_("{problem}. Free or repair the database; writes resume by themselves.").format(problem=problem))
        if self.broker_badge is not None:  # publishing never holds up the buses
            self._refresh_broker()
        loop = runtime.worker.loop_health.summary()
        # coloured by the p99 itself: on a busy machine some stall falls into every minute, and a colour that
        # is always on says nothing (the stalls are in the tooltip)
        p99 = loop["p99_ms"]
        self.loop_chip.set_text(_("loop {ms} ms").format(ms=lang.number(round(p99))))  # sent only when the text changed, as every text below
        colour = "text-red-4" if p99 >= LOOP_RED_MS else "text-orange-4" if p99 >= LOOP_ORANGE_MS else "text-grey-5"
        if colour not in self.loop_chip.classes:  # classes() sends the element each time it is called
            self.loop_chip.classes(replace="text-caption hdr-loop " + colour)
        self.loop_tip.set_text(_("Event-loop lag (it carries every keep-alive): p99 {p99} ms over the last minute, worst "
                                 "{worst} ms, {stalls} stalls over 100 ms since start").format(
            p99=lang.number(loop["p99_ms"]), worst=lang.number(loop["worst_ms"]), stalls=lang.number(loop["stalls"])))
        for bus in runtime.store.buses.values():
            icon, link = self.bus_chips[bus.name]
            words = _("connected") if bus.connected else said(bus.last_error, lang) or _("not connected")
            if self.bus_shown.get(bus.name) == (bus.connected, words):
                continue  # unchanged: nothing goes to the browser
            self.bus_shown[bus.name] = (bus.connected, words)
            icon.set_name("lan" if bus.connected else "link_off")
            icon.set_text_color("green" if bus.connected else "red")
            title = f"{bus.name}: {bus.type} {bus.endpoint}: {words}".replace(chr(34), chr(39))
            link.props(f'aria-label="{bus.name}: {words.replace(chr(34), chr(39))}" title="{title}"')
            item = self.bus_items.get(bus.name)
            if item is not None:
                item.set_content(bus_item_html(bus.name, bus.connected, lang))

    def _refresh_broker(self) -> None:
        broker = self.runtime.mqtt.summary()
        lang = self.lang
        _ = lang.gettext
        state = lang.phrase(broker["state"], "broker")
        self.broker_badge.set_text(_("broker {state}").format(state=state))
        self.broker_badge.set_background_color("green-3" if broker["connected"] else "orange-4")
        self.broker_tip.set_text(f"MQTT {broker['url']}: {state}"
                                 + (f" ({broker['last_error']})" if broker["last_error"] and not broker["connected"] else "")
                                 + "; " + _("{sent} sent, {queued} waiting, {dropped} alarm events dropped").format(
                                     sent=lang.number(broker["sent"]), queued=lang.number(broker["queued"]),
                                     dropped=lang.number(broker["dropped"])))


@contextmanager
def frame(title: str, beat: bool = True):
    """Header, navigation and a content column; yields inside the column. ``beat``: the page can confirm it is
    alive ten times a second (the dead-man rule), which it does while its session holds something and just
    after a user interaction (BEAT_JS); a page that can start or hold nothing (no motion, no outputs, no
    control) leaves the beat out altogether."""
    runtime = rt.current()
    lang = i18n.page_language()
    _ = lang.gettext
    title = _(title)  # a page whose title the catalog has is named in the browser's language
    ui.add_css(CSS)
    ui.page_title(f"{title} - commission")
    health, buses, menu, user, role = _header(runtime, lang)
    client = ui.context.client
    runtime.worker.session_opened(client.id, role or "none")
    from app.browser import BEAT_EVENT
    from app.worker import BEAT_PERIOD_S, BEAT_WINDOW_S

    if beat:
        ui.add_body_html(BEAT_JS % (round(BEAT_PERIOD_S * 1000), round(BEAT_WINDOW_S * 1000), BEAT_EVENT))
    ui.add_body_html(HEADER_FIT_JS)
    if lang.decimal_sign == ",":
        ui.add_body_html(DECIMAL_COMMA_JS)

    # the header runs on every page: built once, then only changed texts and colours go to the browser
    status = HeaderStatus(runtime, user, lang)
    status.build(health, buses, menu)
    status.refresh()
    ui.timer(2.0, status.refresh)
    with ui.column().classes("w-full q-pa-md gap-4"):
        ui.label(title).classes("text-h5")
        if role == "viewer":
            with ui.row().classes("w-full bg-amber-1 q-pa-sm items-center"):
                ui.icon("visibility")
                ui.label(_("Read-only session (viewer): writes, commands and restores are refused. "
                           "Log in as an engineer to change anything."))
        yield


STATUS_COLOR = {"online": "positive", "stale": "warning", "offline": "negative", "unknown": "grey"}


def status_text(status: str, age: float | None, lang: Lang | None = None) -> str:
    if lang is not None:
        _ = lang.gettext
        return {"online": _("online"), "stale": _("stale ({age})").format(age=lang.age(age)), "offline": _("offline"),
                "unknown": _("waiting")}[status]
    return {"online": "online", "stale": f"stale ({fmt_age(age)})", "offline": "offline", "unknown": "waiting"}[status]


def set_status_badge(badge: ui.badge, status: str, age: float | None, lang: Lang | None = None) -> None:
    badge.set_text(status_text(status, age, lang))
    if badge.props.get("color") != STATUS_COLOR[status]:  # runs on every push: no props parsing when unchanged
        badge.props(f"color={STATUS_COLOR[status]}")


def now() -> float:
    return time.time()
