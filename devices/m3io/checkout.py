"""CAN-M3IO checkout: each SSR output switched on, then off, with its load, fuse and triac states.

Declared here, run by the generic runner (``app/record.py``). Section 7.2.3: with the output on,
Last = 1 (a load and supply), Si = 1 (fuse intact) and Triac = 1 (conducting) are expected; on the
HMR, SSR1-3 is one three-phase output whose three phases must all report a load, and with P2 (the
tool's "P2" point, section 4.3) exactly two: the phase without a load reads Last = 0 and its Si and
Triac mean nothing (7.2.3), so it is recorded, not failed; the module's own load check must agree.
SSR4-6 are single outputs on every variant that has them. Every output is switched off again in the
cleanup, also after a failure or an abort.

Pt100 inputs (7.2.2): a reading below 0 or above 200.0 °C is "out of measuring range", which on a
commissioned module means a broken or unconnected sensor: the step fails with the reading.

Inputs E1..E6 (DigIn, bits 0-5): for each the engineer is asked whether a test input is wired
(no: the step is skipped, recorded with who said so), then to toggle it and to toggle it back;
each change must reach the module's DigIn within ``toggle_timeout_s``.
"""

from __future__ import annotations

import time

from devices.m3io import codec
from devices.m3io.adapter import P_LOAD_CHECK, P_P2, temp_channels

TITLE = "SSR outputs on and off"
SETTINGS = {"settle_s": 3.0,  # the module reports the load state in its next temperature frames
            "toggle_timeout_s": 10.0}  # after the engineer was asked to toggle an input
INPUTS = tuple(f"E{n}" for n in range(1, 7))


def _channels(output: str) -> list[int]:
    return [1, 2, 3] if output == "SSR1-3" else [int(output[3:])]


def outputs(options: dict) -> list[str]:
    variant = codec.Variant(options.get("variant", "HM"))
    return [name for name in codec.OUTPUT_BITS[variant] if name.startswith("SSR")]


def steps(options: dict, settings: dict) -> list[dict]:
    listed = [{"name": "Loads connected, area safe (asked)", "limits": "the engineer confirms", "run": _ask}]
    if temp_channels(codec.Variant(options.get("variant", "HM"))):
        listed.append({"name": "Pt100 inputs in range", "limits": f"every Pt100 input reads 0 .. 200 °C within "
                       f"{settings['settle_s']:g} s (outside: sensor broken or not connected, 7.2.2)", "run": _pt100})
    for output in outputs(options):
        listed.append({"name": f"{output} on then off",
                       "limits": (f"on: Last, Si and Triac ok within {settings['settle_s']:g} s"
                                  + ("; three phases with a load, exactly two with P2 (4.3)" if output == "SSR1-3" else "")
                                  + "; off: output off"),
                       "run": lambda ctx, o=output: _cycle(ctx, o)})
    for name in INPUTS:
        listed.append({"name": f"{name} toggled (asked)",
                       "limits": f"where a test input is wired: each toggle seen in DigIn within {settings['toggle_timeout_s']:g} s",
                       "run": lambda ctx, n=name: _toggle(ctx, n)})
    return listed


def _on_off(value) -> str:
    return "unknown" if value is None else ("on" if value else "off")


async def _toggle(ctx, name: str) -> None:
    if not await ctx.choose(f"Is a test input wired to {name}?", f"{name} skipped"):
        ctx.skip(f"{name}: no test input wired (answered by {ctx.user})")
    if not await ctx.wait(lambda: ctx.value(name) is not None, ctx.settings["settle_s"]):
        ctx.fail(f"{name}: no DigIn from the module")
    before = ctx.value(name)
    for turn, expect in (("now", not before), ("back", before)):
        t0 = time.monotonic()
        await ctx.ask(f"Toggle {name} {turn} (it reads {_on_off(ctx.value(name))}), then answer yes")
        seen = await ctx.wait(lambda e=expect: ctx.value(name) == e, ctx.settings["toggle_timeout_s"])
        ctx.measure(f"{name} {_on_off(expect)}", _on_off(ctx.value(name)), expect=_on_off(expect), fail=False)
        if not seen:
            ctx.fail(f"{name} stayed {_on_off(ctx.value(name))} for {ctx.settings['toggle_timeout_s']:g} s after "
                     f"'toggle {turn}': is the test input wired to {name}, is it supplied?")
        ctx.measure(f"{name} {_on_off(expect)}: seen after the answer", round(time.monotonic() - t0, 2), "s", fail=False)


async def _ask(ctx) -> None:
    await ctx.ask("Are the loads connected and supplied, and is it safe to switch the mains outputs?")
    await _take(ctx)


async def _take(ctx) -> None:
    """Control of the module for the run's session (the declared "take control")."""
    await ctx.invoke("take control", {"user": ctx.user})
    # addressed mode: outputs switch only once the product code matched the plant's variant (7.2.4.2.2)
    await ctx.wait(lambda: ctx.value("Variant check") in ("ok", "not possible", "mismatch"), ctx.settings["settle_s"] + 2)
    if ctx.value("Variant check") == "mismatch":
        ctx.fail(ctx.entry("Variant check")["text"])


async def _pt100(ctx) -> None:
    """Each Pt100 input the variant reports (TEMPx) within 0 .. 200 °C; out of range fails (7.2.2)."""
    names = [f"TEMP{c}" for c in temp_channels(codec.Variant(ctx.options.get("variant", "HM")))]
    if not await ctx.wait(lambda: all((ctx.entry(n) or {}).get("raw") is not None for n in names), ctx.settings["settle_s"]):
        missing = [n for n in names if (ctx.entry(n) or {}).get("raw") is None]
        ctx.fail(f"no reading of {', '.join(missing)} within {ctx.settings['settle_s']:g} s: is the module served "
                 "(temperatures come only while DigOut arrives every 2 s)?")
    broken = []
    for name in names:
        word = codec.TempWord(int(ctx.entry(name)["raw"]))
        ctx.measure(name, word.celsius, "°C", low=codec.TEMP_MIN_RAW / 10, high=codec.TEMP_MAX_RAW / 10, fail=False)
        if not word.in_range:
            broken.append(f"{name} reads {word.celsius:.1f} °C")
    if broken:
        ctx.fail(f"{'; '.join(broken)}: outside the measuring range 0 .. 200 °C (7.2.2), the Pt100 is broken or "
                 "not connected; check its wiring and the sensor")


def _point(ctx, name: str):
    return ctx.value(name)


def _two_phase(ctx, output: str) -> bool:
    return output == "SSR1-3" and ctx.value(P_P2) is True


def _phase_ok(ctx, c: int) -> bool:
    return _point(ctx, f"SSR{c} Last") is True and _point(ctx, f"SSR{c} Si") == "ok" and _point(ctx, f"SSR{c} Triac") == "ok"


def _healthy(ctx, output: str, channels: list[int]) -> bool:
    if not _two_phase(ctx, output):
        return all(_phase_ok(ctx, c) for c in channels)
    # P2 (4.3): exactly two phases carry the load; the third reads Last = 0, its Si and Triac mean nothing (7.2.3)
    loaded = [c for c in channels if _point(ctx, f"SSR{c} Last") is True]
    return len(loaded) == 2 and all(_phase_ok(ctx, c) for c in loaded) and ctx.value(P_LOAD_CHECK) == "ok"


async def _cycle(ctx, output: str) -> None:
    settle = ctx.settings["settle_s"]
    channels = _channels(output)
    two_phase = _two_phase(ctx, output)
    await ctx.invoke(f"{output} on")
    healthy = await ctx.wait(lambda: _healthy(ctx, output, channels) and ctx.value(output) is True, settle)
    if output == "SSR1-3":
        loaded = sum(_point(ctx, f"SSR{c} Last") is True for c in channels)
        ctx.measure("Phases with a load" + (" (P2: two-phase load)" if two_phase else ""), loaded,
                    expect=2 if two_phase else 3, fail=False)
        if ctx.value(P_LOAD_CHECK) is not None:
            ctx.measure(P_LOAD_CHECK, ctx.value(P_LOAD_CHECK), expect="ok", fail=False)
    for c in channels:
        if two_phase and _point(ctx, f"SSR{c} Last") is not True:
            ctx.note(f"SSR{c}: no load, as P2 (two-phase load) says: its fuse and triac are not monitored (7.2.3)")
            ctx.measure(f"SSR{c} Last (load)", _point(ctx, f"SSR{c} Last"), fail=False)
            continue
        ctx.measure(f"SSR{c} Last (load)", _point(ctx, f"SSR{c} Last"), expect=True, fail=False)
        ctx.measure(f"SSR{c} Si (fuse)", _point(ctx, f"SSR{c} Si"), expect="ok", fail=False)
        ctx.measure(f"SSR{c} Triac", _point(ctx, f"SSR{c} Triac"), expect="ok", fail=False)
    temp = ctx.value(f"TEMP{channels[0]}")
    if temp is not None:
        ctx.measure(f"TEMP{channels[0]}", temp, "°C", fail=False)
    faults = ctx.value("Faults") or ()  # the module's faults in words (devices/m3io/adapter.py P_FAULTS)
    await ctx.invoke(f"{output} off")
    off = await ctx.wait(lambda: ctx.value(output) is False, 1.0)
    ctx.measure(f"{output} off again", ctx.value(output), expect=False)
    if not healthy:
        bad = [v for v in ctx.step.values if not v["ok"]]
        why = "; ".join(f"{v['name']} {v['value']}" for v in bad) or "no answer"
        ctx.fail(f"{output}: {why}" + (f" (module reports: {'; '.join(faults)})" if faults else ""))
    if not off:
        ctx.fail(f"{output} did not switch off")


async def cleanup(ctx, settings: dict) -> None:
    """Every output off (never refused)."""
    for output in outputs(ctx.options):
        if ctx.value(output):
            await ctx.invoke(f"{output} off")
    await ctx.invoke("release control", {"reason": "checkout finished"})
