"""HD-Lock checkout: door in position, a lock and unlock cycle with the bolt seen moving, the lock's
own time limits and end positions, no error or retry states, and a lock request refused while the door
is open.

Declared here, run by the generic runner (``app/record.py``) through ``ctx``: every command goes
through the worker's gate. The cycle is driven by LockRequestSource in holding 1002, the register
section 3.2.2 names as controlling the bolt: IrsAlways (1) makes the lock bolt once the door is in
position, IrsNever (0) unbolts. Holding 4 reports the source in use (section 6.5.1). Both as the lock
had them are written back at the end (cleanup), also after a failure or an abort, and a change the
checkout made and undid is not left as an unsaved change.

Limits come from the lock itself (section 3.2): LockMaximumTime / UnlockMaximumTime (holding 16 / 26,
from the request to the bolt at its Ok position) plus one poll period for seeing it here, and
LockOkPosition / UnlockOkPosition (holding 11 / 21) for the end positions; a limit the lock did not
report fails the step (it is never replaced by a guess). StateMachineState (input 9) must not enter an
error state (6-12) and RetryLockCounter / RetryUnlockCounter (inputs 12 / 13) must not count during the
cycle. The lock must be seen moving: a bolt that is locked at the start is unlocked first.

With a person's help the lock's door condition is tested while it acts (section 3.2.2, condition 2):
the door is opened, a lock request (IrsAlways) is given, and the bolt must stay in.

What a person reads is a ``Message`` (docs/i18n.md); the register and bit names stay the document's.
"""

from __future__ import annotations

import time
import weakref
from typing import Any

from devices import errors
from devices.commands import WRITE_PARAMETER
from devices.hdlock import STATUS_FRAME_BOLT
from devices.hdlock.params import PARAMS
from devices.message import N_, Message, Word, joined, message_of

TITLE = Message(N_("Lock and unlock cycle"))
SETTINGS = {
    "door_timeout_s": 5.0,  # the door must be in position (DoorInPosition) within this
    "poll_allowance_s": 1.2,  # seeing the bolt at its end here: one poll period, or one 1 s CAN status frame
    "refuse_watch_s": 1.0,  # with the door open and a lock request: watched this long beyond the lock's own limits
}
SOURCE = PARAMS.get("holding", 1002)  # section 3.2.2: LockRequestSource, the register that controls the bolt
SOURCE_IN_USE = PARAMS.get("holding", 4)  # section 6.5.1: the source the lock uses now
STATE = PARAMS.get("input", 9)
PROXIMITY = PARAMS.get("input", 7).name  # "Calculated proxi (normalized)" [Inc]
RETRY_LOCK, RETRY_UNLOCK = PARAMS.get("input", 12), PARAMS.get("input", 13)
LOCK_MAX_TIME, UNLOCK_MAX_TIME = PARAMS.get("holding", 16), PARAMS.get("holding", 26)
LOCK_OK, UNLOCK_OK = PARAMS.get("holding", 11), PARAMS.get("holding", 21)
REQUEST_DELAY = PARAMS.get("holding", 3000)
IRS_NEVER, IRS_ALWAYS = 0, 1
ERROR_STATES = range(6, 13)  # input 9: 6 error locked ... 12 error unlocking
LOCKED_STATE, UNLOCKED_STATE = 4, 2
# what a person is asked to do; "Toggle door" names the twin's control where the lock is simulated (the record
# page and the CLI offer it with the question)
OPEN_DOOR = Message(N_("Toggle door now: open the door and keep it open until you are asked to close it."))
CLOSE_DOOR = Message(N_("Toggle door now: close the door again."))
MOVED_OUT, STAYED_IN = Message(N_("moved out")), Message(N_("stayed in"))  # the bolt with the door open
_SAVED: weakref.WeakKeyDictionary[Any, dict[str, Any]] = weakref.WeakKeyDictionary()  # a run's context -> the source before it


def _status(ctx, bit: str) -> int | None:
    return ctx.field("LockStatus", bit)


def _raw(ctx, param) -> int | None:
    return ctx.state.raw(param)


def _bolt(ctx) -> int | None:
    """The bolt position read last: input 2, or on CAN the 1 s status frame's motorPos when fresher."""
    entries = [e for e in (ctx.entry("BoltPosition"), ctx.entry(STATUS_FRAME_BOLT)) if e is not None and e.get("time")]
    return max(entries, key=lambda e: e["time"])["value"] if entries else None


def _still_at(ctx, ok_param, start: int | None, *, locked: bool) -> bool:
    """The bolt is still at the end position it started from (beyond that end's Ok position, or where it was)."""
    bolt, ok = _bolt(ctx), _raw(ctx, ok_param)
    if bolt is None:
        return True
    if ok is None:
        return bolt == start
    return bolt >= ok if locked else bolt <= ok


def _state_name(value: int | None) -> str:
    if value is None:
        return Message(N_("unknown"))
    if not STATE.enum:
        return str(value)
    # the state's name as the lock's pages word it (a value of the point StateMachineState): "4 verriegelt" in German
    return Message("{value} {name}", value=value, name=Word(STATE.enum.get(value, "?"), STATE.name))


def _limit(ctx, param, unit: str) -> int:
    """A limit the lock itself holds; the step fails when the lock did not report it."""
    raw = _raw(ctx, param)
    if raw is None:
        ctx.fail(Message(N_("{param} (holding {address}) was not read from the lock: the step's limit is the lock's own value "
                            "(section 3.2), not a guess; wait until the settings are read, then run the checkout again"),
                         param=param.name, address=param.address))
    ctx.measure(Message(N_("{param} (the lock's own, holding {address})"), param=param.name, address=param.address), raw, unit,
                fail=False)
    return raw


def steps(options: dict, settings: dict) -> list[dict]:
    allowance = settings["poll_allowance_s"]
    return [
        {"name": Message(N_("Door closed (asked)")), "limits": Message(N_("the engineer confirms")), "run": _ask_door},
        {"name": Message(N_("Door in position, proximity")),
         "limits": Message(N_("DoorInPosition within {timeout:g} s; proximity below the unlock threshold; no overrange"),
                           timeout=settings["door_timeout_s"]), "run": _door},
        {"name": Message(N_("Lock")),
         "limits": Message(N_("bolt seen moving out; BoltLocked within LockMaximumTime (holding 16) + {allowance:g} s; bolt >= "
                              "LockOkPosition (holding 11); StateMachineState Locked, no error state (6-12); RetryLockCounter "
                              "unchanged"), allowance=allowance), "run": _lock},
        {"name": Message(N_("Unlock")),
         "limits": Message(N_("BoltUnlocked within UnlockMaximumTime (holding 26) + {allowance:g} s; bolt <= UnlockOkPosition "
                              "(holding 21); StateMachineState Unlocked, no error state (6-12); RetryUnlockCounter unchanged"),
                           allowance=allowance), "run": _unlock},
        {"name": Message(N_("Lock request refused with the door open (asked)")),
         "limits": Message(N_("door opened by a person; with IrsAlways the bolt stays in for LockRequestDelay + LockMaximumTime "
                              "+ {watch:g} s"), watch=settings["refuse_watch_s"]), "run": _refuse_open_door},
    ]


async def _ask_door(ctx) -> None:
    await ctx.ask(Message(N_("Is the door closed and is nobody in the way of the bolt?")))


async def _door(ctx) -> None:
    s = ctx.settings
    if not await ctx.wait(lambda: _status(ctx, "DoorInPosition") == 1, s["door_timeout_s"]):
        proximity = ctx.value(PROXIMITY)
        ctx.fail(Message(N_("the door is not in position after {timeout:g} s (proximity {proximity} Inc): is it closed, is the "
                            "strike plate in range?"), timeout=s["door_timeout_s"], proximity=proximity))
    # the proximity (input 7) and DoorInPosition (holding 1000) come from different reads: measure a proximity
    # read after the door was seen in position, not one of the door still moving (bounded by one poll)
    seen = (ctx.entry("LockStatus") or {}).get("time") or 0.0
    await ctx.wait(lambda: ((ctx.entry(PROXIMITY) or {}).get("time") or 0.0) > seen, s["poll_allowance_s"])
    ctx.measure("ProximityOverrange", _status(ctx, "ProximityOverrange"), expect=0)
    threshold = ctx.value("SettingsProximityThresholdUnlock")
    proximity = ctx.value(PROXIMITY)
    ctx.measure(Message(N_("Proximity")), proximity, "Inc", high=None if threshold is None else -threshold - 1)
    ctx.measure("DoorInPosition", _status(ctx, "DoorInPosition"), expect=1)


async def _write_source(ctx, value: int) -> None:
    if ctx not in _SAVED:
        _SAVED[ctx] = {"source": _raw(ctx, SOURCE), "in_use": _raw(ctx, SOURCE_IN_USE),
                       "unsaved": {k for k in (SOURCE.key, SOURCE_IN_USE.key) if k in ctx.state.unsaved}}
    await _write(ctx, SOURCE, value)


async def _write(ctx, param, raw: int) -> None:
    """Write ``param`` through the gate; a read-back that differs is written once more (on CAN an answer to a
    poll's read of the same register, sent just before, can arrive as the write's echo), a second one fails."""
    try:
        await ctx.invoke(WRITE_PARAMETER, {"param": param, "value": param.decode(raw)})
    except errors.CommandError as exc:  # only a differing read-back is tried again; the rest is the step's reason
        if "instead of" not in str(exc):
            raise
        ctx.note(Message(N_("{error}; written once more"), error=message_of(exc)))
        await ctx.wait(lambda: False, 0.3)
        await ctx.invoke(WRITE_PARAMETER, {"param": param, "value": param.decode(raw)})


def _why(ctx) -> Message:
    return Message(N_("bolt at {bolt} Inc, LockStatus {status}, StateMachineState {state}, RetryLockCounter {lock}, "
                      "RetryUnlockCounter {unlock}"), bolt=_bolt(ctx),
                   status=f"0x{(_raw(ctx, PARAMS.get('holding', 1000)) or 0):04X}", state=_state_name(_raw(ctx, STATE)),
                   lock=_raw(ctx, RETRY_LOCK), unlock=_raw(ctx, RETRY_UNLOCK))


async def _drive(ctx, *, lock: bool) -> None:
    """Give the request, follow the lock to its end position, and check it against the lock's own limits."""
    s = ctx.settings
    step, bit = (Message(N_("Lock")), "BoltLocked") if lock else (Message(N_("Unlock")), "BoltUnlocked")
    time_param, ok_param = (LOCK_MAX_TIME, LOCK_OK) if lock else (UNLOCK_MAX_TIME, UNLOCK_OK)
    counter, other = (RETRY_LOCK, RETRY_UNLOCK) if lock else (RETRY_UNLOCK, RETRY_LOCK)
    limit_ms = _limit(ctx, time_param, "ms")
    ok_pos = _limit(ctx, ok_param, "Inc")
    limit_s = limit_ms / 1000 + s["poll_allowance_s"]
    count_before = _raw(ctx, counter)
    start_bolt = _bolt(ctx)
    states: list[int] = []
    counted: list[int] = []

    def at_end() -> bool:
        state, n = _raw(ctx, STATE), _raw(ctx, counter)
        if state is not None and (not states or states[-1] != state):
            states.append(state)
        if n is not None and count_before is not None and n > count_before:
            counted.append(n)
        bolt = _bolt(ctx)
        return (_status(ctx, bit) == 1 and bolt is not None and (bolt >= ok_pos if lock else bolt <= ok_pos)
                and state == (LOCKED_STATE if lock else UNLOCKED_STATE))

    def error_seen() -> bool:
        return any(x in ERROR_STATES for x in states) or bool(counted)

    t0 = time.monotonic()
    await _write_source(ctx, IRS_ALWAYS if lock else IRS_NEVER)
    reached = await ctx.wait(lambda: at_end() or error_seen(), limit_s + 0.5) and not error_seen()
    took = round(time.monotonic() - t0, 2)
    went = joined([_state_name(x) for x in states], " -> ") if states else Message(N_("no state read"))
    ctx.note(Message("StateMachineState: {states}", states=went))
    if not reached:
        errors = [_state_name(x) for x in states if x in ERROR_STATES]
        moved = not _still_at(ctx, UNLOCK_OK if lock else LOCK_OK, start_bolt, locked=not lock)
        what = ((Message(N_("the bolt did not leave its unlocked end position")) if lock else
                 Message(N_("the bolt did not leave its locked end position"))) if not moved else
                Message(N_("{bit} (bolt {relation} {position} Inc) not reached"), bit=bit, relation=">=" if lock else "<=",
                        position=ok_pos))
        parts = [Message(N_("{step}: {what} within {register} {limit} ms + {allowance:g} s"), step=step, what=what,
                         register=time_param.name, limit=limit_ms, allowance=s["poll_allowance_s"])]
        if errors:
            parts.append(Message(N_("; the lock reports {errors}"), errors=joined(errors)))
        if counted:
            parts.append(Message("; {counter} {before} -> {after}", counter=counter.name, before=count_before, after=max(counted)))
        parts.append(Message(N_(" ({why}): is the bolt blocked, the strike plate aligned, the supply sufficient?"), why=_why(ctx)))
        ctx.fail(joined(parts, ""))
    ctx.measure(Message(N_("{step} time (request to {bit} seen)"), step=step, bit=bit), took, "s", high=round(limit_s, 2))
    ctx.measure(Message(N_("BoltPosition locked")) if lock else Message(N_("BoltPosition unlocked")), _bolt(ctx), "Inc",
                low=ok_pos if lock else None, high=None if lock else ok_pos)
    ctx.measure("StateMachineState", _state_name(_raw(ctx, STATE)), expect=_state_name(LOCKED_STATE if lock else UNLOCKED_STATE))
    ctx.measure(counter.name, _raw(ctx, counter), expect=count_before)
    if _raw(ctx, other) is not None:
        ctx.measure(other.name, _raw(ctx, other), fail=False)
    moving = f"BoltMoving{'Out' if lock else 'In'}"
    ctx.measure(Message(N_("{bit} after the end position"), bit=moving), _status(ctx, moving), expect=0)
    ctx.measure(Message(N_("Bolt moved (start -> end)")), f"{start_bolt} -> {_bolt(ctx)} Inc", fail=False)


async def _lock(ctx) -> None:
    s = ctx.settings
    for name in ("LockStatus", "StateMachineState"):
        if not await ctx.wait(lambda n=name: ctx.entry(n) is not None, s["door_timeout_s"]):
            ctx.fail(Message(N_("no {name} from the lock"), name=name))
    if _raw(ctx, STATE) in ERROR_STATES:
        ctx.fail(Message(N_("the lock is in an error state before the cycle: StateMachineState {state} ({why}); find and remove "
                            "the cause (blocked bolt, strike plate), then run the checkout again"),
                         state=_state_name(_raw(ctx, STATE)), why=_why(ctx)))
    if _status(ctx, "BoltUnlocked") != 1:
        # a lock that is locked already would pass without moving: unlock it first, so that locking is seen
        ctx.note(Message(N_("the bolt was not unlocked at the start ({why}): unlocking first, so the lock is seen moving out"),
                         why=_why(ctx)))
        limit_ms = _limit(ctx, UNLOCK_MAX_TIME, "ms")
        ok_pos = _limit(ctx, UNLOCK_OK, "Inc")
        start = _bolt(ctx)
        await _write_source(ctx, IRS_NEVER)
        unlocked = await ctx.wait(lambda: _status(ctx, "BoltUnlocked") == 1 and (_bolt(ctx) or 0) <= ok_pos
                                  and _raw(ctx, STATE) not in ERROR_STATES, limit_ms / 1000 + s["poll_allowance_s"] + 0.5)
        if not unlocked:
            what = (Message(N_("did not leave its locked end position")) if _still_at(ctx, LOCK_OK, start, locked=True) else
                    Message(N_("did not reach UnlockOkPosition {position} Inc"), position=ok_pos))
            ctx.fail(Message(N_("unlocking first (the bolt was locked): the bolt {what} within UnlockMaximumTime {limit} ms + "
                                "{allowance:g} s ({why}), so the lock cannot be seen locking; is the bolt blocked?"), what=what,
                             limit=limit_ms, allowance=s["poll_allowance_s"], why=_why(ctx)))
    await _drive(ctx, lock=True)


async def _unlock(ctx) -> None:
    await _drive(ctx, lock=False)


async def _refuse_open_door(ctx) -> None:
    """Section 3.2.2, condition 2: with a source below 0x80 the bolt goes out only while the door is closed."""
    s = ctx.settings
    await ctx.ask(OPEN_DOOR)
    if not await ctx.wait(lambda: _status(ctx, "DoorInPosition") == 0 and _status(ctx, "ProximityInPlace") == 0,
                          s["door_timeout_s"]):
        ctx.fail(Message(N_("the door was to be opened, but the lock still sees it in position after {timeout:g} s (proximity "
                            "{proximity} Inc): is the strike plate's magnet still in range, is the proximity threshold set "
                            "right?"), timeout=s["door_timeout_s"], proximity=ctx.value(PROXIMITY)))
    ctx.measure(Message(N_("DoorInPosition (door open)")), _status(ctx, "DoorInPosition"), expect=0)
    watch_s = (_limit(ctx, REQUEST_DELAY, "ms") + _limit(ctx, LOCK_MAX_TIME, "ms")) / 1000 + s["refuse_watch_s"]
    count_before = _raw(ctx, RETRY_LOCK)
    moved: list[str] = []

    def bolt_out() -> bool:
        if _status(ctx, "BoltMovingOut") == 1 or _status(ctx, "BoltUnlocked") != 1:
            moved.append(Message(N_("bolt at {bolt} Inc"), bolt=_bolt(ctx)))
        return bool(moved)

    await _write_source(ctx, IRS_ALWAYS)
    await ctx.wait(bolt_out, watch_s)
    await _write_source(ctx, IRS_NEVER)
    ctx.measure(Message(N_("Bolt with the door open and IrsAlways")), MOVED_OUT if moved else STAYED_IN, expect=STAYED_IN,
                fail=False)
    if count_before is not None:
        ctx.measure(RETRY_LOCK.name, _raw(ctx, RETRY_LOCK), expect=count_before, fail=False)
    await ctx.ask(CLOSE_DOOR)
    await ctx.wait(lambda: _status(ctx, "DoorInPosition") == 1, s["door_timeout_s"])
    if moved:
        ctx.fail(Message(N_("the lock did not refuse: with the door open and a lock request (IrsAlways) the {bolt} moved out "
                            "(section 3.2.2 condition 2: the door must be closed); check SettingsProximityThreshold and that "
                            "LockRequestSource is not one of 0x80-0x87 (door ignored)"), bolt=moved[0]))
    ctx.measure(Message(N_("DoorInPosition (closed again)")), _status(ctx, "DoorInPosition"), expect=1, fail=False)


async def cleanup(ctx, settings: dict) -> None:
    """LockRequestSource (1002) and the source in use (4) as the lock had them, written back; a change the
    checkout made and undid is not left as an unsaved change (the lock holds what it held before)."""
    before = _SAVED.get(ctx)
    if before is None:
        return
    for param, raw in ((SOURCE, before["source"]), (SOURCE_IN_USE, before["in_use"])):
        if raw is not None and _raw(ctx, param) != raw:
            await _write(ctx, param, raw)
    for param, raw in ((SOURCE, before["source"]), (SOURCE_IN_USE, before["in_use"])):
        if param.key not in before["unsaved"] and _raw(ctx, param) == raw:
            ctx.state.unsaved.discard(param.key)
