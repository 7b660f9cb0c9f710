"""HD-Lock checkout: door in position, a lock and unlock cycle, bolt end positions and times.

Declared here, run by the generic runner (``app/record.py``) through ``ctx``: every command goes
through the worker's gate. The cycle is driven by LockRequestSource (holding 4, section 3.2.2):
IrsAlways (1) makes the lock bolt once the door is in position, IrsNever (0) unbolts; the source
the lock had is written back at the end (cleanup), also after a failure or an abort.
"""

from __future__ import annotations

import time

from devices.commands import WRITE_PARAMETER
from devices.hdlock import STATUS_FRAME_BOLT
from devices.hdlock.params import PARAMS

TITLE = "Lock and unlock cycle"
SETTINGS = {
    "door_timeout_s": 5.0,  # the door must be in position (DoorInPosition) within this
    "lock_time_max_s": 6.0,  # command to BoltLocked seen (includes up to one poll period)
    "unlock_time_max_s": 6.0,
}
SOURCE = PARAMS.get("holding", 4)  # holding 4: the source the lock uses (section 6.5.1), not 1002
IRS_NEVER, IRS_ALWAYS = 0, 1
_SAVED = "_hdlock_source_before"


def _status(ctx, bit: str) -> int | None:
    return ctx.field("LockStatus", bit)


def _bolt(ctx) -> int | None:
    """The bolt position read last: input 2, or on CAN the 1 s status frame's motorPos when fresher."""
    entries = [e for e in (ctx.entry("BoltPosition"), ctx.entry(STATUS_FRAME_BOLT)) if e is not None and e.get("time")]
    return max(entries, key=lambda e: e["time"])["value"] if entries else None


def _source(ctx) -> int | None:
    raw = ctx.state.raw(SOURCE)
    return None if raw is None else SOURCE.decode(raw)


def steps(options: dict, settings: dict) -> list[dict]:
    return [
        {"name": "Door closed (asked)", "limits": "the engineer confirms", "run": _ask_door},
        {"name": "Door in position, proximity", "limits": f"DoorInPosition within {settings['door_timeout_s']:g} s; "
         "proximity below the unlock threshold; no overrange", "run": _door},
        {"name": "Lock", "limits": f"BoltLocked within {settings['lock_time_max_s']:g} s; bolt >= LockOkPosition",
         "run": _lock},
        {"name": "Unlock", "limits": f"BoltUnlocked within {settings['unlock_time_max_s']:g} s; bolt <= UnlockOkPosition",
         "run": _unlock},
    ]


async def _ask_door(ctx) -> None:
    await ctx.ask("Is the door closed and is nobody in the way of the bolt?")


async def _door(ctx) -> None:
    s = ctx.settings
    if not await ctx.wait(lambda: _status(ctx, "DoorInPosition") == 1, s["door_timeout_s"]):
        proximity = ctx.value("Calculated proxi (normalized)")
        ctx.fail(f"the door is not in position after {s['door_timeout_s']:g} s (proximity {proximity} Inc): "
                 "is it closed, is the strike plate in range?")
    ctx.measure("ProximityOverrange", _status(ctx, "ProximityOverrange"), expect=0)
    threshold = ctx.value("SettingsProximityThresholdUnlock")
    proximity = ctx.value("Calculated proxi (normalized)")
    ctx.measure("Proximity", proximity, "Inc", high=None if threshold is None else -threshold - 1)
    ctx.measure("DoorInPosition", _status(ctx, "DoorInPosition"), expect=1)


async def _drive(ctx, value: int, bit: str, limit_s: float) -> float:
    if getattr(ctx, _SAVED, None) is None:
        setattr(ctx, _SAVED, _source(ctx))
    t0 = time.monotonic()
    await ctx.invoke(WRITE_PARAMETER, {"param": SOURCE, "value": SOURCE.decode(value)})
    reached = await ctx.wait(lambda: _status(ctx, bit) == 1, limit_s + 1.0)
    took = round(time.monotonic() - t0, 2)
    if not reached:
        ctx.fail(f"{bit} not reached within {limit_s:g} s (bolt at {_bolt(ctx)} Inc, "
                 f"LockStatus 0x{(ctx.value('LockStatus') or 0):04X})")
    return took


async def _lock(ctx) -> None:
    s = ctx.settings
    took = await _drive(ctx, IRS_ALWAYS, "BoltLocked", s["lock_time_max_s"])
    ctx.measure("Lock time (command to BoltLocked seen)", took, "s", high=s["lock_time_max_s"])
    ctx.measure("BoltPosition locked", _bolt(ctx), "Inc", low=ctx.value("LockOkPosition") or 0)
    ctx.measure("BoltMovingOut after the end position", _status(ctx, "BoltMovingOut"), expect=0)
    ctx.measure("MaximumTimeLock (the lock's own)", ctx.value("MaximumTimeLock"), "ms", fail=False)


async def _unlock(ctx) -> None:
    s = ctx.settings
    took = await _drive(ctx, IRS_NEVER, "BoltUnlocked", s["unlock_time_max_s"])
    ctx.measure("Unlock time (command to BoltUnlocked seen)", took, "s", high=s["unlock_time_max_s"])
    high = ctx.value("UnlockOkPosition")
    ctx.measure("BoltPosition unlocked", _bolt(ctx), "Inc", high=high if high is not None else 5)
    ctx.measure("BoltLocked after unlocking", _status(ctx, "BoltLocked"), expect=0)
    ctx.measure("MaximumTimeUnlock (the lock's own)", ctx.value("MaximumTimeUnlock"), "ms", fail=False)


async def cleanup(ctx, settings: dict) -> None:
    """The lock request source the lock had before the checkout, written back."""
    before = getattr(ctx, _SAVED, None)
    if before is not None and _source(ctx) != before:
        await ctx.invoke(WRITE_PARAMETER, {"param": SOURCE, "value": before})
