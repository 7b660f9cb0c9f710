"""The CAN-M3IO's safety rules (devices/m3io/control.py) under every fault sequence, proven by a stateful
property test in virtual time, and the defects found with it (issue 40).

Invariants after every step of random operator actions (two engineers' pages and a viewer), beats that
stop, pages that disconnect, come back or are gone, another master on the bus, the module's answers, the
variant check, and time in 10-400 ms steps (the program may stall meanwhile):

- no mains output (SSR) is on in what this tool sends more than 0.5 s after the controlling operator is
  gone (silent, disconnected or lost), whatever happens;
- no SSR is on in what this tool sends while the sender's lease is not valid;
- what the sender carries (from the core's actions alone) is what the core says it carries;
- an output on belongs to the session in control;
- a viewer changes nothing;
- this tool never sends DigOut after another master's DigOut was heard (release, never fight), and an
  answer to its own request is no sign of another master.
"""

from __future__ import annotations

import asyncio
import contextlib

import pytest
from hypothesis import settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule

from devices.control import STOP_DEADLINE_S, LeaseState
from devices.m3io import codec
from devices.m3io.codec import Variant
from devices.m3io.control import (ANSWER_WINDOW_S, LISTEN_S, DigOut, EndKeepAlive, KeepAlive, LeaseChange, M3ioControl,
                                  mains_on, stop_form)
from devices.sendpolicy import BusDevice, check_can

SESSIONS = {"eng-1": "engineer", "eng-2": "engineer", "tablet": "viewer"}
OUTPUTS = ["LED", "SSR1-3", *(f"SSR{i}" for i in range(1, 7))]  # of every variant: one the module lacks is refused
DIG_OUT = 0x422
SUPERVISOR_TIMEOUT_S = 0.4  # app.worker.deadman.DEADMAN_TIMEOUT_S: a page silent this long is lost
BEAT_S = 0.1  # a page beats every 100 ms (app.worker.deadman.BEAT_PERIOD_S)
SUB_STEP_S = 0.05  # the supervisor's period (app.worker.loophealth.SUPERVISE_PERIOD_S)


class M3ioSafety(RuleBasedStateMachine):
    """Random operators, pages, masters and time against :class:`M3ioControl`, its actions carried out on a
    model of python-can's cyclic sender with its lease."""

    variant = Variant.HM

    def __init__(self):
        super().__init__()
        self.core = M3ioControl(self.variant, DIG_OUT)
        self.core.listen_left(0.0, 0)  # the bus opened at 0: listened long enough by now
        self.now = 1.0
        self.beating = {s for s, role in SESSIONS.items() if role == "engineer"}
        self.connected = set(SESSIONS)
        self.last_alive = dict.fromkeys(SESSIONS, 0.0)  # the operator's last beat or press
        self.gone_at: dict[str, float] = {}  # operator gone (silent, disconnected, lost) -> when
        self.last_beat = dict.fromkeys(SESSIONS, 0.0)
        self.real_foreign_at: float | None = None
        # the sender as the actions left it (app.can_bus: python-can's cyclic task with the lease)
        self.sending: bytes | None = None
        self.leased = False
        self.sending_since = 0.0
        self.lease = LeaseState(self.core.session.lease.valid_s)

    # -- carrying the actions out, as the adapter does ----------------------------------------------------------
    def _carry_out(self, actions) -> None:
        for action in actions:
            if isinstance(action, KeepAlive):
                self.sending, self.leased, self.sending_since = action.data, action.leased, self.now
            elif isinstance(action, DigOut):
                assert self.sending is not None, "DigOut with no keep-alive running"
                self.sending = action.data
            elif isinstance(action, EndKeepAlive):
                self.sending = None
            elif isinstance(action, LeaseChange):
                if action.what == "grant":
                    self.lease.grant(self.now)
                elif action.what == "revoke":
                    self.lease.revoke()
                elif not (self.lease.valid(self.now) and self.lease.renew(action.at)):
                    self._carry_out(self.core.sender_lapsed(self.now))

    def _wire(self) -> bytes | None:
        if self.sending is None:
            return None
        if self.leased and not self.lease.valid(self.now):
            return stop_form(self.sending)
        return self.sending

    def _operator(self, session: str, decision_or_actions) -> None:
        actions = getattr(decision_or_actions, "actions", decision_or_actions)
        if SESSIONS[session] != "engineer":
            assert not actions or all(not isinstance(a, KeepAlive) for a in actions)
        self._carry_out(actions)

    def _snapshot(self):
        holder = self.core.holder
        return (holder and (holder.session, holder.disconnected), dict(self.core.outputs), dict(self.core.owners),
                self.core.serving)

    def _time(self, dt: float, loop_runs: bool) -> None:
        """``dt`` passes: pages beat every 100 ms; the supervisor (when the loop runs) renews the lease of the
        pages that beat and stops what a page silent for 0.4 s holds."""
        end = self.now + dt
        while self.now < end - 1e-9:
            self.now = min(end, self.now + SUB_STEP_S)
            for s in self.beating & self.connected:
                if self.now - self.last_beat[s] >= BEAT_S - 1e-9:
                    self.last_beat[s] = self.last_alive[s] = self.now
            if not loop_runs:
                continue
            self._carry_out(self.core.tick(self.now))
            alive = {s for s in self.connected if self.now - self.last_alive[s] <= SUPERVISOR_TIMEOUT_S}
            for s in sorted(self.core.holders() - alive):
                self._carry_out(self.core.lost(s, "dead-man: silent", self.now))
                self.gone_at.setdefault(s, self.now)
            self._carry_out(self.core.beat({s: self.last_alive[s] for s in alive}, self.now))
            self._check_wire()

    # -- rules: operators ---------------------------------------------------------------------------------------
    @rule(session=st.sampled_from(sorted(SESSIONS)))
    def take(self, session):
        if session not in self.connected:
            return
        self._carry_out(self.core.tick(self.now))  # what time did meanwhile is not the operator's doing
        before = self._snapshot()
        decision = self.core.take(session, session, self.now, 0.0, 0, role=SESSIONS[session])
        if SESSIONS[session] != "engineer":
            assert not decision.ok and self._snapshot() == before, "a viewer took control"
        self._operator(session, decision)
        if decision.ok:
            self.last_alive[session] = self.now
            self.gone_at.pop(session, None)

    @rule(session=st.sampled_from(sorted(SESSIONS)))
    def release(self, session):
        self._carry_out(self.core.tick(self.now))  # what time did meanwhile is not the operator's doing
        before = self._snapshot()
        actions = self.core.release(session, self.now)
        if SESSIONS[session] != "engineer":
            assert self._snapshot() == before
        self._operator(session, actions)

    @rule(session=st.sampled_from(sorted(SESSIONS)), output=st.sampled_from(OUTPUTS), on=st.booleans())
    def switch(self, session, output, on):
        if session not in self.connected:
            return
        self._carry_out(self.core.tick(self.now))  # what time did meanwhile is not the operator's doing
        before = self._snapshot()
        decision = self.core.set_output(session, output, on, self.now, role=SESSIONS[session])
        if SESSIONS[session] != "engineer":
            if on:
                assert not decision.ok and self._snapshot() == before, "a viewer switched an output on"
            else:  # switching off is a stop every role may give: it only ever switches off
                after = self._snapshot()
                assert after[0] == before[0] and all(not v or before[1][k] for k, v in after[1].items())
        if on and decision.ok:  # a press of its page: it is alive
            self.last_alive[session] = self.now
            self.gone_at.pop(session, None)
        self._operator(session, decision)

    @rule(session=st.sampled_from(["eng-1", "eng-2"]), output=st.sampled_from(OUTPUTS))
    def engineer_takes_and_switches_on(self, session, output):
        """The usual way to mains on: take control, switch an output on (the second page tries it too)."""
        self.take(session)
        if output in self.core.outputs:
            self.switch(session, output, True)

    @rule()
    def all_off(self):
        self._carry_out(self.core.all_off(self.now, "all off pressed"))

    @rule(session=st.sampled_from(sorted(SESSIONS)))
    def stop_beating(self, session):
        """The page freezes (or its tab is starved): no beats from now on."""
        if session in self.beating:
            self.beating.discard(session)
            self.gone_at.setdefault(session, self.last_alive[session])

    @rule(session=st.sampled_from(sorted(SESSIONS)))
    def resume_beating(self, session):
        if session in self.connected and session not in self.beating and SESSIONS[session] == "engineer":
            self.beating.add(session)
            self.last_beat[session] = self.last_alive[session] = self.now
            self.gone_at.pop(session, None)
            self._carry_out(self.core.back(session))

    @rule(session=st.sampled_from(sorted(SESSIONS)))
    def disconnect(self, session):
        if session in self.connected:
            self.connected.discard(session)
            self.gone_at.setdefault(session, self.now)
            self._carry_out(self.core.disconnected(session, "the controlling browser disconnected", self.now))

    @rule(session=st.sampled_from(sorted(SESSIONS)))
    def reconnect(self, session):
        if session not in self.connected:
            self.connected.add(session)
            if SESSIONS[session] == "engineer":
                self.beating.add(session)
            self.last_beat[session] = self.last_alive[session] = self.now
            self.gone_at.pop(session, None)
            self._carry_out(self.core.back(session))

    @rule(session=st.sampled_from(sorted(SESSIONS)))
    def page_gone(self, session):
        self.connected.discard(session)
        self.beating.discard(session)
        self.gone_at.setdefault(session, self.now)
        self._carry_out(self.core.lost(session, "the controlling browser's page is gone", self.now))

    # -- rules: the bus and the module --------------------------------------------------------------------------
    @rule()
    def another_master(self):
        """A PLC's DigOut is heard."""
        self.real_foreign_at = self.now
        self._carry_out(self.core.foreign_dig_out(self.now))
        assert self.sending is None, "this tool went on sending DigOut beside another master"

    @rule(area=st.sampled_from([2, 3, 5]), index=st.integers(1, 15), late=st.floats(0.0, ANSWER_WINDOW_S))
    def own_read(self, area, index, late):
        """This tool asks (Sync, 7.2.4.2); the module answers with MData, perhaps late."""
        self.core.request_sent(area, index, self.now)
        self._time(late, loop_runs=True)
        self._carry_out(self.core.module_frame("MData", self.now, (area, index)))

    @rule(kind=st.sampled_from(["DigIn", "Temp"]))
    def module_talks(self, kind):
        """The module sends DigIn or temperatures: only while a master serves it; if this tool does not, a PLC does."""
        if not self.core.served and self.now > self.core.served_until:
            self.real_foreign_at = self.now
        self._carry_out(self.core.module_frame(kind, self.now))

    @rule(may=st.booleans())
    def variant_check(self, may):
        self._carry_out(self.core.variant_checked(may, "" if may else "variant mismatch", self.now))

    # -- rules: time --------------------------------------------------------------------------------------------
    @rule(dt=st.floats(0.01, 0.4))
    def time_passes(self, dt):
        self._time(dt, loop_runs=True)

    @rule(dt=st.floats(0.01, 0.4))
    def program_stalls(self, dt):
        """The event loop stalls: no beat is processed, no tick; only the sender's own clock runs."""
        self._time(dt, loop_runs=False)
        self._check_wire()

    # -- invariants -----------------------------------------------------------------------------------------------
    def _check_wire(self) -> None:
        wire = self._wire()
        assert wire == self.core.telegram(self.now), "the sender carries what the core did not say"
        mains = mains_on(self.variant, wire or b"")
        if not mains:
            return
        assert not self.leased or self.lease.valid(self.now), "SSR on while the lease is not valid"
        holder = self.core.holder
        assert holder is not None, f"{mains} on with nobody in control"
        assert holder.session in self.connected and holder.disconnected is None, f"{mains} on for a disconnected page"
        silent = self.now - self.last_alive[holder.session]
        assert silent <= STOP_DEADLINE_S + 1e-9, f"{mains} on {silent:.3f} s after the operator's last sign of life"
        gone = self.gone_at.get(holder.session)
        assert gone is None or self.now - gone <= STOP_DEADLINE_S + 1e-9, f"{mains} on {self.now - gone:.3f} s after the operator went"

    @invariant()
    def the_wire_is_safe(self):
        self._check_wire()

    @invariant()
    def outputs_belong_to_the_session_in_control(self):
        on = [name for name, v in self.core.outputs.items() if v]
        if on:
            holder = self.core.holder
            assert holder is not None, f"{on} on with nobody in control"
            assert all(self.core.owners.get(name) == holder.session for name in on), (on, self.core.owners, holder)

    @invariant()
    def never_beside_another_master(self):
        if self.sending is not None and self.real_foreign_at is not None:
            assert self.real_foreign_at < self.sending_since, "DigOut sent after another master was heard"

    @invariant()
    def own_answers_are_no_other_master(self):
        if self.core.foreign_master(self.now):
            assert self.real_foreign_at is not None and self.now - self.real_foreign_at <= codec.WATCHDOG_S + 1e-9


class M3ioHmrSafety(M3ioSafety):
    variant = Variant.HMR


M3ioSafety.TestCase.settings = settings(derandomize=True, max_examples=60, deadline=None, stateful_step_count=40)
M3ioHmrSafety.TestCase.settings = settings(derandomize=True, max_examples=30, deadline=None, stateful_step_count=40)
test_m3io_safety = M3ioSafety.TestCase
test_m3io_hmr_safety = M3ioHmrSafety.TestCase

SAFETY_MACHINES = {"m3io": M3ioSafety}


# -- examples of the rules --------------------------------------------------------------------------------------


def test_a_lapsed_lease_carries_every_ssr_off_and_keeps_the_led():
    core = M3ioControl(Variant.HM, DIG_OUT)
    core.listen_left(0.0, 0)
    assert core.take("a", "anna", 1.0, 0.0, 0).ok
    assert core.set_output("a", "SSR1", True, 1.0).ok and core.set_output("a", "LED", True, 1.0).ok
    assert core.telegram(1.2) == bytes([0x03])
    assert core.telegram(1.0 + core.session.lease.valid_s + 0.01) == bytes([0x01])  # nobody renewed: the stop form
    actions = core.tick(1.5)
    assert not core.outputs["SSR1"] and core.outputs["LED"]
    assert any(getattr(a, "level", "") == "error" and "SSR1" in a.text and "stalled" in a.text for a in actions)


def test_an_answer_to_the_tools_own_request_is_no_other_master():
    core = M3ioControl(Variant.HMR, 0x20A)
    core.listen_left(0.0, 0)
    core.request_sent(codec.AREA_READ_CONFIG, codec.CONFIG_SERIAL, 5.0)
    core.module_frame("MData", 5.02, (codec.AREA_READ_CONFIG, codec.CONFIG_SERIAL))
    assert not core.foreign_master(5.1)
    assert core.take("a", "anna", 5.1, 0.0, 0).ok
    other = M3ioControl(Variant.HMR, 0x20A)
    other.module_frame("MData", 5.02, (codec.AREA_READ_CONFIG, codec.CONFIG_SERIAL))  # asked by someone else
    assert other.foreign_master(5.1) and not other.take("a", "anna", 5.1, 0.0, 0).ok


def test_another_masters_digout_ends_the_keep_alive_without_a_last_frame():
    core = M3ioControl(Variant.HM, DIG_OUT)
    core.listen_left(0.0, 0)
    core.take("a", "anna", 1.0, 0.0, 0)
    core.set_output("a", "SSR2", True, 1.0)
    actions = core.foreign_dig_out(1.1)
    assert any(isinstance(a, EndKeepAlive) for a in actions) and not any(isinstance(a, DigOut) for a in actions)
    assert core.holder is None and core.telegram(1.2) is None
    assert "fight" in core.take("a", "anna", 2.0, 0.0, 0).refused


# -- the send policy: what the module sends is never sent ---------------------------------------------------------

HEATERS = [BusDevice("heater", "m3io", {"sw1": 0x1A, "variant": "HM"}),
           BusDevice("oven", "m3io", {"sw1": 0xCA, "variant": "HMR"})]


@pytest.mark.parametrize(("device", "frame"), [(0, "DigIn"), (0, "Temp1-4"), (0, "Temp5-6"), (1, "DigIn"),
                                               (1, "Temp1-4"), (1, "Temp5-6"), (1, "MData")])
def test_frames_the_module_sends_are_never_sent(device, frame):
    ids = codec.derive_ids(HEATERS[device].options["sw1"]).by_name()
    data = {"DigIn": b"\xc0", "MData": bytes([2, 1, 0x97, 0x84, 0x02, 0x00, 0xFF, 0xFF])}.get(frame, bytes(8))
    verdict = check_can(HEATERS, ids[frame], False, data)
    assert verdict.refused and "sends" in verdict.refused, verdict


def test_the_masters_frames_are_still_judged():
    assert check_can(HEATERS, 0x422, False, b"\x00").allowed
    assert check_can(HEATERS, 0x422, False, b"\x02").confirm


# -- the adapter over its twin ----------------------------------------------------------------------------------------


def hmr_plant() -> str:
    """An HMR in addressed mode (SW1 0xCA, serial 42120023) on a simulated CAN bus, nobody in control."""
    from plants import can_bus, m3io_can, plant_text

    return plant_text(can_bus(m3io_can("hmr", "can7", variant="HMR", sw1=0xCA, serial=42120023), name="can7",
                              bitrate=500000, poll_period=0.2), name=None)


async def test_reading_identity_is_no_sign_of_another_master():
    """Issue 40: "read identity" made the module answer MData, counted as another master: control refused for 2 s."""
    from conftest import wait_for

    from app.plant import parse_plant
    from app.runtime import Runtime

    runtime = Runtime(parse_plant(hmr_plant()), simulate=True)
    await runtime.start()
    try:
        adapter = runtime.worker.adapters["hmr"]
        await asyncio.sleep(LISTEN_S)  # listen to the module's own telegrams for LISTEN_S
        info = await adapter.read_identity()
        assert info["serial"] == "42120023"
        assert not adapter.foreign_master()
        await adapter.take_control("tab", "engineer")
        assert adapter.controller is not None and adapter.controller.session == "tab"
        assert await wait_for(lambda: runtime.store.devices["hmr"].status == "online", timeout=4)
    finally:
        with contextlib.suppress(Exception):
            adapter.release_control("tab")
        await asyncio.wait_for(runtime.stop(), 5)
