"""Full collections of the garbage collector wait while a motion runs under a lease (issue 28).

A full collection holds the interpreter lock for as long as it walks the heap (a hundred milliseconds and
more with many pages open): no keep-alive thread sends meanwhile.
"""

from __future__ import annotations

import asyncio
import gc

from app.runtime import FullCollections, freeze_startup_heap
from devices import lease as lease_module
from devices.lease import Lease, any_granted


def test_any_granted_follows_grant_and_revoke():
    lease = Lease(valid_s=0.01)
    before = any_granted()
    lease.grant()
    assert any_granted()
    assert not lease.valid(now=1e12)  # lapsed: still granted (the stop form is being sent) until revoked
    assert any_granted()
    lease.revoke()
    assert any_granted() == before
    assert lease not in lease_module._GRANTED


def test_due_by_count_and_gap_and_put_off_under_a_lease(monkeypatch):
    collections = FullCollections(min_gap_s=30, longest_defer_s=600)
    collections._thresholds = (700, 10, 10)
    monkeypatch.setattr(gc, "get_count", lambda: (0, 0, 11))
    assert collections.due(now=100, last=0, due_since=None, busy=False)
    assert not collections.due(now=20, last=0, due_since=None, busy=False)  # too soon after the last
    assert not collections.due(now=100, last=0, due_since=None, busy=True)  # a motion runs
    assert not collections.due(now=100, last=0, due_since=50, busy=True)
    assert collections.due(now=700, last=0, due_since=50, busy=True)  # put off for longer than allowed: runs
    monkeypatch.setattr(gc, "get_count", lambda: (0, 0, 3))
    assert not collections.due(now=100, last=0, due_since=None, busy=False)  # not due by CPython's count


async def test_runs_when_due_and_restores_the_thresholds():
    before = gc.get_threshold()
    collections = FullCollections(min_gap_s=0, check_s=0.01, busy=lambda: False)
    collections.start()
    try:
        assert gc.get_threshold()[2] > 10**6  # the full generation is no longer automatic
        collections._thresholds = (before[0], before[1], -1)  # due at every check
        for _ in range(200):
            if collections.runs:
                break
            await asyncio.sleep(0.01)
        assert collections.runs and collections.last_ms is not None
    finally:
        collections._thresholds = before
        await collections.stop()
    assert gc.get_threshold() == before


def test_freeze_startup_heap_counts_what_it_froze():
    try:
        assert freeze_startup_heap() > 0
    finally:
        gc.unfreeze()


async def test_busy_while_a_can_keepalive_runs():
    import uuid

    from app.can_bus import keepalives_running
    from app.runtime import _keepalives_busy
    from test_can_shutdown import _open_bus

    bus = await _open_bus(f"busy-{uuid.uuid4().hex}")
    try:
        assert not keepalives_running()
        bus.start_periodic("k", 0.05, 0x123, b"\x01")
        assert keepalives_running() and _keepalives_busy()
        bus.stop_cyclic("k")
        assert not keepalives_running()
    finally:
        await bus.stop()


def test_raise_priority_is_silent_where_not_permitted(monkeypatch):
    import os

    from app import runtime

    def refuse(*_args):
        raise PermissionError("not permitted")

    monkeypatch.setattr(os, "setpriority", refuse)
    monkeypatch.setattr(os, "getsid", lambda _pid: -1)  # not a session leader: the session's share is left alone
    assert runtime.raise_priority(-20) is False
