"""Discover locks on an RS485 line: broadcast read (one lock) and an address scan (several)."""

from __future__ import annotations

from nicegui import ui

from app import runtime as rt
from pages.session import current_user
from pages.widgets import range_number
from pages.command_client import all_valid


def open_discover_dialog(bus: str) -> None:
    runtime = rt.current()
    known = {d.options.get("address"): d.name for d in runtime.plant.devices_on(bus)}
    with ui.dialog() as dialog, ui.card().classes("w-[36rem]"):
        ui.label(f"Discover locks on {bus}").classes("text-h6")
        ui.label(
            "First a read at broadcast address 0 (answered when a single lock is on the line; left out where "
            "several devices are known on it, whose answers would collide, section 5.6), then a scan "
            "of the address range. Polling on this line pauses meanwhile. Each silent address costs one timeout."
        ).classes("text-caption text-grey-8")
        with ui.row():
            first = range_number("From", 1, 254, integer=True, value=1).classes("w-32")
            last = range_number("To", 1, 254, integer=True, value=16).classes("w-32")
        progress = ui.linear_progress(value=0, show_value=False).classes("w-full")
        status = ui.label().classes("text-body2")
        results = ui.column().classes("gap-1")
        with ui.row().classes("justify-end w-full"):
            ui.button("Close", on_click=dialog.close).props("flat")
            start = ui.button("Start", icon="search")

    def on_progress(done: int, total: int) -> None:
        progress.set_value(done / total)
        status.set_text(f"scanned {done} of {total} addresses")

    async def run() -> None:
        if not all_valid(first, last):
            return  # each field says what it allows; nothing is scanned
        a, b = int(first.value), int(last.value)
        if a > b:
            last.error = f"To must not be below From ({a})"
            return
        start.disable()
        results.clear()
        status.set_text("reading broadcast address 0 ..." if len(known) <= 1 else "scanning ...")
        user, role = current_user()
        try:
            # a scan holds the line's polling and talks to every address: an engineer action, audited
            found = await runtime.worker.engineer_action(
                lambda: runtime.worker.discover(bus, a, b, on_progress), user=user, role=role,
                describe=f"scan line {bus} addresses {a}..{b}", target=bus)
        except Exception as exc:  # noqa: BLE001 - the scan stops; the engineer is told why
            ui.notify(f"discover failed: {exc}", type="negative")
            found = []
        finally:
            start.enable()
        status.set_text(f"found {len(found)} lock{'s' if len(found) != 1 else ''}")
        with results:
            for entry in found:
                plant_name = known.get(entry["address"])
                serial = entry.get("serial")
                ui.label(
                    f"address {entry['address']}"
                    + (f" · serial {serial}" if serial is not None else "")
                    + f" · via {entry['via']}"
                    + (f" · in plant as {plant_name}" if plant_name else " · not in the plant file")
                ).classes("mono")

    start.on_click(run)
    dialog.open()
