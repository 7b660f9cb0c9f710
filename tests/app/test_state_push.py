"""The store's one producer: watchers follow changes (at most 20/s on a page, 10/s for the server's readers), faults
go to the event log."""

from __future__ import annotations

import asyncio
import time

from app.state import AGE_PERIOD_S, AHEAD, PAGE_GAP_S, PUSH_PERIOD_S, DeviceState, StateStore


def _store() -> tuple[StateStore, DeviceState]:
    store = StateStore()
    state = DeviceState("io-1", "m3io", "can0")
    store.add(state)
    return store, state


def test_watchers_run_on_change_and_once_a_second_otherwise():
    store, state = _store()
    calls = []
    store.watch("io-1", lambda: calls.append(state.version))
    assert store.push(now=100.0) == 1  # first round: everything is new
    assert store.push(now=100.1) == 0  # nothing changed, no age round yet
    state.publish("SSR1", True)
    assert store.push(now=100.2) == 1
    assert store.push(now=100.3) == 0
    assert store.push(now=100.0 + AGE_PERIOD_S + 0.01) == 1  # ages move on even without a change
    assert calls == sorted(calls)


def test_slow_watchers_run_once_a_second_only():
    store, state = _store()
    fast, slow = [], []
    store.watch("io-1", lambda: fast.append(1))
    store.watch("io-1", lambda: slow.append(1), slow=True)
    store.push(now=100.0)  # first round is an age round: both draw
    for i in range(1, 10):  # a frame every round for most of a second
        state.publish("Temp", float(i), "°C")
        store.push(now=100.0 + i * 0.1)
    assert (len(fast), len(slow)) == (10, 1)
    state.publish("Temp", 99.0, "°C")
    store.push(now=100.0 + AGE_PERIOD_S + 0.01)
    assert (len(fast), len(slow)) == (11, 2)


def test_once_a_second_rounds_of_many_devices_are_spread_over_the_second():
    store = StateStore()
    calls: list[str] = []
    for i in range(20):  # 20 devices, each shown on a page
        store.add(DeviceState(f"d{i}", "m3io", "can0"))
        store.watch(f"d{i}", lambda i=i: calls.append(f"d{i}"))
    assert store.push(now=100.0) == 20  # first round: everything is new
    per_round = []
    for k in range(1, 31):  # three seconds without a change
        per_round.append(store.push(now=100.0 + k * 0.1 + 0.001))
    assert sum(per_round) == 60  # every device once a second
    assert max(per_round) <= 2  # and never all of them in one round


def test_many_changes_between_rounds_are_one_call():
    store, state = _store()
    calls = []
    store.watch("io-1", lambda: calls.append(1))
    store.push(now=0.0)
    for i in range(500):
        state.publish("Temp", float(i), "°C")
    assert store.push(now=0.1) == 1
    assert len(calls) == 2


def test_cancelled_and_failing_watchers_stop_being_called():
    store, state = _store()
    calls = []
    w = store.watch("io-1", lambda: calls.append("a"))

    def broken() -> None:
        raise RuntimeError("page gone")

    store.watch("io-1", broken)
    store.push(now=0.0)
    assert store.push_errors == 1
    w.cancel()
    state.publish("SSR1", True)
    store.push(now=0.1)
    assert calls == ["a"]
    assert store._watches["io-1"] == []


def test_fault_rising_and_clearing_is_in_the_event_log():
    store, state = _store()
    state.mark_seen()
    state.publish("SSR2 Si", "ok")
    store.push(now=0.0)
    assert not [e for e in state.events if "fuse" in e.text]
    state.publish("SSR2 Si", "blown")
    store.push(now=0.1)
    state.publish("SSR2 Si", "blown")  # still blown: no second event
    store.push(now=0.2)
    state.publish("SSR2 Si", "ok")
    store.push(now=0.3)
    texts = [(e.level, e.text) for e in state.events if "fuse" in e.text]
    assert texts == [("warning", "fault: SSR2 fuse blown"), ("info", "cleared: SSR2 fuse blown")]


def test_alarms_are_evaluated_once_in_the_store_and_raised_on_good_data_only(monkeypatch):
    """The publishers read the store's alarms: the tile is evaluated once per change of the points its alarms
    follow, whoever asks (the event log's round too), and a tile on stale or offline data raises none."""
    from devices.registry import TileSpec

    store, state = _store()
    evaluations = []
    evaluate = TileSpec.evaluate
    monkeypatch.setattr(TileSpec, "evaluate", lambda spec, point, now: evaluations.append(now) or evaluate(spec, point, now))
    state.mark_seen()
    state.publish("SSR2 Si", "blown")
    now = time.time()
    assert store.active_alarms("io-1", now) == ("SSR2 fuse blown",)
    store.push(now=0.1)
    assert store.active_alarms("io-1", now + 1) == ("SSR2 fuse blown",) and len(evaluations) == 1
    assert [e.text for e in state.events if "fuse" in e.text] == ["fault: SSR2 fuse blown"]
    assert store.active_alarms("io-1", now + 3600) == ()  # stale data raises no alarm
    state.publish("SSR2 Si", "ok")
    assert store.active_alarms("io-1") == () and len(evaluations) == 2
    state.publish("SSR2 Si", "blown")
    state.mark_offline("no answer to 3 requests")
    assert store.active_alarms("io-1") == ()
    assert store.active_alarms("nobody") == ()


def test_going_offline_and_back_is_in_the_event_log():
    _store_, state = _store()
    state.mark_seen()
    state.mark_offline("no answer to 3 requests")
    state.mark_seen()
    texts = [e.text for e in state.events]
    assert texts[0] == "no answer to 3 requests"
    assert texts[1].startswith("back online")


def test_the_producer_runs_on_the_loop_and_stops():
    async def main() -> list[int]:
        store, state = _store()
        seen: list[int] = []
        store.watch("io-1", lambda: seen.append(state.version))
        for i in range(5):
            state.publish("Temp", float(i))
            await asyncio.sleep(0.15)
        await store.stop()
        return seen

    seen = asyncio.run(main())
    assert 3 <= len(seen) <= 8  # followed the changes, about one call per round


def test_watchers_are_told_which_call_is_the_once_a_second_round():
    store, state = _store()
    rounds = []
    store.watch("io-1", lambda: rounds.append(store.age_round))
    store.push(now=100.0)  # first seen: an age round
    for i in range(1, 10):
        state.publish("Temp", float(i), "°C")
        store.push(now=100.0 + i * 0.1)
    store.push(now=100.0 + AGE_PERIOD_S + 0.01)  # no change, the age round only
    assert rounds == [True] + [False] * 9 + [True]
    assert store.age_round is False  # only while watchers run


def test_history_keeps_its_minutes_however_slowly_a_device_is_sampled():
    from app.state import HISTORY_SECONDS

    store, state = _store()
    for i in range(3600):  # two hours of a lock polled every 2 s
        state.add_history({"bolt": float(i % 2)}, now=1000.0 + 2 * i)
    newest = 1000.0 + 2 * 3599
    assert state.history[0][0] >= newest - HISTORY_SECONDS  # ten minutes, not the last 6,000 samples (3.3 hours)
    assert len(state.history) == HISTORY_SECONDS // 2 + 1
    for i in range(20_000):  # and a fast device still at most 10 samples a second
        state.add_history({"bolt": 0.0}, now=newest + 1 + i * 0.01)
    assert len(state.history) == state.history.maxlen == HISTORY_SECONDS * 10


def test_a_write_reaches_its_watchers_in_the_same_turn_not_on_a_timer():
    async def main() -> list[float]:
        store, state = _store()
        delays: list[float] = []
        written = [0.0]
        store.watch("io-1", lambda: delays.append(time.monotonic() - written[0]) if written[0] else None)
        await asyncio.sleep(0.3)  # the first round (everything new) is over
        for i in range(5):
            written[0] = time.monotonic()
            state.publish("Temp", float(i))
            await asyncio.sleep(0.15)  # longer than a device's gap: each write goes out at once
        await store.stop()
        return delays

    delays = asyncio.run(main())
    assert len(delays) >= 5
    assert sorted(delays)[len(delays) // 2] < 0.02  # not up to 100 ms behind as with a 100 ms look-up


def test_a_device_changing_15_times_a_second_reaches_a_page_as_it_changes():
    """A lock's 10 status frames a second and its register answers are about 15 changes a second: on a page each
    reaches the screen as it comes, not on a 100 ms grid of the device's turns (which made the delay depend on the
    phase between the frames and the grid: anything up to 100 ms, the same for every frame of a run)."""
    async def main() -> list[float]:
        store, state = _store()
        delays: list[float] = []
        written = [0.0]

        def seen() -> None:
            if written[0]:
                delays.append(time.monotonic() - written[0])
                written[0] = 0.0

        store.watch("io-1", seen, group="page-1")
        await asyncio.sleep(0.3)  # the first round (everything new) is over
        start = time.monotonic()
        for i in range(45):  # 15 a second for 3 s
            written[0] = time.monotonic()
            state.publish("Temp", float(i))
            await asyncio.sleep(max(0.0, start + (i + 1) / 15 - time.monotonic()))
        await store.stop()
        return delays

    delays = sorted(asyncio.run(main()))
    assert len(delays) >= 30
    assert delays[len(delays) // 2] < 0.02 and delays[int(len(delays) * 0.9)] < 0.04, delays


def test_a_device_writing_fast_is_pushed_at_a_bounded_rate_and_its_last_value_arrives():
    async def main() -> tuple[int, float, float]:
        store, state = _store()
        seen: list[float] = []
        store.watch("io-1", lambda: seen.append(state.points["Temp"].value if "Temp" in state.points else -1))
        start = time.monotonic()
        for i in range(200):  # 200 writes a second for a second
            state.publish("Temp", float(i))
            await asyncio.sleep(0.005)
        spent = time.monotonic() - start
        await asyncio.sleep(0.25)  # the store's last round after the burst
        await store.stop()
        return len(seen), spent, seen[-1]

    calls, spent, last = asyncio.run(main())
    assert calls <= spent / PUSH_PERIOD_S + AHEAD + 3  # 10 a second after a burst of AHEAD + 1, and the once-a-second rounds
    assert last == 199.0  # the newest value is pushed after the last write


def test_a_page_following_many_devices_runs_them_together():
    async def main() -> tuple[int, int, float]:
        store = StateStore()
        loop = asyncio.get_running_loop()
        runs: list[int] = []
        turn = [0, False]

        def called() -> None:
            if not turn[1]:  # the first call of a turn: a new message to the page
                turn[0], turn[1] = turn[0] + 1, True
                loop.call_soon(lambda: turn.__setitem__(1, False))
            runs.append(turn[0])

        for i in range(10):
            store.add(DeviceState(f"d{i}", "m3io", "can0"))
            store.watch(f"d{i}", called, group="page-1")
        await asyncio.sleep(0.2)  # the store's first round (everything new) is over
        runs.clear()
        start = time.monotonic()
        for k in range(100):  # every 10 ms another device changes
            store.devices[f"d{k % 10}"].publish("Temp", float(k))
            await asyncio.sleep(0.01)
        spent = time.monotonic() - start
        await store.stop()
        turns = len(set(runs))
        return len(runs), turns, spent

    calls, turns, spent = asyncio.run(main())
    assert calls >= 50  # every device's changes arrived
    assert turns <= spent / PAGE_GAP_S + AHEAD + 2  # in at most 20 turns a second: one message each


def test_a_device_nobody_watches_costs_no_call():
    async def main() -> int:
        store, state = _store()
        store.ensure_running()
        for i in range(20):
            state.publish("Temp", float(i))
            await asyncio.sleep(0.1)
        await store.stop()
        return store.calls

    assert asyncio.run(main()) == 0
