"""The shared simulation card: a twin's declared controls (``devices/simcontrols.py``), one widget for
every device type. Engineers only; each action goes through the worker's gate and into the audit log."""

from __future__ import annotations

from nicegui import ui

from app import runtime as rt
from devices.simcontrols import SimAction, SimControls
from pages.command_client import sim_action, sim_card_allowed


def sim_card(device: str, only: tuple[str, ...] = (), skip: tuple[str, ...] = ()) -> None:
    """The purple "Simulated ..." card of ``device``; nothing when the device is not simulated here.
    ``only``: just these actions (by name); ``skip``: all but these."""
    controls = rt.current().sim_controls(device)
    if controls is None or (only and not any(a.name in only for a in controls.actions)):
        return
    with ui.card().classes("w-full bg-purple-1").props("data-testid=sim-card"):
        ui.label(controls.title).classes("text-subtitle1")
        if controls.note:
            ui.label(controls.note).classes("text-caption text-grey-8")
        if not sim_card_allowed():
            return
        with ui.row().classes("items-center gap-3"):
            for action in controls.actions:
                if (only and action.name not in only) or action.name in skip:
                    continue
                _control(device, controls, action)


def _control(device: str, controls: SimControls, action: SimAction) -> None:
    testid = f"data-testid=sim-{action.testid or action.name.replace(' ', '-')}"

    def run(args: dict):
        try:
            describe = controls.describe(action.name, args)
        except ValueError as exc:
            ui.notify(str(exc), type="warning")
            return None
        return sim_action(device, describe, lambda: controls.invoke(action.name, args))()

    if action.switch:
        ui.switch(action.label, value=bool(action.state()), on_change=lambda e: run({"on": bool(e.value)})).props(testid)
        return
    fields = {}
    with ui.row().classes("items-center gap-1 no-wrap"):
        for p in action.params:
            shown = f"0x{p.default:X}" if p.hex else str(p.default)
            fields[p.name] = ui.input(p.label, value=shown).props(f"dense outlined data-testid=sim-{p.name}").classes("w-32")
        ui.button(action.label, icon=action.icon or None,
                  on_click=lambda: run({name: field.value for name, field in fields.items()})).props(f"outline {testid}")


__all__ = ["sim_card"]
