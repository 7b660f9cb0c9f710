"""The worker's command gate: the one place where something to be sent is checked and audited.

Everything it decides on comes from declarations, never from the caller: the kind of a command
from its declaration (:mod:`devices.commands`), the role from the account store at the moment
of the action (a downgraded or removed account loses its rights at once, whatever an open page
was told when it was built), what bytes may go to a bus from the device types' send policies
(:mod:`devices.sendpolicy`).

Order of work: role, arguments and confirmation are checked; the audit row is written first
(fail closed: no row, nothing sent) and the command runs. Stops are the exception: never
refused, sent first, and audited afterwards from a queue, whatever the audit log's state.
"""

from __future__ import annotations

import asyncio
import inspect
import logging
from collections.abc import Awaitable, Callable, Mapping
from typing import Any

from devices.adapter import ControlChecker, SessionHolder
from devices.commands import OPEN_KINDS as OPEN_KINDS
from devices.commands import Command, CommandError, find
from devices.errors import CommissionError

log = logging.getLogger(__name__)

WRITE_ROLES = {"engineer"}


class PermissionDenied(CommissionError):
    """A session without the engineer role asked for a write."""


class AuditUnavailable(CommissionError):
    """The audit log cannot be written: the write is refused (fail closed)."""


class NeedsConfirmation(CommissionError):
    """The command names a risk and the caller has not confirmed it: ask, then invoke again with ``confirmed``."""

    def __init__(self, command: str, question: str):
        super().__init__(question)
        self.command = command
        self.question = question


def role_now(worker: Any, user: str, claimed: str) -> str:
    """The role of ``user`` as the account store says now; ``claimed`` where no accounts are in use
    (loopback: every browser is the local engineer) or for the worker's own callers (no look-up set)."""
    lookup = getattr(worker, "role_of", None)
    if lookup is None:
        return claimed
    role = lookup(user)
    return claimed if role is None else role


def may_run(kind: str, role: str) -> bool:
    return kind in OPEN_KINDS or role in WRITE_ROLES


def kind_for(worker: Any, device: str, describe: str) -> str:
    """The kind of an action submitted the older way (an adapter callable and its wording, the worker's
    own callers only): the declaration of the device type's command by that name decides; anything
    the type does not declare is a write (checked, confirmed and audited as one)."""
    command = declared(worker, device, describe)
    return command.kind if command is not None else "write"


def declared(worker: Any, device: str, name: str) -> Command | None:
    config = worker.plant.devices.get(device) if hasattr(worker, "plant") else None
    if config is None or not name:
        return None
    return find(config.type, name)


# -- stops: bus first, audit after (queued) ------------------------------------------------------------------

_pending: set[asyncio.Task] = set()


def audit_later(worker: Any, **row: Any) -> asyncio.Task | None:
    """Write an audit row from a task of its own: the caller (a stop) never waits for the database."""
    audit = getattr(worker, "audit", None)
    if audit is None:
        return None

    async def write() -> None:
        try:
            await audit.arecord(**row)
        except Exception as exc:  # noqa: BLE001 - the stop ran; the header shows the audit state
            log.error("audit of a stop (%s) failed: %s", row.get("action", ""), exc)

    task = asyncio.get_running_loop().create_task(write(), name="audit of a stop")
    _pending.add(task)
    task.add_done_callback(_pending.discard)
    return task


async def run_stop(worker: Any, action: Callable[[], Awaitable[Any]], *, device: str, user: str, role: str,
                   describe: str, parameter: str = "", old: Any = "", new: Any = "") -> Any:
    """A stop: runs at once for any role; the audit row (with the outcome) is queued afterwards."""
    try:
        result = await action()
    except Exception as exc:
        audit_later(worker, user=user, role=role, device=device, action=describe, parameter=parameter, old=old,
                    new=new, result=f"failed: {exc}"[:500])
        raise
    audit_later(worker, user=user, role=role, device=device, action=describe, parameter=parameter, old=old, new=new,
                result=f"ok: {result}"[:500] if isinstance(result, str) and result else "ok")
    return result


# -- declared commands -----------------------------------------------------------------------------------------------


async def invoke(worker: Any, device: str, name: str, args: Mapping[str, Any] | None = None, *, user: str,
                 role: str, session: str = "", confirmed: bool = False, action: str = "") -> Any:
    """Run the declared command ``name`` of ``device`` with ``args``.

    ``action`` names the workflow in the audit row (e.g. "restore") in place of the command's own wording.

    :raises KeyError: no such device; :raises CommandError: not declared, or an argument out of range
        (audited as a refusal); :raises PermissionDenied: the role may not (audited);
        :raises NeedsConfirmation: it names a risk and ``confirmed`` is False (nothing audited: a question)
    """
    if device not in worker.adapters:
        raise KeyError(f"no device named {device!r} in this plant")
    command = declared(worker, device, name)
    role = role_now(worker, user, role)
    if command is None:
        reason = f"{name!r} is not a command of {device}"
        await worker.refused(device=device, user=user, role=role, describe=name, reason=reason)
        raise CommandError(reason)
    values = dict(args or {})
    if not may_run(command.kind, role):
        await worker.refused(device=device, user=user, role=role, describe=command.name, new=_shown(values),
                             reason=f"the {role or 'anonymous'} role may not run a {command.kind} command")
        raise PermissionDenied(f"{user or 'anonymous'} has the {role or 'no'} role and may not write ({command.name})")
    try:
        values = command.checked_args(values)
    except CommandError as exc:
        await worker.refused(device=device, user=user, role=role, describe=command.name, reason=str(exc),
                             new=_shown(values))
        raise
    if "user" in command.extras:
        values["user"] = user  # who did it, for what the device reports (an emergency stop names who pressed it)
    adapter = worker.adapters[device]
    if command.refuse_if is not None:
        config = worker.plant.devices[device]
        try:
            reason = command.refuse_if(values, worker.plant.devices_on(config.bus), device)
        except Exception as exc:  # noqa: BLE001 - a policy that cannot judge the request refuses it
            reason = f"the send policy could not check it: {exc}"
        if reason:
            await worker.refused(device=device, user=user, role=role, describe=command.name, reason=reason,
                                 new=_shown(values))
            raise CommandError(reason)
    if command.needs_control and command.kind not in OPEN_KINDS:
        if isinstance(adapter, ControlChecker):  # an adapter that tells control apart from running motion
            controlled = adapter.controls(session)
        else:
            controlled = isinstance(adapter, SessionHolder) and session in adapter.holders()
        if not controlled:
            reason = "take control of the device first"
            await worker.refused(device=device, user=user, role=role, describe=command.name, reason=reason, new=_shown(values))
            raise CommandError(reason)
    risk = command.risk_text(values)
    if risk and not confirmed:
        raise NeedsConfirmation(command.name, risk)

    async def run() -> Any:
        result = command.call(adapter, session, values, confirmed=bool(risk))
        return await result if inspect.isawaitable(result) else result

    row = {"action": command.name, "parameter": "", "old": "", "new": _shown(values)}
    if command.audit is not None:
        row.update(command.audit(values, adapter))
    if action:
        row["action"] = action
    return await worker.checked(run, device=device, role=role, user=user, describe=row["action"], kind=command.kind,
                                record=command.kind != "read", parameter=row["parameter"], old=row["old"], new=row["new"])


CANCELLED = "cancelled: not confirmed"  # an audit row's result when the user answered a question with Cancel


async def cancelled(worker: Any, *, device: str, user: str, role: str, describe: str, parameter: str = "",
                    new: Any = "") -> None:
    """The user answered a confirmation with Cancel: nothing was sent and nothing was refused. Noted on the
    device as information and in the audit log (``CANCELLED``), under the parameter's name where there is one."""
    state = worker.store.devices.get(device)
    if state is not None:
        state.event("info", f"cancelled by {user or 'anonymous'}: {describe}" + (f" = {new}" if new != "" else "")
                    + ": not confirmed, nothing sent")
    audit = getattr(worker, "audit", None)
    if audit is not None:
        try:
            await audit.arecord(user=user, role=role, device=device, action=describe, parameter=parameter, new=new,
                                result=CANCELLED)
        except Exception as exc:  # noqa: BLE001 - nothing was sent anyway; the header shows the audit state
            log.error("audit of a cancelled %s failed: %s", describe, exc)


def question(worker: Any, device: str, name: str, args: Mapping[str, Any] | None = None) -> str:
    """The confirmation the declared command ``name`` asks with ``args`` ("" for none): what a restore
    shows beside a value before anything is sent. :raises CommandError: not declared, out of range, or
    refused by the device type's send policy."""
    command = declared(worker, device, name)
    if command is None:
        raise CommandError(f"{name!r} is not a command of {device}")
    values = command.checked_args(dict(args or {}))
    if command.refuse_if is not None:
        config = worker.plant.devices[device]
        reason = command.refuse_if(values, worker.plant.devices_on(config.bus), device)
        if reason:
            raise CommandError(reason)
    return command.risk_text(values)


def _shown(values: Mapping[str, Any]) -> str:
    return ", ".join(f"{k}={getattr(v, 'name', v)}" for k, v in values.items())
