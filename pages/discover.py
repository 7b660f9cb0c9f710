"""Discover locks on an RS485 line: broadcast read (one lock) and an address scan (several)."""

from __future__ import annotations

import asyncio
import os
import time
from collections.abc import Callable

from nicegui import ui

from app import i18n
from app import runtime as rt
from app.i18n import english, N_, Lang
from app.message import said
from app.plant import DEMO_PLANT, DeviceConfig, append_device, can_id_conflict, device_toml
from app.worker import AuditUnavailable, PermissionDenied
from devices.registry import DEVICE_TYPES, format_can_ids
from pages.frame import ACTION_ERRORS, fmt_age
from pages.session import current_user
from pages.widgets import range_number
from pages.command_client import all_valid


# how a lock was found (devices/hdlock/adapter.py), as the dialog says it
VIA_WORDS = {"broadcast": N_("broadcast"), "scan": N_("scan"), "broadcast address change": N_("broadcast address change")}


def open_discover_dialog(bus: str) -> None:
    """The address scan of an RS485 line, in the language of the page whose button opened it."""
    runtime = rt.current()
    lang = i18n.client_language()
    _ = lang.gettext
    known = {d.options.get("address"): d.name for d in runtime.plant.devices_on(bus)}
    with ui.dialog() as dialog, ui.card().classes("w-[36rem]"):
        ui.label(_("Discover locks on {bus}").format(bus=bus)).classes("text-h6")
        ui.label(_(
            "First a read at broadcast address 0 (answered when a single lock is on the line; left out where "
            "several devices are known on it, whose answers would collide, section 5.6), then a scan "
            "of the address range. Polling on this line pauses meanwhile. Each silent address costs one timeout."
        )).classes("text-caption text-grey-8")
        with ui.row():
            first = range_number(_("From"), 1, 254, integer=True, value=1, lang=lang).classes("w-32")
            last = range_number(_("To"), 1, 254, integer=True, value=16, lang=lang).classes("w-32")
        progress = ui.linear_progress(value=0, show_value=False).classes("w-full")
        status = ui.label().classes("text-body2")
        results = ui.column().classes("gap-1")
        with ui.row().classes("justify-end w-full"):
            ui.button(_("Close"), on_click=dialog.close).props("flat")
            start = ui.button(_("Start"), icon="search")

    def on_progress(done: int, total: int) -> None:
        progress.set_value(done / total)
        status.set_text(_("scanned {done} of {total} addresses").format(done=done, total=total))

    async def run() -> None:
        if not all_valid(first, last, lang=lang):
            return  # each field says what it allows; nothing is scanned
        a, b = int(first.value), int(last.value)
        if a > b:
            last.error = _("To must not be below From ({first})").format(first=a)
            return
        start.disable()
        results.clear()
        status.set_text(_("reading broadcast address 0 ...") if len(known) <= 1 else _("scanning ..."))
        user, role = current_user()
        try:
            # a scan holds the line's polling and talks to every address: an engineer action, audited
            found = await runtime.worker.gate.run(
                lambda: runtime.worker.discover(bus, a, b, on_progress), user=user, role=role,
                describe=f"scan line {bus} addresses {a}..{b}", device=bus, kind="write")
        except ACTION_ERRORS as exc:  # the scan stops; the engineer is told why
            ui.notify(_("discover failed: {error}").format(error=said(exc, lang)), type="negative")
            found = []
        finally:
            start.enable()
        status.set_text(lang.ngettext("found {n} lock", "found {n} locks", len(found)).format(n=len(found)))
        with results:
            for entry in found:
                plant_name = known.get(entry["address"])
                serial = entry.get("serial")
                via = VIA_WORDS.get(entry["via"])
                parts = [_("address {address}").format(address=entry["address"]) if serial is None else
                         _("address {address} · serial {serial}").format(address=entry["address"], serial=serial)]
                parts.append(_("via {how}").format(how=_(via) if via else entry["via"]))
                parts.append(_("in plant as {name}").format(name=plant_name) if plant_name else _("not in the plant file"))
                ui.label(" · ".join(parts)).classes("mono")

    start.on_click(run)
    dialog.open()



def discovered_section(bus: str, tile_row, add_tile: Callable[[str], None], lang: Lang | None = None) -> Callable[[], None]:
    """Devices heard on a CAN bus that the plant does not list yet, with Adopt.

    Only devices that showed the evidence their type needs are listed; unknown IDs still
    being watched, and what was left out, are counted below the list.
    """
    runtime = rt.current()
    lang = english(lang)
    _ = lang.gettext
    section = tile_row.parent_slot.parent
    boxes: list = []  # the list's column, built when there is something to list (most buses never have)
    shown: list = [None]

    ages: dict = {}  # key -> the label with evidence and age, updated in place (the Adopt button stays put)

    def age_text(entry: dict) -> str:
        return f"{said(entry.get('evidence') or '', lang)} · " + _("{n} frames, last {age}").format(
            n=entry["frames"], age=fmt_age(time.time() - entry["last_seen"], lang))

    def refresh() -> None:
        entries = list(runtime.worker.discovered.get(bus, {}).items())
        summary = runtime.worker.discovery_summary(bus)
        watching = summary.get("candidates", 0)
        left_out = summary.get("dropped", 0) + summary.get("listed_dropped", 0)
        flood = summary.get("flood", "")
        signature = ([k for k, _e in entries], watching, left_out, bool(flood))
        if signature == shown[0]:
            for key, entry in entries:  # only the texts change: rows and buttons are not rebuilt under the mouse
                if key in ages:
                    ages[key].set_text(age_text(entry))
            return
        shown[0] = signature
        ages.clear()
        if not boxes:
            if not entries and not watching and not left_out and not flood:
                return
            with section:
                boxes.append(ui.column().classes("gap-1").props(f'data-discovered="{bus}"'))
        box = boxes[0]
        box.clear()
        if not entries and not watching and not left_out and not flood:
            return
        with box:
            if entries:
                ui.label(_("Discovered on {bus}, not in the plant file").format(bus=bus)).classes("text-subtitle2")
            for key, entry in entries:
                with ui.row().classes("items-center gap-3"):
                    ui.icon("fiber_new", color="orange")
                    ident = f"{entry['device_id']} ({'ext' if entry['extended'] else 'std'} 0x{entry['device_id']:X})"
                    title = lang.phrase(DEVICE_TYPES[entry["type"]].title)
                    ui.label(_("{type} with device ID {ident}").format(type=title, ident=ident)).classes("text-body2")
                    ages[key] = ui.label(age_text(entry)).classes("text-caption text-grey-8")
                    ui.button(_("Adopt"), icon="add", on_click=lambda e=entry: adopt_dialog(bus, e, tile_row, add_tile, lang)).props("dense outline").props(
                        f'data-adopt="{entry["device_id"]}"'
                    )
            if flood:  # a flood is shown as a flood, never as devices
                ui.label(_("Discovery on {bus}: {flood}").format(bus=bus, flood=said(flood, lang))).classes("text-body2 text-negative").props("data-discovery-flood")
            notes = []
            if watching:
                rules = "; ".join(said(rule, lang) for rule in summary.get("rules") or [])
                notes.append(lang.ngettext("watching {n} unknown ID", "watching {n} unknown IDs", watching).format(n=watching)
                             + (" " + _("(listed after {rules})").format(rules=rules) if rules else ""))
            if left_out:
                notes.append(_("{n} left out: too many unknown IDs at once").format(n=left_out))
            if notes:
                ui.label(_("Discovery on {bus}: {flood}").format(bus=bus, flood="; ".join(notes))).classes("text-caption text-grey-8").props("data-discovery-note")

    refresh()
    return refresh


def adopt_dialog(bus: str, entry: dict, tile_row, add_tile: Callable[[str], None], lang: Lang | None = None) -> None:
    runtime = rt.current()
    lang = english(lang)
    _ = lang.gettext
    suggested = f"{entry['type']}-{entry['device_id']}"
    path = runtime.plant.path
    bus_config = runtime.plant.buses[bus]
    device_type = DEVICE_TYPES[entry["type"]]

    def config(name: str) -> DeviceConfig:
        return DeviceConfig(name, entry["type"], bus, {"device_id": entry["device_id"], "extended": entry["extended"]})

    # the same check as the plant loader and the worker: one CAN ID, one sender (HD-Lock document 6.2 b)
    conflict = can_id_conflict(runtime.plant.devices_on(bus) + [config(suggested)], bus_config)

    with ui.dialog() as dialog, ui.card().classes("w-[34rem] max-w-full"):
        ui.label(_("Adopt a discovered device")).classes("text-h6")
        name = ui.input(_("Name in the plant"), value=suggested).props("outlined dense")
        own = [u for u in device_type.can_id_uses(config(suggested).options, "can") if not u.shared]
        if own:
            ui.label(_("CAN IDs it uses: {ids}").format(ids="; ".join(f"{format_can_ids(u.first, u.last, u.extended)} {u.use}" for u in own))).classes(
                "text-caption")
        ui.label(_("Lines for the plant file:")).classes("text-caption text-grey-8")
        lines = ui.code(device_toml(config(suggested)), language="toml").classes("w-full")
        name.on_value_change(lambda e: lines.set_content(device_toml(config(e.value or suggested))))
        writable = path is not None and path.exists() and os.access(path, os.W_OK) and path.resolve() != DEMO_PLANT.resolve()
        note = _("Write appends them to {path}.").format(path=path) if writable else \
            _("The plant file cannot be written here (built-in or read-only): copy the lines.")
        ui.label(note).classes("text-caption")
        if conflict is not None:
            ui.label(_("Cannot be adopted: {reason}").format(reason=conflict[1].split(": ", 1)[-1])).classes("text-body2 text-negative").props("data-adopt-conflict")

        async def take(write: bool) -> None:
            dev = config(name.value or suggested)
            user, role = current_user()

            async def adopt() -> None:
                if write:
                    await asyncio.to_thread(append_device, path, dev)
                runtime.worker.adopt(dev)

            try:
                # it changes the running plant (and the plant file): an engineer action, audited
                await runtime.worker.gate.run(
                    adopt, user=user, role=role, device=dev.name, new=device_toml(dev).strip(),
                    describe="adopt discovered device" + (f" and append it to {path.name}" if write else ""), kind="write")
            except (ValueError, OSError, PermissionDenied, AuditUnavailable) as exc:
                ui.notify(_("Cannot adopt: {error}").format(error=said(exc, lang)), type="negative", multi_line=True)
                return
            with tile_row:
                add_tile(dev.name)
            ui.notify(_("{name} added to the running plant and to {file}").format(name=dev.name, file=path.name) if write else
                      _("{name} added to the running plant").format(name=dev.name), type="positive")
            dialog.close()

        with ui.row().classes("justify-end w-full"):
            ui.button(_("Cancel"), on_click=dialog.close).props("flat")
            add_button = ui.button(_("Add to the running plant"), on_click=lambda: take(False)).props("outline")
            write_button = ui.button(_("Add and write to the plant file"), on_click=lambda: take(True))
            if not writable or conflict is not None:
                write_button.disable()
            if conflict is not None:
                add_button.disable()
    dialog.open()
