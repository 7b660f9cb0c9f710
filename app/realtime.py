"""The keep-alive threads' place in the machine's scheduling.

A keep-alive sender (python-can's cyclic task of a CAN keep-alive, the SCU line's RC thread) sleeps
until its next period, sends one telegram and sleeps again: a few hundred microseconds of work ten
times a second. On a laptop whose two cores also draw twenty browser pages it must not wait for a
time slice behind them. Where the system permits it (Linux, CAP_SYS_NICE), such a thread runs under
the round-robin real-time policy at a low real-time priority, so it runs as soon as its sleep ends;
elsewhere it asks for a better nice value, and where neither is allowed it runs as it is. A real-time
thread that never sleeps would take a core: only threads that sleep between short sends belong here
(a sender with a period under :data:`MIN_PERIOD_S` is left as it is).

Such a thread also needs the interpreter lock for every telegram, and a full collection of the cyclic
garbage collector holds it for as long as it walks the heap (bench/can_flood.py: 45-335 ms of wall
time during a flood, the largest keep-alive gaps around them). While a keep-alive runs, CPython's
automatic full collection is put off (:func:`hold_full_collections`); the young generations are
collected as before, and the full collection follows CPython's counts again once the last keep-alive
has stopped. A program that schedules full collections itself (app.runtime.FullCollections: the full
generation's threshold at :data:`FULL_MANAGED`) is left to do so.
"""

from __future__ import annotations

import gc
import os
import threading

RT_PRIORITY = 10  # low among real-time priorities (1..99): above every ordinary program, below the kernel's own threads
KEEPALIVE_NICE = -10  # where real-time is not permitted: ahead of busy ordinary programs
MIN_PERIOD_S = 0.01


def raise_sender(native_id: int | None, period_s: float) -> str:
    """Give the sender thread ``native_id`` (its ``threading.Thread.native_id``) its place; returns which:
    ``"real-time"``, ``"nice"`` or ``"as it is"``."""
    if native_id is None or period_s < MIN_PERIOD_S:
        return "as it is"
    try:
        os.sched_setscheduler(native_id, os.SCHED_RR, os.sched_param(RT_PRIORITY))
        return "real-time"
    except (OSError, AttributeError):  # not permitted, or no such call on this system
        pass
    try:
        os.setpriority(os.PRIO_PROCESS, native_id, KEEPALIVE_NICE)
        return "nice"
    except (OSError, AttributeError):
        return "as it is"


FULL_MANAGED = 1 << 30  # a full-generation threshold this high: no automatic full collection (app.runtime.FullCollections)

_hold_lock = threading.Lock()
_holds = 0
_full_threshold: int | None = None  # the full generation's threshold while a hold put it off; None: not changed here


def hold_full_collections() -> None:
    """A keep-alive sender started: no automatic full collection until every hold is released
    (:func:`release_full_collections`, once per hold). Thread-safe."""
    global _holds, _full_threshold
    with _hold_lock:
        _holds += 1
        if _holds == 1:
            young, middle, full = gc.get_threshold()
            if full < FULL_MANAGED:  # else the program schedules them itself
                _full_threshold = full
                gc.set_threshold(young, middle, FULL_MANAGED)


def release_full_collections() -> None:
    """A keep-alive sender stopped: with the last one, the full collection is CPython's again."""
    global _holds, _full_threshold
    with _hold_lock:
        if _holds == 0:
            return
        _holds -= 1
        if _holds == 0 and _full_threshold is not None:
            young, middle, full = gc.get_threshold()
            if full == FULL_MANAGED:  # nobody else changed it meanwhile
                gc.set_threshold(young, middle, _full_threshold)
            _full_threshold = None


def full_collections_held() -> bool:
    """Whether some keep-alive holds off the automatic full collection now."""
    return _holds > 0
