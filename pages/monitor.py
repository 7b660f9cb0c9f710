"""Bus monitor. Modbus/serial lines: the transaction log of the worker (bounded ring buffer)."""

from __future__ import annotations

from datetime import datetime

from nicegui import ui

from app import runtime as rt
from pages.frame import frame

COLUMNS = [
    {"name": "time", "label": "Time", "field": "time", "align": "left"},
    {"name": "unit", "label": "Unit", "field": "unit", "align": "right"},
    {"name": "request", "label": "Request", "field": "request", "align": "left"},
    {"name": "tx", "label": "Request hex", "field": "tx", "align": "left", "classes": "mono"},
    {"name": "rx", "label": "Response hex", "field": "rx", "align": "left", "classes": "mono"},
    {"name": "decoded", "label": "Decoded", "field": "decoded", "align": "left"},
    {"name": "rtt", "label": "RTT ms", "field": "rtt", "align": "right"},
    {"name": "error", "label": "Error", "field": "error", "align": "left", "classes": "text-negative"},
]
SHOWN = 200


def content(bus: str) -> None:
    runtime = rt.current()
    bus_state = runtime.store.buses[bus]
    with frame(f"Bus monitor {bus}"):
        ui.label(f"{bus_state.type} · {bus_state.endpoint}").classes("text-caption text-grey-8")
        with ui.row().classes("items-center"):
            paused = ui.switch("Pause")
            errors_only = ui.switch("Errors only")
            summary = ui.label().classes("text-body2")
        table = ui.table(columns=COLUMNS, rows=[], row_key="id", pagination=0).classes("w-full reg-table")
        table.props("dense flat bordered")

        def update() -> None:
            log = list(bus_state.transactions)
            errors = sum(1 for t in log if t.error)
            summary.set_text(f"{len(log)} transactions buffered, {errors} with errors")
            if paused.value:
                return
            selected = [t for t in log if t.error] if errors_only.value else log
            table.rows = [
                {
                    "id": i,
                    "time": datetime.fromtimestamp(t.time).strftime("%H:%M:%S.%f")[:-3],
                    "unit": t.unit,
                    "request": t.request,
                    "tx": t.request_hex,
                    "rx": t.response_hex,
                    "decoded": t.decoded,
                    "rtt": "-" if t.rtt_ms is None else f"{t.rtt_ms:.1f}",
                    "error": t.error,
                }
                for i, t in enumerate(reversed(selected[-SHOWN:]))
            ]
            table.update()

        update()
        ui.timer(0.5, update)
