"""The pages' command client: every write, command and question of a page goes through here to the
worker's gate (``worker.gate``, :class:`app.gate.CommandGate`), with the confirmation dialogs, refusals
and the controls a session may not use shown disabled with their reason."""

from __future__ import annotations

import inspect
import logging
import weakref
from collections.abc import Awaitable, Callable

from nicegui import ui

from app import i18n
from app import runtime as rt
from app.i18n import N_, Lang
from app.message import Message, said
from app.state import DeviceState
from app.worker import PermissionDenied
from devices.commands import WRITE_PARAMETER
from devices.params import Param, ParamError
from pages.widgets import follow

log = logging.getLogger(__name__)


def session_role() -> str:
    """Role of the browser session (engineer on loopback, else the account's role)."""
    from pages.session import current_user

    return current_user()[1]


async def confirm(title: str, text: str, ok: str | None = None, danger: bool = True, lang: Lang | None = None) -> bool:
    """Modal confirmation; resolves True only when the engineer presses ``ok`` (by default "Continue").
    ``title``, ``text`` and ``ok`` in the page's language; ``lang`` (by default the page's) words the rest."""
    _ = (lang or i18n.client_language()).gettext
    ok = _("Continue") if ok is None else ok
    with ui.dialog() as dialog, ui.card().classes("max-w-lg"):
        ui.label(title).classes("text-h6")
        ui.label(said(text, lang or i18n.client_language())).classes("text-body1" + (" text-negative" if danger else ""))
        with ui.row().classes("justify-end w-full"):
            ui.button(_("Cancel"), on_click=lambda: dialog.submit(False)).props("flat")
            ui.button(ok, color="negative" if danger else "primary", on_click=lambda: dialog.submit(True))
    result = await dialog
    dialog.delete()
    return bool(result)


async def run_command(
    device: str, action: str, *, success: str = "", args: dict | None = None, session: str = "",
    confirmed: bool = False, title: str = "", ok: str | None = None, parameter: str = "", new: object = "",
) -> tuple[bool, object]:
    """Submit a command to the worker's gate and report the outcome as a notification.

    ``action`` is the name of a command the device type declares (``devices/<type>/policy.py``), run
    with ``args``: the gate takes its kind, ranges, risk and the role (as the account store says now)
    from the declaration; a risk it names is asked here and the command invoked again, confirmed.
    ``confirmed``: the page has asked its own question naming the same risk. ``title`` and ``ok`` word
    the dialog that asks the declared risk (``ok`` by default "Send"), ``success`` the notification, all in
    the page's language. ``parameter`` and ``new``: the parameter's name and value as an engineer reads them,
    for the audit row of a question answered with Cancel.
    """
    from app.gate import NeedsConfirmation, shown
    from devices.commands import CommandError
    from devices.errors import CommissionError
    from pages.session import current_user

    worker = rt.current().worker
    lang = i18n.client_language()
    user, role = current_user()
    try:
        try:
            result = await worker.gate.invoke(device, action, args, user=user or "anonymous", role=role, session=session,
                                              confirmed=confirmed)
        except NeedsConfirmation as question:
            if not await confirm(title or f"{action}?", said(question.question, lang),
                                 ok=lang.gettext("Send") if ok is None else ok):
                await cancelled(device, action, parameter=parameter,
                                new=new if parameter else shown({k: v for k, v in (args or {}).items() if k != "known"}))
                return False, None
            user, role = current_user()  # looked up again: the answer may come much later
            result = await worker.gate.invoke(device, action, args, user=user or "anonymous", role=role, session=session,
                                              confirmed=True)
    except PermissionDenied as exc:
        ui.notify(said(exc, lang), type="negative")
        return False, None
    except CommandError as exc:  # the gate's refusal (the parameter model's among them), in the page's language
        ui.notify(f"{action}: {said(exc, lang)}", type="negative", multi_line=True)
        return False, None
    except CommissionError as exc:  # a refusal of the device, its rules, its line or the audit log: the message says what to do
        ui.notify(f"{action}: {said(exc, lang)}", type="negative", multi_line=True, close_button="OK", timeout=15000)
        return False, None
    except Exception as exc:  # noqa: BLE001 - the page's handler: a fault of this tool is logged with its traceback and said
        log.exception("%s on %s failed", action, device)
        ui.notify(f"{action}: {exc}", type="negative", multi_line=True, close_button="OK", timeout=15000)
        return False, None
    if success:
        ui.notify(success, type="positive")
    return True, result


async def refuse(device: str, describe: str, reason: str, parameter: str = "", new: object = "") -> None:
    """An entry refused before anything was sent: in the device's event log and the audit log."""
    from pages.session import current_user

    user, role = current_user()
    await rt.current().worker.gate.refused(device=device, user=user or "anonymous", role=role, describe=describe,
                                           reason=reason, parameter=parameter, new=new)


async def cancelled(device: str, describe: str, parameter: str = "", new: object = "") -> None:
    """The user answered a question with Cancel: nothing sent, nothing refused (an information on the device,
    audited as cancelled under the parameter's name)."""
    from pages.session import current_user

    user, role = current_user()
    await rt.current().worker.gate.cancelled(device=device, user=user or "anonymous", role=role, describe=describe,
                                             parameter=parameter, new=new)


def all_valid(*fields: ui.number, lang: Lang | None = None) -> bool:
    """Check every :func:`range_number` entry (each marks its own error); True when all hold a valid value."""
    _ = (lang or i18n.client_language()).gettext
    ok = True
    for field in fields:
        if field.value is None:
            rule = getattr(field, "rule", "")
            field.error = _("enter a value first ({rule})").format(rule=rule) if rule else _("enter a value first")
            ok = False
        elif not field.validate():
            ok = False
    return ok


async def checked_value(field: ui.number, device: str, describe: str, parameter: str = "") -> float | None:
    """The value of a :func:`range_number` entry, or None (field marked, refusal audited, nothing sent)."""
    if not all_valid(field):
        if field.value is not None:  # an empty field only asks for a value; a bad one is a refusal
            await refuse(device, describe, f"{field.value:g}: {field.error}", parameter=parameter, new=field.value)
        return None
    return field.value


VIEWER_REASON = N_("read-only session: only an engineer account may change the device")


def viewer_reason(lang: Lang | None = None) -> str:
    """Why this session's write controls are disabled ("" for an engineer), in ``lang`` (by default the page's).
    Display only: the gate decides."""
    from pages.session import can_write

    return "" if can_write() else (lang or i18n.client_language()).gettext(VIEWER_REASON)


class WriteGuard:
    """Disables a device's write controls, with the reason, while the device does not answer or the
    session may not write (a viewer sees them disabled with the reason; the gate refuses them anyway)."""

    def __init__(self, state: DeviceState, *controls: ui.element, lang: Lang | None = None):
        self.state = state
        self.lang = lang or i18n.client_language()  # kept: a store push that updates it runs outside the page
        self.controls: list[ui.element] = list(controls)
        self.reason = ""
        self.read_only = viewer_reason(self.lang)
        follow(state, self.update)
        self.update()

    def add(self, *controls: ui.element) -> None:
        self.controls.extend(controls)
        self.update(force=True)

    def update(self, force: bool = False) -> None:
        status = self.state.status
        if self.read_only:
            reason = self.read_only
        elif status in ("offline", "unknown"):
            _ = self.lang.gettext
            reason = ((_("the device does not answer: {error}").format(error=said(self.state.last_error, self.lang)) if self.state.last_error
                       else _("the device does not answer"))
                      if status == "offline" else _("waiting for the device's first answer"))
        else:
            reason = ""
        if reason == self.reason and not force:
            return
        self.reason = reason
        for control in self.controls:
            _show_reason(control, reason)


def _show_reason(control: ui.element, reason: str) -> None:
    """Enable ``control``, or disable it with ``reason`` as its tooltip."""
    control.set_enabled(not reason)
    if reason:
        text = reason.replace('"', "'")
        control.props(f'title="{text}" data-disabled-reason="{text}"')
    else:
        control.props(remove="title data-disabled-reason")


def enable_unless(control: ui.element, reason: str) -> None:
    """Enable ``control``, or disable it with ``reason`` as its tooltip (changed only when the reason changes):
    for a control whose reason the page works out itself (control held, session open), not the device's silence."""
    if _REASONS.get(control) == reason:
        return
    _REASONS[control] = reason
    _show_reason(control, reason)


def gate_reason(control: ui.element) -> str:
    """The reason :func:`enable_unless` last disabled ``control`` with ("" while it is enabled, or never asked)."""
    return _REASONS.get(control, "")


# the reason each control was last shown disabled with by enable_unless ("" enabled), as long as the control lives
_REASONS: weakref.WeakKeyDictionary[ui.element, str] = weakref.WeakKeyDictionary()


async def write_from_page(device: str, param: Param, value, *, success: str, title: str = "", ok: str | None = None,
                          field: ui.element | None = None, lang: Lang | None = None) -> None:
    """An engineer's entry for one parameter: check it, ask when the parameter wants a
    confirmation, then write through the worker with old and new value for the audit log.

    A refused entry stays in ``field`` as typed, marked with the reason (no toast over the page),
    and is recorded in the audit log; nothing is sent. ``success`` and ``title`` (with ``{name}`` and
    ``{value}``) and ``ok`` (by default "Write anyway") in the page's language."""
    lang = lang or i18n.client_language()
    _ = lang.gettext
    if value is None or value == "":
        if field is not None:
            field.error = _("enter a value first")
        else:
            ui.notify(_("{name}: enter a value first").format(name=param.name), type="warning")
        return
    try:
        accepted = param.accept(value)  # the one check of the entry: the gate, the send policy and the adapter take it
    except ParamError as exc:
        if field is not None:
            field.error = said(exc, lang)
        else:
            ui.notify(said(exc, lang), type="negative")
        await refuse(device, f"write {param.name}", str(exc), parameter=param.label or param.name, new=value)
        return
    if field is not None:
        field.error = None
    # the device type's declared write (every type declares it): the gate asks what its send policy names for the
    # accepted value (the same question as a restore or the API), audits parameter, old and new
    shown = lang.numbers_in(accepted.text)
    await run_command(device, WRITE_PARAMETER, args={"param": param.key, "value": accepted},
                      title=(title or _("Write {name} = {value}?")).format(name=param.name, value=shown),
                      ok=_("Write anyway") if ok is None else ok,
                      success=success.format(name=param.name, value=shown),
                      parameter=param.label or param.name, new=accepted.text)


def sim_card_allowed(note_testid: str = "sim-readonly", lang: Lang | None = None) -> bool:
    """Whether this session may act on the twins; a viewer gets a note in place of the card's controls."""
    lang = lang or i18n.client_language()
    reason = viewer_reason(lang)
    if reason:
        ui.label(lang.gettext("Simulation controls change the simulated plant: engineers only.")).classes("text-caption text-grey-8").props(
            f"data-testid={note_testid}")
    return not reason


def sim_action(device: str, describe: str, fn: Callable[[], object]) -> Callable[[], Awaitable[None]]:
    """A simulation-card action through the worker's gate: engineers only, audited ("simulation: ...")."""

    async def run() -> None:
        from pages.session import current_user

        user, role = current_user()

        async def act() -> str:
            result = fn()
            if inspect.isawaitable(result):
                await result
            return ""

        try:
            await rt.current().worker.gate.run(act, device=device, role=role, user=user or "anonymous",
                                               describe=Message(N_("simulation: {action}"), action=describe), kind="system")
        except Exception as exc:  # noqa: BLE001 - refused or failed: said on the page
            ui.notify(said(exc, i18n.client_language()), type="negative")

    return run
