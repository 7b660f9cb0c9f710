"""The shared simulation card: a twin's declared controls (``devices/simcontrols.py``), one widget for
every device type. Engineers only; each action goes through the worker's gate and into the audit log."""

from __future__ import annotations

import itertools
import re

from nicegui import ui

from app import i18n
from app import runtime as rt
from app.message import said
from devices.simcontrols import CONTEXT, SimAction, SimControls
from pages.command_client import sim_action, sim_card_allowed


def sim_card(device: str, only: tuple[str, ...] = (), skip: tuple[str, ...] = ()) -> None:
    """The purple "Simulated ..." card of ``device``; nothing when the device is not simulated here.
    ``only``: just these actions (by name); ``skip``: all but these."""
    controls = rt.current().sim_controls(device)
    if controls is None or (only and not any(a.name in only for a in controls.actions)):
        return
    lang = i18n.page_language()
    with ui.card().classes("w-full bg-purple-1").props("data-testid=sim-card"):
        ui.label(sim_text(controls.title, lang)).classes("text-subtitle1")
        if controls.note:
            ui.label(sim_text(controls.note, lang)).classes("text-caption text-grey-8")
        if not sim_card_allowed():
            return
        with ui.row().classes("items-center gap-3"):
            for action in controls.actions:
                if (only and action.name not in only) or action.name in skip:
                    continue
                _control(device, controls, action, lang)


_TOKEN = re.compile(r"0x[0-9A-Fa-f]+|-?\d+(?:\.\d+)?")  # a value in a twin's text: a number or a hex literal
_NAMED = re.compile(r"(.*) \(([^()]+)\)")  # a title's trailing "(plant)"


def sim_text(text: str, lang: i18n.Lang) -> str:
    """A twin's declared text (devices/*/sim.py, English) in the page's language, sentence by sentence: the catalog's
    entry (context ``simulation``) of the sentence, else of its pattern with its values as ``{0}``, ``{1}`` ...
    (numbers written the language's way, hex literals as they are), else with a trailing ``(name)`` as ``({0})``.
    What is not found is shown as it came and noted in the language's ``missing``."""
    if not text or lang.code == "en":
        return text
    return " ".join(_sentence(sentence, lang) for sentence in re.split(r"(?<=\.) (?=[A-Z])", text))


def _sentence(text: str, lang: i18n.Lang) -> str:
    if lang.has(text, CONTEXT):
        return lang.pgettext(CONTEXT, text)
    values = _TOKEN.findall(text)
    if values:
        count = itertools.count()
        pattern = _TOKEN.sub(lambda _match: "{%d}" % next(count), text)
        if lang.has(pattern, CONTEXT):
            return lang.pgettext(CONTEXT, pattern).format(*(v if v.startswith("0x") else lang.numbers_in(v) for v in values))
    named = _NAMED.fullmatch(text)
    if named and lang.has(named.group(1) + " ({0})", CONTEXT):
        return lang.pgettext(CONTEXT, named.group(1) + " ({0})").format(named.group(2))
    lang.missing.add(text)
    return text


def _control(device: str, controls: SimControls, action: SimAction, lang: i18n.Lang) -> None:
    testid = f"data-testid=sim-{action.testid or action.name.replace(' ', '-')}"

    def run(args: dict):
        try:
            describe = controls.describe(action.name, args)
        except ValueError as exc:  # a value the action does not take: said in the page's language
            ui.notify(said(exc, lang), type="warning")
            return None
        return sim_action(device, describe, lambda: controls.invoke(action.name, args))()

    if action.switch:
        ui.switch(sim_text(action.label, lang), value=bool(action.state()), on_change=lambda e: run({"on": bool(e.value)})).props(testid)
        return
    fields = {}
    with ui.row().classes("items-center gap-1 no-wrap"):
        for p in action.params:
            shown = f"0x{p.default:X}" if p.hex else str(p.default)
            fields[p.name] = ui.input(sim_text(p.label, lang), value=shown).props(f"dense outlined data-testid=sim-{p.name}").classes("w-32")
        ui.button(sim_text(action.label, lang), icon=action.icon or None,
                  on_click=lambda: run({name: field.value for name, field in fields.items()})).props(f"outline {testid}")


__all__ = ["sim_card"]
