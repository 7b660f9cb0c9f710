"""MO 64 checkout: an open and close cycle with its gate-state transitions and times, the light
barrier and the induction loops seen working, automatic closing where it is switched on, and the
error memory unchanged by the cycle.

Declared here, run by the generic runner (``app/record.py``). The boom is moved with the declared
commands "open pulse" and "close pulse" (``devices/mo64/policy.py``, chapter 5.2.1) through the
worker's gate; their declared risk ("the area is clear") is asked right before each of them (every
motion asks, devices/mo64/control.py), and each answer is recorded with who gave it. Gate state 0x0C (chapter 5.1.12), barrier
status 0x07 (LS, F_ereignis, loops occupied; chapter 5.1.7) and position 0x1D (5.1.29) come from
the adapter's polling; the error memory 0x17 (5.1.23: every change of the error flags is stored
in level 0) is read before and after the cycle with the declared read "read error memory".

Safety functions are tested while they act, with a person's help: the light barrier is interrupted
while the boom closes and the boom must reverse (LS seen, gate state opening or open); each induction
loop that is switched on (0x12, bit 0 of its mode register) is occupied and must be reported occupied
and free again. Positions are checked within ``position_tolerance_pct`` of 100 % and 0 %. An open boom
closes by itself only when t_offen (0x0D) is not 0 (chapter 5.2.4.1: 0 switches automatic closing
off); the step that checks automatic closing is "not available on this unit" then.
"""

from __future__ import annotations

import time
import weakref
from typing import Any

from devices.mo64.adapter import P_LEVELS_UNAVAILABLE
from devices.mo64.codec import ERROR_MEMORY_LEVELS, GATE_STATE_NAMES, TIME_STEP_S, GateState
from devices.mo64.policy import AREA_CLEAR_RISK

TITLE = "Open and close cycle"
SETTINGS = {
    "open_time_max_s": 8.0,  # open pulse to "open" seen (pre-warning, travel, one poll period)
    "close_time_max_s": 8.0,  # close pulse to "closed" seen
    "start_timeout_s": 10.0,  # the first status after start-up
    "position_tolerance_pct": 2,  # an end position within this of 100 % / 0 % (the boom stops on its limit switch)
    "reverse_timeout_s": 8.0,  # close pulse to the boom seen reversing at the interrupted light barrier
    "safety_seen_s": 10.0,  # a loop occupied / freed (or the light barrier freed) seen after the person's answer
}
LOOPS = ("loop A occupied", "loop B occupied", "loop C occupied")
SAFETY = ("LS", "F_ereignis", "Baum ab")
_WHY = {"LS": "light barrier interrupted (LS)", "F_ereignis": "fault event (F_ereignis)", "Baum ab": "boom off (Baum ab)",
        **{loop: loop for loop in LOOPS}}
T_OPEN = "Open time"  # 0x0D t_offen, 10 ms units (adapter NAMES)
LOOP_MODES = "Induction-loop modes"  # 0x12, one 16-bit mode register per loop A, B, C (adapter NAMES)
LOOP_ON_BIT = 0x0001  # chapter 5.1.18: the first row of each loop's mode register, "Schleife eingeschaltet"
_CLOSING = (GateState.PREWARN_CLOSE, GateState.CLOSING)
_REVERSED = (GateState.OPENING, GateState.OPEN, GateState.PREWARN_OPEN)
# what a person is asked to do; "Toggle LS" / "Toggle loop-A" name the twin's controls where the barrier is
# simulated (the record page and the CLI offer them with the question)
LS_READY = ("Toggle LS as the boom closes: stand ready at the light barrier, interrupt it once the boom starts to "
            "close and keep it interrupted until you are asked to free it. Ready?")
LS_FREE = "Toggle LS now: free the light barrier."


def steps(options: dict, settings: dict) -> list[dict]:
    tol = settings["position_tolerance_pct"]
    return [
        {"name": "Area clear (asked)", "limits": "the engineer confirms", "run": _ask},
        {"name": "Error memory before", "limits": "all 10 levels read (or not available on this unit)", "run": _memory_before},
        {"name": "Light barrier, loops, no fault", "limits": "LS, loops A-C, F_ereignis, Baum ab all 0; boom closed",
         "run": _idle},
        {"name": "Open", "limits": f"open within {settings['open_time_max_s']:g} s, position >= {100 - tol} %; "
         "pre-warning, opening, open in that order", "run": _open},
        {"name": "Light barrier reverses a closing boom (asked)",
         "limits": f"interrupted while the boom closes: LS reported and the boom reverses within "
         f"{settings['reverse_timeout_s']:g} s", "run": _light_barrier},
        {"name": "Induction loops (asked)", "limits": f"each loop switched on: occupied and free again seen within "
         f"{settings['safety_seen_s']:g} s", "run": _loops},
        {"name": "Automatic closing (t_offen)", "limits": "with t_offen != 0: the open boom closes by itself within "
         f"t_offen + {settings['close_time_max_s']:g} s (5.2.4.1); t_offen = 0: not available", "run": _auto_close},
        {"name": "Close", "limits": f"closed within {settings['close_time_max_s']:g} s, position <= {tol} %; "
         "light barrier and loops free throughout", "run": _close},
        {"name": "Error memory unchanged", "limits": "every level as before the cycle; F_ereignis 0", "run": _memory_after},
    ]


async def _ask(ctx) -> None:
    await ctx.ask(AREA_CLEAR_RISK)  # before anything is read or waited for; asked again before each motion


def _state(ctx) -> int | None:
    return ctx.value("Gate state")


def _state_name(value) -> str:
    return "unknown" if value is None else GATE_STATE_NAMES.get(value, f"state {value}")


def _t_open_s(ctx) -> float | None:
    """t_offen in seconds as the barrier reported it (0x0D), None while unread."""
    raw = (ctx.entry(T_OPEN) or {}).get("raw")
    return None if raw is None else int(raw) * TIME_STEP_S


def _memory_rows(memory: list[dict]) -> list[tuple[int, int, int]]:
    return sorted((int(e["level"]), int(e["flags"]), int(e["timestamp_h"])) for e in memory)


async def _read_memory(ctx) -> tuple[list[tuple[int, int, int]], list[int]]:
    """The levels read and the levels the unit refused."""
    memory = await ctx.invoke("read error memory")
    point = ctx.state.points.get(P_LEVELS_UNAVAILABLE)
    missing = sorted(point.value) if point is not None and point.value else []
    rows = [r for r in _memory_rows(memory or []) if r[0] not in missing]
    return rows, missing


# a run's context -> the error memory rows and the levels the unit refused, read before the cycle
_MEMORY_BEFORE: weakref.WeakKeyDictionary[Any, tuple[list, list]] = weakref.WeakKeyDictionary()


async def _memory_before(ctx) -> None:
    rows, missing = await _read_memory(ctx)
    _MEMORY_BEFORE[ctx] = (rows, missing)
    if len(missing) >= ERROR_MEMORY_LEVELS or not rows:
        ctx.not_available(f"the barrier refuses every error-memory level (query 0x12, levels {missing or 'all'}): "
                          "its error memory cannot be compared on this unit; read it on the unit's display")
    if missing:
        ctx.note(f"error memory levels not available on this unit: {missing}; the others are compared")
    ctx.measure("Error memory levels read", len(rows), fail=False)
    ctx.measure("Error memory level 0 flags", f"0x{rows[0][1]:08X}", fail=False)


async def _idle(ctx) -> None:
    s = ctx.settings
    if not await ctx.wait(lambda: all(ctx.value(name) is not None for name in (*SAFETY, *LOOPS)) and _state(ctx) is not None,
                          s["start_timeout_s"]):
        ctx.fail("no barrier status or gate state from the barrier")
    bad = [_WHY[name] for name in (*SAFETY, *LOOPS) if ctx.value(name)]
    for name in (*SAFETY, *LOOPS):
        ctx.measure(name, ctx.value(name), expect=False, fail=False)
    if bad:
        ctx.fail(f"not ready for the cycle: {', '.join(bad)}")
    if _state(ctx) != GateState.CLOSED:
        t_open = _t_open_s(ctx)
        if t_open:  # chapter 5.2.4.1: an open boom closes by itself after t_offen ...
            ctx.note(f"the boom was {_state_name(_state(ctx))} at the start: waiting for it to close by itself "
                     f"(t_offen {t_open:g} s)")
            await ctx.wait(lambda: _state(ctx) == GateState.CLOSED, t_open + s["close_time_max_s"])
        else:  # ... unless t_offen = 0 switches automatic closing off: it is closed by command
            why = "t_offen = 0: automatic closing is off" if t_open == 0 else "t_offen not read"
            ctx.note(f"the boom was {_state_name(_state(ctx))} at the start ({why}): closing it by command")
            await ctx.ask(AREA_CLEAR_RISK)
            await ctx.invoke("close pulse")
            await ctx.wait(lambda: _state(ctx) == GateState.CLOSED, s["close_time_max_s"] + 1.0)
    ctx.measure("Gate state", _state_name(_state(ctx)), expect=_state_name(GateState.CLOSED))


def _at_end(ctx, goal: GateState) -> bool:
    pos, tol = ctx.value("Position"), ctx.settings["position_tolerance_pct"]
    if pos is None:
        return False
    return pos >= 100 - tol if goal == GateState.OPEN else pos <= tol


async def _cycle(ctx, command: str, goal: GateState, limit_s: float, ask: bool = True) -> float:
    """Send ``command``, follow the gate state to ``goal`` and record every transition with its time."""
    seen: list[tuple[float, int]] = []
    safety: set[str] = set()

    def follow() -> bool:
        state = _state(ctx)
        now = time.monotonic()
        if state is not None and (not seen or seen[-1][1] != state):
            seen.append((now, state))
        safety.update(name for name in ("LS", "F_ereignis", *LOOPS) if ctx.value(name))
        return state == goal and _at_end(ctx, goal)

    if ask:
        await ctx.ask(AREA_CLEAR_RISK)  # every motion asks, right before it goes out (issue 42 item 6)
    t0 = time.monotonic()
    answer = await ctx.invoke(command)
    ctx.measure(f"{command}: the barrier's answer", answer, expect="ack")
    reached = await ctx.wait(follow, limit_s + 1.0)
    took = round(time.monotonic() - t0, 2)
    transitions = " -> ".join(f"{_state_name(state)} at {t - t0:.2f} s" for t, state in seen)
    ctx.note(f"gate state: {transitions or 'no change seen'}")
    for t, state in seen[1:]:
        ctx.measure(f"Gate state {_state_name(state)} seen after", round(t - t0, 2), "s", fail=False)
    if not reached:
        why = ", ".join(_WHY[name] for name in sorted(safety))
        ctx.fail(f"not {_state_name(goal)} within {limit_s:g} s: the gate state went {transitions or 'nowhere'}, "
                 f"position {ctx.value('Position')} %" + (f"; {why}" if why else ""))
    ctx.measure(f"{command} to {_state_name(goal)} seen", took, "s", high=limit_s)
    tol = ctx.settings["position_tolerance_pct"]
    if goal == GateState.OPEN:
        ctx.measure("Position", ctx.value("Position"), "%", low=100 - tol, high=100)
    else:
        ctx.measure("Position", ctx.value("Position"), "%", low=0, high=tol)
    if safety:
        ctx.fail(f"{', '.join(_WHY[name] for name in sorted(safety))} during the move")
    for name in ("LS", *LOOPS):
        ctx.measure(name, ctx.value(name), expect=False)
    return took


async def _open(ctx) -> None:
    await _cycle(ctx, "open pulse", GateState.OPEN, ctx.settings["open_time_max_s"])


async def _ensure_open(ctx) -> None:
    if _state(ctx) == GateState.OPEN and _at_end(ctx, GateState.OPEN):
        return
    await _cycle(ctx, "open pulse", GateState.OPEN, ctx.settings["open_time_max_s"])


async def _light_barrier(ctx) -> None:
    """Chapter 5.1.7 (LS): the light barrier interrupted while the boom closes reverses it."""
    s = ctx.settings
    await _ensure_open(ctx)
    await ctx.ask(LS_READY)
    await ctx.ask(AREA_CLEAR_RISK)
    seen: list[int] = []
    ls_seen = closing_seen = False

    def follow() -> bool:
        nonlocal ls_seen, closing_seen
        state = _state(ctx)
        if state is not None and (not seen or seen[-1] != state):
            seen.append(state)
        pos = ctx.value("Position")  # a poll may miss the closing state: the boom seen coming down says it too
        closing_seen = closing_seen or state in _CLOSING or (pos is not None and pos < 100 - s["position_tolerance_pct"])
        ls_seen = ls_seen or bool(closing_seen and ctx.value("LS"))
        return closing_seen and ls_seen and state in _REVERSED

    t0 = time.monotonic()
    answer = await ctx.invoke("close pulse")
    ctx.measure("close pulse: the barrier's answer", answer, expect="ack")
    reversed_ = await ctx.wait(follow, s["reverse_timeout_s"])
    took = round(time.monotonic() - t0, 2)
    went = " -> ".join(_state_name(x) for x in seen) or "nowhere"
    ctx.note(f"gate state: {went}")
    ctx.measure("LS reported while the boom closed", ls_seen, expect=True, fail=False)
    if not reversed_:
        if not closing_seen:
            ctx.fail(f"the boom did not start to close (gate state went {went}): nothing to interrupt; is the light "
                     "barrier already interrupted, a loop occupied or an open level held?")
        if not ls_seen:
            ctx.fail(f"the light barrier was to be interrupted while the boom closed, but LS never reported it (gate "
                     f"state went {went}, position {ctx.value('Position')} %): check the light barrier's wiring, "
                     "alignment and supply, and its mode in the configuration flags")
        ctx.fail(f"LS reported, but the boom did not reverse within {s['reverse_timeout_s']:g} s (gate state went "
                 f"{went}, position {ctx.value('Position')} %): the light barrier's safety function does not act")
    ctx.measure("Close pulse to the boom reversing", took, "s", high=s["reverse_timeout_s"])
    await ctx.ask(LS_FREE)
    if not await ctx.wait(lambda: not ctx.value("LS"), s["safety_seen_s"]):
        ctx.fail(f"LS still reported {s['safety_seen_s']:g} s after the light barrier was freed: is something in the beam?")
    ctx.measure("LS after freeing", ctx.value("LS"), expect=False)


def _loops_on(ctx) -> list[str] | None:
    modes = ctx.value(LOOP_MODES)
    if not isinstance(modes, list | tuple) or len(modes) != 3:
        return None
    return [loop for loop, mode in zip("ABC", modes) if int(mode) & LOOP_ON_BIT]


async def _loops(ctx) -> None:
    """Chapter 5.1.7 (Status2 bits 3-5): each loop switched on is occupied and freed by a person."""
    s = ctx.settings
    on = _loops_on(ctx)
    if on is None:
        on = [x for x in "ABC" if await ctx.choose(f"The loop modes (0x12) were not read: is loop {x} installed and "
                                                      "switched on?", f"loop {x} not tested")]
    else:
        ctx.note(f"loops switched on (0x12): {', '.join(on) or 'none'}")
    if not on:
        ctx.not_available("no induction loop is switched on at this barrier (0x12)")
    for loop in on:
        name = f"loop {loop} occupied"
        await ctx.ask(f"Toggle loop-{loop} now: occupy loop {loop} (drive or place a vehicle on it) and leave it "
                      "occupied until you are asked to free it.")
        occupied = await ctx.wait(lambda n=name: ctx.value(n) is True, s["safety_seen_s"])
        ctx.measure(f"Loop {loop} occupied seen", ctx.value(name), expect=True, fail=False)
        if not occupied:
            ctx.fail(f"loop {loop} was to be occupied, but the barrier did not report it within {s['safety_seen_s']:g} s: "
                     "check the loop, its detector's sensitivity and the loop-adjust state")
        await ctx.ask(f"Toggle loop-{loop} now: free loop {loop}.")
        freed = await ctx.wait(lambda n=name: ctx.value(n) is False, s["safety_seen_s"])
        ctx.measure(f"Loop {loop} free again", ctx.value(name), expect=False, fail=False)
        if not freed:
            ctx.fail(f"loop {loop} still reported occupied {s['safety_seen_s']:g} s after it was freed")


async def _close(ctx) -> None:
    if _state(ctx) in _CLOSING:  # closing by itself (t_offen) meanwhile: let it end, then open to close by command
        await ctx.wait(lambda: _state(ctx) == GateState.CLOSED, ctx.settings["close_time_max_s"])
    if _state(ctx) != GateState.OPEN:
        await _cycle(ctx, "open pulse", GateState.OPEN, ctx.settings["open_time_max_s"])
    await _cycle(ctx, "close pulse", GateState.CLOSED, ctx.settings["close_time_max_s"])


async def _auto_close(ctx) -> None:
    """Chapter 5.2.4.1: an open boom closes by itself after t_offen; t_offen = 0 switches that off."""
    s = ctx.settings
    t_open = _t_open_s(ctx)
    if t_open is None:
        ctx.not_available("t_offen (0x0D) was not read from this barrier: whether it closes by itself is unknown")
    ctx.measure("t_offen", round(t_open, 2), "s", fail=False)
    if t_open == 0:
        ctx.not_available("t_offen = 0: automatic closing is switched off on this unit (5.2.4.1)")
    if _state(ctx) != GateState.OPEN:
        await _cycle(ctx, "open pulse", GateState.OPEN, s["open_time_max_s"])
    t0 = time.monotonic()
    limit = t_open + s["close_time_max_s"]
    closed = await ctx.wait(lambda: _state(ctx) == GateState.CLOSED and _at_end(ctx, GateState.CLOSED), limit + 1.0)
    took = round(time.monotonic() - t0, 2)
    if not closed:
        ctx.fail(f"t_offen is {t_open:g} s, but the boom did not close by itself within {limit:g} s (gate state "
                 f"{_state_name(_state(ctx))}, position {ctx.value('Position')} %; light barrier "
                 f"{'interrupted' if ctx.value('LS') else 'free'})")
    ctx.measure("Open to closed by itself", took, "s", high=limit)
    ctx.measure("Position", ctx.value("Position"), "%", low=0, high=s["position_tolerance_pct"])


async def _memory_after(ctx) -> None:
    before = _MEMORY_BEFORE.get(ctx)
    if before is None:
        ctx.fail("the error memory was not read before the cycle")
    rows_before, missing_before = before
    if len(missing_before) >= ERROR_MEMORY_LEVELS or not rows_before:
        ctx.not_available("the barrier refuses every error-memory level: nothing to compare (see 'Error memory before')")
    after, missing = await _read_memory(ctx)
    ctx.measure("F_ereignis (fault event)", ctx.value("F_ereignis"), expect=False, fail=False)
    levels = {r[0] for r in rows_before} & {r[0] for r in after}
    if not levels:
        ctx.fail(f"the error memory could not be read after the cycle (levels not available: {missing})")
    b, a = ({r[0]: r for r in rows if r[0] in levels} for rows in (rows_before, after))
    changed = [f"level {n}: flags 0x{b[n][1]:08X} -> 0x{a[n][1]:08X} at {a[n][2]} h" for n in sorted(levels) if a[n] != b[n]]
    ctx.measure("Error memory levels compared", len(levels), fail=False)
    ctx.measure("Error memory levels changed", len(changed), expect=0, fail=False)
    if changed:
        ctx.fail("the error memory changed during the cycle: " + "; ".join(changed))
    if ctx.value("F_ereignis"):
        ctx.fail("fault event (F_ereignis) set after the cycle")


async def cleanup(ctx, settings: dict) -> None:
    """Nothing is left held: the checkout sends pulses only, never levels. An open boom closes by
    itself after t_offen (chapter 5.2.4.1) unless its light barrier or a loop holds it, or t_offen = 0."""
    if _state(ctx) not in (GateState.CLOSED, None):
        t_open = _t_open_s(ctx)
        if t_open:
            ctx.note(f"the boom was left {_state_name(_state(ctx))}: it closes by itself after t_offen ({t_open:g} s)")
        else:
            ctx.note(f"the boom was left {_state_name(_state(ctx))} and does not close by itself "
                     f"({'t_offen = 0' if t_open == 0 else 't_offen unknown'}): close it from the device page")
