"""The keep-alive threads' place in the machine's scheduling.

A keep-alive sender (python-can's cyclic task of a CAN keep-alive, the SCU line's RC thread) sleeps
until its next period, sends one telegram and sleeps again: a few hundred microseconds of work ten
times a second. On a laptop whose two cores also draw twenty browser pages it must not wait for a
time slice behind them. Where the system permits it (Linux, CAP_SYS_NICE), such a thread runs under
the round-robin real-time policy at a low real-time priority, so it runs as soon as its sleep ends;
elsewhere it asks for a better nice value; on Windows it runs at the time-critical thread priority
within the process's class (any user may set it); where none of these is allowed (macOS: app/host.py)
it runs as it is. A real-time
thread that never sleeps would take a core: only threads that sleep between short sends belong here
(a sender with a period under :data:`MIN_PERIOD_S` is left as it is).

Such a thread also needs the interpreter lock for every telegram, and a full collection of the cyclic
garbage collector holds it for as long as it walks the heap (bench/can_flood.py: 45-335 ms of wall
time during a flood, the largest keep-alive gaps around them). While a keep-alive runs, CPython's
automatic full collection is put off (:func:`hold_full_collections`); the young generations are
collected as before, and the full collection follows CPython's counts again once the last keep-alive
has stopped. A program that schedules full collections itself (app.runtime.FullCollections: the full
generation's threshold at :data:`FULL_MANAGED`) is left to do so.

When its sleep ends the sender waits for the interpreter lock: CPython asks the thread that holds it to
give it up only after the switch interval (``sys.setswitchinterval``, 5 ms by default), and a reader
thread or the event loop busy with a flood takes it back after every hand-over. While a keep-alive runs
the interval is :data:`KEEPALIVE_SWITCH_S`; the interval the program had comes back once the last
keep-alive has stopped (unless somebody else changed it meanwhile). bench/can_flood.py, 5 s phases, two runs
each at load 13-33: worst control gap 168 and 157 ms at 1 ms, 113 and 123 ms at 0.5 ms; the process's
CPU time 44-45 s user+sys against 40-44 s, its voluntary context switches 15 % and 84 % more.

A shorter interval helps only while the holder runs. On a loaded machine the thread that holds the lock
(the event loop, a CAN reader) waits for a CPU behind the other programs like any ordinary thread, and
the sender waits as long: bench/can_flood.py at load 30 on two cores, worst control gap 525 ms (flood from
a thread) and 687 ms (from a second process); this process's threads waited 1.1-3.3 times as long for a
CPU as they ran. So while a keep-alive runs, every thread of the interpreter runs under the round-robin
real-time policy too, at :data:`HOLDER_PRIORITY`, below the senders (:func:`hold_keepalive`); the policy
each had comes back with the last release. They take the interpreter lock in turn, so together they run
Python on one CPU at a time: this is done only on a machine with two CPUs or more whose kernel throttles
real-time threads (a runaway one still leaves time to every other program). New threads and child
processes start as ordinary ones (``SCHED_RESET_ON_FORK``); threads started during a hold get their place
with :func:`refresh_holders`.
"""

from __future__ import annotations

import gc
import os
import sys
import threading

from app import host

RT_PRIORITY = 10  # low among real-time priorities (1..99): above every ordinary program, below the kernel's own threads
KEEPALIVE_NICE = -10  # where real-time is not permitted: ahead of busy ordinary programs
MIN_PERIOD_S = 0.01


def raise_sender(native_id: int | None, period_s: float) -> str:
    """Give the sender thread ``native_id`` (its ``threading.Thread.native_id``) its place; returns which:
    ``"real-time"``, ``"nice"``, ``"time-critical"`` (Windows) or ``"as it is"``."""
    if native_id is None or period_s < MIN_PERIOD_S:
        return "as it is"
    try:
        host.set_thread_round_robin(native_id, RT_PRIORITY)
        return "real-time"
    except (OSError, AttributeError):  # not permitted, or no such call on this system (host.Unsupported)
        pass
    try:
        host.set_nice(native_id, KEEPALIVE_NICE)
        return "nice"
    except (OSError, AttributeError):  # Windows, a thread on macOS
        pass
    try:
        host.set_thread_time_critical(native_id)
        return "time-critical"
    except (OSError, AttributeError):  # refused, or not Windows (macOS): an ordinary thread (docs/windows-macos.md)
        return "as it is"


HOLDER_PRIORITY = 1  # the interpreter's other threads while a keep-alive runs: real-time, below RT_PRIORITY
# False: the other threads stay as they are (only the senders are raised); COMMISSION_RT_HOLDERS=0 in the
# environment turns it off for a process and its children (a test run: several processes beside chromium)
HOLDERS_REAL_TIME = os.environ.get("COMMISSION_RT_HOLDERS", "1") != "0"


def _real_time_bounded() -> bool:
    """Whether real-time threads that may not sleep still leave the machine usable: two CPUs or more and the
    kernel's real-time throttling on (Linux only: :func:`app.host.real_time_bounded`)."""
    return host.real_time_bounded()


_boosted: dict[int, int] = {}  # native id -> the policy it had, of the threads raised to HOLDER_PRIORITY


def _boost_holders() -> None:
    """Every ordinary thread of the interpreter to HOLDER_PRIORITY (the caller holds ``_hold_lock``)."""
    if not HOLDERS_REAL_TIME or not _real_time_bounded():
        return
    alive = set()
    for thread in threading.enumerate():
        tid = thread.native_id
        if tid is None:
            continue
        alive.add(tid)
        if tid in _boosted:
            continue
        try:
            policy = host.thread_policy_raw(tid)
            if host.policy_kind(policy) != host.ordinary_policy():  # a sender already, or asked to stay behind
                continue
            host.set_thread_round_robin(tid, HOLDER_PRIORITY, reset_on_fork=True)
            _boosted[tid] = policy
        except ProcessLookupError:  # ended meanwhile
            continue
        except (OSError, AttributeError):  # not permitted, or no such call on this system: as they are
            return
    for tid in [t for t in _boosted if t not in alive]:
        del _boosted[tid]


def _restore_holders() -> None:
    """The threads raised by :func:`_boost_holders` get their policy back (the caller holds ``_hold_lock``)."""
    for tid, policy in _boosted.items():
        try:
            if (host.thread_policy(tid) == host.round_robin_policy()
                    and host.thread_rt_priority(tid) == HOLDER_PRIORITY):  # not changed by anybody else meanwhile
                host.set_thread_policy(tid, policy)
        except (OSError, AttributeError):  # ended meanwhile
            continue
    _boosted.clear()


def refresh_holders() -> None:
    """While a keep-alive that guards motion runs: threads started since it began get their place too (cheap;
    call it now and then)."""
    with _hold_lock:
        if _boost_holds > 0:
            _boost_holders()


def holders_raised() -> list[int]:
    """Native ids of the threads running at HOLDER_PRIORITY for the keep-alives now."""
    return list(_boosted)


FULL_MANAGED = 1 << 30  # a full-generation threshold this high: no automatic full collection (app.runtime.FullCollections)

KEEPALIVE_SWITCH_S = 0.0005  # the switch interval while a keep-alive runs (CPython's default: 0.005; measured in the module's text)

_hold_lock = threading.Lock()
_holds = 0
_boost_holds = 0  # of the holds, those whose keep-alive guards a motion or mains output (a lease): the other threads raised
_full_threshold: int | None = None  # the full generation's threshold while a hold put it off; None: not changed here
_switch_interval: float | None = None  # the switch interval before a hold lowered it; None: not changed here
_switch_set = 0.0  # the interval as CPython reports it after the hold set it (whole microseconds)


def hold_full_collections(boost: bool = True) -> None:
    """A keep-alive sender started: no automatic full collection until every hold is released
    (:func:`release_full_collections`, once per hold, with the same ``boost``). Thread-safe.

    ``boost``: the keep-alive guards a motion or mains output (a lease, a tight watchdog), so while it runs
    the interpreter's switch interval is at most :data:`KEEPALIVE_SWITCH_S` and its other threads run
    real-time below it (where bounded). A keep-alive with a wide margin (an I/O module served idle, every
    output off, every 500 ms against its 2 s watchdog) leaves both as they are: an idle plant must not run
    real-time for good."""
    global _holds, _boost_holds, _full_threshold, _switch_interval, _switch_set
    with _hold_lock:
        _holds += 1
        if _holds == 1:
            young, middle, full = gc.get_threshold()
            if full < FULL_MANAGED:  # else the program schedules them itself
                _full_threshold = full
                gc.set_threshold(young, middle, FULL_MANAGED)
        if not boost:
            return
        _boost_holds += 1
        _boost_holders()
        if _boost_holds == 1:
            before = sys.getswitchinterval()
            if before > KEEPALIVE_SWITCH_S:
                _switch_interval = before
                sys.setswitchinterval(KEEPALIVE_SWITCH_S)
                _switch_set = sys.getswitchinterval()


def release_full_collections(boost: bool = True) -> None:
    """A keep-alive sender stopped: with the last one guarding motion the switch interval and the threads'
    policies are what they were; with the last one of all, the full collection is CPython's again."""
    global _holds, _boost_holds, _full_threshold, _switch_interval
    with _hold_lock:
        if _holds == 0:
            return
        _holds -= 1
        if boost and _boost_holds > 0:
            _boost_holds -= 1
            if _boost_holds == 0:
                _restore_holders()
                if _switch_interval is not None:
                    if sys.getswitchinterval() == _switch_set:  # nobody else changed it meanwhile
                        sys.setswitchinterval(_switch_interval)
                    _switch_interval = None
        if _holds == 0 and _full_threshold is not None:
            young, middle, full = gc.get_threshold()
            if full == FULL_MANAGED:  # nobody else changed it meanwhile
                gc.set_threshold(young, middle, _full_threshold)
            _full_threshold = None


hold_keepalive, release_keepalive = hold_full_collections, release_full_collections  # what a hold is for: a keep-alive


def full_collections_held() -> bool:
    """Whether some keep-alive holds off the automatic full collection now."""
    return _holds > 0
