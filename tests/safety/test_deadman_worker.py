"""The dead-man rule measures silence while this program runs on time (issue 32 item 2, issue 33 item 7).

A browser's beats that waited because the server's loop was busy are not a dead browser; a browser
that stays silent while the loop runs on time is. The supervisor is driven by hand with explicit
monotonic times, as its 50 ms tick does (app.worker.loophealth.tick calling DeadmanSupervisor.tick).
"""

from __future__ import annotations

import time

from app.plant import parse_plant
from app.worker import DEADMAN_BOUND_S, DEADMAN_TIMEOUT_S, SUPERVISE_PERIOD_S, Worker


class Holder:
    """Something a session keeps running (an M3IO output, a jog), under the dead-man rule."""

    def __init__(self, session: str):
        self.session = session
        self.lost: list[str] = []
        self.renewed = 0

    def holders(self) -> set[str]:
        return set() if self.lost else {self.session}

    def session_lost(self, session: str, reason: str) -> None:
        if session == self.session:
            self.lost.append(reason)

    def renew_leases(self, alive: set[str]) -> None:
        if self.session in alive:
            self.renewed += 1


def worker_at(t0: float) -> Worker:
    worker = Worker(parse_plant('name = "empty"\n'))
    worker.deadman.live, worker.deadman.live_at = 0.0, t0
    return worker


def tick(worker: Worker, now: float) -> None:
    """One supervision tick at monotonic time ``now`` (what the worker's tick does every 50 ms)."""
    worker.deadman.tick(now)


def held_at(t0: float) -> tuple[Worker, Holder]:
    """A worker at ``t0`` whose session "tab" holds an output and has beaten once."""
    worker = worker_at(t0)
    holder = Holder("tab")
    worker.add_holder("output", holder)
    worker.heartbeat("tab", 1000.0)
    return worker, holder


def tick_until_lost(worker: Worker, holders: list[Holder], start: float) -> int:
    """Tick every supervision period from ``start`` until every one of ``holders`` is lost (40 ticks at the
    most); returns how many ticks that took."""
    n = 0
    while not all(h.lost for h in holders) and n < 40:
        n += 1
        tick(worker, start + n * SUPERVISE_PERIOD_S)
    return n


def test_a_busy_server_is_not_a_dead_browser():
    t0 = time.monotonic()
    worker, holder = held_at(t0)
    # the loop stalls for 0.6 s (a page built, a plot serialised): the browser's beats wait in the socket
    tick(worker, t0 + 0.6)
    assert holder.lost == [], "a server stall was taken for a dead browser"
    worker.heartbeat("tab", 1100.0)  # the waiting beats arrive right after the stall
    for n in range(1, 5):
        tick(worker, t0 + 0.6 + n * SUPERVISE_PERIOD_S)
        worker.heartbeat("tab", 1100.0 + n * 100)
    assert holder.lost == [] and holder.renewed >= 4


def test_a_silent_browser_trips_while_the_server_runs_on_time():
    t0 = time.monotonic()
    worker, holder = held_at(t0)
    silent = tick_until_lost(worker, [holder], time.monotonic()) * SUPERVISE_PERIOD_S
    assert holder.lost, "a silent browser was never stopped"
    assert DEADMAN_TIMEOUT_S - 0.01 <= silent <= DEADMAN_BOUND_S
    assert "while this program ran on time" in holder.lost[0] and "not confirmed it is alive" in holder.lost[0]


def test_a_trip_after_a_stall_says_how_long_the_server_was_busy():
    t0 = time.monotonic()
    worker, holder = held_at(t0)
    last = time.monotonic()
    tick(worker, last + 1.0)  # a 1 s stall, and the browser never beats again
    tick_until_lost(worker, [holder], last + 1.0)
    assert holder.lost
    assert "this program was busy for" in holder.lost[0]


async def test_the_running_worker_ticks_the_supervisor_and_measures_the_loop():
    """The composition: start() runs the 50 ms tick that feeds loop health and the dead-man supervisor."""
    import asyncio

    worker = Worker(parse_plant('name = "empty"\n'))
    holder = Holder("tab")
    worker.add_holder("output", holder)
    await worker.start()
    try:
        worker.heartbeat("tab", 1000.0)  # one beat, then silence
        loop = asyncio.get_running_loop()
        end = loop.time() + 3.0
        while not holder.lost and loop.time() < end:
            await asyncio.sleep(SUPERVISE_PERIOD_S)
        assert holder.lost and "not confirmed it is alive" in holder.lost[0]
        assert len(worker.loop_health.lags_ms) >= DEADMAN_TIMEOUT_S / SUPERVISE_PERIOD_S
        assert worker.deadman.trips and worker.deadman.trips[-1]["session"] == "tab"
    finally:
        await asyncio.wait_for(worker.stop(), 10)
    assert worker.tasks == []


# -- pages beat only while needed: the supervisor asks the page of a holding session to beat ---------------------

class Resumer(Holder):
    """A holder that keeps idle control over a dropped connection and gives it back on the first beat."""

    def __init__(self, session: str):
        super().__init__(session)
        self.holding = False
        self.back: list[str] = []

    def holders(self) -> set[str]:
        return {self.session} if self.holding and not self.lost else set()

    def session_back(self, session: str) -> None:
        self.back.append(session)


def asking_worker(t0: float) -> tuple[Worker, list[tuple[str, bool]]]:
    worker = worker_at(t0)
    asks: list[tuple[str, bool]] = []
    worker.on_beat_ask(lambda session, on: asks.append((session, on)))
    return worker, asks


def test_the_page_of_a_holding_session_is_asked_to_beat_and_told_to_stop_after_the_hold():
    from app.worker import BEAT_RELEASE_S

    t0 = time.monotonic()
    worker, asks = asking_worker(t0)
    holder = Resumer("tab")
    worker.add_holder("output", holder)
    worker.session_opened("tab")
    tick(worker, t0 + SUPERVISE_PERIOD_S)
    assert asks == [], "a page that holds nothing was asked to beat"
    worker.heartbeat("tab", 1000.0)  # the interaction that switches the output on beats first
    holder.holding = True
    now = t0 + 2 * SUPERVISE_PERIOD_S
    tick(worker, now)
    assert asks == [("tab", True)]
    for n in range(1, 20):  # 1 s of holding while beating: asked once, never tripped
        worker.heartbeat("tab", 1000.0 + n * 50)
        tick(worker, now + n * SUPERVISE_PERIOD_S)
    assert asks == [("tab", True)] and holder.lost == [] and holder.renewed >= 19
    holder.holding = False
    off = now + 20 * SUPERVISE_PERIOD_S
    tick(worker, off)
    tick(worker, off + BEAT_RELEASE_S - 2 * SUPERVISE_PERIOD_S)
    assert asks == [("tab", True)], "told to stop while it might hold again at once"
    tick(worker, off + BEAT_RELEASE_S)
    assert asks == [("tab", True), ("tab", False)]
    tick(worker, off + BEAT_RELEASE_S + 1.0)
    assert asks == [("tab", True), ("tab", False)], "told twice"


def test_the_rule_is_the_same_for_an_asked_page_that_goes_silent_and_for_one_that_never_beat():
    """Asking changes what the page sends, never when a silent session trips."""
    t0 = time.monotonic()
    worker, asks = asking_worker(t0)
    silent, never = Resumer("tab"), Resumer("other")
    worker.add_holder("output", silent)
    worker.add_holder("jog", never)
    worker.heartbeat("tab", 1000.0)
    silent.holding = never.holding = True
    n = tick_until_lost(worker, [silent, never], t0)
    assert silent.lost and never.lost
    assert ("tab", True) in asks and ("other", True) in asks
    assert n * SUPERVISE_PERIOD_S <= DEADMAN_BOUND_S


def test_a_page_that_reconnects_is_asked_to_beat_and_its_first_beat_gives_its_control_back():
    from app.worker import BEAT_RELEASE_S

    t0 = time.monotonic()
    worker, asks = asking_worker(t0)
    holder = Resumer("tab")  # idle control: held, nothing running (not among the holders)
    worker.add_holder("control", holder)
    worker.session_opened("tab")
    worker.session_connected("tab")
    assert asks == [], "a page's first connection is no reconnect"
    worker.session_closed("tab")
    worker.session_connected("tab")  # it came back: its page is asked to beat
    assert asks == [("tab", True)]
    worker.heartbeat("tab", 5000.0)
    assert holder.back == ["tab"]
    tick(worker, t0 + BEAT_RELEASE_S + 0.1)
    assert asks == [("tab", True), ("tab", False)], "it holds nothing: told to stop"
    worker.session_closed("tab")
    worker.session_deleted("tab")
    worker.session_connected("tab")
    assert asks == [("tab", True), ("tab", False)], "a page gone for good is not asked"
