"""What the two bus monitors (pages/monitor.py for lines, pages/can_monitor.py for CAN buses) share:
the length of a list, the page's CSS and the links to the engineer's bus tools."""

from __future__ import annotations

from nicegui import ui

from app.i18n import N_, Lang

from pages.session import can_write

SHOWN = 200  # rows of a frame/transaction list (one page while paused)
# the CAN controller's state (python-can's words, the CAN standard's error states) as the CAN monitor's badge and the
# overview's bus line show it
STATE_WORDS = {"error-active": N_("error-active"), "error-passive": N_("error-passive"), "bus-off": N_("bus-off"),
               "not connected": N_("not connected"), "unknown": N_("unknown")}


def controller_state(state: str, lang: Lang) -> str:
    """The CAN controller's state ``state`` in ``lang`` (one it has no word for as it is)."""
    word = STATE_WORDS.get(state)
    return lang.gettext(word) if word else state

CSS = """
.can-table .q-table td, .can-table .q-table th { padding: 1px 8px; height: 24px; font-size: 13px; }
.can-table .q-table td.mono, .can-table .q-table td .mono { white-space: pre; }
.byte { margin-right: 0.45em; }
.byte-changed { color: #e65100; font-weight: 700; background: #fff3e0; border-radius: 2px; }
.row-error td { background: #fde8ea; }
.can-table .q-table td.decoded { white-space: normal; min-width: 200px; overflow-wrap: anywhere; }
.reg-table .q-table { table-layout: fixed; width: 100%; }
.reg-table .q-table td, .reg-table .q-table th { padding: 2px 6px; font-size: 13px; }
.reg-table .q-table td.cut { white-space: nowrap; overflow: hidden; text-overflow: ellipsis; }
.reg-table .q-table td.wrap { white-space: normal; overflow-wrap: anywhere; }
.reg-table .q-table td.hex { white-space: normal; overflow-wrap: normal; word-break: normal; font-size: 12px; line-height: 1.35; }
.reg-table .q-table td.clamp > div { display: -webkit-box; -webkit-line-clamp: 2; -webkit-box-orient: vertical;
                                     overflow: hidden; white-space: normal; overflow-wrap: anywhere; line-height: 1.35; }
.reg-table .q-table tbody td { height: auto; padding-top: 2px; padding-bottom: 2px; vertical-align: top; }
.monitor-fill { max-height: calc(100vh - 300px); min-height: 240px; overflow-y: auto; }
@media (max-width: 1279px) { .reg-table .q-table td.cut { white-space: normal; overflow-wrap: anywhere; } }
.monitor-scroll thead tr th { position: sticky; top: 0; z-index: 1; background: white; }
.can-table .q-table td.nowrap, .can-table .q-table th.nowrap { white-space: nowrap; }
.can-table .q-table td.cycle { white-space: normal; min-width: 90px; max-width: 150px; }
.can-table tbody tr { cursor: pointer; }
/* a tablet: a frame's bytes wrap (four to a line) and the cycle column narrows, so Decoded stays in sight */
@media (max-width: 899px) {
  .can-table .q-table th { white-space: normal; }
  .can-table .q-table td.mono, .can-table .q-table td .mono { white-space: normal; }
  .can-table .q-table td.bytes { min-width: 8.5em; }
  .can-table .q-table td.bytes .byte { display: inline-block; }
  .can-table .q-table td.cycle { min-width: 70px; max-width: 100px; }
  .can-table .q-table td.decoded { min-width: 160px; }
}
"""


def tool_links(bus: str, tools: list[tuple[str, str, str]]) -> None:
    """The engineer's bus tools (pages of their own), linked for engineers only."""
    if not can_write():
        return
    with ui.row().classes("items-center gap-2").mark("bus-tools"):
        for label, tool, icon in tools:
            ui.button(label, icon=icon, on_click=lambda t=tool: ui.navigate.to(f"/monitor/{bus}/{t}")).props(
                f"flat dense no-caps data-monitor=tool-{tool}")


def bus_tool_opened(bus: str, lang: Lang, not_for_it: str = "") -> bool:
    """The head of a bus tool's page: the link back to the bus monitor, then ``not_for_it`` (why the tool is not for
    this bus) where there is a reason. Whether the tool goes on."""
    _ = lang.gettext
    ui.link(_("← bus monitor {bus}").format(bus=bus), f"/monitor/{bus}")
    if not_for_it:
        ui.label(not_for_it)
    return not not_for_it
