"""Sparkplug commands from anyone who may publish to the broker (issue 41, item 3): one bounded,
rate-limited audit row per refused command, sizes capped, nothing on a device's page or under a
device's name in the audit log (the as-left report's audit section keeps the engineer's rows), and
a row also for an empty payload and a topic with extra levels. Rebirth still works."""

from __future__ import annotations

import logging
import random
import time
import tracemalloc

from app.audit import AuditLog
from app.plant import parse_plant
from app.sparkplug import BOOLEAN, REBIRTH, STRING, Payload, SparkplugNode
from app.state import StateStore
from devices.live import DeviceState

NCMD = "spBv1.0/hall/NCMD/cab"
DCMD = "spBv1.0/hall/DCMD/cab/door-1"


def _node(tmp_path):
    plant = parse_plant('name = "cab"\n[mqtt]\nurl = "mqtt://127.0.0.1:1883"\nsite = "hall"\nsparkplug = true\n')
    store = StateStore()
    store.add(DeviceState("door-1", "hdlock", "line1"))
    audit = AuditLog(tmp_path / "audit.sqlite")
    return SparkplugNode(plant.mqtt, store, "cab", audit=audit), store, audit


def _command(*metrics: tuple[str, int, object]) -> bytes:
    payload = Payload(timestamp=1)
    for name, datatype, value in metrics:
        metric = payload.metrics.add(name=name, datatype=datatype)
        if datatype == BOOLEAN:
            metric.boolean_value = bool(value)
        else:
            metric.string_value = str(value)
    return payload.SerializeToString()


def _rows(audit):
    return [r for r in audit.query(limit=100_000) if r.action.startswith("Sparkplug")]


def _longest(rows) -> int:
    return max((len(str(getattr(r, c))) for r in rows for c in ("user", "role", "device", "action", "parameter", "old", "new", "result")),
               default=0)


async def test_one_bounded_row_per_refused_command(tmp_path):
    node, _store, audit = _node(tmp_path)
    try:
        await node._on_command(NCMD, _command(*[(f"m{i}", STRING, "x") for i in range(20_000)]))
        rows = _rows(audit)
        assert len(rows) == 1, len(rows)
        await node._on_command(NCMD, _command(*[(f"m{i}", STRING, "x") for i in range(2000)]))
        rows = _rows(audit)
        assert len(rows) == 2 and "2000 metrics" in rows[0].result, rows[0]
        await node._on_command(NCMD, _command(("n" * 1_000_000, STRING, "v" * 4_000_000)))
        rows = _rows(audit)
        assert len(rows) == 3 and _longest(rows) <= 1000, _longest(rows)
        assert max(len(str(r)) for r in node.refused) <= 2000
    finally:
        audit.close()


async def test_nothing_from_the_broker_lands_on_a_device(tmp_path):
    node, store, audit = _node(tmp_path)
    try:
        door = store.devices["door-1"]
        events = len(door.events)
        await node._on_command(DCMD, _command(*[(f"Param{i}", STRING, 1) for i in range(300)]))
        for _ in range(10):
            await node._on_command(DCMD, _command(("x" * 2_000_000, STRING, 1)))
        assert len(door.events) == events, "an unauthenticated command must not reach the device's page"
        assert not audit.query(device="door-1"), "the device's audit rows (and its as-left report) are the engineer's"
        rows = _rows(audit)
        assert rows and all("door-1" in r.parameter for r in rows)
    finally:
        audit.close()


async def test_rows_are_rate_limited_and_the_rest_counted(tmp_path):
    node, _store, audit = _node(tmp_path)
    try:
        for i in range(200):
            await node._on_command(NCMD, _command((f"Node Control/Reboot{i}", BOOLEAN, True)))
        rows = _rows(audit)
        assert 1 <= len(rows) <= 10, len(rows)
        assert node.summary()["refused"] == 200
    finally:
        audit.close()


async def test_empty_payload_and_extra_levels_are_refused_with_a_row(tmp_path):
    node, _store, audit = _node(tmp_path)
    try:
        await node._on_command(NCMD, b"")
        await node._on_command(DCMD + "/extra/levels", _command(("Param", STRING, 1)))
        await node._on_command(NCMD + "/extra", _command((REBIRTH, BOOLEAN, True)))
        rows = _rows(audit)
        assert len(rows) == 3, [(r.parameter, r.result) for r in rows]
        assert not node._rebirth.is_set(), "a Rebirth on a topic not ours is no Rebirth"
        await node._on_command(NCMD, _command((REBIRTH, BOOLEAN, True)))
        assert node._rebirth.is_set() and len(_rows(audit)) == 3
    finally:
        audit.close()


async def test_fuzz_of_malformed_commands_is_bounded(tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="app.sparkplug")
    node, _store, audit = _node(tmp_path)
    rng = random.Random(41)
    topics = [NCMD, DCMD, NCMD + "/x", DCMD + "/y/z", "spBv1.0/hall/DCMD/cab/ghost", "spBv1.0/hall/NCMD"]
    tracemalloc.start()
    base = None
    started = time.monotonic()
    try:
        for i in range(10_000):
            kind = rng.random()
            if kind < 0.4:
                data = bytes(rng.randrange(256) for _ in range(rng.randrange(64)))
            elif kind < 0.8:
                data = _command(*[(f"m{rng.randrange(10**6)}", STRING, "v" * rng.randrange(50)) for _ in range(rng.randrange(5))])
            else:
                data = b""
            await node._on_command(rng.choice(topics), data)
            if i == 2000:
                base = tracemalloc.get_traced_memory()[0]
        grown = tracemalloc.get_traced_memory()[0] - base
        assert len(_rows(audit)) <= 20
    finally:
        tracemalloc.stop()
        audit.close()
    assert time.monotonic() - started < 20
    assert grown < 2_000_000, grown
    lines = [r for r in caplog.records if r.name == "app.sparkplug"]
    assert len(lines) <= 20, f"{len(lines)} log lines for 10,000 commands from outside"
