"""Electrak HD checkout: move a given distance out and back, position within tolerance, current below
the limit, no fault flags, Saturated not held (status 0x07, SY2 document).

Limits from the network's own configuration (model, gearing and stroke of each actuator, codec.Limits):
the speed is the middle of the speed range every gearing of the network accepts ("Geschwindigkeit" by
gearing, B017 11-58 ... B160 1-5 mm/s), the current limit is the models' own (MD12 25 A, HD24 12.5 A,
HD48 6.5 A). The peak current is taken after the start-up: the document excludes the inrush
("Diese Strombegrenzung gilt nicht während der Motor-Anfahrphase"). "Saturated" must not stay on under
CAN control ("Der Anwender muss sicherstellen, dass dieses Bit bei keinem Gerät aktiviert bleibt").

Declared here, run by the generic runner (``app/record.py``); reads the published points and invokes the
declared commands (devices/electrak/policy.py). Control is taken for the run's session (under the dead-man
rule); the cleanup stops and releases it, also after an abort. What a person reads is a ``Message`` (docs/i18n.md).
"""

from __future__ import annotations

from devices.electrak import codec
from devices.electrak.policy import AREA_CLEAR_RISK
from devices.message import N_, Message, Word

TITLE = Message(N_("Move out and back"))
ERROR_FLAGS, POSITION = Message(N_("Error flags")), Message(N_("Position"))  # the points, measured by their names
SETTINGS = {
    "distance_mm": 20.0,
    "speed_mm_s": None,  # None: the middle of the speed range every actuator's gearing accepts
    "tolerance_mm": 1.0,
    "current_max_a": None,  # None: the actuators' own limit by model (the lowest of the network)
    "startup_s": 0.5,  # the inrush after each start is not counted in the peak current (document: Strombegrenzung)
    "saturated_max_s": 1.0,  # Saturated on this long without a break fails the move
    "move_timeout_s": 20.0,
}


def limits_of(options: dict, settings: dict) -> tuple[float, float]:
    """(speed mm/s, current limit A) for this network: the settings', else from its actuators' model and gearing."""
    try:
        limits = codec.Limits.of([codec.Actuator(a["model"], a["gearing"], float(a["stroke_mm"]))
                                  for a in options.get("actuators", [])])
    except (codec.CodecError, KeyError, TypeError, ValueError):
        limits = None
    speed = settings.get("speed_mm_s")
    if speed is None:
        speed = round((limits.speed_min + limits.speed_max) / 2, 1) if limits is not None else 5.0
    current = settings.get("current_max_a")
    if current is None:
        current = limits.current_a if limits is not None else 6.5
    return float(speed), float(current)


def steps(options: dict, settings: dict) -> list[dict]:
    speed, current = limits_of(options, settings)
    move = Message(N_("{distance:g} mm at {speed:g} mm/s (middle of the gearings' range), position within "
                      "±{tolerance:g} mm, current after start-up <= {current:g} A (the models' limit), no error "
                      "flags, Saturated not on for {saturated:g} s"), distance=settings["distance_mm"], speed=speed,
                   tolerance=settings["tolerance_mm"], current=current, saturated=settings["saturated_max_s"])
    return [
        {"name": Message(N_("Area clear (asked)")), "limits": Message(N_("the engineer confirms")), "run": _ask},
        {"name": Message(N_("Take control, no faults")), "limits": Message(N_("every configured actuator heard; error flags 0")),
         "run": _take},
        {"name": Message(N_("Move out")), "limits": move, "run": lambda ctx: _move(ctx, +1)},
        {"name": Message(N_("Move back")), "limits": move, "run": lambda ctx: _move(ctx, -1)},
    ]


async def _ask(ctx) -> None:
    # the question Go asks (its declared risk): answered here once, before control is taken
    await ctx.ask(AREA_CLEAR_RISK)


def _flags(ctx) -> Word:
    """The error flags in the adapter's words, worded as the device page words them (the point's context)."""
    e = ctx.entry("Error flags")
    return Word((e or {}).get("text") or str((e or {}).get("value")), "Error flags")


async def _take(ctx) -> None:
    await ctx.invoke("take control", {"user": ctx.user})
    # a message-timeout flag from before control was taken clears with the first control telegrams
    await ctx.wait(lambda: ctx.value("Error flags") == 0, 2.0)
    ctx.measure(ERROR_FLAGS, ctx.value("Error flags"), expect=0, fail=False)
    if ctx.value("Error flags"):
        ctx.fail(Message(N_("error flags set before moving: {flags}"), flags=_flags(ctx)))
    configured = ctx.value("Devices configured")
    await ctx.wait(lambda: (ctx.value("Devices heard") or 0) >= (configured or 1), 2.0)
    ctx.measure(Message(N_("Devices heard (status telegrams per 100 ms)")), ctx.value("Devices heard"), low=configured or 1)
    ctx.start_mm = ctx.value("Position")
    ctx.measure(Message(N_("Start position")), ctx.start_mm, "mm")


async def _move(ctx, direction: int) -> None:
    import time

    s = ctx.settings
    speed, current_max = limits_of(ctx.options, s)
    start = ctx.start_mm
    stroke = ctx.value("Stroke") or 0
    if direction > 0:
        target = start + s["distance_mm"] if start + s["distance_mm"] <= stroke else start - s["distance_mm"]
        ctx.out_mm = target
    else:
        target = start
    peak = {"a": 0.0, "errors": 0, "saturated_since": None, "saturated_s": 0.0}
    started = {"at": None}

    def arrived() -> bool:
        now = time.monotonic()
        if started["at"] is not None and now - started["at"] >= s["startup_s"]:  # the inrush is not counted
            peak["a"] = max(peak["a"], ctx.value("Current") or 0.0)
        peak["errors"] |= ctx.value("Error flags") or 0
        if peak["errors"]:
            return True
        if (ctx.value("Motion flags") or 0) & 0b100:  # Saturated
            peak["saturated_since"] = peak["saturated_since"] or now
            peak["saturated_s"] = max(peak["saturated_s"], now - peak["saturated_since"])
            if peak["saturated_s"] >= s["saturated_max_s"]:
                return True
        else:
            peak["saturated_since"] = None
        pos = ctx.value("Position")
        return pos is not None and abs(pos - target) <= s["tolerance_mm"] and not (ctx.value("Motion flags") or 0) & 0b11

    await ctx.invoke("set target", {"position_mm": float(target), "speed_mm_s": speed, "current_a": 0.0})
    await ctx.invoke("go")
    started["at"] = time.monotonic()
    reached = await ctx.wait(arrived, s["move_timeout_s"])
    await ctx.invoke("stop")
    if peak["errors"]:
        ctx.measure(ERROR_FLAGS, peak["errors"], expect=0, fail=False)
        ctx.fail(Message(N_("error flags during the move: {flags} (peak current after start-up {current:.1f} A)"),
                         flags=_flags(ctx), current=peak["a"]))
    ctx.measure(Message(N_("Saturated, longest time on")), round(peak["saturated_s"], 2), "s", high=s["saturated_max_s"], fail=False)
    if peak["saturated_s"] >= s["saturated_max_s"]:
        ctx.fail(Message(N_("Saturated stayed on for {on:.1f} s: the actuators run at the highest speed their supply and load "
                            "allow at {speed:g} mm/s; the document: it must not stay on under CAN control (lower the speed, "
                            "check the supply voltage and the load)"), on=peak["saturated_s"], speed=speed))
    ctx.measure(POSITION, ctx.value("Position"), "mm", low=target - s["tolerance_mm"], high=target + s["tolerance_mm"],
                fail=reached)
    if not reached:
        ctx.fail(Message(N_("target {target:g} mm not reached within {timeout:g} s (at {position} mm)"), target=target,
                         timeout=s["move_timeout_s"], position=ctx.value("Position")))
    ctx.measure(Message(N_("Peak current after start-up")), round(peak["a"], 2), "A", high=current_max)
    ctx.measure(ERROR_FLAGS, ctx.value("Error flags"), expect=0)


async def cleanup(ctx, settings: dict) -> None:
    await ctx.invoke("stop")
    await ctx.invoke("release control", {"reason": "checkout finished"})
