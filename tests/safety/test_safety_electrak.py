"""The Electrak's safety rules (devices/electrak/control.py) under random operator actions and faults, in virtual time.

A hypothesis ``RuleBasedStateMachine`` drives the control core the way the adapter and the worker do: two
engineers' pages and a viewer act (take, set target, Go, jog and its release, stop, override with and without
its confirmation, release), pages stop beating and beat again, disconnect, come back or are gone, another
sender of 0x06 appears, actuators disappear and come back, the program stalls, and time passes in steps of
10-400 ms. A model of the worker carries the core's actions out: python-can's periodic sender (every 100 ms,
on a thread of its own, the stop form once its lease is not valid), the dead-man supervisor (every 50 ms;
a holder silent for 0.4 s is lost), the lease the sender checks. Every control telegram that leaves is
checked as it leaves, and the state after every step:

- no telegram with enable (or override/reset) leaves more than 0.5 s after the operator who started it stopped
  beating or is gone, while this program runs on time. If the event loop stalls meanwhile, the lease stops it:
  the supervisor renews it while it heard the page within 0.4 s, so the stop form leaves at most 0.4 + 0.05 +
  0.35 = 0.8 s after the page's last beat (a stall and a silent browser at once). A supervisor that tells each
  page's last beat (a mapping) makes the lease count from it: then 0.5 s holds across a stall too (both are run);
- enable is never sent while the lease is not valid;
- a viewer changes nothing (its stop only clears enable and override);
- override/reset is never sent without its confirmation, and no longer than its pulse (or the lease) after it;
- Go is never granted, and enable never sent, with fewer actuators heard than configured after an override/reset
  that counted fewer;
- another sender of 0x06: control is released at once and not taken while it sends.

``SAFETY_MACHINES`` lets bench/safety_properties.py run the same machine with many more sequences.
"""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, rule

from devices.commands import commands_of
from devices.control import LEASE_S, LeaseChange, LeaseState
from devices.electrak import codec
from devices.electrak.control import (
    OVERRIDE_PULSE_S,
    ElectrakControl,
    ModifyPeriodic,
    Send,
    StartPeriodic,
    StopPeriodic,
    is_stop,
    stop_form,
)
from devices.sendpolicy import BusDevice, check_can

CONFIGURED = 2
LIMITS = codec.Limits.of([codec.Actuator("HD24", "B026", 300.0)] * CONFIGURED)
PERIOD_MS = 100  # the control telegram (codec.CONTROL_PERIOD_S)
SUPERVISE_MS = 50  # the dead-man supervisor's tick (app.worker)
DEADMAN_TIMEOUT_MS = 400  # a holder silent this long is lost (app.worker.deadman.DEADMAN_TIMEOUT_S)
BOUND_S = 0.5  # ARCHITECTURE.md rule 7: motion stops within 0.5 s of the controlling browser going away
ENGINEERS = ("A", "B")
VIEWER = "V"


class Page:
    """One browser page: its session (a new one after it was gone), whether it beats and is connected."""

    def __init__(self, name: str):
        self.name, self.generation = name, 0
        self.beating = True
        self.connected = True
        self.gone = False
        self.quiet_since: float | None = None  # when it stopped beating, disconnected or went

    @property
    def session(self) -> str:
        return f"{self.name}{self.generation}"

    def live(self) -> bool:
        return self.beating and self.connected and not self.gone

    def alive_until(self, t: float) -> float:
        return t if self.live() else self.quiet_since


class ElectrakSafety(RuleBasedStateMachine):
    def __init__(self):
        super().__init__()
        self.core = ElectrakControl(LIMITS, CONFIGURED)
        self.ms = 1000  # virtual time in whole milliseconds
        self.core.bus_opened(0.0)
        self.core.actuators_heard(CONFIGURED, self.t)
        self.heard = CONFIGURED
        self.pages = {name: Page(name) for name in (*ENGINEERS, VIEWER)}
        self.last_beat: dict[str, float] = {}  # session -> the supervisor's last beat of it
        self.holding_since: dict[str, float] = {}  # holders it never heard beating -> since when it saw them holding
        self.sender_lease = LeaseState(LEASE_S)  # the periodic sender's lease, as the adapter's actions set it
        self.periodic: codec.ControlFrame | None = None
        self.next_period = 0
        self.next_tick = self.ms
        self.mover: Page | None = None  # the page whose press started what runs
        self.override_confirmed_at: float | None = None
        self.count_reset = False  # an override/reset counted fewer actuators than configured
        self.sent: list[tuple[float, codec.ControlFrame]] = []
        self.stalls: list[tuple[float, float]] = []  # when the event loop ran nothing
        self.tells_beats = False  # the supervisor tells each page's last beat (the lease counts from it)

    @initialize(tells=st.booleans())
    def supervisor(self, tells):
        self.tells_beats = tells

    @property
    def t(self) -> float:
        return self.ms / 1000

    # -- the worker, as a model: the adapter's shell, the periodic sender, the supervisor ---------------------
    def carry(self, actions) -> None:
        t = self.t
        for a in actions:
            if isinstance(a, Send):
                self.emit(t, a.frame)
            elif isinstance(a, StartPeriodic):
                self.periodic = a.frame
                self.emit(t, self.sender_form(t, a.frame))  # python-can sends the first one at once
                self.next_period = self.ms + PERIOD_MS
            elif isinstance(a, ModifyPeriodic):
                assert self.periodic is not None, "modify without a periodic sender"
                self.periodic = a.frame
                if a.send_now:
                    self.emit(t, self.sender_form(t, a.frame))
            elif isinstance(a, StopPeriodic):
                self.periodic = None
            elif isinstance(a, LeaseChange) and a.what == "grant":
                self.sender_lease.grant(a.at)
            elif isinstance(a, LeaseChange) and a.what == "renew":
                self.sender_lease.renew(a.at)
            elif isinstance(a, LeaseChange) and a.what == "revoke":
                self.sender_lease.revoke()

    def sender_form(self, t: float, frame: codec.ControlFrame) -> codec.ControlFrame:
        """What the sender puts on the bus: the frame, or its stop form while its lease is not valid."""
        if (frame.enable or frame.override) and not self.sender_lease.valid(t):
            return stop_form(frame)
        return frame

    def supervise(self) -> None:
        t = self.t
        for page in self.pages.values():
            if page.live():
                self.last_beat[page.session] = t
        self.carry(self.core.tick(t))  # the adapter's timers: the end of the override pulse, the sender's lapse
        alive = set()
        holding = self.core.holders()
        for session in list(self.holding_since):
            if session not in holding:
                del self.holding_since[session]
        for session in holding:
            last = self.last_beat.get(session)
            if last is None:  # a holder never heard beating (its connection dropped): timed from when it was first seen
                last = self.holding_since.setdefault(session, t)
            if (t - last) * 1000 > DEADMAN_TIMEOUT_MS:
                self.carry(self.core.lost(session, "dead-man: the controlling browser is silent", t))
            else:
                alive.add(session)
        if alive:
            self.carry(self.core.beat({s: self.last_beat.get(s, t) for s in alive} if self.tells_beats else alive, t))

    def advance(self, ms: int, stalled: bool = False) -> None:
        """Time passes; while ``stalled`` the event loop runs nothing (the sender's thread goes on)."""
        end = self.ms + ms
        if stalled:
            self.stalls.append((self.t, end / 1000))
        while True:
            due = [d for d in (self.next_period if self.periodic is not None else None,
                               None if stalled else self.next_tick) if d is not None]
            if not due or min(due) > end:
                break
            self.ms = min(due)
            if self.periodic is not None and self.ms == self.next_period:
                self.emit(self.t, self.sender_form(self.t, self.periodic))
                self.next_period += PERIOD_MS
            if not stalled and self.ms == self.next_tick:
                self.supervise()
                self.next_tick += SUPERVISE_MS
        self.ms = end
        if stalled:
            self.next_tick = end  # the loop runs again: its supervisor at once

    # -- what leaves, checked as it leaves ------------------------------------------------------------------
    def emit(self, t: float, frame: codec.ControlFrame) -> None:
        self.sent.append((t, frame))
        if not (frame.enable or frame.override):
            return
        mover = self.mover
        assert mover is not None, f"{frame} sent with nobody having started it"
        quiet = mover.alive_until(t)
        late = t - quiet
        # the bound holds while this program runs on time; a stall meanwhile leaves the lease to stop it: renewed while
        # the supervisor heard the page within its timeout, it runs out LEASE_S after that (see the module's note)
        stalled = any(start < t and end > quiet for start, end in self.stalls)
        bound = (DEADMAN_TIMEOUT_MS + SUPERVISE_MS) / 1000 + LEASE_S if stalled and not self.tells_beats else BOUND_S
        assert late <= bound + 1e-9, f"{frame} sent {late:.3f} s after the operator {mover.session} stopped beating or went"
        assert self.core.session.lease.valid(t) or self.sender_lease.valid(t), f"{frame} sent at {t} without a valid lease"
        if frame.enable:
            assert self.sender_lease.valid(t), f"enable sent at {t} while the sender's lease is not valid"
            assert not (self.count_reset and self.heard < CONFIGURED), \
                f"enable sent with {self.heard} of {CONFIGURED} actuators heard after an override/reset"
        if frame.override:
            at = self.override_confirmed_at
            assert at is not None and t - at <= max(OVERRIDE_PULSE_S + SUPERVISE_MS / 1000, LEASE_S) + 1e-9, \
                f"override sent at {t} without a confirmation within its pulse (confirmed at {at})"

    # -- operators ------------------------------------------------------------------------------------------
    def _engineer(self, name: str) -> Page | None:
        page = self.pages[name]
        if not page.live():
            return None  # a frozen or closed page sends nothing
        self.last_beat[page.session] = self.t  # a page beats before the command of an interaction reaches the server
        return page

    def _decided(self, decision, page: Page, moves: bool = False) -> bool:
        if decision.ok:
            if moves:
                self.mover = page
            self.carry(decision.actions)
        return decision.ok

    @rule(name=st.sampled_from(ENGINEERS))
    def take(self, name):
        page = self._engineer(name)
        if page is not None:
            foreign = self.core.foreign_sender(self.t)
            ok = self._decided(self.core.take(page.session, page.name, self.t, 0.0), page)
            assert not (ok and foreign), "control taken while another sender of 0x06 is heard"

    @rule(name=st.sampled_from(ENGINEERS), position=st.floats(0, 300), speed=st.floats(6, 32), current=st.floats(0, 12.5))
    def set_target(self, name, position, speed, current):
        page = self._engineer(name)
        if page is not None:
            self._decided(self.core.set_target(page.session, round(position, 1), round(speed, 1), round(current, 1), self.t),
                          page, moves=self.core.command.enable)

    @rule(name=st.sampled_from(ENGINEERS), position=st.floats(0, 300))
    def take_and_go(self, name, position):
        """What an engineer does most: take control (if free), set a target, Go."""
        self.take(name)
        self.set_target(name, position, 20.0, 0.0)
        self.go(name)

    @rule(name=st.sampled_from(ENGINEERS))
    def go(self, name):
        page = self._engineer(name)
        if page is not None and self._decided(self.core.go(page.session, self.t), page, moves=True):
            assert self.heard >= CONFIGURED, f"Go granted with {self.heard} of {CONFIGURED} actuators heard"

    @rule(name=st.sampled_from(ENGINEERS), direction=st.sampled_from((-1, 1)))
    def jog(self, name, direction):
        page = self._engineer(name)
        if page is not None and self._decided(self.core.jog(page.session, direction, None, self.t, 100.0), page, moves=True):
            assert self.heard >= CONFIGURED, f"jog granted with {self.heard} of {CONFIGURED} actuators heard"

    @rule(name=st.sampled_from(ENGINEERS))
    def jog_release(self, name):
        page = self._engineer(name)
        if page is not None:
            self.carry(self.core.jog_release(page.session, self.t, 100.0))

    @rule(name=st.sampled_from((*ENGINEERS, VIEWER)))
    def stop(self, name):
        page = self.pages[name]
        if page.live():
            self.carry(self.core.stop(page.session, self.t))
            assert not (self.core.command.enable or self.core.command.override)

    @rule(name=st.sampled_from(ENGINEERS), confirmed=st.booleans())
    def override(self, name, confirmed):
        page = self._engineer(name)
        if page is None:
            return
        before = self.core.command
        decision = self.core.override(page.session, True, self.t, confirmed=confirmed)
        if not confirmed:
            assert not decision.ok and self.core.command == before, "override/reset without its confirmation"
            return
        if decision.ok:
            self.override_confirmed_at = self.t
            self.count_reset = self.heard < CONFIGURED
        self._decided(decision, page, moves=True)

    @rule(name=st.sampled_from(ENGINEERS))
    def release(self, name):
        page = self._engineer(name)
        if page is not None:
            self.carry(self.core.release(page.session, "released", self.t))

    # -- a viewer: the gate lets it run stops only; nothing it does changes what is sent but a stop ----------------
    @rule(command=st.sampled_from(("take control", "set target", "go", "jog", "jog stop", "override", "release control",
                                   "stop")))
    def viewer(self, command):
        page = self.pages[VIEWER]
        if not page.live():
            return
        before = self.snapshot()
        if commands_of("electrak")[command].open:  # what every role may run: reads and stops
            session, t = page.session, self.t
            if command == "stop":
                self.carry(self.core.stop(session, t))
            elif command == "jog stop":
                self.carry(self.core.jog_release(session, t, 100.0))
            else:
                self.carry(self.core.release(session, "released", t))
        after = self.snapshot()
        if command == "stop":
            command, holder, sending, _running, reset = before  # a stop ends what runs: its lease too
            assert after == (stop_form(command), holder, sending, False, reset), \
                "a viewer's stop changed more than enable and override"
        else:
            assert after == before, f"a viewer's {command} changed {before} -> {after}"

    def snapshot(self) -> tuple:
        c = self.core
        return (c.command, c.holder, c.sending, c.session.running, c.count_reset_to)

    # -- pages' lives -----------------------------------------------------------------------------------------
    @rule(name=st.sampled_from((*ENGINEERS, VIEWER)))
    def beats_stop(self, name):
        page = self.pages[name]
        if page.live():
            page.beating, page.quiet_since = False, self.t

    @rule(name=st.sampled_from((*ENGINEERS, VIEWER)))
    def beats_again(self, name):
        page = self.pages[name]
        if not page.beating and page.connected and not page.gone:
            page.beating, page.quiet_since = True, None
            self.carry(self.core.back(page.session))

    @rule(name=st.sampled_from((*ENGINEERS, VIEWER)))
    def disconnect(self, name):
        page = self.pages[name]
        if page.connected and not page.gone:
            if page.live():
                page.quiet_since = self.t
            page.connected = False
            self.last_beat.pop(page.session, None)
            self.carry(self.core.disconnected(page.session, "the controlling browser disconnected", self.t))

    @rule(name=st.sampled_from((*ENGINEERS, VIEWER)))
    def reconnect(self, name):
        page = self.pages[name]
        if not page.connected and not page.gone:
            page.connected, page.beating, page.quiet_since = True, True, None
            self.carry(self.core.back(page.session))

    @rule(name=st.sampled_from((*ENGINEERS, VIEWER)))
    def page_gone(self, name):
        page = self.pages[name]
        if not page.gone:
            if page.live():
                page.quiet_since = self.t
            page.gone = True
            self.carry(self.core.lost(page.session, "the controlling browser's page is gone", self.t))

    @rule(name=st.sampled_from((*ENGINEERS, VIEWER)))
    def new_page(self, name):
        page = self.pages[name]
        if page.gone:
            page.generation += 1
            page.gone, page.connected, page.beating, page.quiet_since = False, True, True, None

    # -- the bus and the plant --------------------------------------------------------------------------------
    @rule(rarely=st.integers(0, 5))
    def foreign_sender(self, rarely):
        if rarely:  # one step in six: another sender of 0x06 ends every control, so the others get their turn
            return
        self.carry(self.core.foreign_control(self.t))
        assert self.core.holder is None and not self.core.sending, "control kept while another sender of 0x06 sends"

    @rule(heard=st.sampled_from((CONFIGURED, CONFIGURED, CONFIGURED - 1, CONFIGURED - 1, 0)))
    def actuators(self, heard):
        self.heard = heard
        self.carry(self.core.actuators_heard(heard, self.t))

    @rule(ms=st.integers(10, 400))
    def wait(self, ms):
        self.advance(ms)

    @rule(ms=st.integers(100, 1500))
    def stall(self, ms):
        self.advance(ms, stalled=True)

    # -- after every step -----------------------------------------------------------------------------------
    @invariant()
    def enable_only_under_a_valid_lease(self):
        c, t = self.core, self.t
        if c.command.enable and c.session.lease.lapsed_at is None and c.session.lease.until is not None:
            assert c.session.holder is not None, "enable wanted with nobody in control"
        if c.sending:
            assert c.holder is not None and self.periodic is not None
        wanted = c.telegram(t)
        if wanted.enable or wanted.override:
            assert c.session.lease.valid(t) and self.sender_lease.valid(t)

    @invariant()
    def nobody_in_control_sends_no_keepalive(self):
        if self.core.holder is None:
            assert self.periodic is None


SAFETY_MACHINES = {"electrak": ElectrakSafety}

ElectrakSafety.TestCase.settings = settings(derandomize=True, max_examples=100, deadline=None, stateful_step_count=40)
TestElectrakSafety = ElectrakSafety.TestCase


# -- raw control telegrams: the policy decodes them as the command they amount to --------------------------------

LIFT = BusDevice("lift", "electrak", {"actuators": [{"model": "HD24", "gearing": "B026", "stroke_mm": 300}] * 2})


@settings(derandomize=True, max_examples=300, deadline=None)
@given(data=st.binary(min_size=8, max_size=8))
def test_a_raw_control_telegram_is_a_stop_only_with_enable_and_override_cleared(data):
    verdict = check_can([LIFT], codec.CONTROL_ID, False, data)
    if data[7] & codec.ENABLE:
        assert verdict.refused  # Go: the Electrak page only
    elif data[7] & codec.OVERRIDE:
        assert verdict.allowed and verdict.kind != "stop" and verdict.confirm  # override/reset: asked
    else:
        assert is_stop(data) and verdict.kind == "stop" and not verdict.confirm


def test_motion_stops_when_an_actuator_goes_after_an_override_that_counted_fewer():
    """After an override/reset with one actuator missing, the network's own 'Too few devices' lock is gone: the core
    stops motion itself as soon as fewer actuators are heard again, and refuses Go until all are heard."""
    core = ElectrakControl(LIMITS, CONFIGURED)
    core.bus_opened(0.0)
    core.actuators_heard(1, 0.5)
    assert core.take("s", "engineer", 1.0, 0.0).ok
    assert core.override("s", True, 1.0, confirmed=True).ok and core.count_reset_to == 1
    core.tick(1.0 + OVERRIDE_PULSE_S)
    assert "Reconnect" in core.go("s", 1.4).refused
    core.actuators_heard(2, 1.5)  # the missing one is back
    assert core.go("s", 1.5).ok and core.command.enable
    actions = core.actuators_heard(1, 1.6)
    assert not core.command.enable and any(isinstance(a, ModifyPeriodic) and not a.frame.enable for a in actions)
    assert "Reconnect" in core.jog("s", 1, None, 1.7).refused
    core.actuators_heard(2, 1.8)
    assert core.override("s", True, 1.9, confirmed=True).ok and core.count_reset_to is None  # all counted again


SAFETY_PROPERTIES = {"electrak": [test_a_raw_control_telegram_is_a_stop_only_with_enable_and_override_cleared]}


def test_the_lease_counts_from_the_pages_last_beat_when_the_supervisor_tells_it():
    """A page that froze at 1.0 s just before this program stalls: renewed from its last beat, the lease ends at
    1.35 s, and the sender carries only the stop form from then on, whatever the supervisor renewed meanwhile."""
    core = ElectrakControl(LIMITS, CONFIGURED)
    core.bus_opened(0.0)
    core.actuators_heard(CONFIGURED, 0.5)
    assert core.take("s", "engineer", 1.0, 0.0).ok and core.go("s", 1.0).ok
    for tick in range(1, 7):  # the supervisor still counts the page alive (silent < 0.4 s); then the program stalls
        core.beat({"s": 1.0}, 1.0 + tick * 0.05)
    assert core.telegram(1.35).enable and not core.telegram(1.36).enable
    told_nothing = ElectrakControl(LIMITS, CONFIGURED)
    told_nothing.bus_opened(0.0)
    told_nothing.actuators_heard(CONFIGURED, 0.5)
    assert told_nothing.take("s", "engineer", 1.0, 0.0).ok and told_nothing.go("s", 1.0).ok
    for tick in range(1, 7):
        told_nothing.beat({"s"}, 1.0 + tick * 0.05)
    assert told_nothing.telegram(1.6).enable  # renewed at 1.3: a stall then keeps enable until 1.65
