"""The SCU's functions on its line: RE, RS, jog, the emergency stop and the watchdog test (document 002, sections 4.4
to 4.6 and 5).

Every RE is followed by its RS (section 4.6), also under the worker's dead-man rule: a browser that goes away has
RS sent at once for everything it runs. RC (when due) and an RE go out back to back under the function's lock, so
an RS of the same function is never sent before its RE. The emergency stop (F20, fnc_ID 19) is never refused and
released only explicitly (RS 19). The rules are the core's (devices/scu/control.py); this part carries them out.
"""

from __future__ import annotations

import asyncio
import time
from typing import TYPE_CHECKING

from devices.live import session_tag
from devices.control import dead_man
from devices.message import Message, N_, Word
from devices.scu import codec
from devices.scu.control import EMERGENCY_STOP, ESTOP, NOT_HELD, SendRS
from devices.scu.facts import CommandError, ControlBusy

if TYPE_CHECKING:
    from devices.scu.adapter import ScuAdapter


class ScuFunctions:
    """RE and RS of one SCU adapter's functions, with their locks and the stops asked meanwhile."""

    def __init__(self, adapter: ScuAdapter):
        self.adapter = adapter
        self.started: set[int] = set()  # functions run since the session opened (Stop sends RS to them)
        self.stop_tasks: set[asyncio.Task] = set()
        self.fn_locks: dict[int, asyncio.Lock] = {}
        self.stop_marks: dict[int, float] = {}  # fnc_ID -> when a stop of it was asked
        self.stop_all_at = 0.0  # when a stop of everything was asked

    def session_lost(self, session: str, reason: str) -> None:
        """The browser of ``session`` went away or froze: RS at once for everything it runs, release control."""
        actions = self.adapter.core.session_lost(session, reason)
        held = [a.fn for a in actions if isinstance(a, SendRS)]
        now = time.monotonic()
        for fn in held:
            self.stop_marks[fn] = now
        if held:
            self.adapter.state.event("warning", Message(N_("{reason}; RS to {functions}"), reason=dead_man(reason), functions=", ".join(
                codec.FUNCTIONS[codec.Function(f)].label for f in held)))
            task = asyncio.get_running_loop().create_task(self.stop_functions(held, dead_man(reason)))
            self.stop_tasks.add(task)
            task.add_done_callback(self.stop_tasks.discard)
        for action in actions:
            if not isinstance(action, SendRS):
                self.adapter.apply(action)

    async def stopped(self) -> None:
        """Wait for the RS frames that :meth:`session_lost` has sent off (tests, shutdown)."""
        while self.stop_tasks:
            await asyncio.gather(*list(self.stop_tasks), return_exceptions=True)

    async def stop_functions(self, functions: list[int], why: str) -> list[int]:
        """RS to each function; the functions whose RS was not acknowledged."""
        return [fn for fn in functions if not await self.send_rs(fn, why)]

    def fn_lock(self, fn: int) -> asyncio.Lock:
        lock = self.fn_locks.get(fn)
        if lock is None:
            lock = self.fn_locks[fn] = asyncio.Lock()
        return lock

    async def send_rs(self, fn: int, why: str) -> bool:
        """RS of ``fn`` after any RE of it still on the line (never before it); True once acknowledged."""
        async with self.fn_lock(fn):
            with self.adapter.rc.guard:
                by_thread = fn in self.adapter.rc.stopped_by_thread
                self.adapter.rc.stopped_by_thread.discard(fn)
            if by_thread and fn in self.adapter.running:  # the line's thread got its RS acknowledged after a lapse
                self.adapter.running.pop(fn, None)
                self.adapter.rs_pending.pop(fn, None)
                self.adapter.sync_held()
                return True
            return await self.rs(fn, why)

    async def rs(self, fn: int, why: str) -> bool:
        """RS as the core rules it: sent again on CSE or no answer, in the three-byte form after a PCE; not
        acknowledged, it is a failed stop and RC is withheld (devices/scu/control.py)."""
        await self.adapter.carry_out([SendRS(fn, why, three_bytes=self.adapter.core.rs_three_bytes)])
        if fn == ESTOP:
            return self.adapter.core.estop is None
        return fn not in self.adapter.running and fn not in self.adapter.rs_pending

    async def stop_held(self, session: str, why: str) -> None:
        await self.stop_functions([fn for fn, s in self.adapter.running.items() if s == session and fn not in NOT_HELD], why)

    def stopped_since(self, fn: int, since: float) -> bool:
        return max(self.stop_all_at, self.stop_marks.get(fn, 0.0)) > since

    async def run_function(self, session: str, function: int, motion: int = -1, ramp: int = -1,
                           requested_at: float | None = None) -> str:
        """RE of a function (F1..F10 with motion and ramp; buzzer, outputs, LEDs with -1, -1).

        RC (when due) and the RE go out back to back under the function's lock, so an RS of the same
        function (Stop, jog release, dead-man) is never sent before the RE; a stop requested after
        ``requested_at`` (the moment the page saw the press) cancels the RE, or is followed by RS right after it.
        """
        requested_at = time.monotonic() if requested_at is None else requested_at
        self.adapter.check_holder(session)
        fn = codec.Function(function)
        if fn == codec.Function.EMERGENCY_STOP:
            return await self.emergency_stop(session)
        decision = self.adapter.core.check_run(session, int(fn))
        if not decision.ok:
            raise (ControlBusy if decision.busy else CommandError)(decision.refused)
        await self.adapter.ensure_open()
        self.adapter.check_open()
        frame = codec.encode_re(fn, motion, ramp) if fn in codec.MOTION_FUNCTIONS else codec.encode_re(fn)
        label = codec.FUNCTIONS[fn].label
        words = (f"{label} {codec.MOTION_LABELS[codec.Motion(motion)]}, ramp {codec.Ramp(ramp & 0xFF).name.lower()}"
                 if fn in codec.MOTION_FUNCTIONS else f"{label} {codec.FUNCTIONS[fn].description}")
        sent = (Message(N_("RE {function} {motion}, ramp {ramp}"), function=label,
                        motion=Message(codec.MOTION_LABELS[codec.Motion(motion)]),
                        ramp=Word(codec.Ramp(ramp & 0xFF).name.lower(), "Ramp"))
                if fn in codec.MOTION_FUNCTIONS else  # a template without words: not marked (docs/i18n.md)
                Message("RE {function} {description}", function=label, description=codec.FUNCTIONS[fn].description))
        async with self.fn_lock(int(fn)):
            if self.stopped_since(int(fn), requested_at):
                raise CommandError(f"{label}: a stop came after this request: no RE sent")
            if self.adapter.rc.due():
                await self.adapter.send_rc()
            if self.stopped_since(int(fn), requested_at):
                raise CommandError(f"{label}: a stop came after this request: no RE sent")
            # runs from now on (the controlling session pressed just now: alive; the supervisor renews its lease),
            # before the request: a lost answer must still be followed by RS
            self.adapter.core.re_sent(session, int(fn), time.monotonic())
            self.adapter.sync_held()
            try:
                await self.adapter.link.request(frame, f"RE {words}", keepalive=False)
            except BaseException as exc:
                await self.adapter.carry_out(self.adapter.core.re_answered(int(fn), self.adapter.outcome(exc)))
                raise
            if self.stopped_since(int(fn), requested_at):
                await self.rs(int(fn), Message(N_("stop requested while the RE was on the line")))
                raise CommandError(f"{label}: stopped right after its RE (a stop came while the RE was on the line)")
        self.started.add(int(fn))
        self.adapter.state.event("info", sent)
        return words

    async def stop(self, session: str | None = None, function: int | None = None) -> list[str]:
        """RS to ``function``, or to every function run (anyone may stop); raises when an RS is not acknowledged."""
        now = time.monotonic()
        if function is None:
            self.stop_all_at = now
        else:
            self.stop_marks[int(function)] = now
        if self.adapter.session != "open" and not self.adapter.running and not self.adapter.rs_pending:
            return [f"nothing sent: the session is {self.adapter.session}; without RC the unit has stopped remote motion"]
        await self.adapter.ensure_open()
        targets = self.adapter.core.stop_targets(function, self.started)
        failed = await self.stop_functions(targets, Message(N_("stop")))
        if failed:
            withheld = self.adapter.core.withheld_since is not None
            raise CommandError("STOP FAILED: no acknowledged RS for "
                               + ", ".join(codec.FUNCTIONS[codec.Function(f)].label for f in failed)
                               + f" ({self.adapter.state.last_error}); " + (
                                   "RC is withheld, so the unit's own watchdog stops every drive within 500 ms "
                                   "(section 5)" if withheld else "RS is sent again on every poll"))
        return [codec.FUNCTIONS[codec.Function(f)].label for f in targets]

    async def jog(self, session: str, function: int, direction: int, ramp: int = -1,
                  requested_at: float | None = None) -> str:
        """Hold-to-run: +1 out, -1 in while held; 0 (release) sends RS, after the press's RE if that is on the line."""
        if direction == 0:
            fn = int(function)
            self.stop_marks[fn] = time.monotonic()  # a press whose RE has not gone out yet sends none
            lock = self.fn_locks.get(fn)
            if self.adapter.running.get(fn) == session or (lock is not None and lock.locked()) or fn in self.adapter.rs_pending:
                if not await self.send_rs(fn, Message(N_("jog released"))):
                    raise CommandError(f"STOP FAILED: RS {codec.FUNCTIONS[codec.Function(fn)].label} not acknowledged")
            return "stopped"
        return await self.run_function(session, function, codec.Motion.OUT if direction > 0 else codec.Motion.IN, ramp,
                                       requested_at=requested_at)

    async def jog_stop(self, session: str, function: int) -> str:
        """Release of a jog button: RS after the press's RE (the declared stop ``jog stop (RS)``)."""
        return await self.jog(session, function, 0)

    async def emergency_stop(self, session: str | None = None, user: str | None = None) -> str:
        """RE of function 19 (no confirmation, no control needed, in any state of the session: never refused); every
        other running function gets RS whatever the unit answers, and what cannot be stopped so is stopped by the
        unit's watchdog (RC withheld)."""
        self.stop_all_at = time.monotonic()
        c = self.adapter.controller
        who = user or (c.user if c is not None and session and c.session == session
                       else f"page {session_tag(session)}" if session else "a page")
        actions = self.adapter.core.estop_pressed(who, time.monotonic(), time.time())
        self.adapter.publish_estop()
        await self.adapter.carry_out(actions)
        self.adapter.publish_estop()
        # what ran before the press and has not had an acknowledged RS yet gets it now (under its lock)
        await self.stop_functions(sorted(self.adapter.core.held), EMERGENCY_STOP)
        e = self.adapter.core.estop
        if e is not None and e.confirmed:
            return "emergency stop active"
        return ("emergency stop ON in this tool; " + self.adapter.estop_text().split("; ", 1)[1]
                + ": no motion starts until it is released")

    async def withhold_rc(self, session: str) -> str:
        """The watchdog test (section 5), a declared and confirmed command of the controlling engineer: RC is withheld
        on purpose, so the unit must stop every drive within 500 ms and leave remote mode (error bit 22). The session
        is opened again after that, and every RE still running gets its RS."""
        self.adapter.check_holder(session)
        self.adapter.check_open()
        for action in self.adapter.core.withhold(Message(N_("withheld on purpose: the watchdog test (section 5)")), time.monotonic()):
            self.adapter.apply(action)
        self.adapter.state.event("warning", Message(N_("RC withheld on purpose (watchdog test): the unit must stop every "
                                                       "drive within 500 ms and leave remote mode")))
        return "RC withheld: the unit's watchdog must stop every drive within 500 ms"

    async def release_emergency_stop(self, session: str) -> str:
        """RS 19: the only way the emergency stop is released (never by a stop, a reopening or the dead-man rule)."""
        decision = self.adapter.core.estop_release(session)
        if not decision.ok:
            raise (ControlBusy if decision.busy else CommandError)(decision.refused)
        await self.adapter.ensure_open()
        self.adapter.check_open()
        async with self.fn_lock(ESTOP):
            await self.adapter.carry_out(decision.actions)
        self.adapter.publish_estop()
        if self.adapter.core.estop is not None:
            raise CommandError("RS 19 not acknowledged: the emergency stop is still on (RE 19 was sent again)")
        self.adapter.state.event("info", Message(N_("emergency stop released (RS 19)")))
        return "emergency stop released"

