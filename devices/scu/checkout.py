"""Ewellix SCU checkout: each actuator moved a given distance and back (positions, currents, no
error bits), and the watchdog trip test where the adapter offers one.

Declared here, run by the generic runner (``app/record.py``). Control is taken for the run's
session (one session drives the unit; its RE are under the dead-man rule and the RC lease); each
move writes the remote position (RT 0x3021.., table 7) and starts the function that drives the
actuator with "to the remote position" (RE Fn 09, table 9), and ends with its RS (section 4.6:
every RE is followed by an RS, also when the actuator stopped at its target). The stop is the
declared command "stop (RS)"; the cleanup stops and releases control, also after an abort.

Watchdog trip (section 5: RC at least every 500 ms, "Die Kommunikation mit RC arbeitet als
Watchdog"): RC must be withheld while a function runs and the drive seen to stop within 500 ms.
It runs where the type declares a command to withhold RC (``withhold RC``); otherwise the step is
recorded as not available, with the reason. What a person reads is a ``Message`` (docs/i18n.md).
"""

from __future__ import annotations

import time

from devices.commands import find
from devices.message import N_, Message, Word, joined
from devices.scu import codec
from devices.scu.adapter import P_FUNCTIONS, P_SCALES, P_SESSION

TITLE = Message(N_("Actuators out and back"))
WITHHOLD_RC = "withhold RC"  # the declared command the watchdog trip test needs (devices/scu/policy.py)
ERROR_CODE = Message(N_("Error code"))  # the point, measured by its name
SETTINGS = {
    "distance_mm": 10.0,  # where the actuator converts counts to mm (plant file: counts_per_mm or stroke_mm)
    "distance_counts": 150,  # otherwise
    "tolerance_counts": 10,
    "current_max_a": 8.0,
    "move_timeout_s": 8.0,
    "watchdog_stop_max_s": 0.5,  # section 5
    "watchdog_tolerance_s": 0.2,  # the unit's own cycle and this measurement (positions come with RC, 200 ms apart)
}


def actuators(options: dict) -> list[int]:
    listed = options.get("actuators", 1)
    return list(range(1, (listed if isinstance(listed, int) else len(listed)) + 1))


def steps(options: dict, settings: dict) -> list[dict]:
    limits = Message(N_("{distance:g} mm (or {counts} counts) and back, position within ±{tolerance} counts, current <= "
                        "{current:g} A, no error bits"), distance=settings["distance_mm"], counts=settings["distance_counts"],
                     tolerance=settings["tolerance_counts"], current=settings["current_max_a"])
    listed = [
        {"name": Message(N_("Area clear (asked)")), "limits": Message(N_("the engineer confirms")), "run": _ask},
        {"name": Message(N_("Take control, no error bits")), "limits": Message(N_("remote session open; Error code 0")),
         "run": _take},
    ]
    for n in actuators(options):
        listed.append({"name": Message(N_("A{n} out and back"), n=n), "limits": limits, "run": lambda ctx, n=n: _out_and_back(ctx, n)})
    listed.append({"name": Message(N_("Watchdog trip (RC withheld)")),
                   "limits": Message(N_("motion stops within {stop:.0f} ms (+{tolerance:.0f} ms measuring), error bit 22 "
                                        "reported"), stop=settings["watchdog_stop_max_s"] * 1000,
                                     tolerance=settings["watchdog_tolerance_s"] * 1000),
                   "run": _watchdog})
    return listed


async def _ask(ctx) -> None:
    await ctx.ask(Message(N_("Is the area around the actuators clear for a short move out and back of each?")))


def _error_text(ctx) -> Word:
    """Error_Code in table 10's words (``bit 14: total current exceeded``), worded as the page words the point."""
    e = ctx.entry("Error code") or {}
    return Word(e.get("text") or str(e.get("value")), "Error code")


async def _take(ctx) -> None:
    await ctx.invoke("take control", {"user": ctx.user})
    if not await ctx.wait(lambda: ctx.value(P_SESSION) == "open", 5.0):
        # a unit watched with RG alone opens the session for a command: the first RG of a move opens it
        ctx.note(Message(N_("remote session {session}: opened by the first command"), session=Word(str(ctx.value(P_SESSION)), P_SESSION)))
    await ctx.wait(lambda: ctx.value("Error code") is not None, 3.0)
    code = ctx.value("Error code") or 0
    ctx.measure(ERROR_CODE, code, expect=0, fail=False)
    if code & ~codec.CLEARED_BY_NEXT_MOVE:
        ctx.fail(Message(N_("error bits set before moving: {errors}"), errors=_error_text(ctx)))
    if code:
        # each bit with its cause as table 10 and the SCU's page word it ("Bit 14: Summenstrom wurde überschritten")
        names = joined([Message("{cause}", cause=Word(f"bit {b.bit}: {b.cause}", "Error code")) for b in codec.error_bits(code)])
        ctx.note(Message(N_("{bits}: reset by the next movement (table 10); the first move must clear it"), bits=names))


def _function_of(ctx, n: int) -> int | None:
    """The function (fnc_ID) that drives actuator ``n`` alone (plant file, else SCP11: F(n) drives A(n))."""
    only = [fn for fn, acts in ctx.value(P_FUNCTIONS).actuators if list(acts) == [n]]
    return only[0] if only else None


def _position(ctx, n: int) -> int | None:
    return ctx.value(f"A{n} position")


async def _move(ctx, n: int, fn: int, target: int, what: str) -> None:
    s = ctx.settings
    watch = {"peak": 0.0, "errors": 0, "last": None, "still": 0}
    # bits that clear with this movement (table 10) may still be shown set until the unit's next status arrives
    latched = (ctx.value("Error code") or 0) & codec.CLEARED_BY_NEXT_MOVE

    def arrived() -> bool:
        watch["peak"] = max(watch["peak"], ctx.value(f"A{n} current") or 0.0)
        watch["errors"] |= (ctx.value("Error code") or 0) & ~latched
        if watch["errors"]:
            return True
        pos = _position(ctx, n)
        if pos is None or abs(pos - target) > s["tolerance_counts"] or ctx.value(f"A{n} motion"):
            watch["still"] = 0
            return False
        watch["still"] = watch["still"] + 1 if pos == watch["last"] else 0
        watch["last"] = pos
        return watch["still"] >= 2  # the same position in three looks: it stands

    await ctx.invoke("set remote position", {"actuator": n, "value": target})
    t0 = time.monotonic()
    await ctx.invoke("go (RE)", {"function": fn, "motion": int(codec.Motion.REMOTE_POSITION), "ramp": int(codec.Ramp.SOFT)})
    reached = await ctx.wait(arrived, s["move_timeout_s"])
    took = round(time.monotonic() - t0, 2)
    await ctx.invoke("stop (RS)")  # every RE is followed by its RS (section 4.6)
    if watch["errors"]:
        ctx.measure(ERROR_CODE, watch["errors"], expect=0, fail=False)
        ctx.measure(Message(N_("A{n} peak current"), n=n), round(watch["peak"], 1), "A", fail=False)
        ctx.fail(Message(N_("A{n} {what}: error bits during the move: {errors} (peak current {current:.1f} A, at {position} "
                            "counts)"), n=n, what=what, errors=_error_text(ctx), current=watch["peak"], position=_position(ctx, n)))
    ctx.measure(Message(N_("A{n} position {what}"), n=n, what=what), _position(ctx, n), "counts",
                low=target - s["tolerance_counts"], high=target + s["tolerance_counts"], fail=reached)
    if not reached:
        ctx.fail(Message(N_("A{n} {what}: {target} counts not reached within {timeout:g} s (at {position} counts)"), n=n,
                         what=what, target=target, timeout=s["move_timeout_s"], position=_position(ctx, n)))
    ctx.measure(Message(N_("A{n} {what}: time to standstill"), n=n, what=what), took, "s", fail=False)
    ctx.measure(Message(N_("A{n} peak current {what}"), n=n, what=what), round(watch["peak"], 1), "A", high=s["current_max_a"])
    ctx.measure(ERROR_CODE, ctx.value("Error code"), expect=0)


async def _out_and_back(ctx, n: int) -> None:
    s = ctx.settings
    fn = _function_of(ctx, n)
    if fn is None:
        ctx.not_available(Message(N_("no function drives A{n} alone (plant file 'functions'): it cannot be moved on its own"),
                                  n=n))
    if not await ctx.wait(lambda: _position(ctx, n) is not None, 3.0):
        ctx.fail(Message(N_("no position of A{n} from the unit"), n=n))
    start = int(_position(ctx, n))
    scale = ctx.value(P_SCALES)[n - 1]
    distance = scale.counts(s["distance_mm"]) - scale.counts(0) if scale.has_mm else int(s["distance_counts"])
    top = scale.out_counts if scale.out_counts is not None else None
    target = start + distance if top is None or start + distance <= top else start - distance
    source = Message(N_("assumed, SCP11")) if ctx.value(P_FUNCTIONS).assumed else Message(N_("plant file"))
    ctx.note(Message(N_("A{n} by {function} ({source}): {start} -> {target} -> {start} counts"), n=n,
                     function=codec.FUNCTIONS[codec.Function(fn)].label, source=source, start=start, target=target))
    ctx.measure(Message(N_("A{n} start position"), n=n), start, "counts", fail=False)
    await _move(ctx, n, fn, target, Message(N_("out")) if target > start else Message(N_("in")))
    await _move(ctx, n, fn, start, Message(N_("back")))


async def _watchdog(ctx) -> None:
    if find(ctx.config.type, WITHHOLD_RC) is None:
        ctx.not_available(Message(N_("the SCU type declares no command to withhold RC: test it on the unit by pulling the "
                                     "RS232 cable during a jog")))
    n = actuators(ctx.options)[0]
    fn = _function_of(ctx, n)
    if fn is None:
        ctx.not_available(Message(N_("no function drives A{n} alone"), n=n))
    # While RC is withheld nothing is read from the unit (the position arrives with RC): the drive's standstill is
    # worked out from its speed before and the position read once the session is open again.
    start = _position(ctx, n)
    await ctx.invoke("go (RE)", {"function": fn, "motion": int(codec.Motion.OUT), "ramp": int(codec.Ramp.SOFT)})
    await ctx.wait(lambda: _position(ctx, n) != start, 2.0)
    moving_at = time.time()
    # past the soft start (the unit ramps up, section 4.6), its speed from two positions 0.3 s apart
    await ctx.wait(lambda: (ctx.entry(f"A{n} position") or {}).get("time", 0) >= moving_at + 0.6, 2.0)
    first = ctx.entry(f"A{n} position") or {}
    await ctx.wait(lambda: (ctx.entry(f"A{n} position") or {}).get("time", 0) >= (first.get("time") or 0) + 0.3, 2.0)
    before = ctx.entry(f"A{n} position") or {}
    span = (before.get("time") or 0) - (first.get("time") or 0)
    speed = abs((before.get("value") or 0) - (first.get("value") or 0)) / span if span > 0 else 0.0
    if speed <= 0:
        ctx.fail(Message(N_("A{n} did not move after Go: the watchdog cannot be tested"), n=n))
    await ctx.invoke(WITHHOLD_RC)
    withheld_at = time.time()  # RC stopped at the latest now (the command runs after its audit row)
    # the session opens again once the unit's watchdog has tripped; the first position after that tells the travel
    fresh = await ctx.wait(lambda: ctx.value(P_SESSION) == "open"
                           and (ctx.entry(f"A{n} position") or {}).get("time", 0) > withheld_at + 1.0, 8.0)
    if not fresh:
        ctx.fail(Message(N_("no position of A{n} after the session was opened again: the standstill cannot be measured"), n=n))
    after = ctx.entry(f"A{n} position") or {}
    travel = abs((after.get("value") or 0) - (before.get("value") or 0))
    stopped_at = (before.get("time") or withheld_at) + travel / speed  # it ran at its speed until it stopped
    ctx.note(Message(N_("A{n} at {speed:.0f} counts/s; {travel} counts after its last position before RC was withheld"), n=n,
                     speed=speed, travel=travel))
    ctx.measure(Message(N_("A{n} last movement after RC withheld"), n=n), round(max(0.0, stopped_at - withheld_at), 2), "s",
                high=ctx.settings["watchdog_stop_max_s"] + ctx.settings["watchdog_tolerance_s"])
    # the unit reports why: error bit 22 (remote communication timeout), read once the session is open again
    reported = await ctx.wait(lambda: bool((ctx.value("Error code") or 0) & codec.REMOTE_TIMEOUT_MASK), 5.0)
    ctx.measure(Message(N_("Error bit 22 (remote communication timeout) reported")), reported, expect=True)


async def cleanup(ctx, settings: dict) -> None:
    await ctx.invoke("stop (RS)")
    await ctx.invoke("release control", {})
