"""The SCU's safety rules under every fault sequence: hypothesis drives devices/scu/control.py in virtual time.

A model of the unit from document 002 alone (remote mode opened by RO, kept by RC within 500 ms, its
watchdog stopping every drive and ending remote mode, RE/RS, F20) answers each request, or refuses it
(CSE, PCE for the form it does not take, PDE for F20 on a V2B0 unit, PE outside remote mode), or loses
it (request or answer). A shell as thin as the adapter's carries the core's actions out on it: the RC
thread every 200 ms, the poll every 200 ms, the dead-man supervisor every 50 ms. Operators take control,
run functions, stop, press and release the emergency stop, release the unit (RA), stop beating, leave.

Invariants after every step:

- nothing the tool believes stopped moves on the unit (the core never forgets a running function);
- no motion continues more than 500 ms after the controlling operator's lease lapsed, whatever the unit
  answers (RC is withheld at the lapse, so at worst the unit's own watchdog stops it);
- a stop that is refused or unanswered ends with the unit stopped by its own watchdog within 500 ms of the
  failure, and it is reported (STOP FAILED);
- the emergency stop, once pressed, is never refused and stays on until its explicit release is
  acknowledged; while it is on, no motion RE reaches the unit;
- RS 19 reaches the unit only from the explicit release.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import pytest
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, rule

from devices.control import ControlChanged, LeaseState, Report
from devices.scu import codec
from devices.scu.control import (ESTOP, MOTION, OpenSession, Outcome, ScuControl, SendEstop, SendRS, WithholdRC)

WATCHDOG_S = codec.WATCHDOG_S
RC_PERIOD_S = codec.KEEP_ALIVE_PERIOD_S
POLL_S = 0.2
BEAT_S = 0.05
ANSWER_S = 0.005  # an answered request takes this long on the line
TIMEOUT_S = 0.3  # a lost one this long (the line's timeout)
SLACK_S = 0.05  # the granularity of the virtual clock's steps and the requests in flight
F1, F2, BUZZER = 0, 1, int(codec.Function.BUZZER)


@dataclass
class UnitModel:
    """An SCU as document 002 describes it, with the readings a real unit may follow."""

    rs_refusal: Outcome | None = None  # every RS answered with this (CSE, PE) instead of executed
    rs_three_bytes_only: bool = False  # PCE to the two-byte RS (table 3 lists P2 and P3)
    ro_two_bytes_only: bool = False  # PCE to the one-byte RO (table 3 lists Safety_ID and para_ID[0])
    v2b0: bool = False  # no F20: RE/RS 19 answered PDE (table 8: from V2B1)
    lose_next: int = 0  # the next N requests are lost (alternately before and after they are executed)
    line_dropped: bool = False
    remote: bool = False
    last_rc: float = 0.0
    moving: dict[int, float] = field(default_factory=dict)  # fnc_ID -> since
    estop: bool = False
    watchdog_trips: list[float] = field(default_factory=list)
    log: list[tuple[float, str, int]] = field(default_factory=list)
    _lost_count: int = 0

    def check_watchdog(self, now: float) -> None:
        if self.remote and now - self.last_rc > WATCHDOG_S:
            self.remote = False
            self.moving.clear()  # Safety_ID 1: every motion stopped (table 3, RO)
            self.estop = False  # F20 is a remote function: it ends with remote mode (the reading that asks most of the tool)
            self.watchdog_trips.append(self.last_rc + WATCHDOG_S)

    def request(self, kind: str, fn: int = -1, *, form: int = 0, now: float) -> Outcome:
        """One request; returns how it was answered (LOST: no answer)."""
        self.check_watchdog(now)
        if self.line_dropped:
            return Outcome.LOST
        if self.lose_next:
            self.lose_next -= 1
            self._lost_count += 1
            if self._lost_count % 2:
                return Outcome.LOST  # the request itself was lost: nothing executed
            self._execute(kind, fn, form, now)  # executed, its answer lost
            return Outcome.LOST
        return self._execute(kind, fn, form, now)

    def _execute(self, kind: str, fn: int, form: int, now: float) -> Outcome:
        self.log.append((now, kind, fn))
        if kind == "RO":
            if self.ro_two_bytes_only and form != 2:
                return Outcome.PCE
            self.remote, self.last_rc = True, now  # (no RC yet: only RC, RA, RO until it comes)
            return Outcome.ACK
        if kind == "RA":
            self.remote = False
            self.estop = False
            self.moving.clear()
            return Outcome.ACK
        if not self.remote:
            return Outcome.PE
        if kind == "RC":
            self.last_rc = now
            return Outcome.ACK
        if kind == "RE":
            if fn == ESTOP:
                if self.v2b0:
                    return Outcome.PDE
                self.estop = True
                self.moving.clear()
                return Outcome.ACK
            if fn in MOTION and self.estop:
                return Outcome.PE
            if fn in MOTION:
                self.moving.setdefault(fn, now)
            return Outcome.ACK
        if kind == "RS":
            if fn == ESTOP and self.v2b0:
                return Outcome.PDE
            if self.rs_three_bytes_only and form != 3:
                return Outcome.PCE
            if self.rs_refusal is not None:
                return self.rs_refusal
            if fn == ESTOP:
                self.estop = False
            self.moving.pop(fn, None)
            return Outcome.ACK
        return Outcome.ICE


class WatchedLease(LeaseState):
    """The core's lease, noting every end of it while the core still holds a function."""

    def __init__(self, shell: Shell):
        super().__init__()
        self.shell = shell

    def revoke(self) -> None:
        if self.shell.core.held:
            self.shell.ended_with_held.append(self.shell.core.held)
        super().revoke()


class Shell:
    """What the adapter does with the core's actions, on the unit model, in virtual time."""

    def __init__(self, unit: UnitModel):
        self.unit = unit
        self.core = ScuControl(lease=WatchedLease(self))
        self.now = 0.0
        self.reports: list[tuple[float, str, str]] = []
        self.stop_failed_at: list[float] = []
        self.withheld_at: list[float] = []
        self.started: set[int] = set()
        self.next_rc = 0.0
        self.next_poll = 0.0
        self.next_beat = 0.0
        self.alive: set[str] = set()
        self.rs19_allowed = False
        self.last_answer = 0.0
        # the line's thread stops what is held once the lease is not valid: the core ends the lease only when nothing is
        # held any more (a lease ended beside a held function was a lapse that never was, 2026-11-29)
        self.ended_with_held: list[frozenset[int]] = []

    # -- the line ---------------------------------------------------------------------------------------------
    def send(self, kind: str, fn: int = -1, form: int = 0) -> Outcome:
        if kind == "RE" and fn in MOTION:
            assert self.core.estop is None, "a motion RE went out while the emergency stop is on"
        executed_at = self.now
        outcome = self.unit.request(kind, fn, form=form, now=self.now)
        self.now += TIMEOUT_S if outcome == Outcome.LOST else ANSWER_S
        if outcome != Outcome.LOST:
            self.last_answer = executed_at  # what the answer says is the unit's state at that moment
        elif self.now - self.last_answer > WATCHDOG_S:  # the adapter's rule: silent for 500 ms, the session is lost
            self.carry(self.core.lost("no answer for more than 500 ms", self.now))
        self.unit.check_watchdog(self.now)
        return outcome

    # -- carrying actions out -----------------------------------------------------------------------------------
    def carry(self, actions) -> None:
        todo = list(actions)
        while todo:
            action = todo.pop(0)
            if isinstance(action, Report):
                self.reports.append((self.now, action.level, action.text))
                if action.text.startswith("STOP FAILED"):
                    self.stop_failed_at.append(self.now)
            elif isinstance(action, ControlChanged):
                pass  # the adapter publishes who holds control
            elif isinstance(action, WithholdRC):
                self.withheld_at.append(self.now)
            elif isinstance(action, SendRS):
                assert action.fn != ESTOP or self.rs19_allowed, "RS 19 sent by something other than its release"
                outcome = self.send("RS", action.fn, 3 if action.three_bytes else 2)
                todo[:0] = self.core.rs_answered(action, outcome, self.now)
            elif isinstance(action, SendEstop):
                todo[:0] = self.core.estop_answered(self.send("RE", ESTOP), self.now)
            elif isinstance(action, OpenSession):
                todo[:0] = self.open(forced=action.forced)
            else:
                raise AssertionError(f"unknown action {action!r}")

    def open(self, forced: bool = False) -> list:
        if self.core.may_open(self.now, forced):
            return []
        self.core.opening()
        outcome = self.send("RO", form=2 if self.core.ro_two_bytes else 1)
        if outcome != Outcome.ACK and self.core.ro_refused(outcome):
            outcome = self.send("RO", form=2)
        if outcome == Outcome.ACK:
            outcome = self.send("RC")
        if outcome != Outcome.ACK:
            self.core.open_failed(f"RO/RC: {outcome.value}", self.now, answered_before=True)
            return self.core.estop_unreachable(outcome.value, self.now) if forced else []
        return self.core.opened(self.now)

    # -- the clocks of the adapter: RC thread, poll, dead-man supervisor ---------------------------------------------
    def advance(self, seconds: float) -> None:
        end = self.now + seconds
        while self.now < end:
            self.now = min(end, min(self.next_rc, self.next_poll, self.next_beat))
            self.unit.check_watchdog(self.now)
            if self.now >= self.next_beat:
                self.next_beat = self.now + BEAT_S
                self.carry(self.core.beat(self.alive, self.now))
            if self.now >= self.next_rc:
                self.next_rc = self.now + RC_PERIOD_S
                self.carry(self.core.tick(self.now))  # the thread looks at the lease before every RC
                if self.core.rc_allowed(self.now):
                    outcome = self.send("RC")
                    if outcome == Outcome.PE:
                        self.carry(self.core.lost("PE to RC", self.now))
            if self.now >= self.next_poll:
                self.next_poll = self.now + POLL_S
                self.poll()

    def poll(self) -> None:
        core = self.core
        if core.needs_session(False) and core.phase != "open":
            self.carry(self.open())
        elif core.phase == "open":
            for fn in sorted(core.rs_pending):
                self.carry([SendRS(fn, core.rs_pending[fn], three_bytes=core.rs_three_bytes)])

    # -- operator commands, as the adapter runs them -----------------------------------------------------------------
    def run(self, session: str, fn: int) -> str:
        core = self.core
        decision = core.check_run(session, fn)
        if not decision.ok:
            return decision.refused
        if core.phase != "open":
            self.carry(self.open())
            if core.phase != "open":
                return "the session is not open"
        core.re_sent(session, fn, self.now)
        self.started.add(fn)
        self.alive.add(session)
        self.carry(core.re_answered(fn, self.send("RE", fn)))
        return ""

    def stop(self, fn: int | None) -> None:
        core = self.core
        if core.phase != "open" and not core.running and not core.rs_pending:
            return
        if core.phase != "open":
            self.carry(self.open())
        targets = core.stop_targets(fn, self.started)
        self.carry([SendRS(f, "stop", three_bytes=core.rs_three_bytes) for f in targets])

    def estop(self, who: str) -> None:
        self.carry(self.core.estop_pressed(who, self.now, 0.0))

    def release_estop(self, session: str) -> None:
        decision = self.core.estop_release(session)
        if decision.ok:
            if self.core.phase != "open":
                self.carry(self.open())
            self.rs19_allowed = True
            self.carry(decision.actions)
            self.rs19_allowed = False

    def release_unit(self) -> None:
        core = self.core
        self.carry([SendRS(fn, "release of the SCU", three_bytes=core.rs_three_bytes) for fn in sorted(core.held)])
        self.send("RA")
        core.released()


class ScuSafety(RuleBasedStateMachine):
    def __init__(self):
        super().__init__()
        self.unit = UnitModel()
        self.shell = Shell(self.unit)
        self.gone_at: dict[str, float] = {}  # session -> when it stopped beating
        self.estop_pressed = False

    @initialize()
    def engineer_takes_control(self):
        """Most sequences start where the trouble starts: an engineer holds control and the session is open."""
        self.take("s1")
        self.shell.advance(0.5)

    # -- the unit's readings and faults ----------------------------------------------------------------------------
    @rule(refusal=st.sampled_from([None, Outcome.CSE, Outcome.PE]), three_byte_rs=st.booleans(),
          two_byte_ro=st.booleans(), v2b0=st.booleans())
    def unit_reads_the_document_so(self, refusal, three_byte_rs, two_byte_ro, v2b0):
        """Which reading the unit follows, and whether it refuses every RS (CSE: noise, PE: its mode)."""
        self.unit.rs_refusal = refusal
        self.unit.rs_three_bytes_only = three_byte_rs
        self.unit.ro_two_bytes_only = two_byte_ro
        self.unit.v2b0 = v2b0

    @rule(n=st.integers(1, 4))
    def requests_lost(self, n):
        self.unit.lose_next = n

    @rule(dropped=st.booleans())
    def line(self, dropped):
        self.unit.line_dropped = dropped

    # -- operators ---------------------------------------------------------------------------------------------------
    @rule(session=st.sampled_from(["s1", "s2"]))
    def take(self, session):
        self.shell.core.control.take(session, session, self.shell.now, 0.0)
        self.shell.alive.add(session)
        self.gone_at.pop(session, None)

    @rule(session=st.sampled_from(["s1", "s2"]), fn=st.sampled_from([F1, F2, BUZZER]))
    def run(self, session, fn):
        if session in self.gone_at:
            return  # a page that stopped beating presses nothing
        self.shell.run(session, fn)

    @rule(fn=st.sampled_from([None, F1, F2]))
    def stop(self, fn):
        self.shell.stop(fn)

    @rule(who=st.sampled_from(["s1", "s2", "viewer"]))
    def press_estop(self, who):
        self.shell.estop(who)
        self.estop_pressed = True

    @rule(session=st.sampled_from(["s1", "s2"]))
    def release_estop(self, session):
        self.shell.release_estop(session)
        if self.shell.core.estop is None:
            self.estop_pressed = False

    @rule()
    def release_unit(self):
        self.shell.release_unit()

    @rule()
    def reopen(self):
        self.shell.core.reopen_asked()
        self.shell.carry(self.shell.open())

    @rule(session=st.sampled_from(["s1", "s2"]))
    def page_stops_beating(self, session):
        if session in self.shell.alive:
            self.shell.alive.discard(session)
            self.gone_at[session] = self.shell.now

    @rule(session=st.sampled_from(["s1", "s2"]))
    def page_gone(self, session):
        """The worker's dead-man supervisor has noticed the page is gone: RS now, control released."""
        self.page_stops_beating(session)
        self.shell.carry(self.shell.core.session_lost(session, "the page is gone"))

    @rule(ms=st.integers(10, 400))
    def time_passes(self, ms):
        self.shell.advance(ms / 1000)

    @rule(s=st.floats(0.5, 3.0))
    def a_while_passes(self, s):
        self.shell.advance(s)

    # -- invariants --------------------------------------------------------------------------------------------------
    @invariant()
    def nothing_moves_that_the_core_thinks_stopped(self):
        core = self.shell.core
        for fn in self.unit.moving:
            assert fn in core.running or fn in core.rs_pending, (fn, core.running, core.rs_pending)

    @invariant()
    def no_motion_long_after_its_operator_is_gone(self):
        core, now = self.shell.core, self.shell.now
        for fn, since in self.unit.moving.items():
            owner = core.running.get(fn)
            gone = self.gone_at.get(owner) if owner else None
            if gone is None or since > gone:
                continue
            # the lease lapses LEASE_S after the last renewal; RC is withheld then, the watchdog trips 500 ms later;
            # requests in flight (an RS timing out) delay nothing the unit does by itself
            limit = gone + core.control.lease.valid_s + WATCHDOG_S + RC_PERIOD_S + TIMEOUT_S + SLACK_S
            assert now <= limit, f"{codec.FUNCTIONS[codec.Function(fn)].label} still moves {now - gone:.2f} s after its operator left"

    @invariant()
    def a_failed_stop_ends_with_the_watchdog(self):
        core, now = self.shell.core, self.shell.now
        if core.estop is not None and core.estop.confirmed:
            return  # F20 on in the unit keeps every drive stopped
        for since in self.unit.moving.values():
            failures = [t for t in self.shell.stop_failed_at if t >= since]
            if failures:
                assert now <= failures[0] + WATCHDOG_S + RC_PERIOD_S + TIMEOUT_S + SLACK_S, (
                    f"a stop failed at {failures[0]:.2f} s and the drive still moves at {now:.2f} s")

    @invariant()
    def the_lease_ends_only_when_nothing_is_held(self):
        assert not self.shell.ended_with_held, f"the lease ended while {sorted(self.shell.ended_with_held[0])} was held"

    @invariant()
    def the_emergency_stop_stays_on_until_released(self):
        if self.estop_pressed:
            assert self.shell.core.estop is not None

    @invariant()
    def the_emergency_stop_is_shown_confirmed_only_while_the_unit_has_it_on(self):
        estop = self.shell.core.estop
        trips = self.unit.watchdog_trips
        if trips and self.shell.last_answer <= trips[-1]:
            return  # the unit has not answered since its watchdog tripped: the tool cannot know yet
        if estop is not None and estop.confirmed and self.shell.core.phase == "open":
            assert self.unit.estop, "the tool shows F20 confirmed while the unit's is off"

    @invariant()
    def the_emergency_stop_stops_every_drive(self):
        core = self.shell.core
        if core.estop is None or not self.unit.moving:
            return
        # pressed: RE 19 (the unit stops all) or RS to each; refused or lost: RC withheld, the watchdog stops all
        pressed_at = max((t for t, level, text in self.shell.reports if "emergency stop (function 19, F20) pressed" in text),
                         default=None)
        if pressed_at is not None and min(self.unit.moving.values()) < pressed_at:
            assert self.shell.now <= pressed_at + 2.0, (
                "the emergency stop left a drive running")


def controlled(unit: UnitModel, beating: bool = False) -> Shell:
    """A shell on ``unit`` whose session s1 has taken control (its browser beating, with ``beating``), 0.5 s on."""
    shell = Shell(unit)
    shell.core.control.take("s1", "anna", 0.0, 0.0)
    if beating:
        shell.alive.add("s1")
    shell.advance(0.5)
    return shell


SCU_SETTINGS = settings(derandomize=True, max_examples=60, stateful_step_count=40, deadline=None)
TestScuSafety = ScuSafety.TestCase
TestScuSafety.settings = SCU_SETTINGS
SAFETY_MACHINES = {"scu": ScuSafety}


def test_no_motion_re_reaches_the_unit_while_the_emergency_stop_is_on():
    """Checked on the unit's log: after a press, the only RE of a motion function follows an acknowledged release."""
    unit = UnitModel(v2b0=True)
    shell = controlled(unit, beating=True)
    assert shell.run("s1", F1) == ""
    shell.estop("viewer")
    assert shell.core.estop is not None and not shell.core.estop.confirmed
    assert F1 not in unit.moving, "RE 19 refused (V2B0) left F1 running"
    assert "emergency stop" in shell.run("s1", F1)
    shell.advance(2.0)
    assert not [e for e in unit.log if e[1] == "RE" and e[2] in MOTION and e[0] > 0.5 + ANSWER_S * 3]


@pytest.mark.parametrize("refusal", [Outcome.CSE, Outcome.PE])
def test_a_stop_never_acknowledged_withholds_rc_until_the_watchdog_stopped_the_drive(refusal):
    """Issue 40: every RS refused, browser gone: the reopen's RO + RC fed the watchdog and F1 drove on."""
    unit = UnitModel(rs_refusal=refusal)
    shell = controlled(unit, beating=True)
    shell.run("s1", F1)
    shell.advance(0.3)
    shell.alive.clear()  # the browser is gone
    shell.carry(shell.core.session_lost("s1", "the page is gone"))
    gone = shell.now
    shell.advance(6.0)
    assert not unit.moving, "F1 still drives 6 s after its operator left"
    assert unit.watchdog_trips and unit.watchdog_trips[0] <= gone + WATCHDOG_S + TIMEOUT_S * 3 + SLACK_S
    assert any(text.startswith("STOP FAILED") for _, _, text in shell.reports)


def test_the_emergency_stop_is_never_refused_in_a_released_session():
    unit = UnitModel()
    shell = controlled(unit)
    shell.release_unit()
    assert shell.core.phase == "released"
    shell.estop("viewer")
    assert unit.estop and shell.core.estop is not None and shell.core.estop.confirmed


def test_a_unit_that_takes_only_the_three_byte_rs_is_stopped():
    unit = UnitModel(rs_three_bytes_only=True)
    shell = controlled(unit, beating=True)
    shell.run("s1", F1)
    shell.stop(F1)
    assert not unit.moving and not shell.core.running and shell.core.rs_three_bytes


def test_a_unit_that_takes_only_the_two_byte_ro_opens_a_session():
    unit = UnitModel(ro_two_bytes_only=True)
    shell = controlled(unit)
    assert shell.core.phase == "open" and shell.core.ro_two_bytes


def test_stopping_one_function_keeps_the_lease_of_the_other():
    """F1 and F2 run; F1's RS is acknowledged: F2 is still held, so its lease goes on (the line's thread would
    otherwise take the ended lease for a lapse and stop F2 with RC withheld)."""
    shell = controlled(UnitModel(), beating=True)
    assert shell.run("s1", F1) == "" and shell.run("s1", F2) == ""
    shell.stop(F1)
    assert shell.core.held == {F2} and shell.core.control.lease.granted and not shell.ended_with_held
    shell.advance(1.0)
    assert F2 in shell.unit.moving, "F2 was stopped with F1"
