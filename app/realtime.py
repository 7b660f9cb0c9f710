"""The keep-alive threads' place in the machine's scheduling.

A keep-alive sender (python-can's cyclic task of a CAN keep-alive, the SCU line's RC thread) sleeps
until its next period, sends one telegram and sleeps again: a few hundred microseconds of work ten
times a second. On a laptop whose two cores also draw twenty browser pages it must not wait for a
time slice behind them. Where the system permits it (Linux, CAP_SYS_NICE), such a thread runs under
the round-robin real-time policy at a low real-time priority, so it runs as soon as its sleep ends;
elsewhere it asks for a better nice value, and where neither is allowed it runs as it is. A real-time
thread that never sleeps would take a core: only threads that sleep between short sends belong here
(a sender with a period under :data:`MIN_PERIOD_S` is left as it is).
"""

from __future__ import annotations

import os

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
