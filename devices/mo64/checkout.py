"""MO 64 checkout: an open and close cycle with its gate-state transitions and times, the light
barrier and the induction loops as expected, and the error memory unchanged by the cycle.

Declared here, run by the generic runner (``app/record.py``). The boom is moved with the declared
commands "open pulse" and "close pulse" (``devices/mo64/policy.py``, chapter 5.2.1) through the
worker's gate; their declared risk ("the area is clear") is asked right before each of them (every
motion asks, devices/mo64/control.py), and each answer is recorded with who gave it. Gate state 0x0C (chapter 5.1.12), barrier
status 0x07 (LS, F_ereignis, loops occupied; chapter 5.1.7) and position 0x1D (5.1.29) come from
the adapter's polling; the error memory 0x17 (5.1.23: every change of the error flags is stored
in level 0) is read before and after the cycle with the declared read "read error memory".
"""

from __future__ import annotations

import time

from devices.mo64.adapter import P_LEVELS_UNAVAILABLE
from devices.mo64.codec import GATE_STATE_NAMES, GateState
from devices.mo64.policy import AREA_CLEAR_RISK

TITLE = "Open and close cycle"
SETTINGS = {
    "open_time_max_s": 8.0,  # open pulse to "open" seen (pre-warning, travel, one poll period)
    "close_time_max_s": 8.0,  # close pulse to "closed" seen
    "start_timeout_s": 10.0,  # an open boom closing by itself, or the first status after start-up
}
LOOPS = ("loop A occupied", "loop B occupied", "loop C occupied")
SAFETY = ("LS", "F_ereignis", "Baum ab")
_WHY = {"LS": "light barrier interrupted (LS)", "F_ereignis": "fault event (F_ereignis)", "Baum ab": "boom off (Baum ab)",
        **{loop: loop for loop in LOOPS}}


def steps(options: dict, settings: dict) -> list[dict]:
    return [
        {"name": "Area clear (asked)", "limits": "the engineer confirms", "run": _ask},
        {"name": "Error memory before", "limits": "all 10 levels read (or not available on this unit)", "run": _memory_before},
        {"name": "Light barrier, loops, no fault", "limits": "LS, loops A-C, F_ereignis, Baum ab all 0; boom closed",
         "run": _idle},
        {"name": "Open", "limits": f"open within {settings['open_time_max_s']:g} s, position 100 %; "
         "pre-warning, opening, open in that order", "run": _open},
        {"name": "Close", "limits": f"closed within {settings['close_time_max_s']:g} s, position 0 %; "
         "light barrier and loops free throughout", "run": _close},
        {"name": "Error memory unchanged", "limits": "every level as before the cycle; F_ereignis 0", "run": _memory_after},
    ]


async def _ask(ctx) -> None:
    await ctx.ask(AREA_CLEAR_RISK)  # before anything is read or waited for; asked again before each motion


def _state(ctx) -> int | None:
    return ctx.value("Gate state")


def _state_name(value) -> str:
    return "unknown" if value is None else GATE_STATE_NAMES.get(value, f"state {value}")


def _memory_rows(memory: list[dict]) -> list[tuple[int, int, int]]:
    return sorted((int(e["level"]), int(e["flags"]), int(e["timestamp_h"])) for e in memory)


async def _read_memory(ctx) -> list[tuple[int, int, int]]:
    memory = await ctx.invoke("read error memory")
    point = ctx.state.points.get(P_LEVELS_UNAVAILABLE)
    missing = list(point.value) if point is not None and point.value else []
    if missing:
        ctx.note(f"error memory levels not available on this unit: {missing}")
    return _memory_rows(memory or [])


async def _memory_before(ctx) -> None:
    rows = await _read_memory(ctx)
    ctx._mo64_memory = rows
    newest = rows[0] if rows else None
    ctx.measure("Error memory levels read", len(rows), fail=False)
    ctx.measure("Error memory level 0 flags", None if newest is None else f"0x{newest[1]:08X}", fail=False)


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
    if _state(ctx) != GateState.CLOSED:  # an open boom closes by itself after t_open (chapter 5.2.4.1)
        ctx.note(f"the boom was {_state_name(_state(ctx))} at the start: waiting for it to close")
        await ctx.wait(lambda: _state(ctx) == GateState.CLOSED, s["start_timeout_s"])
    ctx.measure("Gate state", _state_name(_state(ctx)), expect=_state_name(GateState.CLOSED))


async def _cycle(ctx, command: str, goal: GateState, limit_s: float, position: int) -> None:
    """Send ``command``, follow the gate state to ``goal`` and record every transition with its time."""
    seen: list[tuple[float, int]] = []
    safety: set[str] = set()

    def follow() -> bool:
        state = _state(ctx)
        now = time.monotonic()
        if state is not None and (not seen or seen[-1][1] != state):
            seen.append((now, state))
        safety.update(name for name in ("LS", "F_ereignis", *LOOPS) if ctx.value(name))
        return state == goal and ctx.value("Position") == position

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
    ctx.measure("Position", ctx.value("Position"), "%", expect=position)
    if safety:
        ctx.fail(f"{', '.join(_WHY[name] for name in sorted(safety))} during the move")
    for name in ("LS", *LOOPS):
        ctx.measure(name, ctx.value(name), expect=False)


async def _open(ctx) -> None:
    await _cycle(ctx, "open pulse", GateState.OPEN, ctx.settings["open_time_max_s"], 100)


async def _close(ctx) -> None:
    await _cycle(ctx, "close pulse", GateState.CLOSED, ctx.settings["close_time_max_s"], 0)


async def _memory_after(ctx) -> None:
    before = getattr(ctx, "_mo64_memory", None)
    after = await _read_memory(ctx)
    ctx.measure("F_ereignis (fault event)", ctx.value("F_ereignis"), expect=False, fail=False)
    if before is None:
        ctx.fail("the error memory was not read before the cycle")
    changed = [f"level {a[0]}: flags 0x{b[1]:08X} -> 0x{a[1]:08X} at {a[2]} h" for b, a in zip(before, after) if a != b]
    ctx.measure("Error memory levels changed", len(changed) + abs(len(after) - len(before)), expect=0, fail=False)
    if changed or len(after) != len(before):
        ctx.fail("the error memory changed during the cycle: " + ("; ".join(changed) or f"{len(before)} -> {len(after)} levels"))
    if ctx.value("F_ereignis"):
        ctx.fail("fault event (F_ereignis) set after the cycle")


async def cleanup(ctx, settings: dict) -> None:
    """Nothing is left held: the checkout sends pulses only, never levels. An open boom closes by
    itself after t_open (chapter 5.2.4.1), unless its light barrier or a loop holds it."""
    if _state(ctx) not in (GateState.CLOSED, None):
        ctx.note(f"the boom was left {_state_name(_state(ctx))}: it closes by itself after the open time")
