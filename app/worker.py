"""The bus worker: owns every transport, polls every device, runs commands from pages.

Pages never touch a transport. They read :class:`~app.state.StateStore` and call
:meth:`Worker.command`, which checks the role, runs the adapter method on the bus
task's transport and returns the result or a clear error.
"""

from __future__ import annotations

import asyncio
import importlib
import logging
import time
from collections import OrderedDict, deque
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, field
from typing import Any

from app import gate
from app.gate import AuditUnavailable, PermissionDenied  # noqa: F401 - raised by the gate; named here for callers
from app.audit import AuditLog
from app.can_bus import CanBus, CanBusState
from app.modbus_line import ModbusLine
from app.logited import LogitedRs485, LogitedTcp
from app.serial_line import SerialLine
from app.plant import DeviceConfig, Plant, can_id_conflict
from app.state import BusState, DeviceState, StateStore
from devices.adapter import LeaseRenewer, SessionHolder, SessionResumer, SessionStopper, ShutdownAdapter
from devices.registry import DEVICE_TYPES, CanIdUse, fixed_can_id_uses

log = logging.getLogger(__name__)

WRITE_ROLES = {"engineer"}

# Dead-man rule (ARCHITECTURE rule 6): every page confirms it is alive about ten times a
# second; motion and mains outputs of a session that stopped confirming (closed, disconnected,
# frozen, network lost) are stopped within DEADMAN_BOUND_S of its last confirmation.
BEAT_PERIOD_S = 0.1
DEADMAN_TIMEOUT_S = 0.4  # a browser tab starved of CPU on a loaded laptop (another tab loading) sends a beat 300+ ms late
SUPERVISE_PERIOD_S = 0.05
DEADMAN_BOUND_S = 0.5  # the stated bound: timeout + one supervision period (0.45 s) + sending
STALL_S = 0.1  # an event-loop stall longer than this is logged and shown
# Silence is counted on a clock that runs only while this program runs on time: a supervision tick
# credits at most LIVE_CREDIT_S however late it comes, so beats that waited in the socket because the
# server was busy are not mistaken for a dead browser (a stalled loop is covered by the leases instead).
LIVE_CREDIT_S = 2 * SUPERVISE_PERIOD_S
SILENCE_LIMIT_S = 2.0  # however busy this program was: no sign of life for this long in real time stops the session
LAG_WINDOW = 1200  # supervision ticks kept for the loop-lag figures (one minute)


@dataclass
class LoopHealth:
    """How late the event loop runs the 50 ms supervision tick (it carries every keep-alive)."""

    lags_ms: deque = field(default_factory=lambda: deque(maxlen=LAG_WINDOW))
    stalls: int = 0
    worst_ms: float = 0.0
    last_stall: float | None = None

    def add(self, lag_s: float, now: float) -> None:
        lag_ms = max(0.0, lag_s * 1000)
        self.lags_ms.append(lag_ms)
        self.worst_ms = max(self.worst_ms, lag_ms)
        if lag_s > STALL_S:
            self.stalls += 1
            self.last_stall = now
            log.warning("event loop stalled for %.0f ms: keep-alives were late", lag_ms)

    def p99_ms(self) -> float:
        if not self.lags_ms:
            return 0.0
        ordered = sorted(self.lags_ms)
        return ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))]

    def summary(self) -> dict:
        recent = self.lags_ms[-1] if self.lags_ms else 0.0
        return {"lag_ms": round(recent, 1), "p99_ms": round(self.p99_ms(), 1), "worst_ms": round(self.worst_ms, 1),
                "stalls": self.stalls, "last_stall": self.last_stall}


MAX_CANDIDATES = 512  # unknown CAN IDs watched per bus while they show evidence; beyond, new ones are dropped and counted
MAX_DISCOVERED = 128  # devices listed as discovered per bus
CANDIDATE_STALE_PERIODS = 2.5  # a candidate silent for this many of its periods gives its place to a new one
# A flood: more new IDs of a device's form within one second than a plant ever powers up at once. Discovery
# then lists nothing (a flood cycling through IDs at a device's period would look like a crowd of devices),
# watches nothing, and says so; it resumes once FLOOD_QUIET_S passed without such a second.
FLOOD_NEW_IDS_PER_S = 64
FLOOD_QUIET_S = 10.0


@dataclass(slots=True)
class _Candidate:
    """An unknown ID whose frames have the form of a device's: the evidence so far."""

    entry: dict  # the codec's ``discovered()`` answer for the last fitting frame
    heard: float  # time of the last frame (the frame's own time stamp)
    first_seen: float  # wall clock
    frames: int = 1
    streak: int = 1  # fitting frames in a row at the expected period
    last_fit: float | None = None  # time of the last fitting frame
    intervals: deque = field(default_factory=lambda: deque(maxlen=4))

    def __post_init__(self) -> None:
        self.last_fit = self.heard

    @property
    def period_s(self) -> float:
        return (self.entry.get("evidence") or {}).get("period_s", 1.0)

    def add(self, entry: dict | None, heard: float) -> None:
        self.frames += 1
        self.heard = heard
        if entry is None or entry.get("type") != self.entry.get("type"):
            self.streak, self.last_fit = 0, None  # a frame of another form on this ID: start over
            return
        evidence = entry.get("evidence") or {}
        period, tolerance = evidence.get("period_s"), evidence.get("tolerance", 0.0)
        if self.last_fit is None or period is None:
            self.streak = 1
        else:
            interval = heard - self.last_fit
            self.intervals.append(interval)
            # too fast (another sender, a flood) or a gap (lost frames): the count starts over
            self.streak = self.streak + 1 if abs(interval - period) <= tolerance * period else 1
        self.last_fit = heard
        self.entry = entry

    def convinced(self) -> bool:
        return self.streak >= (self.entry.get("evidence") or {}).get("frames", 1)

    def evidence_text(self) -> str:
        if not self.intervals:
            return f"{self.frames} frame{'s' if self.frames != 1 else ''}"
        shown = ", ".join(f"{i:.2f}" for i in list(self.intervals)[-(self.streak - 1):])
        return f"{self.streak} frames in a row, {shown} s apart"


@dataclass
class CanDiscovery:
    """Discovery on one CAN bus: bounded candidates, the refused IDs and what was left out."""

    refused: dict[tuple[bool, int], str] = field(default_factory=dict)  # ID -> its use by a device type
    refused_ranges: list[tuple[CanIdUse, str]] = field(default_factory=list)
    candidates: OrderedDict = field(default_factory=OrderedDict)  # key -> _Candidate, least recently heard first
    dropped: int = 0  # new candidates not watched: the table was full of live ones
    evicted: int = 0  # candidates that went silent and gave their place
    refused_frames: int = 0  # frames on IDs that a device type occupies
    listed_dropped: int = 0  # devices not listed: the list was full
    window_start: float = 0.0  # frame time of the current one-second window
    window_ids: set = field(default_factory=set)  # new IDs of a device's form heard in it (at most FLOOD_NEW_IDS_PER_S + 1)
    flood_until: float = 0.0  # frame time until which discovery is paused (0: no flood)
    flood_since: float | None = None  # wall clock: when the flood was seen
    flood_end: float = 0.0  # wall clock: when discovery resumes unless the flood goes on
    floods: int = 0
    flood_frames: int = 0  # frames of unknown IDs that arrived during floods

    def roll_window(self, heard: float) -> None:
        """Start a new one-second window when ``heard`` is past the current one."""
        if heard - self.window_start >= 1.0 or heard < self.window_start:
            self.window_start = heard
            self.window_ids.clear()

    def flooded(self, key: tuple[bool, int], heard: float, recognised: bool) -> bool:
        """Count a frame of an unknown ID in the one-second window; True while the bus is flooded
        (nothing is watched or listed then)."""
        if recognised and len(self.window_ids) <= FLOOD_NEW_IDS_PER_S:
            self.window_ids.add(key)
            if len(self.window_ids) > FLOOD_NEW_IDS_PER_S:
                self._flood(heard)
        if self.flood_until and heard >= self.flood_until:
            self.flood_until = 0.0  # quiet for FLOOD_QUIET_S: discovery resumes
            self.flood_since = None
            log.info("discovery resumes: no flood of new CAN IDs for %.0f s", FLOOD_QUIET_S)
        if self.flood_until:
            self.flood_frames += 1
            return True
        return False

    def _flood(self, heard: float) -> None:
        if not self.flood_until:
            self.floods += 1
            self.flood_since = time.time()
            log.warning("CAN discovery: a flood of new IDs (over %d a second): nothing is listed until it has been quiet "
                        "for %.0f s; %d watched IDs forgotten", FLOOD_NEW_IDS_PER_S, FLOOD_QUIET_S, len(self.candidates))
            self.candidates.clear()  # flood-born: none of them is evidence of a device
        self.flood_until = heard + FLOOD_QUIET_S
        self.flood_end = time.time() + FLOOD_QUIET_S

    def refused_reason(self, key: tuple[bool, int]) -> str | None:
        reason = self.refused.get(key)
        if reason is None and self.refused_ranges:
            reason = next((r for use, r in self.refused_ranges if use.covers(*key)), None)
        return reason

    def make_room(self, now: float) -> bool:
        """Forget up to two silent candidates (oldest first); True when a new one fits."""
        for _ in range(2):
            if not self.candidates:
                break
            oldest = next(iter(self.candidates.values()))
            if now - oldest.heard <= CANDIDATE_STALE_PERIODS * oldest.period_s:
                break
            self.candidates.popitem(last=False)
            self.evicted += 1
        return len(self.candidates) < MAX_CANDIDATES


class Worker:
    """Runs one polling task per bus; every adapter is reached through it."""

    def __init__(self, plant: Plant, store: StateStore | None = None, audit: AuditLog | None = None):
        self.plant = plant
        self.audit = audit
        self.store = store or StateStore()
        self.lines: dict[str, ModbusLine | SerialLine | LogitedTcp | LogitedRs485] = {}
        self.adapters: dict[str, Any] = {}
        self.tasks: list[asyncio.Task] = []
        self.paused: set[str] = set()
        self.sessions: dict[str, str] = {}  # connected browser sessions -> role
        self.beats: dict[str, float] = {}  # session -> monotonic time of its last sign of life
        self._beats_live: dict[str, float] = {}  # session -> the live clock (LIVE_CREDIT_S) at its last sign of life
        self._browser_sent: dict[str, float] = {}  # session -> the browser's own time of its last beat (ms)
        self.late_beats = 0  # beats that came late because this program was busy, not because the browser was silent
        self._live = 0.0  # seconds this program ran on time (advanced by the supervision tick)
        self._live_at: float | None = None  # monotonic time of the last advance
        self._holding_since: dict[str, float] = {}  # holders that never sent a beat (live clock)
        self.trips: deque[dict] = deque(maxlen=100)  # dead-man trips, newest last
        self.extra_holders: dict[str, Any] = {}  # transmit lists, replays: under the dead-man rule like adapters
        self.loop_health = LoopHealth()
        self.can_buses: dict[str, CanBus] = {}
        for bus in plant.buses.values():
            if bus.type == "can":
                can_state = CanBusState(bus.name, bus.type, f"{bus.options['interface']} {bus.options['channel']}")
                self.store.buses[bus.name] = can_state
                self.can_buses[bus.name] = CanBus(bus.name, bus.options, can_state)
            else:
                bus_state = BusState(bus.name, bus.type, bus.endpoint)
                self.store.buses[bus.name] = bus_state
                line_class = {"serial": SerialLine, "logited-tcp": LogitedTcp, "logited-rs485": LogitedRs485}.get(bus.type, ModbusLine)
                self.lines[bus.name] = line_class(bus.name, bus.options, bus_state)
        self.discovered: dict[str, dict[tuple[bool, int], dict]] = {name: {} for name in self.can_buses}  # listed devices
        self._discovery_codecs = {
            t.name: importlib.import_module(t.can_codec) for t in DEVICE_TYPES.values() if t.can_codec and "can" in t.bus_types
        }
        self.discovery: dict[str, CanDiscovery] = {name: CanDiscovery() for name in self.can_buses}
        for name, can_bus in self.can_buses.items():
            can_bus.listeners.append(lambda msg, bus=name: self._discover_frame(bus, msg))
        for dev in plant.devices.values():
            self._add_adapter(dev)
        for name in self.can_buses:
            self._refuse_ids(name)

    def _add_adapter(self, dev: DeviceConfig) -> None:
        device_type = DEVICE_TYPES[dev.type]
        bus = self.plant.buses[dev.bus]
        period = bus.options.get("poll_period", 0.5)
        state = DeviceState(
            dev.name, dev.type, dev.bus, params=device_type.params,
            stale_after=max(3.0, 3 * period + 2 * bus.options.get("timeout", 0.5)),
        )
        self.store.devices[dev.name] = state
        transport = self.lines.get(dev.bus) or self.can_buses.get(dev.bus)
        self.adapters[dev.name] = device_type.adapter_class(bus.type)(dev, state, transport)
        attach = getattr(transport, "attach_device", None)
        if attach is not None and isinstance(dev.options.get("address"), int):
            attach(dev.options["address"], state)  # its stale threshold follows the line's measured cycle

    # -- CAN discovery -----------------------------------------------------------------------
    def _refuse_ids(self, bus: str) -> None:
        """IDs never listed as a discovered device on ``bus``: every type's fixed IDs, and the
        IDs of the devices configured there (``DeviceType.can_fixed_ids`` / ``can_ids``)."""
        table = self.discovery[bus]
        table.refused.clear()
        table.refused_ranges.clear()
        uses = [(t, use) for t, use in fixed_can_id_uses()]
        for dev in self.plant.devices_on(bus):
            device_type = DEVICE_TYPES[dev.type]
            uses += [(device_type, use) for use in device_type.can_ids(dev.options, "can")]
        for device_type, use in uses:
            reason = f"{use.use} ({device_type.title})"
            if use.last - use.first < 4096:
                for can_id in range(use.first, use.last + 1):
                    table.refused.setdefault((use.extended, can_id), reason)
            else:  # a wide range is checked as a range: the per-frame cost stays bounded
                table.refused_ranges.append((use, reason))
        for key in [k for k in table.candidates if table.refused_reason(k)]:
            del table.candidates[key]
        for key in [k for k in self.discovered[bus] if table.refused_reason(k)]:
            del self.discovered[bus][key]

    def _recognise(self, msg, data: bytes) -> dict | None:
        for codec in self._discovery_codecs.values():
            try:
                entry = codec.discovered(msg.arbitration_id, msg.is_extended_id, data)
            except Exception:  # noqa: BLE001 - a frame a codec cannot parse is simply not its device
                entry = None
            if entry:
                return entry
        return None

    def _discover_frame(self, bus: str, msg) -> None:
        """A frame whose ID no adapter owns: a piece of evidence for a device to list.

        O(1) per frame: dictionary look-ups and one codec call per device type. A device is
        listed only after the evidence its codec asks for (e.g. an HD-Lock: three status
        frames about 1 s apart) on an ID that no device type occupies; until then it is a
        candidate in a bounded table (a flood of new IDs is dropped and counted).
        """
        key = (msg.is_extended_id, msg.arbitration_id)
        listed = self.discovered[bus].get(key)
        if listed is not None:
            listed["last_seen"] = time.time()
            listed["frames"] += 1
            return
        table = self.discovery[bus]
        if table.refused_reason(key):
            table.refused_frames += 1
            return
        data = bytes(msg.data)
        heard = msg.timestamp if msg.timestamp and msg.timestamp > 0 else time.time()
        candidate = table.candidates.get(key)
        if candidate is None:
            table.roll_window(heard)
            if key in table.window_ids:  # heard in this second already: no codec call (a flood repeats itself)
                entry = None
            else:
                entry = self._recognise(msg, data)
            if table.flooded(key, heard, entry is not None) or entry is None:
                return
            if not table.make_room(heard):
                table.dropped += 1
                return
            candidate = table.candidates[key] = _Candidate(entry, heard, time.time())
        else:
            table.candidates.move_to_end(key)
            codec = self._discovery_codecs.get(candidate.entry["type"])
            try:
                entry = codec.discovered(msg.arbitration_id, msg.is_extended_id, data) if codec else None
            except Exception:  # noqa: BLE001 - not the device's frame
                entry = None
            candidate.add(entry, heard)
        if candidate.convinced():
            del table.candidates[key]
            if len(self.discovered[bus]) >= MAX_DISCOVERED:
                table.listed_dropped += 1
                return
            now = time.time()
            listed = dict(candidate.entry)
            listed.pop("evidence", None)
            listed.update(first_seen=candidate.first_seen, last_seen=now, frames=candidate.frames, bus=bus,
                          evidence=candidate.evidence_text())
            self.discovered[bus][key] = listed
            log.info("%s: discovered %s at CAN ID 0x%X (%s-bit): %s", bus, listed["type"], key[1], "29" if key[0] else "11",
                     listed["evidence"])

    def discovery_summary(self, bus: str) -> dict:
        """What the overview shows under the discovered devices of a CAN bus."""
        table = self.discovery.get(bus)
        if table is None:
            return {}
        rules = []
        for type_name, codec in self._discovery_codecs.items():
            evidence = getattr(codec, "DISCOVERY_EVIDENCE", None)
            if evidence:
                rules.append(f"{DEVICE_TYPES[type_name].title}: {evidence['frames']} {evidence.get('text', 'frames')} "
                             f"about {evidence['period_s']:g} s apart")
        flood = ""
        if table.flood_until and time.time() < table.flood_end:
            flood = (f"flood of new CAN IDs since {time.strftime('%H:%M:%S', time.localtime(table.flood_since))} "
                     f"(over {FLOOD_NEW_IDS_PER_S} new IDs a second): "
                     f"nothing is listed until it has been quiet for {FLOOD_QUIET_S:.0f} s")
        return {"candidates": len(table.candidates), "dropped": table.dropped, "refused_frames": table.refused_frames,
                "listed_dropped": table.listed_dropped, "rules": rules, "flood": flood, "floods": table.floods,
                "flood_frames": table.flood_frames}

    # -- browser sessions -------------------------------------------------------------------
    def session_opened(self, session: str, role: str = "engineer") -> None:
        self.sessions[session] = role

    def session_closed(self, session: str) -> None:
        """A page's connection dropped (closed, reloaded, or a reconnect under load): stop at once what it
        keeps running (motion, mains outputs). Idle control, which moves nothing, stays with the page until
        it is gone for good (:meth:`session_deleted`), so a page that reconnects keeps it."""
        self.beats.pop(session, None)
        self._beats_live.pop(session, None)
        self._browser_sent.pop(session, None)
        self._holding_since.pop(session, None)
        reason = "the controlling browser disconnected"
        for name, adapter in self._holder_items():
            if isinstance(adapter, SessionStopper):
                stop = adapter.session_stop
            elif isinstance(adapter, SessionHolder):
                stop = adapter.session_lost
            else:
                continue
            try:
                stop(session, reason)
            except Exception:  # one adapter's failure must not keep the others running
                log.exception("%s: stopping for a disconnected session failed", name)

    def session_deleted(self, session: str) -> None:
        """A page is gone for good (it did not reconnect): release everything it controlled."""
        self.sessions.pop(session, None)
        self.beats.pop(session, None)
        self._beats_live.pop(session, None)
        self._browser_sent.pop(session, None)
        self._holding_since.pop(session, None)
        self._session_lost(session, "the controlling browser's page is gone")

    def _live_clock(self, now: float) -> float:
        """Seconds this program ran on time up to ``now`` (a stall counts as at most LIVE_CREDIT_S)."""
        if self._live_at is None:
            return self._live
        return self._live + min(max(0.0, now - self._live_at), LIVE_CREDIT_S)

    def heartbeat(self, session: str, sent_ms: float | None = None) -> None:
        """A page confirms it is alive (about every :data:`BEAT_PERIOD_S`).

        :param sent_ms: the browser's own clock when it sent the beat (``performance.now()`` of its tick
            worker), to tell a beat that came late because this program was busy from a browser that was silent
        """
        now = time.monotonic()
        last = self.beats.get(session)
        if last is None:  # its first beat, or the first since its connection dropped: what it controls is its own again
            for name, adapter in self._holder_items():
                if isinstance(adapter, SessionResumer):
                    try:
                        adapter.session_back(session)
                    except Exception:  # noqa: BLE001 - one adapter's failure must not stop the beats
                        log.exception("%s: session_back failed", name)
        self.beats[session] = now
        self._beats_live[session] = self._live_clock(now)
        if isinstance(sent_ms, int | float) and not isinstance(sent_ms, bool) and sent_ms == sent_ms:
            before = self._browser_sent.get(session)
            self._browser_sent[session] = float(sent_ms)
            if last is not None and before is not None and now - last > DEADMAN_TIMEOUT_S:
                browser_gap_s = (float(sent_ms) - before) / 1000
                if browser_gap_s < DEADMAN_TIMEOUT_S:  # sent on time, received late: this program (or the network) was slow
                    self.late_beats += 1
                    log.info("session %s: a beat came %.0f ms after the one before, but the browser's ticks were %.0f ms apart: "
                             "late on the way (this program, the network or the page was busy), not a dead browser",
                             session, (now - last) * 1000, browser_gap_s * 1000)

    def add_holder(self, name: str, holder: Any) -> None:
        """Put something that is not a device adapter (an engineer's cyclic transmit list, a replay)
        under the dead-man rule: it offers ``holders()`` and ``session_lost(session, reason)`` like an adapter."""
        self.extra_holders[name] = holder

    def remove_holder(self, name: str) -> None:
        self.extra_holders.pop(name, None)

    def _holder_items(self) -> list[tuple[str, Any]]:
        return [*self.adapters.items(), *self.extra_holders.items()]

    def _session_lost(self, session: str, reason: str) -> None:
        for name, adapter in self._holder_items():
            if not isinstance(adapter, SessionHolder):
                continue
            try:
                adapter.session_lost(session, reason)
            except Exception:  # one adapter's failure must not keep the others running
                log.exception("%s: stopping for a lost session failed", name)

    def _supervise_deadman(self, now: float) -> None:
        """Stop what a session keeps running once it has not confirmed it is alive for DEADMAN_TIMEOUT_S
        of this program's running time; renew the leases of the sessions that did (devices/lease.py)."""
        holding: set[str] = set()
        for _name, adapter in self._holder_items():
            if isinstance(adapter, SessionHolder):
                holding |= adapter.holders()
        for session in list(self._holding_since):
            if session not in holding:
                del self._holding_since[session]
        live_now = self._live_clock(now)
        alive: set[str] = set()
        for session in holding:
            last = self._beats_live.get(session)
            if last is None:
                last = self._holding_since.setdefault(session, live_now)
            silent = live_now - last
            heard = self.beats.get(session)
            waited = now - heard if heard is not None else silent
            if silent <= DEADMAN_TIMEOUT_S and waited <= SILENCE_LIMIT_S:
                alive.add(session)
                continue
            busy = max(0.0, waited - silent)
            reason = (f"dead-man: the controlling browser has not confirmed it is alive for {silent * 1000:.0f} ms "
                      "while this program ran on time (the browser is frozen, asleep or its network is lost)")
            if busy > SUPERVISE_PERIOD_S:
                reason += f"; besides, this program was busy for {busy * 1000:.0f} ms of the {waited * 1000:.0f} ms since its last beat"
            log.warning("session %s: %s", session, reason)
            self._session_lost(session, reason)
            self._holding_since.pop(session, None)
            self.trips.append({"session": session, "time": time.time(), "silent_ms": round(silent * 1000),
                               "busy_ms": round(busy * 1000)})
        if alive:
            for name, adapter in self._holder_items():
                if not isinstance(adapter, LeaseRenewer):
                    continue
                try:
                    adapter.renew_leases(alive)
                except Exception:  # one adapter's failure must not keep the others' leases from renewing
                    log.exception("%s: renewing its lease failed", name)

    async def _supervise(self) -> None:
        """Every 50 ms: measure how late the loop runs, and apply the dead-man rule."""
        loop = asyncio.get_running_loop()
        expected = loop.time() + SUPERVISE_PERIOD_S
        self._live_at = time.monotonic()
        while True:
            await asyncio.sleep(max(0.0, expected - loop.time()))
            now = loop.time()
            self.loop_health.add(now - expected, time.time())
            expected = now + SUPERVISE_PERIOD_S
            mono = time.monotonic()
            self._live = self._live_clock(mono)
            self._live_at = mono
            try:
                self._supervise_deadman(mono)
            except Exception:  # the supervisor itself must never end
                log.exception("dead-man supervision failed")

    def known_ids(self, bus: str) -> set[tuple[bool, int]]:
        """IDs of devices on a CAN bus (in the plant or discovered): for decoding in the monitor."""
        can_bus = self.can_buses.get(bus)
        if can_bus is None:
            return set()
        return set(can_bus.handlers) | set(self.discovered.get(bus, {}))

    def adopt(self, dev: DeviceConfig) -> None:
        """Take a discovered device into the running plant (the plant file is the caller's business).

        :raises ValueError: the name exists, or the device would share a CAN ID with a device of the bus
        """
        if dev.name in self.plant.devices:
            raise ValueError(f"a device named {dev.name!r} exists already")
        bus = self.plant.buses.get(dev.bus)
        if bus is None:
            raise ValueError(f"no bus named {dev.bus!r} in this plant")
        conflict = can_id_conflict(self.plant.devices_on(dev.bus) + [dev], bus)
        if conflict is not None:
            raise ValueError(conflict[1])
        self.plant.devices[dev.name] = dev
        self._add_adapter(dev)
        for key, entry in list(self.discovered.get(dev.bus, {}).items()):
            if DEVICE_TYPES[dev.type].bus_identity(dev.options, "can") == DEVICE_TYPES[entry["type"]].bus_identity(
                {"device_id": entry["device_id"], "extended": entry["extended"]}, "can"
            ):
                del self.discovered[dev.bus][key]
        if dev.bus in self.discovery:
            self._refuse_ids(dev.bus)

    async def start(self) -> None:
        for can_bus in self.can_buses.values():
            await can_bus.start()
        for name in self.plant.buses:
            self.tasks.append(asyncio.create_task(self._poll_bus(name), name=f"bus {name}"))
        self.tasks.append(asyncio.create_task(self._supervise(), name="supervisor"))
        self.store.ensure_running()  # the one producer that pushes changes to pages and publishers

    async def stop(self) -> None:
        # A cancellation can be swallowed when pymodbus's wait_for gets its answer in the same
        # loop iteration: cancel again until every task has really ended (bounded).
        pending = set(self.tasks)
        loop = asyncio.get_running_loop()
        end = loop.time() + 5.0
        while pending and loop.time() < end:
            for task in pending:
                task.cancel()
            _done, pending = await asyncio.wait(pending, timeout=0.2)
        for task in pending:
            log.error("bus task %s did not end", task.get_name())
        self.tasks.clear()
        # an adapter's last words on its still open line, answered (e.g. MO 64 levels deactivated and acknowledged)
        last = [a.shutdown() for a in self.adapters.values() if isinstance(a, ShutdownAdapter)]
        if last:
            try:
                await asyncio.wait_for(asyncio.gather(*last, return_exceptions=True), 5.0)
            except asyncio.TimeoutError:
                log.error("the adapters' shutdown steps did not end within 5 s")
        for line in self.lines.values():
            line.close()
        for can_bus in self.can_buses.values():
            await can_bus.stop()
        await self.store.stop()

    async def _poll_bus(self, bus_name: str) -> None:
        """Round-robin polling of every device on the bus, at the configured period."""
        bus = self.plant.buses[bus_name]
        period = bus.options.get("poll_period", 0.5)
        while True:
            started = time.monotonic()
            can_bus = self.can_buses.get(bus_name)
            if can_bus is not None and not can_bus.state.connected:
                for name in [d.name for d in self.plant.devices_on(bus_name)]:
                    if self.store.devices[name].online is not False and can_bus.state.last_error:
                        self.store.devices[name].mark_offline(f"bus {bus_name}: {can_bus.state.last_error}")
            elif bus_name not in self.paused:
                for name in [d.name for d in self.plant.devices_on(bus_name)]:
                    try:
                        await self.adapters[name].poll()
                    except asyncio.CancelledError:
                        raise
                    except Exception as exc:  # a bug in one adapter must not stop the bus
                        log.exception("polling %s failed", name)
                        self.store.devices[name].error(f"internal error while polling: {exc}")
            elapsed = time.monotonic() - started
            await asyncio.sleep(max(0.02, period - elapsed))

    async def command(
        self,
        device: str,
        action: Callable[[Any], Awaitable[Any]],
        *,
        role: str = "engineer",
        user: str = "local",
        describe: str = "",
        write: bool = True,
        record: bool = True,
        parameter: str = "",
        old: Any = "",
        new: Any = "",
    ) -> Any:
        """Run ``action(adapter)`` for ``device`` on behalf of a session (the older way, left to the
        worker's own callers such as restore's save step; pages, the API and the tools use :meth:`invoke`).

        The kind comes from the device type's declared command named ``describe`` when there is one
        (:func:`app.gate.kind_for`); ``write`` counts only where the type declares nothing of that name,
        and no module of ``pages/`` or ``app/`` passes it (tests/test_layering.py).
        """
        if device not in self.adapters:
            raise KeyError(f"no device named {device!r} in this plant")
        adapter = self.adapters[device]
        kind = gate.kind_for(self, device, describe, write, record)
        return await self.checked(
            lambda: action(adapter), device=device, role=role, user=user, describe=describe, kind=kind,
            record=record or kind != "read", parameter=parameter, old=old, new=new,
        )

    async def invoke(self, device: str, name: str, args: dict | None = None, *, user: str, role: str,
                     session: str = "", confirmed: bool = False) -> Any:
        """Run the declared command ``name`` of ``device`` (:func:`app.gate.invoke`)."""
        return await gate.invoke(self, device, name, args, user=user, role=role, session=session, confirmed=confirmed)

    async def engineer_action(
        self, action: Callable[[], Awaitable[Any]], *, user: str, role: str, describe: str, target: str = "",
        parameter: str = "", new: Any = "",
    ) -> Any:
        """Anything that changes the plant, the plant file, a device or files on disk
        (adopting a device, recordings, line scans, backups): engineer only, audited."""
        return await self.checked(action, device=target, role=role, user=user, describe=describe, parameter=parameter, new=new)

    async def checked(
        self, action: Callable[[], Awaitable[Any]], *, device: str, role: str, user: str, describe: str,
        kind: str = "write", record: bool = True, parameter: str = "", old: Any = "", new: Any = "",
    ) -> Any:
        """The one place where a change is checked (role) and audited (fail closed) before it runs.

        ``kind`` comes from a declared command (:func:`app.gate.invoke`); the worker's own actions that
        are no device command (a simulation control, ending a recording, stopping the transmit list or
        a replay) name theirs. The role is the account store's at this moment (:func:`app.gate.role_now`).
        A ``stop`` runs for every role, first, and is audited afterwards from a queue; a ``read`` for
        every role, unaudited.
        """
        what = describe or "command"
        role = gate.role_now(self, user, role)
        state = self.store.devices.get(device)
        if kind == "stop":
            return await gate.run_stop(self, action, device=device, user=user, role=role, describe=what,
                                       parameter=parameter, old=old, new=new)
        if not gate.may_run(kind, role):
            if state is not None:
                state.event("warning", f"refused for {user} ({role}): {what}")
            if record and self.audit is not None:
                try:
                    await self.audit.arecord(user=user, role=role, device=device, action=what, parameter=parameter,
                                             old=old, new=new, result=f"refused: the {role or 'anonymous'} role may not write")
                except Exception as exc:  # noqa: BLE001 - refused anyway; the audit state shows the failure
                    log.error("audit: %s", exc)
            raise PermissionDenied(f"{user or 'anonymous'} has the {role or 'no'} role and may not write ({what})")
        row = None
        if record and kind != "read" and self.audit is not None:
            try:
                row = await self.audit.arecord(user=user, role=role, device=device, action=what, parameter=parameter,
                                               old=old, new=new, result="started")
            except Exception as exc:  # noqa: BLE001 - fail closed: no audit row, no write
                if state is not None:
                    state.event("error", f"{what} refused: the audit log cannot be written ({exc})")
                raise AuditUnavailable(
                    f"{what} refused: the audit log cannot be written ({exc}). Nothing was sent. "
                    f"Free or repair {self.audit.path} (locked by another program, read-only or disk full) and try again."
                ) from None
        try:
            result = await action()
        except Exception as exc:
            if row is not None:
                await self.audit.afinish(row, f"failed: {exc}")
            raise
        if row is not None:
            # an outcome in words (e.g. which lock took a broadcast address) goes into the row too
            await self.audit.afinish(row, f"ok: {result}"[:500] if isinstance(result, str) and result else "ok")
        return result

    async def refused(
        self, *, device: str, user: str, role: str, describe: str, reason: str, parameter: str = "", new: Any = "",
    ) -> None:
        """An entry or a request refused before anything was sent (out of range, not confirmed, forbidden by
        the device document): logged on the device and in the audit log with the reason."""
        state = self.store.devices.get(device)
        if state is not None:
            state.event("warning", f"refused for {user or 'anonymous'}: {describe or 'entry'}: {reason}")
        if self.audit is not None:
            try:
                await self.audit.arecord(user=user, role=role, device=device, action=describe or "entry",
                                         parameter=parameter, new=new, result=f"refused: {reason}"[:500])
            except Exception as exc:  # noqa: BLE001 - nothing was sent anyway; the audit state shows the failure
                log.error("audit: %s", exc)

    async def discover(self, bus: str, first: int, last: int, progress=None) -> list[dict]:
        """Find devices on a Modbus line (broadcast, then a scan), with polling held meanwhile."""
        if not isinstance(self.lines.get(bus), ModbusLine):
            raise KeyError(f"{bus} is not a Modbus RTU line")
        bus_type = self.plant.buses[bus].type
        # the scans of the types on the line; on a line without devices, of every type that sits on such lines
        by_type = {d.type for d in self.plant.devices_on(bus)} or {
            t.name for t in DEVICE_TYPES.values() if bus_type in t.bus_types}
        found: list[dict] = []
        self.paused.add(bus)
        try:
            for type_name in sorted(by_type):
                scan = DEVICE_TYPES[type_name].line_scan(bus_type) if type_name in DEVICE_TYPES else None
                if scan is not None:
                    found += await scan(self.lines[bus], first, last, progress)
        finally:
            self.paused.discard(bus)
        return found
