"""The generic runner of declared checkouts (``devices/<type>/checkout.py``): one run's steps in
order, the context a step acts through (every command through the worker's gate), the answers a
person gave, and the bus traffic of each step as evidence. The record service (app/record.py)
starts runs and stores their results in the commissioning record.

What a person reads of a run (titles, step names, limits, questions, reasons, notes, the runner's own words) is a
:class:`~app.message.Message`: the record stores its English, and beside it (``worded``) the template and fields
of each, so that a page, the report and the command line word the run in their language, also after a restart.
"""

from __future__ import annotations

import asyncio
import importlib
import logging
import time
import uuid
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any

from app.i18n import N_
from app.message import Message, message_of, worded_table
from app.record_store import RecordError
from devices.errors import CommissionError

log = logging.getLogger(__name__)


def role_refusal(user: str, role: str, with_role: str, without_role: str) -> Message:
    """Why ``user`` may not act: ``with_role`` names the ``role``, ``without_role`` says there is none."""
    return Message(with_role, user=user, role=Message(role)) if role else Message(without_role, user=user)


# -- evidence: the bus traffic of a checkout step ------------------------------------------------

class TrafficTap:
    """Collects what the bus monitor buffers of one bus hold from the moment it starts: CAN frames
    (``CanBusState.frames``) or serial, Modbus and LogiTed transactions (``BusState.transactions``).
    Swept every 0.2 s while a step runs, so a busy bus cannot push frames out of the ring first."""

    def __init__(self, bus_state):
        self.bus_state = bus_state
        self.is_can = bus_state.type == "can"
        self.items: list = []
        self.since = time.time()
        self._last = self.since - 1e-6

    def sweep(self) -> None:
        buffer = self.bus_state.frames if self.is_can else self.bus_state.transactions
        new = []
        for item in reversed(buffer):
            if item.time <= self._last:
                break
            new.append(item)
        if new:
            new.reverse()
            self._last = new[-1].time
            self.items.extend(new)

    def take(self) -> dict:
        self.sweep()
        items, self.items = self.items, []
        if self.is_can:
            rows = [{"t": f.time, "id": f.arbitration_id, "ext": f.is_extended_id, "dir": f.direction,
                     "data": f.data.hex(), "err": f.is_error_frame} for f in items]
            return {"kind": "can", "frames": rows}
        rows = [{"t": t.time, "request": t.request, "tx": t.request_hex, "rx": t.response_hex, "decoded": t.decoded,
                 "error": t.error} for t in items]
        return {"kind": "serial", "transactions": rows}


# -- checkouts ---------------------------------------------------------------------------------
def _with_unit(value: object, unit: str) -> Message:
    """A measured value or a limit with its unit (none: alone), as the step records it and a reason says it."""
    return Message("{value} {unit}", value=value, unit=unit) if unit else Message("{value}", value=value)


class Aborted(CommissionError):
    """The engineer aborted the checkout (or the page that ran it went away)."""


class StepFailed(CommissionError):
    """A step's check failed; the message is the reason the report shows."""


NOT_AVAILABLE = "not available"


class NotAvailable(CommissionError):
    """A step this device (or its adapter) cannot do; the message says why. It does not fail the
    checkout: the report lists the step as "not available" with the reason."""

    status = NOT_AVAILABLE  # the step's status in the report

NOT_FAILING = ("passed", NOT_AVAILABLE, "skipped")  # step results that let a checkout pass


class Skipped(NotAvailable):
    """A step the person running the checkout chose to leave out (e.g. no test input wired); the
    message says who and why."""

    status = "skipped"


@dataclass
class StepResult:
    name: str
    limits: str = ""
    status: str = "pending"  # pending, running, passed, failed, aborted, error, skipped, not available
    reason: str = ""
    values: list[dict] = field(default_factory=list)
    answers: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    started: float | None = None
    ended: float | None = None
    evidence: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {"name": self.name, "limits": self.limits, "status": self.status, "reason": self.reason, "values": self.values,
                "answers": self.answers, "notes": self.notes, "started": self.started, "ended": self.ended,
                "evidence": self.evidence}


AskFn = Callable[[str], Awaitable[bool]]


def checkout_module(device_type: str):
    """``devices/<type>/checkout.py``, or None when the type declares no checkout."""
    try:
        return importlib.import_module(f"devices.{device_type}.checkout")
    except ModuleNotFoundError:
        return None


class CheckoutContext:
    """What a declared checkout step may do: every command through the worker's gate (the one
    place that sends), waits on conditions, measurements against limits, questions to a person."""

    WAIT_STEP_S = 0.05

    def __init__(self, run: "CheckoutRun"):
        self._run = run
        runtime = run.runtime
        self.device = run.device
        self.state = runtime.store.devices[run.device]
        self.config = runtime.plant.devices[run.device]
        self.options = dict(self.config.options)
        self.session = run.session
        self.user = run.user
        self.settings = run.settings
        self.adapter = runtime.worker.adapters[run.device]  # to ask what it offers; commands go through invoke()

    @property
    def step(self) -> StepResult:
        return self._run.current

    def check_abort(self) -> None:
        if self._run.abort_event.is_set():
            raise Aborted(self._run.abort_reason or Message(N_("aborted")))

    async def invoke(self, name: str, args: dict | None = None) -> Any:
        """Run the device type's declared command ``name`` through the worker's gate, for the run's
        session. A command that names a risk is run confirmed only when the person running the checkout
        answered that risk's question yes in this run (asked here if not yet; the answer is recorded)."""
        from app.gate import NeedsConfirmation

        self.check_abort()
        worker = self._run.runtime.worker
        confirmed = False
        while True:
            try:
                return await worker.gate.invoke(self.device, name, args, user=self.user, role=self._run.role,
                                                session=self.session, confirmed=confirmed)
            except NeedsConfirmation as exc:
                if confirmed:
                    raise
                if exc.question not in self._run.confirmed:
                    await self.ask(exc.question)
                else:
                    self.note(Message(N_("{command}: {question!r} answered yes earlier in this run"), command=name,
                                      question=exc.question))
                confirmed = True

    async def wait(self, predicate: Callable[[], bool], timeout_s: float) -> bool:
        """True once ``predicate()`` holds, False after ``timeout_s``; an abort ends the wait at once."""
        loop = asyncio.get_running_loop()
        end = loop.time() + timeout_s
        while True:
            self.check_abort()
            try:
                if predicate():
                    return True
            except (KeyError, TypeError, ValueError):
                pass
            if loop.time() >= end:
                return False
            self._run.tap_sweep()
            await asyncio.sleep(self.WAIT_STEP_S)

    def entry(self, name: str) -> dict | None:
        return self.state.entry(name)

    def value(self, name: str) -> Any:
        e = self.state.entry(name)
        return None if e is None else e.get("value")

    def field(self, name: str, field_name: str) -> int | None:
        e = self.state.entry(name)
        return None if e is None or not e.get("fields") else e["fields"].get(field_name)

    def measure(self, name: str, value: Any, unit: str = "", *, low: float | None = None, high: float | None = None,
                expect: Any = None, fail: bool = True) -> bool:
        """Record a measured value against its limit; a value outside it fails the step (``fail``)."""
        ok = True
        limit: str = ""
        if value is None:
            ok, limit = False, Message(N_("a value"))
        if expect is not None:
            limit = Message("= {expect}", expect=expect)
            ok = ok and value == expect
        if low is not None:
            limit = Message(">= {low:g}", low=low) if high is None else Message("{low:g} .. {high:g}", low=low, high=high)
            ok = ok and value is not None and value >= low
        if high is not None:
            limit = limit or Message("<= {high:g}", high=high)
            ok = ok and value is not None and value <= high
        self.step.values.append({"name": name, "value": value, "unit": unit, "limit": _with_unit(limit, unit) if limit else "",
                                 "ok": ok})
        if not ok and fail:
            shown = Message(N_("no value")) if value is None else _with_unit(value, unit)
            raise StepFailed(Message(N_("{name}: {value}, expected {limit}"), name=name, value=shown, limit=_with_unit(limit, unit)))
        return ok

    def note(self, text: str) -> None:
        self.step.notes.append(text)

    def fail(self, reason: str) -> None:
        raise StepFailed(reason)

    def not_available(self, reason: str) -> None:
        """End the step as "not available" (it does not fail the checkout) with ``reason``."""
        raise NotAvailable(reason)

    def skip(self, reason: str) -> None:
        """End the step as "skipped" by the person running it (it does not fail the checkout)."""
        raise Skipped(reason)

    async def ask(self, question: str) -> bool:
        """Ask the person running the checkout; the answer and who gave it are recorded. "No" fails the step."""
        self.check_abort()
        answer = await self._run.ask(question)
        self.step.answers.append({"question": question, "answer": "yes" if answer else "no", "by": self.user,
                                  "role": self._run.role, "time": time.time()})
        if not answer:
            raise StepFailed(Message(N_("{question} - answered no by {user}"), question=question, user=self.user))
        self._run.confirmed.add(question)
        return True

    async def choose(self, question: str, no_means: str) -> bool:
        """Ask a question whose "no" is an answer, not a failure (e.g. "is a test input wired to E1?");
        the answer and who gave it are recorded; ``no_means`` says in the step's notes what "no" did."""
        self.check_abort()
        answer = await self._run.ask(question)
        self.step.answers.append({"question": question, "answer": "yes" if answer else "no", "by": self.user,
                                  "role": self._run.role, "time": time.time()})
        if not answer:
            self.note(Message(N_("answered no by {user}: {consequence}"), user=self.user, consequence=no_means))
        return bool(answer)


class CheckoutRun:
    """One run of a device's declared checkout: progress, a visible abort, evidence per step.

    :param session: the browser session the run belongs to: outputs it switches on are under
        that session's dead-man rule. Without one (CLI, tests) the run confirms it is alive itself.
    """

    def __init__(self, runtime, device: str, *, user: str, role: str, ask: AskFn | None = None, session: str = "",
                 settings: dict | None = None):
        state = runtime.store.devices[device]
        module = checkout_module(state.type)
        if module is None:
            raise RecordError(Message(N_("{device}: the {type} type declares no checkout"), device=device, type=state.type))
        self.runtime, self.device, self.user, self.role = runtime, device, user, role
        self.module = module
        self.settings = {**module.SETTINGS, **(settings or {})}
        self.steps_decl = module.steps(runtime.plant.devices[device].options, self.settings)
        self.results = [StepResult(s["name"], s.get("limits", "")) for s in self.steps_decl]
        self.current: StepResult = self.results[0] if self.results else StepResult("-")
        self.session = session or f"checkout-{uuid.uuid4().hex[:8]}"
        self._own_session = not session
        self._ask = ask
        self.abort_event = asyncio.Event()
        self.abort_reason = ""
        self.status = "ready"
        self.started: float | None = None
        self.ended: float | None = None
        self.listeners: list[Callable[[], None]] = []
        self._tap = TrafficTap(runtime.store.buses[state.bus])
        self.record_id: int | None = None
        self.confirmed: set[str] = set()  # questions answered yes in this run (a declared risk is asked once)
        self.drift_before: set[str] = set()  # keys drifting before the run (set by RecordService.new_run)

    @property
    def progress(self) -> float:
        done = sum(r.status not in ("pending", "running") for r in self.results)
        return done / max(1, len(self.results))

    def abort(self, reason: str = "") -> None:
        self.abort_reason = reason or Message(N_("aborted by the engineer"))
        self.abort_event.set()

    def tap_sweep(self) -> None:
        self._tap.sweep()

    def _changed(self) -> None:
        for fn in list(self.listeners):
            try:
                fn()
            except Exception:  # a page's callback (one gone away, or its bug) must not end a run on
                log.debug("checkout listener failed", exc_info=True)  # real equipment before its cleanup

    async def ask(self, question: str) -> bool:
        if self._ask is None:
            raise StepFailed(Message(N_("{question} - nobody to ask (run it from the device's record page)"), question=question))
        return await self._ask(question)

    async def _beat(self) -> None:
        while True:
            self.runtime.worker.heartbeat(self.session)
            await asyncio.sleep(0.1)

    async def run(self) -> dict:
        """Run every step in order; the first failure ends the run (later steps are skipped), the
        cleanup always runs. Returns the result as stored (its ``record_id`` set)."""
        if self.role != "engineer":
            raise PermissionError(role_refusal(self.user, self.role, N_("{user} has the {role} role and may not run checkouts"),
                                               N_("{user} has the no role and may not run checkouts")))
        ctx = CheckoutContext(self)
        beat = asyncio.create_task(self._beat()) if self._own_session else None
        self.status, self.started = "running", time.time()
        self._changed()
        try:
            for decl, result in zip(self.steps_decl, self.results):
                self.current = result
                result.status, result.started = "running", time.time()
                self._tap.take()  # the evidence of each step starts with it
                self._changed()
                try:
                    ctx.check_abort()
                    await decl["run"](ctx)
                    result.status = "passed"
                except StepFailed as exc:
                    result.status, result.reason = "failed", message_of(exc)
                except NotAvailable as exc:
                    result.status, result.reason = exc.status, message_of(exc)
                except Aborted as exc:
                    result.status, result.reason = "aborted", message_of(exc)
                except CommissionError as exc:  # a refused or failed command is the step's reason
                    result.status, result.reason = "failed", f"{type(exc).__name__}: " if not str(exc) else message_of(exc)
                result.ended = time.time()
                result.evidence = self._tap.take()
                self._changed()
                if result.status not in NOT_FAILING:
                    break
            for result in self.results:
                if result.status == "pending":
                    result.status, result.reason = "skipped", Message(N_("not run: an earlier step did not pass"))
        finally:
            ctx.step.notes.append(Message(N_("cleanup ran")))
            self.abort_event.clear()  # the cleanup stops and restores: it must run after an abort too
            try:
                await self.module.cleanup(ctx, self.settings)
            except CommissionError as exc:  # a refused or failed command: said in the result
                ctx.step.notes.append(Message(N_("cleanup failed: {error}"), error=message_of(exc)))
            if beat is not None:
                beat.cancel()
        self.ended = time.time()
        if any(r.status == "aborted" for r in self.results):
            self.status = "aborted"
        elif all(r.status in NOT_FAILING for r in self.results):
            self.status = "passed"
        else:
            self.status = "failed"
        data = self.as_dict()
        title = Message("{title}: {status}", title=self.module.TITLE, status=Message(self.status))
        data["worded"] = worded_table([data, title], leave_out=("evidence",))  # the English's templates, for its readers
        service = self.runtime.record
        service.check_drift(self.device)  # what the checkout changed and restored is no longer held back
        self.record_id = await service.add(self.device, "checkout", user=self.user, role=self.role, data=data, title=title)
        data["record_id"] = self.record_id
        self._changed()
        return data

    def as_dict(self) -> dict:
        failed = next((r for r in self.results if r.status in ("failed", "aborted")), None)
        return {"device": self.device, "title": self.module.TITLE, "status": self.status, "reason": failed.reason if failed else "",
                "user": self.user, "role": self.role, "started": self.started, "ended": self.ended,
                "duration_s": None if self.started is None or self.ended is None else round(self.ended - self.started, 2),
                "settings": self.settings, "steps": [r.as_dict() for r in self.results]}
