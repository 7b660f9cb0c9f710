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

What a person reads is a ``Message`` (docs/i18n.md): the gate states as the plant view words them (Torzustand), the
light barrier (LS), loops and F_ereignis in the document's words.
"""

from __future__ import annotations

import time
import weakref
from typing import Any

from devices.mo64.adapter import P_LEVELS_UNAVAILABLE
from devices.message import N_, Message, Word, joined
from devices.mo64.codec import ERROR_MEMORY_LEVELS, GATE_STATE_NAMES, TIME_STEP_S, Command, Function, GateState
from devices.mo64.control import COMMAND_NAMES, FUNCTION_WORDS
from devices.mo64.policy import AREA_CLEAR_RISK

TITLE = Message(N_("Open and close cycle"))
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
_WHY = {"LS": Message(N_("light barrier interrupted (LS)")), "F_ereignis": Message(N_("fault event (F_ereignis)")),
        "Baum ab": Message(N_("boom off (Baum ab)")), "loop A occupied": Message(N_("loop A occupied")),
        "loop B occupied": Message(N_("loop B occupied")), "loop C occupied": Message(N_("loop C occupied"))}
GATE_STATE, POSITION = Message(N_("Gate state")), Message(N_("Position"))  # the points, measured by their names
T_OPEN = "Open time"  # 0x0D t_offen, 10 ms units (adapter NAMES)
LOOP_MODES = "Induction-loop modes"  # 0x12, one 16-bit mode register per loop A, B, C (adapter NAMES)
LOOP_ON_BIT = 0x0001  # chapter 5.1.18: the first row of each loop's mode register, "Schleife eingeschaltet"
_CLOSING = (GateState.PREWARN_CLOSE, GateState.CLOSING)
_REVERSED = (GateState.OPENING, GateState.OPEN, GateState.PREWARN_OPEN)
# what a person is asked to do; "Toggle LS" / "Toggle loop-A" name the twin's controls where the barrier is
# simulated (the record page and the CLI offer them with the question)
LS_READY = Message(N_("Toggle LS as the boom closes: stand ready at the light barrier, interrupt it once the boom starts "
                      "to close and keep it interrupted until you are asked to free it. Ready?"))
LS_FREE = Message(N_("Toggle LS now: free the light barrier."))
OPEN_PULSE, CLOSE_PULSE = "open pulse", "close pulse"  # the declared commands (devices/mo64/policy.py)


def _command(command: str) -> Message:
    """A declared pulse command in words, as the device page names it ("open pulse", "öffnen Impuls")."""
    return Message(FUNCTION_WORDS[Function.PULSE], command=Message(COMMAND_NAMES[Command.OPEN if command == OPEN_PULSE
                                                                               else Command.CLOSE]))


def steps(options: dict, settings: dict) -> list[dict]:
    tol = settings["position_tolerance_pct"]
    return [
        {"name": Message(N_("Area clear (asked)")), "limits": Message(N_("the engineer confirms")), "run": _ask},
        {"name": Message(N_("Error memory before")), "limits": Message(N_("all 10 levels read (or not available on this unit)")),
         "run": _memory_before},
        {"name": Message(N_("Light barrier, loops, no fault")),
         "limits": Message(N_("LS, loops A-C, F_ereignis, Baum ab all 0; boom closed")), "run": _idle},
        {"name": Message(N_("Open")),
         "limits": Message(N_("open within {limit:g} s, position >= {position} %; pre-warning, opening, open in that order"),
                           limit=settings["open_time_max_s"], position=100 - tol), "run": _open},
        {"name": Message(N_("Light barrier reverses a closing boom (asked)")),
         "limits": Message(N_("interrupted while the boom closes: LS reported and the boom reverses within {limit:g} s"),
                           limit=settings["reverse_timeout_s"]), "run": _light_barrier},
        {"name": Message(N_("Induction loops (asked)")),
         "limits": Message(N_("each loop switched on: occupied and free again seen within {limit:g} s"),
                           limit=settings["safety_seen_s"]), "run": _loops},
        {"name": Message(N_("Automatic closing (t_offen)")),
         "limits": Message(N_("with t_offen != 0: the open boom closes by itself within t_offen + {limit:g} s (5.2.4.1); "
                              "t_offen = 0: not available"), limit=settings["close_time_max_s"]), "run": _auto_close},
        {"name": Message(N_("Close")),
         "limits": Message(N_("closed within {limit:g} s, position <= {position} %; light barrier and loops free throughout"),
                           limit=settings["close_time_max_s"], position=tol), "run": _close},
        {"name": Message(N_("Error memory unchanged")), "limits": Message(N_("every level as before the cycle; F_ereignis 0")),
         "run": _memory_after},
    ]


async def _ask(ctx) -> None:
    await ctx.ask(AREA_CLEAR_RISK)  # before anything is read or waited for; asked again before each motion


def _state(ctx) -> int | None:
    return ctx.value("Gate state")


def _state_name(value) -> str:
    if value is None:
        return Message(N_("unknown"))
    name = GATE_STATE_NAMES.get(value)
    return Message(N_("state {value}"), value=value) if name is None else Message("{state}", state=Word(name, "Gate state"))


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
        ctx.not_available(Message(N_("the barrier refuses every error-memory level (query 0x12, levels {levels}): its error "
                                     "memory cannot be compared on this unit; read it on the unit's display"),
                                  levels=str(missing) if missing else Message(N_("all"))))
    if missing:
        ctx.note(Message(N_("error memory levels not available on this unit: {levels}; the others are compared"),
                         levels=str(missing)))
    ctx.measure(Message(N_("Error memory levels read")), len(rows), fail=False)
    ctx.measure(Message(N_("Error memory level 0 flags")), f"0x{rows[0][1]:08X}", fail=False)


async def _idle(ctx) -> None:
    s = ctx.settings
    if not await ctx.wait(lambda: all(ctx.value(name) is not None for name in (*SAFETY, *LOOPS)) and _state(ctx) is not None,
                          s["start_timeout_s"]):
        ctx.fail(Message(N_("no barrier status or gate state from the barrier")))
    bad = [_WHY[name] for name in (*SAFETY, *LOOPS) if ctx.value(name)]
    for name in (*SAFETY, *LOOPS):
        ctx.measure(_WHY[name] if name in LOOPS else name, ctx.value(name), expect=False, fail=False)
    if bad:
        ctx.fail(Message(N_("not ready for the cycle: {why}"), why=joined(bad)))
    if _state(ctx) != GateState.CLOSED:
        t_open = _t_open_s(ctx)
        if t_open:  # chapter 5.2.4.1: an open boom closes by itself after t_offen ...
            ctx.note(Message(N_("the boom was {state} at the start: waiting for it to close by itself (t_offen {t_open:g} s)"),
                             state=_state_name(_state(ctx)), t_open=t_open))
            await ctx.wait(lambda: _state(ctx) == GateState.CLOSED, t_open + s["close_time_max_s"])
        else:  # ... unless t_offen = 0 switches automatic closing off: it is closed by command
            why = Message(N_("t_offen = 0: automatic closing is off")) if t_open == 0 else Message(N_("t_offen not read"))
            ctx.note(Message(N_("the boom was {state} at the start ({why}): closing it by command"),
                             state=_state_name(_state(ctx)), why=why))
            await ctx.ask(AREA_CLEAR_RISK)
            await ctx.invoke(CLOSE_PULSE)
            await ctx.wait(lambda: _state(ctx) == GateState.CLOSED, s["close_time_max_s"] + 1.0)
    ctx.measure(GATE_STATE, _state_name(_state(ctx)), expect=_state_name(GateState.CLOSED))


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
    ctx.measure(Message(N_("{command}: the barrier's answer"), command=_command(command)), answer, expect="ack")
    reached = await ctx.wait(follow, limit_s + 1.0)
    took = round(time.monotonic() - t0, 2)
    transitions = joined([Message(N_("{state} at {seconds:.2f} s"), state=_state_name(state), seconds=t - t0)
                          for t, state in seen], " -> ")
    ctx.note(Message(N_("gate state: {transitions}"), transitions=transitions if seen else Message(N_("no change seen"))))
    for t, state in seen[1:]:
        ctx.measure(Message(N_("Gate state {state} seen after"), state=_state_name(state)), round(t - t0, 2), "s", fail=False)
    if not reached:
        why = [_WHY[name] for name in sorted(safety)]
        went = Message(N_("not {state} within {limit:g} s: the gate state went {transitions}, position {position} %"),
                       state=_state_name(goal), limit=limit_s, transitions=transitions if seen else Message(N_("nowhere")),
                       position=ctx.value("Position"))
        ctx.fail(Message("{went}; {why}", went=went, why=joined(why)) if why else went)
    ctx.measure(Message(N_("{command} to {state} seen"), command=_command(command), state=_state_name(goal)), took, "s",
                high=limit_s)
    tol = ctx.settings["position_tolerance_pct"]
    if goal == GateState.OPEN:
        ctx.measure(POSITION, ctx.value("Position"), "%", low=100 - tol, high=100)
    else:
        ctx.measure(POSITION, ctx.value("Position"), "%", low=0, high=tol)
    if safety:
        ctx.fail(Message(N_("{why} during the move"), why=joined([_WHY[name] for name in sorted(safety)])))
    for name in ("LS", *LOOPS):
        ctx.measure(name, ctx.value(name), expect=False)
    return took


async def _open(ctx) -> None:
    await _cycle(ctx, OPEN_PULSE, GateState.OPEN, ctx.settings["open_time_max_s"])


async def _ensure_open(ctx) -> None:
    if _state(ctx) == GateState.OPEN and _at_end(ctx, GateState.OPEN):
        return
    await _cycle(ctx, OPEN_PULSE, GateState.OPEN, ctx.settings["open_time_max_s"])


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
    answer = await ctx.invoke(CLOSE_PULSE)
    ctx.measure(Message(N_("{command}: the barrier's answer"), command=_command(CLOSE_PULSE)), answer, expect="ack")
    reversed_ = await ctx.wait(follow, s["reverse_timeout_s"])
    took = round(time.monotonic() - t0, 2)
    went = joined([_state_name(x) for x in seen], " -> ") if seen else Message(N_("nowhere"))
    ctx.note(Message(N_("gate state: {transitions}"), transitions=went))
    ctx.measure(Message(N_("LS reported while the boom closed")), ls_seen, expect=True, fail=False)
    if not reversed_:
        if not closing_seen:
            ctx.fail(Message(N_("the boom did not start to close (gate state went {went}): nothing to interrupt; is the light "
                                "barrier already interrupted, a loop occupied or an open level held?"), went=went))
        if not ls_seen:
            ctx.fail(Message(N_("the light barrier was to be interrupted while the boom closed, but LS never reported it (gate "
                                "state went {went}, position {position} %): check the light barrier's wiring, alignment and "
                                "supply, and its mode in the configuration flags"), went=went, position=ctx.value("Position")))
        ctx.fail(Message(N_("LS reported, but the boom did not reverse within {limit:g} s (gate state went {went}, position "
                            "{position} %): the light barrier's safety function does not act"), limit=s["reverse_timeout_s"],
                         went=went, position=ctx.value("Position")))
    ctx.measure(Message(N_("Close pulse to the boom reversing")), took, "s", high=s["reverse_timeout_s"])
    await ctx.ask(LS_FREE)
    if not await ctx.wait(lambda: not ctx.value("LS"), s["safety_seen_s"]):
        ctx.fail(Message(N_("LS still reported {limit:g} s after the light barrier was freed: is something in the beam?"),
                         limit=s["safety_seen_s"]))
    ctx.measure(Message(N_("LS after freeing")), ctx.value("LS"), expect=False)


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
        on = [x for x in "ABC" if await ctx.choose(
            Message(N_("The loop modes (0x12) were not read: is loop {loop} installed and switched on?"), loop=x),
            Message(N_("loop {loop} not tested"), loop=x))]
    else:
        ctx.note(Message(N_("loops switched on (0x12): {loops}"), loops=", ".join(on) if on else Message(N_("none"))))
    if not on:
        ctx.not_available(Message(N_("no induction loop is switched on at this barrier (0x12)")))
    for loop in on:
        name = f"loop {loop} occupied"
        await ctx.ask(Message(N_("Toggle loop-{loop} now: occupy loop {loop} (drive or place a vehicle on it) and leave it "
                                 "occupied until you are asked to free it."), loop=loop))
        occupied = await ctx.wait(lambda n=name: ctx.value(n) is True, s["safety_seen_s"])
        ctx.measure(Message(N_("Loop {loop} occupied seen"), loop=loop), ctx.value(name), expect=True, fail=False)
        if not occupied:
            ctx.fail(Message(N_("loop {loop} was to be occupied, but the barrier did not report it within {limit:g} s: check "
                                "the loop, its detector's sensitivity and the loop-adjust state"), loop=loop,
                             limit=s["safety_seen_s"]))
        await ctx.ask(Message(N_("Toggle loop-{loop} now: free loop {loop}."), loop=loop))
        freed = await ctx.wait(lambda n=name: ctx.value(n) is False, s["safety_seen_s"])
        ctx.measure(Message(N_("Loop {loop} free again"), loop=loop), ctx.value(name), expect=False, fail=False)
        if not freed:
            ctx.fail(Message(N_("loop {loop} still reported occupied {limit:g} s after it was freed"), loop=loop,
                             limit=s["safety_seen_s"]))


async def _close(ctx) -> None:
    if _state(ctx) in _CLOSING:  # closing by itself (t_offen) meanwhile: let it end, then open to close by command
        await ctx.wait(lambda: _state(ctx) == GateState.CLOSED, ctx.settings["close_time_max_s"])
    if _state(ctx) != GateState.OPEN:
        await _cycle(ctx, OPEN_PULSE, GateState.OPEN, ctx.settings["open_time_max_s"])
    await _cycle(ctx, CLOSE_PULSE, GateState.CLOSED, ctx.settings["close_time_max_s"])


async def _auto_close(ctx) -> None:
    """Chapter 5.2.4.1: an open boom closes by itself after t_offen; t_offen = 0 switches that off."""
    s = ctx.settings
    t_open = _t_open_s(ctx)
    if t_open is None:
        ctx.not_available(Message(N_("t_offen (0x0D) was not read from this barrier: whether it closes by itself is unknown")))
    ctx.measure("t_offen", round(t_open, 2), "s", fail=False)
    if t_open == 0:
        ctx.not_available(Message(N_("t_offen = 0: automatic closing is switched off on this unit (5.2.4.1)")))
    if _state(ctx) != GateState.OPEN:
        await _cycle(ctx, OPEN_PULSE, GateState.OPEN, s["open_time_max_s"])
    t0 = time.monotonic()
    limit = t_open + s["close_time_max_s"]
    closed = await ctx.wait(lambda: _state(ctx) == GateState.CLOSED and _at_end(ctx, GateState.CLOSED), limit + 1.0)
    took = round(time.monotonic() - t0, 2)
    if not closed:
        ctx.fail(Message(N_("t_offen is {t_open:g} s, but the boom did not close by itself within {limit:g} s (gate state "
                            "{state}, position {position} %; light barrier {barrier})"), t_open=t_open, limit=limit,
                         state=_state_name(_state(ctx)), position=ctx.value("Position"),
                         barrier=Message(N_("interrupted")) if ctx.value("LS") else Message(N_("free"))))
    ctx.measure(Message(N_("Open to closed by itself")), took, "s", high=limit)
    ctx.measure(POSITION, ctx.value("Position"), "%", low=0, high=s["position_tolerance_pct"])


async def _memory_after(ctx) -> None:
    before = _MEMORY_BEFORE.get(ctx)
    if before is None:
        ctx.fail(Message(N_("the error memory was not read before the cycle")))
    rows_before, missing_before = before
    if len(missing_before) >= ERROR_MEMORY_LEVELS or not rows_before:
        ctx.not_available(Message(N_("the barrier refuses every error-memory level: nothing to compare (see 'Error memory "
                                     "before')")))
    after, missing = await _read_memory(ctx)
    ctx.measure(Message(N_("F_ereignis (fault event)")), ctx.value("F_ereignis"), expect=False, fail=False)
    levels = {r[0] for r in rows_before} & {r[0] for r in after}
    if not levels:
        ctx.fail(Message(N_("the error memory could not be read after the cycle (levels not available: {levels})"),
                         levels=str(missing)))
    b, a = ({r[0]: r for r in rows if r[0] in levels} for rows in (rows_before, after))
    changed = [Message(N_("level {level}: flags {before} -> {after} at {hours} h"), level=n, before=f"0x{b[n][1]:08X}",
                       after=f"0x{a[n][1]:08X}", hours=a[n][2]) for n in sorted(levels) if a[n] != b[n]]
    ctx.measure(Message(N_("Error memory levels compared")), len(levels), fail=False)
    ctx.measure(Message(N_("Error memory levels changed")), len(changed), expect=0, fail=False)
    if changed:
        ctx.fail(Message(N_("the error memory changed during the cycle: {levels}"), levels=joined(changed, "; ")))
    if ctx.value("F_ereignis"):
        ctx.fail(Message(N_("fault event (F_ereignis) set after the cycle")))


async def cleanup(ctx, settings: dict) -> None:
    """Nothing is left held: the checkout sends pulses only, never levels. An open boom closes by
    itself after t_offen (chapter 5.2.4.1) unless its light barrier or a loop holds it, or t_offen = 0."""
    if _state(ctx) not in (GateState.CLOSED, None):
        t_open = _t_open_s(ctx)
        if t_open:
            ctx.note(Message(N_("the boom was left {state}: it closes by itself after t_offen ({t_open:g} s)"),
                             state=_state_name(_state(ctx)), t_open=t_open))
        else:
            ctx.note(Message(N_("the boom was left {state} and does not close by itself ({why}): close it from the device page"),
                             state=_state_name(_state(ctx)),
                             why="t_offen = 0" if t_open == 0 else Message(N_("t_offen unknown"))))
