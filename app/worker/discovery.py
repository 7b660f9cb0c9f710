"""CAN discovery: devices heard on a CAN bus that the plant file does not name, listed on evidence.

Every frame whose ID no adapter owns reaches :meth:`CanDiscovery.frame` (O(1): dictionary look-ups
and one codec call per device type). A device is listed only after the evidence its codec asks for
(e.g. an HD-Lock: three status frames about 1 s apart) on an ID that no device type occupies; until
then it is a candidate in a bounded table, and a flood of new IDs is dropped and counted.

Modbus lines have no such listening: :func:`scan_line` asks the device types' line scans.
"""

from __future__ import annotations

import importlib
import logging
import time
from collections import OrderedDict, deque
from collections.abc import Iterable
from dataclasses import dataclass, field

from app.i18n import N_
from app.message import Message, joined
from app.plant import Plant
from devices.registry import DEVICE_TYPES, CanIdUse, fixed_can_id_uses

log = logging.getLogger(__name__)

MAX_CANDIDATES = 512  # unknown CAN IDs watched per bus while they show evidence; beyond, new ones are dropped and counted
MAX_DISCOVERED = 128  # devices listed as discovered per bus
CANDIDATE_STALE_PERIODS = 2.5  # a candidate silent for this many of its periods gives its place to a new one
# A flood: more new IDs of a device's form within one second than a plant ever powers up at once. Discovery
# then lists nothing (a flood cycling through IDs at a device's period would look like a crowd of devices),
# watches nothing, and says so; it resumes once FLOOD_QUIET_S passed without such a second.
FLOOD_NEW_IDS_PER_S = 64
FLOOD_QUIET_S = 10.0
# what a device type's DISCOVERY_EVIDENCE names the frames it waits for (the HD-Lock's "status frames"), as the
# overview words the discovery rules
EVIDENCE_WORDS = (N_("frames"), N_("status frames"))


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

    def evidence_text(self) -> Message:
        """"3 frames in a row, 0.10, 0.10 s apart" (a page words it in its language)."""
        if not self.intervals:
            return Message(N_("{n} frame") if self.frames == 1 else N_("{n} frames"), n=self.frames)
        shown = joined([Message("{s:.2f}", s=i) for i in list(self.intervals)[-(self.streak - 1):]])
        return Message(N_("{n} frames in a row, {intervals} s apart"), n=self.streak, intervals=shown)


@dataclass
class DiscoveryTable:
    """Discovery on one CAN bus: bounded candidates, the refused IDs and what was left out."""

    refused: dict[tuple[bool, int], str] = field(default_factory=dict)  # ID -> its use by a device type
    refused_ranges: list[tuple[CanIdUse, str]] = field(default_factory=list)
    candidates: OrderedDict = field(default_factory=OrderedDict)  # key -> _Candidate, least recently heard first
    dropped: int = 0  # new candidates not watched: the table was full of live ones
    evicted: int = 0  # candidates that went silent and gave their place
    refused_frames: int = 0  # frames on IDs that a device type occupies
    listed_dropped: int = 0  # devices not listed: the list was full
    window_start: float = 0.0  # frame time of the current one-second window
    window_ids: set = field(default_factory=set)  # new IDs of a device's form heard in it (at most flood_ids_per_s + 1)
    flood_until: float = 0.0  # frame time until which discovery is paused (0: no flood)
    flood_since: float | None = None  # wall clock: when the flood was seen
    flood_end: float = 0.0  # wall clock: when discovery resumes unless the flood goes on
    floods: int = 0
    flood_frames: int = 0  # frames of unknown IDs that arrived during floods
    flood_ids_per_s: int = FLOOD_NEW_IDS_PER_S  # new IDs a second that make a flood

    def roll_window(self, heard: float) -> None:
        """Start a new one-second window when ``heard`` is past the current one."""
        if heard - self.window_start >= 1.0 or heard < self.window_start:
            self.window_start = heard
            self.window_ids.clear()

    def flooded(self, key: tuple[bool, int], heard: float, recognised: bool) -> bool:
        """Count a frame of an unknown ID in the one-second window; True while the bus is flooded
        (nothing is watched or listed then)."""
        if recognised and len(self.window_ids) <= self.flood_ids_per_s:
            self.window_ids.add(key)
            if len(self.window_ids) > self.flood_ids_per_s:
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
                        "for %.0f s; %d watched IDs forgotten", self.flood_ids_per_s, FLOOD_QUIET_S, len(self.candidates))
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


class CanDiscovery:
    """Discovery on every CAN bus of a plant: the listed devices and each bus's table.

    :param buses: the names of the CAN buses
    :param flood_ids_per_s: new IDs a second that make a flood (FLOOD_NEW_IDS_PER_S unless chosen)
    """

    def __init__(self, plant: Plant, buses: Iterable[str], flood_ids_per_s: int = FLOOD_NEW_IDS_PER_S):
        self.plant = plant
        names = list(buses)
        self.discovered: dict[str, dict[tuple[bool, int], dict]] = {name: {} for name in names}  # listed devices
        self.tables: dict[str, DiscoveryTable] = {name: DiscoveryTable(flood_ids_per_s=flood_ids_per_s) for name in names}
        self.codecs = {
            t.name: importlib.import_module(t.can_codec) for t in DEVICE_TYPES.values() if t.can_codec and "can" in t.bus_types
        }
        for name in names:
            self.refuse_ids(name)

    def refuse_ids(self, bus: str) -> None:
        """IDs never listed as a discovered device on ``bus``: every type's fixed IDs, and the
        IDs of the devices configured there (``DeviceType.can_fixed_ids`` / ``can_ids``)."""
        table = self.tables[bus]
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

    def adopted(self, bus: str, type_name: str, options: dict) -> None:
        """A device of ``type_name`` with ``options`` joined the plant on ``bus``: it is listed no more,
        and its IDs are refused from now on."""
        if bus not in self.tables:
            return
        for key, entry in list(self.discovered[bus].items()):
            if DEVICE_TYPES[type_name].bus_identity(options, "can") == DEVICE_TYPES[entry["type"]].bus_identity(
                {"device_id": entry["device_id"], "extended": entry["extended"]}, "can"
            ):
                del self.discovered[bus][key]
        self.refuse_ids(bus)

    def _recognise(self, msg, data: bytes) -> dict | None:
        for codec in self.codecs.values():
            try:
                entry = codec.discovered(msg.arbitration_id, msg.is_extended_id, data)
            except Exception:  # noqa: BLE001 - a frame a codec cannot parse is simply not its device
                entry = None
            if entry:
                return entry
        return None

    def frame(self, bus: str, msg) -> None:
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
        table = self.tables[bus]
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
            codec = self.codecs.get(candidate.entry["type"])
            try:
                entry = codec.discovered(msg.arbitration_id, msg.is_extended_id, data) if codec else None
            except Exception:  # noqa: BLE001 - not the device's frame
                entry = None
            candidate.add(entry, heard)
        if candidate.convinced():
            self._list(bus, key, candidate)

    def _list(self, bus: str, key: tuple[bool, int], candidate: _Candidate) -> None:
        table = self.tables[bus]
        del table.candidates[key]
        if len(self.discovered[bus]) >= MAX_DISCOVERED:
            table.listed_dropped += 1
            return
        listed = dict(candidate.entry)
        listed.pop("evidence", None)
        listed.update(first_seen=candidate.first_seen, last_seen=time.time(), frames=candidate.frames, bus=bus,
                      evidence=candidate.evidence_text())
        self.discovered[bus][key] = listed
        log.info("%s: discovered %s at CAN ID 0x%X (%s-bit): %s", bus, listed["type"], key[1], "29" if key[0] else "11",
                 listed["evidence"])

    def summary(self, bus: str) -> dict:
        """What the overview shows under the discovered devices of a CAN bus."""
        table = self.tables.get(bus)
        if table is None:
            return {}
        rules = []
        for type_name, codec in self.codecs.items():
            evidence = getattr(codec, "DISCOVERY_EVIDENCE", None)
            if evidence:
                rules.append(Message(N_("{type}: {n} {frames} about {period:g} s apart"), type=Message(DEVICE_TYPES[type_name].title),
                                     n=evidence["frames"], frames=Message(evidence.get("text", EVIDENCE_WORDS[0])),
                                     period=float(evidence["period_s"])))
        flood = ""
        if table.flood_until and time.time() < table.flood_end:
            flood = Message(N_("flood of new CAN IDs since {since} (over {n} new IDs a second): nothing is listed until it has "
                               "been quiet for {quiet} s"), since=time.strftime("%H:%M:%S", time.localtime(table.flood_since)),
                            n=table.flood_ids_per_s, quiet=f"{FLOOD_QUIET_S:.0f}")
        return {"candidates": len(table.candidates), "dropped": table.dropped, "refused_frames": table.refused_frames,
                "listed_dropped": table.listed_dropped, "rules": rules, "flood": flood, "floods": table.floods,
                "flood_frames": table.flood_frames}


async def scan_line(plant: Plant, bus: str, line, first: int, last: int, progress=None) -> list[dict]:
    """Find devices on the Modbus line ``bus`` (broadcast, then a scan of ``first`` .. ``last``): the scans
    of the types on the line; on a line without devices, of every type that sits on such lines.
    The caller holds the line's polling meanwhile."""
    bus_type = plant.buses[bus].type
    by_type = {d.type for d in plant.devices_on(bus)} or {t.name for t in DEVICE_TYPES.values() if bus_type in t.bus_types}
    found: list[dict] = []
    for type_name in sorted(by_type):
        scan = DEVICE_TYPES[type_name].line_scan(bus_type) if type_name in DEVICE_TYPES else None
        if scan is not None:
            found += await scan(line, first, last, progress)
    return found
