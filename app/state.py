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
from typing import TYPE_CHECKING, Any

from app.i18n import N_
from app.message import Message
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

if TYPE_CHECKING:
    from devices.registry import TileAlarm

__all__ = [
    "EVENT_LIMIT", "HISTORY_SECONDS", "QUALITIES", "BusState", "Counters", "DeviceState", "Event", "LiveValue", "Point",
    "RaisedAlarm", "StateStore", "jsonable", "session_tag",
]


@dataclass(frozen=True)
class RaisedAlarm:
    """An alarm of a device's tile that holds, as the store found it (:meth:`StateStore.raised_alarms`).

    :param alarm: the declaration (``devices/registry.py`` ``TileAlarm``): its text, a template of the point's fields
    :param entry: the live entry of the point it follows, as the alarm was evaluated from it (the fields its
        template names; None where the point was not heard)
    :param text: the alarm in the engineer's words (the event log, MQTT and OPC UA say it so)
    """

    alarm: TileAlarm
    entry: dict[str, Any] | None
    text: str

    @property
    def point(self) -> str:
        """The name of the point the alarm follows."""
        return self.alarm.when.point


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

PUSH_PERIOD_S = 0.1  # the server's readers of a device (publishers, checks, alarms) are called at most 10 times a second
PAGE_GAP_S = 0.05  # the watchers of one page (one group) at most 20 times a second, all its devices in one go; one device's
# watchers on a page at that rate too: a device that changes more often than 10 times a second (a lock's 10 status frames
# and its register answers) would otherwise have every frame wait for its turn on a 100 ms grid, up to 100 ms
AGE_PERIOD_S = 1.0  # watchers are called at least this often, so ages and stale marks move on
AGE_PHASES = 10  # the devices' once-a-second rounds fall into this many slots of the second, not all into one
AHEAD = 3  # a device's or page's calls may run this many periods ahead of their rate (a burst), never more
SERVER = "server"  # the group of watchers that belong to no page (publishers, identity and drift checks)


class Watch:
    """One reader following one device: ``callback()`` runs after the device changed (at most every
    :data:`PUSH_PERIOD_S` for the server's readers, :data:`PAGE_GAP_S` on a page) and at least every :data:`AGE_PERIOD_S`. ``cancel()`` ends it."""

    __slots__ = ("store", "device", "callback", "alive", "slow", "group")

    def __init__(self, store: "StateStore", device: str, callback: Callable[[], object], slow: bool = False,
                 group: "_Group | None" = None):
        self.store, self.device, self.callback, self.alive = store, device, callback, True
        self.slow = slow  # called only once a second (counters, ages): a page that shows them changes once a second
        self.group = group

    def cancel(self) -> None:
        if self.alive:
            self.alive = False
            self.store.unwatch(self)


class _Group:
    """The watchers of one page (or of the server): called together, so that what changed on several
    devices reaches the page in one message, at most every :data:`PAGE_GAP_S`."""

    __slots__ = ("key", "watches", "dirty", "ages", "due", "due_device", "handle", "gap", "ahead", "period")

    def __init__(self, key: object, gap: float = PAGE_GAP_S, ahead: int = AHEAD, period: float = PAGE_GAP_S):
        self.key = key
        self.period = period  # the bound of one device's watchers in this group (at most one call every ``period``)
        # a page: at most every ``gap``, after a burst of ``ahead`` (what changed reaches the screen at once);
        # the server's readers (publishers, checks, alarms): rounds every PUSH_PERIOD_S, changes of many devices together
        self.gap, self.ahead = gap, ahead
        self.watches: dict[str, list[Watch]] = {}  # device -> this group's watchers of it
        self.dirty: set[str] = set()  # devices changed since this group's watchers of them last ran
        self.ages: set[str] = set()  # devices whose once-a-second round is due here
        # the rate bounds, as "theoretical arrival times" (GCRA): the group may run while it is at most
        # AHEAD periods ahead of its bound. A source at exactly the bound's rate (a status frame every 100 ms) is
        # then pushed as it comes, never trailing its frames by a period
        self.due = float("-inf")
        self.due_device: dict[str, float] = {}  # device -> the same for this group's watchers of it
        self.handle: asyncio.Handle | None = None


class StateStore:
    """All live state of one plant, and the one producer that tells its readers what changed.

    Adapters write the device records; a write makes the store call the watchers of that device
    soon after (in the same turn of the loop when the device's last call is older than
    :data:`PAGE_GAP_S` on a page, :data:`PUSH_PERIOD_S` for the server's readers), never on a timer of its own: a page sees a frame within milliseconds
    and nothing runs while nothing changes. The watchers of one page run together (at most every
    :data:`PAGE_GAP_S`), so a page gets one message for what changed meanwhile on all its devices.
    Alarms rising and clearing are noted in the devices' event logs as they change. Once a second
    per watched device (spread over the second) the watchers run anyway, so ages and stale marks
    move on; a device nobody watches has no such round.
    """

    def __init__(self) -> None:
        self.buses: dict[str, BusState] = {}
        self._watches: dict[str, list[Watch]] = {}
        self._pushed: dict[str, int] = {}  # device -> version last pushed by push()
        # device -> time of its last once-a-second round. The devices' rounds are spread over the
        # second (AGE_PHASES phases), so that no round calls every watcher of every page at once
        self._aged: dict[str, float] = {}
        self._phase: dict[str, int] = {}  # device -> its slot of the second
        self.alarms: dict[str, tuple[str, ...]] = {}  # device -> its tile's alarms as last seen (the event log's)
        self._alarm_inputs: dict[str, tuple] = {}  # device -> the values its alarms were last noted from
        self._raised: dict[str, tuple[tuple, tuple[RaisedAlarm, ...]]] = {}  # device -> (inputs, the alarms that hold on them)
        self._groups: dict[object, _Group] = {}
        self._alarms = _Group("alarms", PUSH_PERIOD_S, 0, PUSH_PERIOD_S)  # noting alarms: one more reader of every device, bounded like the others
        self._pending: set[str] = set()  # devices written since the last fan-out
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: int | None = None
        self._fan_handle: asyncio.Handle | None = None
        self._age_handle: asyncio.TimerHandle | None = None
        self.devices: dict[str, DeviceState] = {}  # added by :meth:`add`, each then telling the store of its changes
        self.push_errors = 0
        self.calls = 0  # watcher calls so far (for benchmarks and tests)
        # while watchers run: whether this call is their device's once-a-second round (a watcher
        # that draws read times or ages as well as values then draws both in one go)
        self.age_round = False

    def device(self, name: str) -> DeviceState:
        return self.devices[name]

    def add(self, state: DeviceState) -> DeviceState:
        """Keep ``state`` as the record of its device; from now on each of its writes tells this store
        (``DeviceState.touch``: the one call that notifies)."""
        state.on_change = self.changed
        self.devices[state.name] = state
        self._changed(state.name)
        return state

    # -- following changes ---------------------------------------------------------
    def watch(self, device: str, callback: Callable[[], object], slow: bool = False, group: object = SERVER) -> Watch:
        """Call ``callback`` whenever ``device`` changed (at most 20 times a second on a page, 10 for the server's
        readers) and once a second;
        ``slow``: only once a second (for what moves with every frame, such as counters). ``group``:
        the page the watcher belongs to (its watchers run together, see :data:`PAGE_GAP_S`)."""
        g = self._groups.get(group)
        if g is None:
            g = self._groups[group] = _Group(group) if group != SERVER else _Group(group, PUSH_PERIOD_S, 0, PUSH_PERIOD_S)
        w = Watch(self, device, callback, slow, g)
        self._watches.setdefault(device, []).append(w)
        g.watches.setdefault(device, []).append(w)
        self.ensure_running()
        return w

    def unwatch(self, w: Watch) -> None:
        """Call ``w`` no more (:meth:`Watch.cancel`); a page whose last watcher goes is forgotten."""
        watches = self._watches.get(w.device)
        if watches is not None and w in watches:
            watches.remove(w)
        if w.group is not None:
            self._leave(w)

    def _leave(self, w: Watch) -> None:
        g = w.group
        watches = g.watches.get(w.device)
        if watches is not None and w in watches:
            watches.remove(w)
            if not watches:
                del g.watches[w.device]
                g.dirty.discard(w.device)
                g.ages.discard(w.device)
                g.due_device.pop(w.device, None)
        if not g.watches and self._groups.get(g.key) is g:  # the page is gone
            del self._groups[g.key]
            if g.handle is not None:
                g.handle.cancel()
                g.handle = None

    def ensure_running(self) -> None:
        """Follow changes on the running loop (idempotent; no-op without a loop)."""
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            return
        if self._loop is loop and not loop.is_closed():
            return
        import threading

        self._loop, self._thread = loop, threading.get_ident()
        self._groups = {key: g for key, g in self._groups.items() if g.watches}
        for g in (*self._groups.values(), self._alarms):
            g.handle = None
            self._schedule(g, time.monotonic())
        self._fan_handle = None
        self._age_handle = loop.call_later(AGE_PERIOD_S / AGE_PHASES, self._age_tick)
        self._pending.update(self.devices)
        self._fan_soon()

    async def stop(self) -> None:
        for g in (*self._groups.values(), self._alarms):
            if g.handle is not None:
                g.handle.cancel()
                g.handle = None
        for handle in (self._fan_handle, self._age_handle):
            if handle is not None:
                handle.cancel()
        self._fan_handle = self._age_handle = None
        self._loop = None

    def changed(self, name: str) -> None:
        """A device record was written (its ``touch``, the call every write of it ends with): its readers are called
        soon, once for all writes of this turn of the loop."""
        self._changed(name)

    def _changed(self, name: str) -> None:
        """A device record was written: fan out soon, once for all writes of this turn."""
        if name in self._pending:
            return
        self._pending.add(name)
        if self._fan_handle is None and self._loop is not None:
            self._fan_soon()

    def _fan_soon(self) -> None:
        import threading

        loop = self._loop
        if loop is None or self._fan_handle is not None or loop.is_closed():
            return
        if threading.get_ident() == self._thread:
            self._fan_handle = loop.call_soon(self._fan_out)
        else:  # a writer outside the loop: the loop does the rest
            self._fan_handle = loop.call_soon_threadsafe(self._fan_out)

    def _fan_out(self) -> None:
        """The devices written since the last fan-out: into the groups that watch them."""
        self._fan_handle = None
        names, self._pending = self._pending, set()
        now = time.monotonic()
        for name in names:
            if name not in self.devices:
                continue
            self._alarms.dirty.add(name)
            age = self._age_due(name, now)  # a change when the round is due is that round (one call, not two)
            for g in self._groups.values():
                if name in g.watches:
                    g.dirty.add(name)
                    if age:
                        g.ages.add(name)
                    self._schedule(g, now)
        self._schedule(self._alarms, now)

    def _age_due(self, name: str, now: float) -> bool:
        aged = self._aged.get(name)
        if aged is None:  # first seen: its once-a-second rounds get a phase of their own
            phase = self._phase.setdefault(name, len(self._phase) % AGE_PHASES)
            self._aged[name] = now - phase * AGE_PERIOD_S / AGE_PHASES
            return True
        if now - aged < AGE_PERIOD_S:
            return False
        self._aged[name] = aged + AGE_PERIOD_S if now - aged < 2 * AGE_PERIOD_S else now
        return True

    def _age_tick(self) -> None:
        """Every tenth of a second: the watched devices whose once-a-second round is due. The next tick is
        set first: a failure here (a bug, logged by the loop with its traceback) does not end the rounds."""
        loop = self._loop
        if loop is None:
            return
        self._age_handle = loop.call_later(AGE_PERIOD_S / AGE_PHASES, self._age_tick)
        now = time.monotonic()
        for name, watches in self._watches.items():
            if watches and self._age_due(name, now):
                for g in self._groups.values():
                    if name in g.watches:
                        g.ages.add(name)
                        self._schedule(g, now)

    def _schedule(self, g: _Group, now: float) -> None:
        if g.handle is not None or (not g.dirty and not g.ages) or self._loop is None:
            return
        wait = g.due - g.ahead * g.gap - now
        if g.dirty and not g.ages:  # only changes: none of them is due before its device's own bound
            wait = max(wait, min(g.due_device.get(n, float("-inf")) for n in g.dirty) - g.ahead * g.period - now)
        g.handle = self._loop.call_later(wait, self._run, g) if wait > 0 else self._loop.call_soon(self._run, g)

    def _run(self, g: _Group) -> None:
        """Call one group's watchers of the devices that changed (or whose round is due) for it. A watcher's
        failure is its own (:meth:`_call`); the group's next run is scheduled whatever happens here, so a
        failure of the round itself (a bug, logged by the loop with its traceback) does not end the producer."""
        g.handle = None
        now = time.monotonic()
        g.due = max(g.due, now) + g.gap
        try:
            if g is self._alarms:
                for name in list(g.dirty):
                    due = g.due_device.get(name, float("-inf"))
                    if now >= due - g.ahead * g.period:
                        g.dirty.discard(name)
                        g.due_device[name] = max(due, now) + g.period
                        state = self.devices.get(name)
                        if state is not None:
                            self._note_alarms(name, state)
                return
            for name in list(g.dirty | g.ages):
                age = name in g.ages
                due = g.due_device.get(name, float("-inf"))
                if not age and now < due - g.ahead * g.period:
                    continue  # its device's bound: the next run takes it
                if name in g.dirty:  # a round for ages alone takes nothing from the device's bound
                    g.dirty.discard(name)
                    g.due_device[name] = max(due, now) + g.period
                g.ages.discard(name)
                self._call(g.watches.get(name, ()), age)
        finally:
            self.age_round = False
            self._schedule(g, now)

    def _call(self, watches, age_round: bool) -> int:
        calls = 0
        self.age_round = age_round
        for w in list(watches):
            if w.slow and not age_round:
                continue
            try:
                w.callback()
                calls += 1
            except Exception:  # one reader's failure does not stop the others
                self.push_errors += 1
                log.exception("a watcher of %s failed; it is removed", w.device)
                w.cancel()
        self.calls += calls
        return calls

    def push(self, now: float | None = None) -> int:
        """One round at once, without the loop (tests, a store without a running loop): alarms of the
        changed devices, then the watchers of the changed devices and of those whose once-a-second round
        is due; returns the number of calls."""
        now = time.monotonic() if now is None else now
        calls = 0
        for name, state in self.devices.items():
            changed = self._pushed.get(name) != state.version
            if changed:
                self._pushed[name] = state.version
                self._note_alarms(name, state)
            age_round = self._age_due(name, now)
            if not (changed or age_round):
                continue
            try:
                calls += self._call(self._watches.get(name, ()), age_round)
            finally:
                self.age_round = False
        return calls

    # -- alarms: evaluated here, once per change of the points they follow -----------------------------
    def active_alarms(self, name: str, now: float | None = None) -> tuple[str, ...]:
        """The alarms of the device's tile (devices/registry.py) that hold now, on good data only (a tile whose
        points are stale or offline raises none), in the engineer's words: what the MQTT publisher and the OPC UA
        server publish."""
        return tuple(raised.text for raised in self.raised_alarms(name, now))

    def raised_alarms(self, name: str, now: float | None = None) -> tuple[RaisedAlarm, ...]:
        """:meth:`active_alarms` with what each was found from (its declaration, the point and its fields): what the
        plant view words for an operator, in the operator's language."""
        state = self.devices.get(name)
        device_type = _device_type(state)
        if device_type is None:
            return ()
        now = time.time() if now is None else now
        if tile_quality(device_type.tile, state, now) not in ALARM_QUALITIES:
            return ()
        return self._tile_alarms(name, state, device_type.tile, now)

    def _tile_alarms(self, name: str, state: DeviceState, spec, now: float) -> tuple[RaisedAlarm, ...]:
        """The tile's alarms that hold on the device's values. They follow from the values of the points they
        name: while those are as at the last evaluation, the tile is not evaluated again (most polls bring the
        same values)."""
        inputs = _alarm_inputs(spec, state)
        known = self._raised.get(name)
        if known is not None and known[0] == inputs:
            return known[1]
        tile = spec.evaluate(lambda point: state.entry(point, now), now)
        raised = tuple(RaisedAlarm(alarm, entry, text) for (alarm, entry), text in zip(tile["raised"], tile["alarms"], strict=True))
        self._raised[name] = (inputs, raised)
        return raised

    def _note_alarms(self, name: str, state: DeviceState) -> None:
        """Faults are states with a history: each tile alarm rising and clearing goes to the event log."""
        device_type = _device_type(state)
        if device_type is None or state.online is not True:
            return
        inputs = _alarm_inputs(device_type.tile, state)
        if self._alarm_inputs.get(name) == inputs:
            return
        now = time.time()
        if tile_quality(device_type.tile, state, now) in ALARM_QUALITIES:
            alarms = tuple(raised.text for raised in self._tile_alarms(name, state, device_type.tile, now))
            self._alarm_inputs[name] = inputs
        else:
            alarms = self.alarms.get(name, ())
            self._alarm_inputs.pop(name, None)
        before = self.alarms.get(name, ())
        if alarms == before:
            return
        self.alarms[name] = alarms
        version = state.version
        for text in alarms:
            if text not in before:
                state.event("warning", Message(N_("fault: {text}"), text=text))
        for text in before:
            if text not in alarms:
                state.event("info", Message(N_("cleared: {text}"), text=text))
        state.version = version  # the events themselves are not a new change to push again


ALARM_QUALITIES = ("good", "unknown")  # a tile raises its alarms on these qualities only (not on stale or offline data)
_ALARM_POINTS: dict[int, tuple[str, ...]] = {}
_TILE_POINTS: dict[int, tuple[str, ...]] = {}


def _device_type(state: DeviceState | None):
    """The declaration of the device's type (None: no such device, or a type the registry does not know)."""
    from devices.registry import DEVICE_TYPES

    return DEVICE_TYPES.get(state.type) if state is not None else None


def tile_quality(spec, state: DeviceState, now: float) -> str:
    """The worst quality of the points a tile shows, as its evaluation says it (``unknown``: none heard yet)."""
    from devices.registry import QUALITY_RANK

    names = _TILE_POINTS.get(id(spec))
    if names is None:
        names = _TILE_POINTS[id(spec)] = tuple(sorted(spec.point_names()))
    qualities = [value.quality for n in names if (value := state.live(n, now)) is not None]
    return max(qualities, key=QUALITY_RANK.__getitem__, default="unknown")


def _alarm_inputs(spec, state: DeviceState) -> tuple:
    """What a tile's alarms are evaluated from: each named point's value, text, raw word and unit (a
    register parameter's raw value), not its time."""
    names = _ALARM_POINTS.get(id(spec))
    if names is None:
        names = _ALARM_POINTS[id(spec)] = tuple(sorted(
            {a.when.point for a in spec.alarms} | {a.unless.point for a in spec.alarms if a.unless is not None}))
    return point_inputs(state, names)


def point_inputs(state: DeviceState, names) -> tuple:
    """The named points' value, text, raw word and unit (a register parameter's raw value), not their times:
    what a tile or its alarms are evaluated from, compared to tell whether evaluating again can change them."""
    points, params = state.points, state.params
    inputs = []
    for n in names:
        p = points.get(n)
        if p is not None:
            inputs.append((p.value, p.text, p.raw, p.unit))
        else:
            param = params.by_name.get(n) if params is not None else None
            inputs.append(None if param is None else state.raw(param))
    return tuple(inputs)
