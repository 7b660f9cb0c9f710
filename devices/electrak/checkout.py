"""Electrak HD checkout: move a given distance out and back at a given speed, position within
tolerance, current below the limit, no fault flags (status 0x07, SY2 document).

Declared here, run by the generic runner (``app/record.py``); reads the published points and invokes the
declared commands (devices/electrak/policy.py). Control is taken for the run's session (under the dead-man
rule); the cleanup stops and releases it, also after an abort.
"""

from __future__ import annotations

from devices.electrak.policy import AREA_CLEAR_RISK

TITLE = "Move out and back"
SETTINGS = {
    "distance_mm": 20.0,
    "speed_mm_s": 15.0,
    "tolerance_mm": 1.0,
    "current_max_a": 8.0,
    "move_timeout_s": 10.0,
}


def steps(options: dict, settings: dict) -> list[dict]:
    move = (f"{settings['distance_mm']:g} mm at {settings['speed_mm_s']:g} mm/s, position within ±{settings['tolerance_mm']:g} mm, "
            f"current <= {settings['current_max_a']:g} A, no error flags")
    return [
        {"name": "Area clear (asked)", "limits": "the engineer confirms", "run": _ask},
        {"name": "Take control, no faults", "limits": "every configured actuator heard; error flags 0", "run": _take},
        {"name": "Move out", "limits": move, "run": lambda ctx: _move(ctx, +1)},
        {"name": "Move back", "limits": move, "run": lambda ctx: _move(ctx, -1)},
    ]


async def _ask(ctx) -> None:
    # the question Go asks (its declared risk): answered here once, before control is taken
    await ctx.ask(AREA_CLEAR_RISK)


def _flags(ctx) -> str:
    e = ctx.entry("Error flags")
    return (e or {}).get("text") or str((e or {}).get("value"))


async def _take(ctx) -> None:
    await ctx.invoke("take control", {"user": ctx.user})
    # a message-timeout flag from before control was taken clears with the first control telegrams
    await ctx.wait(lambda: ctx.value("Error flags") == 0, 2.0)
    ctx.measure("Error flags", ctx.value("Error flags"), expect=0, fail=False)
    if ctx.value("Error flags"):
        ctx.fail(f"error flags set before moving: {_flags(ctx)}")
    configured = ctx.value("Devices configured")
    await ctx.wait(lambda: (ctx.value("Devices heard") or 0) >= (configured or 1), 2.0)
    ctx.measure("Devices heard (status telegrams per 100 ms)", ctx.value("Devices heard"), low=configured or 1)
    ctx.start_mm = ctx.value("Position")
    ctx.measure("Start position", ctx.start_mm, "mm")


async def _move(ctx, direction: int) -> None:
    s = ctx.settings
    start = ctx.start_mm
    stroke = ctx.value("Stroke") or 0
    if direction > 0:
        target = start + s["distance_mm"] if start + s["distance_mm"] <= stroke else start - s["distance_mm"]
        ctx.out_mm = target
    else:
        target = start
    peak = {"a": 0.0, "errors": 0}

    def arrived() -> bool:
        peak["a"] = max(peak["a"], ctx.value("Current") or 0.0)
        peak["errors"] |= ctx.value("Error flags") or 0
        if peak["errors"]:
            return True
        pos = ctx.value("Position")
        return pos is not None and abs(pos - target) <= s["tolerance_mm"] and not (ctx.value("Motion flags") or 0) & 0b11

    await ctx.invoke("set target", {"position_mm": float(target), "speed_mm_s": float(s["speed_mm_s"]), "current_a": 0.0})
    await ctx.invoke("go")
    reached = await ctx.wait(arrived, s["move_timeout_s"])
    await ctx.invoke("stop")
    if peak["errors"]:
        ctx.measure("Error flags", peak["errors"], expect=0, fail=False)
        ctx.fail(f"error flags during the move: {_flags(ctx)} (peak current {peak['a']:.1f} A)")
    ctx.measure("Position", ctx.value("Position"), "mm", low=target - s["tolerance_mm"], high=target + s["tolerance_mm"],
                fail=reached)
    if not reached:
        ctx.fail(f"target {target:g} mm not reached within {s['move_timeout_s']:g} s (at {ctx.value('Position')} mm)")
    ctx.measure("Peak current", round(peak["a"], 2), "A", high=s["current_max_a"])
    ctx.measure("Error flags", ctx.value("Error flags"), expect=0)


async def cleanup(ctx, settings: dict) -> None:
    await ctx.invoke("stop")
    await ctx.invoke("release control", {"reason": "checkout finished"})
