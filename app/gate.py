"""The command gate: the one place where something to be sent or changed is checked, audited and run.

The worker builds one :class:`CommandGate` (``worker.gate``), and everything a page, the API, a tool
or the worker's own parts ask of a device or of the plant goes through it:

- :meth:`CommandGate.invoke` runs a command the device type declares (``devices/<type>/policy.py``);
- :meth:`CommandGate.run` runs an action that is no declared command (adopting a device, a backup, a
  line scan, a transmit list, a replay, a simulation control): its kind is the caller's, else the
  declared kind of the command its wording names, else a write;
- :meth:`CommandGate.refused` and :meth:`CommandGate.cancelled` note a request refused before
  anything was sent, or a question answered with Cancel.

Everything it decides on comes from declarations, never from the caller: the kind of a command
from its declaration (:mod:`devices.commands`), the role from the account store at the moment
of the action (a downgraded or removed account loses its rights at once, whatever an open page
was told when it was built: :attr:`GateWorker.role_of`), what bytes may go to a bus from the device
types' send policies (:mod:`devices.sendpolicy`). The role and the permission are worked out once
per request.

Order of work: role, arguments and confirmation are checked; the audit row is written first
(fail closed: no row, nothing sent) and the command runs. Stops are the exception: never
refused, sent first, and audited afterwards from a queue, whatever the audit log's state.
"""

from __future__ import annotations

import asyncio
import inspect
import logging
import sqlite3
from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from app.audit import AuditLog
from app.i18n import N_
from app.message import Message, message_of
from app.plant import Plant
from app.state import StateStore
from devices.adapter import ControlChecker, SessionHolder
from devices.commands import OPEN_KINDS as OPEN_KINDS
from devices.commands import Command, CommandError, find
from devices.errors import CommissionError
from devices.params import Accepted, Param

log = logging.getLogger(__name__)

WRITE_ROLES = {"engineer"}
AUDIT_ERRORS = (OSError, sqlite3.Error, RuntimeError)  # writing a row: the file, the database, a log closed at the end
CANCELLED = "cancelled: not confirmed"  # an audit row's result when the user answered a question with Cancel


class PermissionDenied(CommissionError):
    """A session without the engineer role asked for a write."""


class UnknownDevice(CommissionError, KeyError):
    """A request names no device of the plant (a ``KeyError`` too, as callers look a device up)."""


class AuditUnavailable(CommissionError):
    """The audit log cannot be written: the write is refused (fail closed)."""


class NeedsConfirmation(CommissionError):
    """The command names a risk and the caller has not confirmed it: ask, then invoke again with ``confirmed``."""

    def __init__(self, command: str, question: str):
        super().__init__(question)
        self.command = command
        self.question = question


def not_declared(device: str, name: str) -> Message:
    """The refusal of a command ``device``'s type does not declare."""
    return Message(N_("{name} is not a command of {device}"), name=repr(name), device=device)


def write_refusal(user: str, role: str, action: str) -> Message:
    """Why ``user`` with ``role`` may not write (``action`` names what was asked), worded in the reader's language."""
    who = user or Message(N_("anonymous"))
    if role:
        return Message(N_("{user} has the {role} role and may not write ({action})"), user=who, role=Message(role), action=action)
    return Message(N_("{user} has the no role and may not write ({action})"), user=who, action=action)


class GateWorker(Protocol):
    """What the gate uses of the worker (:class:`app.worker.Worker`)."""

    plant: Plant
    store: StateStore
    audit: AuditLog | None

    role_of: Callable[[str], str | None]
    """The role of a user as the account store says now; None where no accounts are in use (the caller's role
    stands)."""
    after_change: Callable[[], Awaitable[None]]
    """Awaited after every action that is not a read (the runtime keeps unsaved reminders on disk)."""

    @property
    def adapters(self) -> Mapping[str, Any]:
        """Device name -> its adapter (whatever the device type's adapter is: a declared command names its method)."""


def may_run(kind: str, role: str) -> bool:
    return kind in OPEN_KINDS or role in WRITE_ROLES


@dataclass(frozen=True)
class Row:
    """The fields of one audit row, worked out once per request (the result is added when it is written)."""

    user: str
    role: str
    device: str
    action: str
    parameter: str = ""
    old: Any = ""
    new: Any = ""

    def fields(self) -> dict[str, Any]:
        return dict(vars(self))  # the values themselves (a list of register values stays the list the caller gave)


class CommandGate:
    """Checks, audits and runs every request of ``worker``'s callers (see the module's description).

    :param done: called after every request, whatever its outcome (the worker's supervision tick
        hurries: a command may have taken control)
    """

    def __init__(self, worker: GateWorker, done: Callable[[], None] = lambda: None):
        self.worker = worker
        self.done = done
        self._pending: set[asyncio.Task] = set()  # the audit rows of stops, written after the stop

    # -- what the gate decides on ----------------------------------------------------------------------------
    def role_now(self, user: str, claimed: str) -> str:
        """The role of ``user`` as the account store says now; ``claimed`` where no accounts are in use
        (loopback: every browser is the local engineer)."""
        role = self.worker.role_of(user)
        return claimed if role is None else role

    def declared(self, device: str, name: str, *, served: bool = False) -> Command | None:
        """The declared command ``name`` of ``device``'s type, or None; ``served``: only one that the type's
        adapter for the device's bus kind runs (the HD-Lock on Modbus lacks its CAN-only commands)."""
        config = self.worker.plant.devices.get(device)
        if config is None or not name:
            return None
        bus = self.worker.plant.buses.get(config.bus) if served else None
        return find(config.type, name, bus.type if bus is not None else "")

    def kind_for(self, device: str, describe: str) -> str:
        """The kind of an action known by its wording: the declaration of the device type's command by that
        name decides; anything the type does not declare is a write (checked, confirmed and audited as one)."""
        command = self.declared(device, describe)
        return command.kind if command is not None else "write"

    def adapter(self, device: str) -> Any:
        """:raises UnknownDevice: no such device (a ``KeyError``)"""
        adapter = self.worker.adapters.get(device)
        if adapter is None:
            raise UnknownDevice(Message(N_("no device named {name} in this plant"), name=repr(device)))
        return adapter

    # -- the ways in ---------------------------------------------------------------------------------------------
    async def invoke(self, device: str, name: str, args: Mapping[str, Any] | None = None, *, user: str, role: str,
                     session: str = "", confirmed: bool = False, action: str = "") -> Any:
        """Run the declared command ``name`` of ``device`` with ``args``.

        ``action`` names the workflow in the audit row (e.g. "restore") in place of the command's own wording.

        :raises UnknownDevice: no such device (a ``KeyError``); :raises CommandError: not declared, or an argument out of range
            (audited as a refusal); :raises PermissionDenied: the role may not (audited);
            :raises NeedsConfirmation: it names a risk and ``confirmed`` is False (nothing audited: a question)
        """
        try:
            return await self._invoke(device, name, dict(args or {}), user=user, role=self.role_now(user, role),
                                      session=session, confirmed=confirmed, action=action)
        finally:
            self.done()

    async def run(self, action: Callable[[], Awaitable[Any]], *, device: str = "", user: str, role: str, describe: str = "",
                  kind: str | None = None, parameter: str = "", old: Any = "", new: Any = "") -> Any:
        """Check the role, write the audit row (fail closed), run ``action``, finish the row.

        For what is no declared command of a device: changes of the plant, the plant file, files on disk
        (``device`` names the bus or device concerned, or is ""), a simulation control, ending a recording,
        stopping a transmit list or a replay. ``kind``: the caller's (``stop``, ``system``, ...), else the
        declared kind of ``device``'s command named ``describe`` (:meth:`kind_for`), else a write.
        A ``stop`` runs for every role, first, and is audited afterwards from a queue; a ``read`` for every
        role, unaudited.
        """
        try:
            kind = kind or self.kind_for(device, describe)
            row = Row(user=user, role=self.role_now(user, role), device=device, action=describe or "command",
                      parameter=parameter, old=old, new=new)
            if not may_run(kind, row.role):
                await self._refuse_role(row)
            return await self._execute(action, kind, row)
        finally:
            self.done()

    async def refused(self, *, device: str, user: str, role: str, describe: str, reason: str, parameter: str = "",
                      new: Any = "") -> None:
        """An entry or a request refused before anything was sent (out of range, not confirmed, forbidden by
        the device document): noted on the device and in the audit log with the reason."""
        state = self.worker.store.devices.get(device)
        if state is not None:
            state.event("warning", Message(N_("refused for {user}: {action}: {reason}"), user=user or Message(N_("anonymous")),
                                           action=describe or Message(N_("entry")), reason=reason))
        await self._note("audit: %s", user=user, role=role, device=device, action=describe or "entry",
                         parameter=parameter, new=new, result=f"refused: {reason}"[:500])

    async def cancelled(self, *, device: str, user: str, role: str, describe: str, parameter: str = "",
                        new: Any = "") -> None:
        """The user answered a confirmation with Cancel: nothing was sent and nothing was refused. Noted on the
        device as information and in the audit log (``CANCELLED``), under the parameter's name where there is one."""
        state = self.worker.store.devices.get(device)
        if state is not None:
            state.event("info", Message(N_("cancelled by {user}: {action} = {value}: not confirmed, nothing sent"),
                                        user=user or Message(N_("anonymous")), action=describe, value=new) if new != "" else
                        Message(N_("cancelled by {user}: {action}: not confirmed, nothing sent"),
                                user=user or Message(N_("anonymous")), action=describe))
        await self._note(f"audit of a cancelled {describe} failed: %s", user=user, role=role, device=device,
                         action=describe, parameter=parameter, new=new, result=CANCELLED)

    def question(self, device: str, name: str, args: Mapping[str, Any] | None = None) -> str:
        """The confirmation the declared command ``name`` asks with ``args`` ("" for none): what a restore
        shows beside a value before anything is sent. :raises CommandError: not declared, out of range, or
        refused by the device type's send policy."""
        command = self.declared(device, name, served=True)
        if command is None:
            raise CommandError(not_declared(device, name))
        values = command.checked_args(dict(args or {}))
        reason = self._policy_refusal(command, device, values)
        if reason:
            raise CommandError(reason)
        return command.risk_text(values)

    # -- declared commands ---------------------------------------------------------------------------------------
    async def _invoke(self, device: str, name: str, values: dict[str, Any], *, user: str, role: str, session: str,
                      confirmed: bool, action: str) -> Any:
        adapter = self.adapter(device)
        command = self.declared(device, name, served=True)
        if command is None:
            reason = not_declared(device, name)
            await self.refused(device=device, user=user, role=role, describe=name, reason=reason)
            raise CommandError(reason)
        if not may_run(command.kind, role):
            await self.refused(device=device, user=user, role=role, describe=command.name, new=shown(values),
                               reason=f"the {role or 'anonymous'} role may not run a {command.kind} command")
            raise PermissionDenied(write_refusal(user, role, command.name))
        try:
            values = command.checked_args(values)
        except CommandError as exc:
            await self.refused(device=device, user=user, role=role, describe=command.name, reason=str(exc),
                               new=shown(values))
            raise
        if "user" in command.extras:
            values["user"] = user  # who did it, for what the device reports (an emergency stop names who pressed it)
        try:
            reason = self._policy_refusal(command, device, values)
        except Exception as exc:  # noqa: BLE001 - a policy that cannot judge the request refuses it
            reason = Message(N_("the send policy could not check it: {error}"), error=message_of(exc))
        if not reason and command.needs_control and command.kind not in OPEN_KINDS and not _controls(adapter, session):
            reason = Message(N_("take control of the device first"))
        if reason:
            await self.refused(device=device, user=user, role=role, describe=command.name, reason=reason,
                               new=shown(values))
            raise CommandError(reason)
        risk = command.risk_text(values)
        if risk and not confirmed:
            raise NeedsConfirmation(command.name, risk)

        async def run() -> Any:
            result = command.call(adapter, session, values, confirmed=bool(risk))
            return await result if inspect.isawaitable(result) else result

        wording = {"action": command.name, "parameter": "", "old": "", "new": shown(values)}
        if command.audit is not None:
            wording.update(command.audit(values, adapter))
        if action:
            wording["action"] = action
        row = Row(user=user, role=role, device=device, action=wording["action"] or "command",
                  parameter=wording["parameter"], old=wording["old"], new=wording["new"])
        return await self._execute(run, command.kind, row)

    def _policy_refusal(self, command: Command, device: str, values: Mapping[str, Any]) -> str:
        """Why the device type's send policy refuses ``values`` ("" when it does not)."""
        if command.refuse_if is None:
            return ""
        config = self.worker.plant.devices[device]
        return command.refuse_if(values, self.worker.plant.devices_on(config.bus), device)

    # -- running: audit row first (or, for a stop, after) --------------------------------------------------------
    async def _execute(self, action: Callable[[], Awaitable[Any]], kind: str, row: Row) -> Any:
        """Run ``action`` whose role is checked. A stop runs first and its row (with the outcome) is queued
        afterwards; anything else but a read is audited first (fail closed) and finished with its outcome."""
        audit = self.worker.audit
        stop = kind == "stop"
        started = await self._audit_start(audit, row) if not stop and kind != "read" and audit is not None else None
        try:
            result = await action()
        except Exception as exc:  # re-raised: the row tells how it ended
            await self._finish(row, started, f"failed: {exc}"[:500] if stop else f"failed: {exc}", stop=stop)
            raise
        finally:
            if not stop and kind != "read":
                await self.worker.after_change()
        # an outcome in words (e.g. which lock took a broadcast address) goes into the row too
        await self._finish(row, started, _outcome(result), stop=stop)
        return result

    async def _finish(self, row: Row, started: Any, result: str, *, stop: bool) -> None:
        """How an action ended: into the row written before it, or (a stop) into a row written now from a queue."""
        if stop:
            self._audit_later(row, result)
        elif started is not None and self.worker.audit is not None:
            await self.worker.audit.afinish(started, result)

    def _audit_later(self, row: Row, result: str) -> None:
        """Write an audit row from a task of its own: the caller (a stop) never waits for the database."""
        audit = self.worker.audit
        if audit is None:
            return

        async def write() -> None:
            try:
                await audit.arecord(**row.fields(), result=result)
            except Exception as exc:  # noqa: BLE001 - a task of its own: the stop ran; the header shows the audit state
                log.error("audit of a stop (%s) failed: %s", row.action, exc)

        task = asyncio.get_running_loop().create_task(write(), name="audit of a stop")
        self._pending.add(task)
        task.add_done_callback(self._pending.discard)

    async def _audit_start(self, audit: AuditLog, row: Row) -> Any:
        """The audit row of a change about to run. :raises AuditUnavailable: it cannot be written (nothing is sent)"""
        try:
            return await audit.arecord(**row.fields(), result="started")
        except Exception as exc:  # noqa: BLE001 - fail closed: whatever stops the row, nothing is sent
            state = self.worker.store.devices.get(row.device)
            if state is not None:
                state.event("error", Message(N_("{action} refused: the audit log cannot be written ({error})"),
                                             action=row.action, error=str(exc)))
            raise AuditUnavailable(Message(
                N_("{action} refused: the audit log cannot be written ({error}). Nothing was sent. Free or repair {path} "
                   "(locked by another program, read-only or disk full) and try again."),
                action=row.action, error=str(exc), path=str(audit.path))) from None

    async def _note(self, failure: str, **row: Any) -> None:
        """Write the audit row of a request that sends nothing (refused, cancelled). A row that cannot be
        written is logged with ``failure`` (a %-format for the error): the request's outcome stands, and the
        header shows the audit state."""
        audit = self.worker.audit
        if audit is None:
            return
        try:
            await audit.arecord(**row)
        except AUDIT_ERRORS as exc:
            log.error(failure, exc)

    async def _refuse_role(self, row: Row) -> None:
        """The role may not run it: noted on the device and in the audit log. :raises PermissionDenied: always"""
        state = self.worker.store.devices.get(row.device)
        if state is not None:
            state.event("warning", Message(N_("refused for {user} ({role}): {action}"), user=row.user, role=Message(row.role),
                                           action=row.action))
        await self._note("audit: %s", **row.fields(), result=f"refused: the {row.role or 'anonymous'} role may not write")
        raise PermissionDenied(write_refusal(row.user, row.role, row.action))


def _controls(adapter: Any, session: str) -> bool:
    """Whether ``session`` controls the device of ``adapter``."""
    if isinstance(adapter, ControlChecker):  # an adapter that tells control apart from running motion
        return adapter.controls(session)
    return isinstance(adapter, SessionHolder) and session in adapter.holders()


def _outcome(result: Any) -> str:
    """An audit row's result: "ok", with the outcome when the action said it in words."""
    return f"ok: {result}"[:500] if isinstance(result, str) and result else "ok"


def shown(values: Mapping[str, Any]) -> str:
    """Arguments as the audit log and a cancelled question show them: a parameter or a choice by its name, a value
    the parameter model accepted by its value and raw word."""
    return ", ".join(f"{k}={v.value}, raw={v.raw}" if isinstance(v, Accepted) else f"{k}={v.name if isinstance(v, Param) else v}"
                     for k, v in values.items())
