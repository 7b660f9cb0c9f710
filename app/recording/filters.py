"""The bus monitor's filters and formatting: which device owns a frame, the filter of the list, and
the texts of identifiers, data and times."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Reversible
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from app.can_bus import FrameRecord
from devices.adapter import FrameOwner
from devices.registry import DEVICE_TYPES


# -- filters and formatting ---------------------------------------------------------------------------


def parse_id(text: str | None) -> int | None:
    """A CAN ID typed as hex (``704``, ``0x704``, ``A1284``); None for empty.

    :raises ValueError: not a hex number or above 0x1FFFFFFF
    """
    text = (text or "").strip().replace("_", "")
    if not text:
        return None
    value = int(text, 16)
    if not 0 <= value <= 0x1FFFFFFF:
        raise ValueError(f"{text} is not a CAN ID (0..1FFFFFFF)")
    return value


Owner = Callable[[int, bool, bytes], bool]


def owner_of(adapter: Any) -> Owner:
    """``adapter.owns_frame``, or a filter that matches nothing for adapters without it."""
    if not isinstance(adapter, FrameOwner):
        return lambda _id, _ext, _data: False
    owns = adapter.owns_frame

    def safe(arbitration_id: int, is_extended: bool, data: bytes) -> bool:
        try:
            return bool(owns(arbitration_id, is_extended, data))
        except (LookupError, ValueError):  # a frame the adapter cannot parse (a codec's ValueError) is not its frame
            return False

    return safe


MAX_DEVICE_NAMES = 3  # a broadcast request names at most this many devices, then counts the rest


def device_owners(worker: Any, bus: str) -> list[tuple[str, Owner]]:
    """``(plant name, owner)`` for every device on a CAN bus.

    The owner is the adapter's ``owns_frame`` (frames it sends and requests addressed to it),
    else the CAN IDs its device type declares for it (``DeviceType.can_id_uses``).
    """
    owners: list[tuple[str, Owner]] = []
    for dev in worker.plant.devices_on(bus):
        adapter = worker.adapters.get(dev.name)
        if isinstance(adapter, FrameOwner):
            owners.append((dev.name, owner_of(adapter)))
            continue
        device_type = DEVICE_TYPES.get(dev.type)
        uses = device_type.can_id_uses(dev.options, "can") if device_type is not None else ()
        if uses:
            owners.append((dev.name, lambda can_id, ext, _data, uses=uses: any(u.covers(ext, can_id) for u in uses)))
    return owners


def device_of(owners: Iterable[tuple[str, Owner]], arbitration_id: int, is_extended: bool, data: bytes) -> str:
    """The names of the devices that own a frame (one, or several for a broadcast), else ``""``."""
    names = [name for name, owns in owners if owns(arbitration_id, is_extended, data)]
    if len(names) > MAX_DEVICE_NAMES:
        return ", ".join(names[:MAX_DEVICE_NAMES]) + f" +{len(names) - MAX_DEVICE_NAMES}"
    return ", ".join(names)


@dataclass
class FrameFilter:
    """ID range (inclusive, either end open) and/or a device's frames, or only error frames."""

    id_min: int | None = None
    id_max: int | None = None
    owner: Owner | None = None
    errors_only: bool = False

    @property
    def active(self) -> bool:
        return self.id_min is not None or self.id_max is not None or self.owner is not None or self.errors_only

    def matches(self, arbitration_id: int, is_extended: bool, data: bytes, is_error_frame: bool = False) -> bool:
        if self.errors_only and not is_error_frame:
            return False
        if self.id_min is not None and arbitration_id < self.id_min:
            return False
        if self.id_max is not None and arbitration_id > self.id_max:
            return False
        return self.owner is None or (not is_error_frame and self.owner(arbitration_id, is_extended, data))

    def matches_record(self, rec: FrameRecord) -> bool:
        return self.matches(rec.arbitration_id, rec.is_extended_id, rec.data, rec.is_error_frame)


def newest(frames: Iterable[FrameRecord], flt: FrameFilter, limit: int) -> list[FrameRecord]:
    """The newest ``limit`` frames that match, newest first (frames in arrival order).

    Walks from the end, so the cost is bounded by the buffer, not by the traffic.
    """
    result: list[FrameRecord] = []
    source: Iterator[FrameRecord] = reversed(frames) if isinstance(frames, Reversible) else reversed(list(frames))
    if not flt.active:
        for rec in source:
            result.append(rec)
            if len(result) >= limit:
                break
        return result
    for rec in source:
        if flt.matches_record(rec):
            result.append(rec)
            if len(result) >= limit:
                break
    return result


def format_id(arbitration_id: int, is_extended: bool) -> str:
    """``0x704`` (standard) or ``0x000A1284 (ext)``."""
    return f"0x{arbitration_id:08X} (ext)" if is_extended else f"0x{arbitration_id:03X}"


def format_data(data: bytes) -> str:
    return data.hex(" ").upper()


def format_time(t: float, relative_to: float | None = None) -> str:
    """Clock time with milliseconds, or seconds since ``relative_to``."""
    if relative_to is not None:
        return f"{t - relative_to:.3f}"
    try:
        return datetime.fromtimestamp(t).strftime("%H:%M:%S.%f")[:-3]
    except (OverflowError, OSError, ValueError):
        return f"{t:.3f}"


def changed_bytes(data: bytes, changed: int) -> list[tuple[str, bool]]:
    """Each byte as hex with whether it changed since the previous frame of its ID."""
    return [(f"{b:02X}", bool(changed >> i & 1)) for i, b in enumerate(data)]
