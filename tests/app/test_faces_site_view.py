"""``commission view`` against messages that do not fit (issue 41, item 4): every received payload is
checked against its schema; what does not fit is dropped and counted, the view keeps answering, and
nesting and size are bounded before anything is kept."""

from __future__ import annotations

import json
import random
import time
import tracemalloc

from app.site_view import MAX_PAYLOAD, SiteStore

NOW = 1_795_000_000.0


def _store() -> SiteStore:
    return SiteStore("mqtt://127.0.0.1:1883")


def _good(store: SiteStore) -> None:
    store.handle("commission/hall/$instances/cab", json.dumps({"schema": "commission-instance", "version": 1, "instance": "cab",
                                                               "site": "hall", "state": "online", "heartbeat": 2,
                                                               "devices": ["door-1"], "time": NOW}).encode(), now=NOW)
    store.handle("commission/hall/door-1/state", json.dumps({
        "schema": "commission-state", "version": 1, "instance": "cab", "device": "door-1", "type": "hdlock", "bus": "line1",
        "status": "online", "time": NOW,
        "values": {"LockStatus": {"value": 279, "unit": "", "quality": "good", "time": NOW, "text": "0x0117", "raw": 279,
                                  "fields": {"BoltLocked": 1}}}}).encode(), now=NOW)


def test_a_heartbeat_of_the_wrong_type_is_dropped_and_the_view_answers():
    store = _store()
    _good(store)
    before = store.ignored
    store.handle("commission/hall/$instances/cab", json.dumps({"schema": "commission-instance", "version": 1, "instance": "cab",
                                                               "state": "online", "heartbeat": "30"}).encode(), now=NOW + 1)
    assert store.ignored == before + 1
    snapshot = store.snapshot(now=NOW + 1)  # the view and /api/site go on answering
    assert snapshot["sites"][0]["devices"][0]["view_status"] == "online"


def test_wrong_types_in_device_messages_are_dropped():
    store = _store()
    _good(store)
    bad = [
        ("commission/hall/door-1/state", {"instance": "cab", "status": "online", "values": {"X": 5}}),
        ("commission/hall/door-1/state", {"instance": "cab", "status": "online", "values": [1, 2]}),
        ("commission/hall/door-1/state", {"instance": ["cab"], "values": {}}),
        ("commission/hall/door-1/status", {"status": "online", "counters": "many"}),
        ("commission/hall/door-1/status", {"status": {"x": 1}}),
        ("commission/hall/door-1/alarms", {"active": "fire"}),
        ("commission/hall/door-1/alarms", {"active": [{"x": 1}]}),
        ("commission/hall/$instances/cab", {"state": "online", "devices": "door-1"}),
        ("commission/hall/$instances/cab", {"state": "online", "heartbeat": -5}),
    ]
    for topic, payload in bad:
        before = store.ignored
        store.handle(topic, json.dumps(payload).encode(), now=NOW + 1)
        assert store.ignored == before + 1, (topic, payload)
        store.snapshot(now=NOW + 2)
    view = store.snapshot(now=NOW + 2)["sites"][0]["devices"][0]
    assert view["values"]["LockStatus"]["value"] == 279


def test_deep_nesting_and_size_are_bounded():
    store = _store()
    _good(store)
    depth = 200_000
    before = store.ignored
    store.handle("commission/hall/door-1/state", b"[" * depth + b"]" * depth, now=NOW)  # no RecursionError to the subscriber
    deep = {"instance": "cab", "status": "online", "values": {"X": {"value": None}}}
    inner = deep["values"]["X"]
    for _ in range(100):
        inner["value"] = {"v": None}
        inner = inner["value"]
    store.handle("commission/hall/door-1/state", json.dumps(deep).encode(), now=NOW)
    store.handle("commission/hall/door-1/state", b'{"values": "' + b"x" * (MAX_PAYLOAD + 1) + b'"}', now=NOW)
    assert store.ignored == before + 3
    assert store.snapshot(now=NOW)["sites"][0]["devices"][0]["values"]["LockStatus"]["value"] == 279


def test_fuzz_of_malformed_messages_is_bounded_in_time_and_memory():
    store = _store()
    _good(store)
    rng = random.Random(41)
    leaves = ["state", "status", "alarms", "alarm", "x"]
    samples = [b"", b"{", b"null", b"[]", b'{"heartbeat": "30"}', b'{"values": {"a": 1}}', b'{"active": 5}',
               b'{"state": 5}', b'{"counters": []}', b'{"devices": [1, 2]}', b"\xff\xfe", b'{"time": "now"}']
    tracemalloc.start()
    base = None
    started = time.monotonic()
    for i in range(10_000):
        site = f"s{rng.randrange(3)}"
        middle = rng.choice(["$instances", f"d{rng.randrange(5)}"])
        topic = f"commission/{site}/{middle}/{rng.choice(leaves)}" if rng.random() < 0.9 else "commission/" + "/x" * rng.randrange(8)
        payload = rng.choice(samples) if rng.random() < 0.7 else bytes(rng.randrange(256) for _ in range(rng.randrange(40)))
        store.handle(topic, payload, now=NOW + i * 0.01)
        if i % 500 == 0:
            store.snapshot(now=NOW + i * 0.01)
        if i == 2000:
            base = tracemalloc.get_traced_memory()[0]
    grown = tracemalloc.get_traced_memory()[0] - base
    tracemalloc.stop()
    assert time.monotonic() - started < 10
    assert grown < 2_000_000, f"memory grew by {grown} bytes"
    assert store.snapshot(now=NOW)["broker"]["ignored"] > 0
