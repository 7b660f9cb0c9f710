"""Live state of one plant: the device records (see :mod:`devices.live`) and the bus states.

Written only by the bus worker; read by pages and the API. No UI imports. The device-facing
records live in ``devices/live.py`` so adapters never import ``app``; their names are
re-exported here for the pages, the API and the tests.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from devices.live import (
    EVENT_LIMIT,
    HISTORY_SECONDS,
    QUALITIES,
    Counters,
    DeviceState,
    Event,
    LiveValue,
    Point,
    jsonable,
    session_tag,
)

__all__ = [
    "EVENT_LIMIT", "HISTORY_SECONDS", "QUALITIES", "BusState", "Counters", "DeviceState", "Event", "LiveValue", "Point",
    "StateStore", "jsonable", "session_tag",
]


@dataclass
class BusState:
    name: str
    type: str
    endpoint: str
    connected: bool = False
    last_error: str = ""
    reconnects: int = 0
    transactions: deque = field(default_factory=lambda: deque(maxlen=2000))  # monitor ring buffer
    cycle_s: float | None = None  # Modbus: measured time to poll every device once
    address_conflicts: int = 0  # Modbus: answers from another unit than the one asked


log = logging.getLogger(__name__)

PUSH_PERIOD_S = 0.1  # changes reach the pages at most 10 times a second
AGE_PERIOD_S = 1.0  # watchers are called at least this often, so ages and stale marks move on
AGE_PHASES = 10  # the devices' once-a-second rounds fall into this many push rounds, not all into one


class Watch:
    """One reader following one device: ``callback()`` runs after the device changed (at most every
    :data:`PUSH_PERIOD_S`) and at least every :data:`AGE_PERIOD_S`. ``cancel()`` ends it."""

    __slots__ = ("store", "device", "callback", "alive", "slow")

    def __init__(self, store: "StateStore", device: str, callback: Callable[[], object], slow: bool = False):
        self.store, self.device, self.callback, self.alive = store, device, callback, True
        self.slow = slow  # called only once a second (counters, ages): a page that shows them changes once a second

    def cancel(self) -> None:
        if self.alive:
            self.alive = False
            watches = self.store._watches.get(self.device)
            if watches is not None and self in watches:
                watches.remove(self)


class StateStore:
    """All live state of one plant, and the one producer that tells its readers what changed.

    Adapters write the device records; every 0.1 s :meth:`push` looks at which devices changed
    (an integer comparison per device), notes their alarms rising and clearing in their event
    logs, and calls the watchers of the changed devices: the pages, the API and the broker
    publisher follow the store instead of each polling it on a timer of its own.
    """

    def __init__(self) -> None:
        self.devices: dict[str, DeviceState] = {}
        self.buses: dict[str, BusState] = {}
        self._watches: dict[str, list[Watch]] = {}
        self._pushed: dict[str, int] = {}  # device -> version last pushed
        # device -> time of its last once-a-second round. The devices' rounds are spread over the
        # second (AGE_PHASES phases), so that no push calls every watcher of every page at once
        self._aged: dict[str, float] = {}
        self.alarms: dict[str, tuple[str, ...]] = {}  # device -> its tile's alarms as last seen
        self._task: asyncio.Task | None = None
        self.push_errors = 0
        # while watchers run: whether this call is their device's once-a-second round (a watcher
        # that draws read times or ages as well as values then draws both in one go)
        self.age_round = False

    def device(self, name: str) -> DeviceState:
        return self.devices[name]

    # -- following changes ---------------------------------------------------------
    def watch(self, device: str, callback: Callable[[], object], slow: bool = False) -> Watch:
        """Call ``callback`` whenever ``device`` changed (at most 10 times a second) and once a second;
        ``slow``: only once a second (for what moves with every frame, such as counters)."""
        w = Watch(self, device, callback, slow)
        self._watches.setdefault(device, []).append(w)
        self.ensure_running()
        return w

    def ensure_running(self) -> None:
        """Start the producer on the running loop (idempotent; no-op without a loop)."""
        if self._task is not None and not self._task.done():
            return
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        self._task = loop.create_task(self._run(), name="state-push")

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            try:
                await self._task
            except (asyncio.CancelledError, Exception):  # noqa: BLE001 - stopping
                pass
            self._task = None

    async def _run(self) -> None:
        while True:
            await asyncio.sleep(PUSH_PERIOD_S)
            try:
                self.push()
            except Exception:  # the producer must never end
                self.push_errors += 1
                log.exception("pushing live changes failed")

    def push(self, now: float | None = None) -> int:
        """One round: alarms of changed devices, then their watchers; returns the number of calls."""
        now = time.monotonic() if now is None else now
        calls = 0
        for index, (name, state) in enumerate(self.devices.items()):
            changed = self._pushed.get(name) != state.version
            if changed:
                self._pushed[name] = state.version
                self._note_alarms(name, state)
            aged = self._aged.get(name)
            if aged is None:  # first seen: its once-a-second rounds get a phase of their own (see below)
                age_round = True
                self._aged[name] = now - (index % AGE_PHASES) * AGE_PERIOD_S / AGE_PHASES
            else:
                age_round = now - aged >= AGE_PERIOD_S
                if age_round:
                    self._aged[name] = aged + AGE_PERIOD_S if now - aged < 2 * AGE_PERIOD_S else now
            if not (changed or age_round):
                continue
            self.age_round = age_round
            try:
                for w in list(self._watches.get(name, ())):
                    if w.slow and not age_round:
                        continue
                    try:
                        w.callback()
                        calls += 1
                    except Exception:  # one reader's failure does not stop the others
                        self.push_errors += 1
                        log.exception("a watcher of %s failed; it is removed", name)
                        w.cancel()
            finally:
                self.age_round = False
        return calls

    def _note_alarms(self, name: str, state: DeviceState) -> None:
        """Faults are states with a history: each tile alarm rising and clearing goes to the event log."""
        from devices.registry import DEVICE_TYPES

        device_type = DEVICE_TYPES.get(state.type)
        if device_type is None or state.online is not True:
            return
        tile = device_type.tile.evaluate(lambda point: state.entry(point), time.time())
        alarms = tuple(tile["alarms"]) if tile["quality"] in ("good", "unknown") else self.alarms.get(name, ())
        before = self.alarms.get(name, ())
        if alarms == before:
            return
        self.alarms[name] = alarms
        version = state.version
        for text in alarms:
            if text not in before:
                state.event("warning", f"fault: {text}")
        for text in before:
            if text not in alarms:
                state.event("info", f"cleared: {text}")
        state.version = version  # the events themselves are not a new change to push again
