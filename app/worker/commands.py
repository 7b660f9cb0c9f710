"""The hand-off to the command gate: every change a page, the API or a tool asks of a device.

Declared commands go to :func:`app.gate.invoke`, which decides from the declarations alone and comes
back through :func:`checked` (role, audit row first, fail closed) and :func:`refused` (a request
refused before anything was sent). :func:`command` is the older way, an adapter callable with its
wording, left to the worker's own callers (restore's save step): its kind comes from the declared
command of that name, else it counts as a write.
"""

from __future__ import annotations

import logging
from collections.abc import Awaitable, Callable
from typing import Any

from app import gate
from app.gate import AuditUnavailable, PermissionDenied

log = logging.getLogger(__name__)


async def command(worker: Any, device: str, action: Callable[[Any], Awaitable[Any]], *, role: str, user: str,
                  describe: str, record: bool, parameter: str, old: Any, new: Any) -> Any:
    """Run ``action(adapter)`` for ``device`` (see :meth:`app.worker.Worker.command`)."""
    if device not in worker.adapters:
        raise KeyError(f"no device named {device!r} in this plant")
    adapter = worker.adapters[device]
    kind = gate.kind_for(worker, device, describe)
    return await checked(
        worker, lambda: action(adapter), device=device, role=role, user=user, describe=describe, kind=kind,
        record=record or kind != "read", parameter=parameter, old=old, new=new,
    )


async def checked(worker: Any, action: Callable[[], Awaitable[Any]], *, device: str, role: str, user: str,
                  describe: str, kind: str, record: bool, parameter: str, old: Any, new: Any) -> Any:
    """Check the role, write the audit row (fail closed), run ``action``, finish the row
    (see :meth:`app.worker.Worker.checked`)."""
    what = describe or "command"
    role = gate.role_now(worker, user, role)
    if kind == "stop":
        return await gate.run_stop(worker, action, device=device, user=user, role=role, describe=what,
                                   parameter=parameter, old=old, new=new)
    row_fields = {"user": user, "role": role, "device": device, "action": what, "parameter": parameter, "old": old,
                  "new": new}
    if not gate.may_run(kind, role):
        await _refuse_role(worker, row_fields, record)
    row = None
    if record and kind != "read" and worker.audit is not None:
        row = await _audit_start(worker, row_fields)
    try:
        result = await action()
    except Exception as exc:
        if row is not None:
            await worker.audit.afinish(row, f"failed: {exc}")
        raise
    finally:
        after_change = getattr(worker, "after_change", None)  # the runtime's: unsaved reminders onto disk
        if kind != "read" and after_change is not None:
            await after_change()
    if row is not None:
        # an outcome in words (e.g. which lock took a broadcast address) goes into the row too
        await worker.audit.afinish(row, f"ok: {result}"[:500] if isinstance(result, str) and result else "ok")
    return result


async def _refuse_role(worker: Any, row: dict, record: bool) -> None:
    """The role may not run it: noted on the device and in the audit log. :raises PermissionDenied: always"""
    user, role, what = row["user"], row["role"], row["action"]
    state = worker.store.devices.get(row["device"])
    if state is not None:
        state.event("warning", f"refused for {user} ({role}): {what}")
    if record and worker.audit is not None:
        try:
            await worker.audit.arecord(**row, result=f"refused: the {role or 'anonymous'} role may not write")
        except Exception as exc:  # noqa: BLE001 - refused anyway; the audit state shows the failure
            log.error("audit: %s", exc)
    raise PermissionDenied(f"{user or 'anonymous'} has the {role or 'no'} role and may not write ({what})")


async def _audit_start(worker: Any, row: dict) -> Any:
    """The audit row of a change about to run. :raises AuditUnavailable: it cannot be written (nothing is sent)"""
    try:
        return await worker.audit.arecord(**row, result="started")
    except Exception as exc:  # noqa: BLE001 - fail closed: no audit row, no write
        what = row["action"]
        state = worker.store.devices.get(row["device"])
        if state is not None:
            state.event("error", f"{what} refused: the audit log cannot be written ({exc})")
        raise AuditUnavailable(
            f"{what} refused: the audit log cannot be written ({exc}). Nothing was sent. "
            f"Free or repair {worker.audit.path} (locked by another program, read-only or disk full) and try again."
        ) from None


async def refused(worker: Any, *, device: str, user: str, role: str, describe: str, reason: str, parameter: str,
                  new: Any) -> None:
    """Note a request refused before anything was sent, on the device and in the audit log."""
    state = worker.store.devices.get(device)
    if state is not None:
        state.event("warning", f"refused for {user or 'anonymous'}: {describe or 'entry'}: {reason}")
    if worker.audit is not None:
        try:
            await worker.audit.arecord(user=user, role=role, device=device, action=describe or "entry",
                                       parameter=parameter, new=new, result=f"refused: {reason}"[:500])
        except Exception as exc:  # noqa: BLE001 - nothing was sent anyway; the audit state shows the failure
            log.error("audit: %s", exc)
