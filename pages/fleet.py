"""Batch apply (/fleet): one parameter set to several devices of one type, each with its own identity
check and dry-run diff first, then device by device with progress, stopping at the first failure."""

from __future__ import annotations

import asyncio

from nicegui import ui

from app import backup, batch, project
from app import runtime as rt
from pages.frame import frame, notify_error
from pages.session import can_write, current_user
from pages.widgets import confirm

STATUS_CLASS = {batch.WRITTEN: "text-positive", batch.UNCHANGED: "text-grey-8", batch.FAILED: "text-negative",
                batch.SKIPPED: "text-warning", batch.REFUSED: "text-negative"}


def _backup_files(directory, device_type: str) -> dict[str, str]:
    found = {}
    if not directory.is_dir():
        return found
    for path in sorted(directory.glob("*.json"), key=lambda p: p.stat().st_mtime, reverse=True):
        try:
            doc = backup.load_document(path.read_bytes(), path.name)
        except backup.BackupError:
            continue
        if doc["device"].get("type") == device_type:
            found[str(path)] = f"backup {path.name}"
    return found


def content() -> None:
    runtime = rt.current()
    by_type: dict[str, list[str]] = {}
    for name, state in runtime.store.devices.items():
        if backup.device_backs_up(runtime, name):
            by_type.setdefault(state.type, []).append(name)
    with frame("Apply to several devices"):
        ui.label("One set to several devices of one type and variant: each device is checked (type, variant, "
                 "identity) and compared first; nothing is written before you press Apply. Applying runs device by "
                 "device through the same checked, verified write as a restore, and stops at the first failure.") \
            .classes("text-body2 text-grey-9")
        if not by_type:
            ui.label("No device of this plant keeps parameters.")
            return
        with ui.card().classes("w-full"):
            with ui.row().classes("items-center gap-4"):
                kind = ui.select(list(by_type), value=next(iter(by_type)), label="Device type").props(
                    "dense outlined data-testid=fleet-type").classes("w-40")
                source = ui.select({}, label="Source").props("dense outlined data-testid=fleet-source").classes("w-96")
            boxes_row = ui.row().classes("gap-4").props("data-testid=fleet-devices")
            with ui.row().classes("items-center"):
                compare = ui.button("Check and compare", icon="compare_arrows").props("data-testid=fleet-compare")
                apply = ui.button("Apply device by device", icon="upload", color="negative").props("data-testid=fleet-apply")
                apply.set_visibility(False)
            progress = ui.linear_progress(value=0, show_value=False).classes("w-full")
            summary = ui.label().classes("text-body1").props("data-testid=fleet-summary")
        results = ui.column().classes("w-full gap-2")
    boxes: dict[str, ui.checkbox] = {}
    state: dict = {"plan": None, "labels": {}}

    async def fill() -> None:
        devices = by_type.get(kind.value, [])
        boxes_row.clear()
        boxes.clear()
        with boxes_row:
            for name in devices:
                variant = runtime.plant.devices[name].options.get("variant")
                boxes[name] = ui.checkbox(f"{name}" + (f" ({variant})" if variant else ""), value=True).props(
                    f'data-fleet-device="{name}"')
        options = {}
        for name in devices:
            if name in runtime.record.approved:
                options[f"approved:{name}"] = f"approved set of {name}"
        if any(project.has_project(runtime.plant, n) for n in devices):
            options["project"] = "each device's project (plant file)"
        options.update(await asyncio.to_thread(_backup_files, runtime.backups_dir, kind.value))
        for name in devices:
            options[f"device:{name}"] = f"{name} as it is now (sibling)"
        source.set_options(options, value=next(iter(options), None))
        apply.set_visibility(False)
        results.clear()
        summary.set_text("")

    kind.on_value_change(fill)
    ui.timer(0, fill, once=True)

    async def run_compare() -> None:
        chosen = [n for n, box in boxes.items() if box.value]
        if not chosen or not source.value:
            ui.notify("Choose devices and a source", type="warning")
            return
        compare.disable()
        progress.set_value(0)
        try:
            plan = await batch.plan_batch(runtime, chosen, source.value, progress.set_value)
        except Exception as exc:  # noqa: BLE001 - an unreadable source
            notify_error(f"Cannot compare: {exc}")
            return
        finally:
            compare.enable()
        state["plan"] = plan
        results.clear()
        state["labels"] = {}
        with results:
            for error in plan.errors:
                ui.label(f"✖ {error}").classes("text-negative text-body1")
            for entry in plan.devices:
                with ui.card().classes("w-full q-pa-sm").props(f'data-fleet-result="{entry.device}"'):
                    with ui.row().classes("items-center gap-3"):
                        ui.label(entry.device).classes("text-subtitle1 text-weight-bold")
                        state["labels"][entry.device] = ui.label(
                            "refused: " + entry.error if entry.error else f"{len(entry.changed)} to write (dry run)") \
                            .classes("text-body1 " + ("text-negative" if entry.error else "")).props("data-fleet-status")
                    if entry.check is not None:
                        for note in entry.check.notes:
                            ui.label(f"⚠ {note}").classes("text-caption text-warning")
                    if entry.plan is not None:
                        for warning in entry.plan.warnings:
                            if "serial number" not in warning:
                                ui.label(f"⚠ {warning}").classes("text-caption text-warning")
                        for row in entry.changed:
                            risk = f"  (needs confirmation: {row.risk})" if row.risk else ""
                            ui.label(f"{row.name}: {row.current_text} → {row.backup_text}{risk}").classes(
                                "text-body2 mono" + (" text-negative" if row.risk else ""))
        ready = plan.ready and any(e.changed for e in plan.devices)
        summary.set_text(("ready: " if plan.ready else "cannot apply: ")
                         + ", ".join(f"{e.device} {'refused' if e.error else f'{len(e.changed)} to write'}" for e in plan.devices))
        summary.classes(replace="text-body1 " + ("" if plan.ready else "text-negative"))
        apply.set_visibility(ready)
        apply.set_enabled(can_write())

    async def run_apply() -> None:
        plan: batch.BatchPlan | None = state["plan"]
        if plan is None or not plan.ready:
            return
        writing = [e for e in plan.devices if e.changed]
        if not await confirm(f"Apply to {len(writing)} device(s), one by one?",
                             "Each device: its differing parameters written, read back and saved; the batch stops at the "
                             "first device that fails. " + "; ".join(f"{e.device}: {len(e.changed)}" for e in writing),
                             ok="Apply"):
            return
        confirmed: set[str] = set()
        for entry in writing:
            for row in entry.plan.risky({r.key for r in entry.changed}):
                if row.name in confirmed:
                    continue
                if not await confirm(f"Write {row.name} = {row.backup_text}?", row.risk, ok="Write anyway"):
                    ui.notify(f"{row.name} not confirmed: nothing written", type="warning")
                    return
                confirmed.add(row.name)
        user, role = current_user()
        apply.disable()
        compare.disable()

        def said(result: batch.DeviceResult) -> None:
            label = state["labels"].get(result.device)
            if label is not None:
                label.set_text(f"{result.status}: {result.text}")
                label.classes(replace="text-body1 " + STATUS_CLASS.get(result.status, ""))

        for entry in plan.devices:
            label = state["labels"].get(entry.device)
            if label is not None and entry.changed:
                label.set_text("waiting")
        try:
            done = await batch.apply_batch(runtime, plan, user=user, role=role, confirmed=confirmed,
                                           progress=progress.set_value, on_device=said)
        finally:
            compare.enable()
        failed = [r for r in done if r.status in (batch.FAILED, batch.REFUSED)]
        summary.set_text(", ".join(f"{r.device} {r.status}" for r in done)
                         + (f": stopped at {failed[0].device}, {failed[0].text}" if failed else ""))
        summary.classes(replace="text-body1 " + ("text-negative" if failed else "text-positive"))
        apply.set_visibility(False)

    compare.on_click(run_compare)
    apply.on_click(run_apply)
