"""Keep-alive sender threads get a place ahead of busy programs where the system permits it."""

from __future__ import annotations

import os
import threading

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
