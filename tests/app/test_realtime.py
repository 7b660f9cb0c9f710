"""Keep-alive sender threads get a place ahead of busy programs where the system permits it."""

from __future__ import annotations

import os
import threading

import pytest

from app import realtime


def _in_thread(fn):
    out = {}

    def run():
        out["tid"] = threading.get_native_id()
        out["result"] = fn(out["tid"])
        out["policy"] = os.sched_getscheduler(0)
        out["nice"] = os.getpriority(os.PRIO_PROCESS, out["tid"])

    t = threading.Thread(target=run)
    t.start()
    t.join()
    return out


def test_a_sender_runs_real_time_where_permitted_else_nice_else_as_it_is():
    out = _in_thread(lambda tid: realtime.raise_sender(tid, 0.1))
    assert out["result"] in {"real-time", "nice", "as it is"}
    if out["result"] == "real-time":
        assert out["policy"] == os.SCHED_RR
    elif out["result"] == "nice":
        assert out["policy"] == os.SCHED_OTHER and out["nice"] == realtime.KEEPALIVE_NICE
    assert os.sched_getscheduler(0) == os.SCHED_OTHER  # the calling thread (the event loop's) is left as it is


def test_a_fast_or_unknown_thread_is_left_as_it_is():
    out = _in_thread(lambda tid: realtime.raise_sender(tid, 0.001))
    assert out["result"] == "as it is" and out["policy"] == os.SCHED_OTHER
    assert realtime.raise_sender(None, 0.1) == "as it is"


def test_refused_everywhere_is_silent(monkeypatch):
    def refuse(*_args):
        raise PermissionError("not permitted")

    monkeypatch.setattr(os, "sched_setscheduler", refuse)
    monkeypatch.setattr(os, "setpriority", refuse)
    out = _in_thread(lambda tid: realtime.raise_sender(tid, 0.1))
    assert out["result"] == "as it is" and out["policy"] == os.SCHED_OTHER


def _permitted() -> bool:
    out = _in_thread(lambda tid: os.sched_setscheduler(tid, os.SCHED_RR, os.sched_param(1)) or True) if _can_try() else {}
    return out.get("policy") == os.SCHED_RR


def _can_try() -> bool:
    return hasattr(os, "sched_setscheduler") and realtime._real_time_bounded()


class _Idle:
    """A thread of the interpreter that waits (as the event loop or a reader does between frames)."""

    def __init__(self):
        self.go, self.ready = threading.Event(), threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()
        self.ready.wait()

    def _run(self):
        self.ready.set()
        self.go.wait()

    def policy(self) -> tuple[int, int]:
        tid = self.thread.native_id
        return os.sched_getscheduler(tid) & ~os.SCHED_RESET_ON_FORK, os.sched_getparam(tid).sched_priority

    def end(self):
        self.go.set()
        self.thread.join()


def test_while_a_keepalive_runs_the_other_threads_run_real_time_below_the_senders(monkeypatch):
    monkeypatch.setattr(realtime, "HOLDERS_REAL_TIME", True)  # the default; a test session may turn it off
    if not _permitted():
        pytest.skip("real-time not permitted here, or not bounded (one CPU, no throttling)")
    before, sender = _Idle(), _Idle()
    os.sched_setscheduler(sender.thread.native_id, os.SCHED_RR, os.sched_param(realtime.RT_PRIORITY))
    try:
        realtime.hold_keepalive()
        try:
            assert before.policy() == (os.SCHED_RR, realtime.HOLDER_PRIORITY)
            assert os.sched_getscheduler(0) & ~os.SCHED_RESET_ON_FORK == os.SCHED_RR  # the caller's thread too
            assert sender.policy() == (os.SCHED_RR, realtime.RT_PRIORITY)  # a sender stays above them
            later = _Idle()  # started during the hold: an ordinary thread (reset on fork) until the next refresh
            assert later.policy() == (os.SCHED_OTHER, 0)
            realtime.refresh_holders()
            assert later.policy() == (os.SCHED_RR, realtime.HOLDER_PRIORITY)
        finally:
            realtime.release_keepalive()
        assert before.policy() == (os.SCHED_OTHER, 0) and later.policy() == (os.SCHED_OTHER, 0)
        assert os.sched_getscheduler(0) == os.SCHED_OTHER and not realtime.holders_raised()
        assert sender.policy() == (os.SCHED_RR, realtime.RT_PRIORITY)  # not raised here: not lowered here
        later.end()
    finally:
        before.end()
        sender.end()


def test_other_threads_stay_as_they_are_where_it_is_not_bounded_or_not_permitted(monkeypatch):
    idle = _Idle()
    monkeypatch.setattr(realtime, "HOLDERS_REAL_TIME", True)
    try:
        monkeypatch.setattr(realtime, "_real_time_bounded", lambda: False)  # one CPU, or no real-time throttling
        realtime.hold_keepalive()
        assert idle.policy() == (os.SCHED_OTHER, 0) and not realtime.holders_raised()
        realtime.release_keepalive()
        monkeypatch.setattr(realtime, "_real_time_bounded", lambda: True)

        def refuse(*_args):
            raise PermissionError("not permitted")

        monkeypatch.setattr(os, "sched_setscheduler", refuse)
        realtime.hold_keepalive()
        assert idle.policy() == (os.SCHED_OTHER, 0) and not realtime.holders_raised()
        realtime.release_keepalive()
    finally:
        idle.end()


def test_a_keepalive_without_a_lease_leaves_the_other_threads_and_the_switch_interval_as_they_are(monkeypatch):
    """An I/O module served idle (every output off, DigOut every 500 ms against a 2 s watchdog) must not
    keep an idle plant's program real-time for good: only a keep-alive that guards motion raises the others."""
    import gc
    import sys

    monkeypatch.setattr(realtime, "HOLDERS_REAL_TIME", True)
    monkeypatch.setattr(realtime, "_real_time_bounded", lambda: True)
    raised: list[int] = []
    monkeypatch.setattr(os, "sched_setscheduler", lambda tid, *_args: raised.append(tid))
    monkeypatch.setattr(os, "sched_getscheduler", lambda tid: os.SCHED_OTHER)
    saved_interval, saved_thresholds = sys.getswitchinterval(), gc.get_threshold()
    sys.setswitchinterval(0.005)
    gc.set_threshold(700, 10, 10)
    try:
        realtime.hold_keepalive(boost=False)
        assert gc.get_threshold()[2] == realtime.FULL_MANAGED  # the full collection waits all the same
        assert sys.getswitchinterval() == pytest.approx(0.005) and not raised
        realtime.hold_keepalive()  # then a motion starts: its lease guards it
        assert sys.getswitchinterval() == pytest.approx(realtime.KEEPALIVE_SWITCH_S, abs=1e-6) and raised
        realtime.release_keepalive()  # the motion ended, the idle sender still runs
        assert sys.getswitchinterval() == pytest.approx(0.005) and not realtime.holders_raised()
        assert gc.get_threshold()[2] == realtime.FULL_MANAGED
        realtime.release_keepalive(boost=False)
        assert gc.get_threshold() == (700, 10, 10)
    finally:
        sys.setswitchinterval(saved_interval)
        gc.set_threshold(*saved_thresholds)


def test_only_a_leased_can_keepalive_raises_the_other_threads(monkeypatch):
    import uuid

    from app.can_bus import CanBus, CanBusState, PeriodicSender
    from devices.lease import Lease

    calls: list[tuple[str, bool]] = []
    monkeypatch.setattr(realtime, "hold_keepalive", lambda boost=True: calls.append(("hold", boost)))
    monkeypatch.setattr(realtime, "release_keepalive", lambda boost=True: calls.append(("release", boost)))

    channel = f"rt-{uuid.uuid4().hex[:10]}"
    bus = CanBus("rt", {"interface": "virtual", "channel": channel}, CanBusState("rt", "can", channel))
    bus.bus = bus.open()
    try:
        for lease, boost in ((None, False), (Lease(), True)):
            periodic = PeriodicSender(bus.link, "k", 0.5, 0x100, b"\0", False, lease, None, None)
            periodic.start(bus.bus)
            periodic.stop(join=True)
            assert calls == [("hold", boost), ("release", boost)]
            calls.clear()
    finally:
        bus.bus.shutdown()
