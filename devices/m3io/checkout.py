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

What a person reads is a ``Message`` (docs/i18n.md), in the document's words (Last, Si, Triac, Sicherung).
"""

from __future__ import annotations

import time

from devices.m3io import codec
from devices.m3io.adapter import P_LOAD_CHECK, P_P2, temp_channels
from devices.message import N_, Message, Word, joined

TITLE = Message(N_("SSR outputs on and off"))
SETTINGS = {"settle_s": 3.0,  # the module reports the load state in its next temperature frames
            "toggle_timeout_s": 10.0}  # after the engineer was asked to toggle an input
INPUTS = tuple(f"E{n}" for n in range(1, 7))


def _channels(output: str) -> list[int]:
    return [1, 2, 3] if output == "SSR1-3" else [int(output[3:])]


def outputs(options: dict) -> list[str]:
    variant = codec.Variant(options.get("variant", "HM"))
    return [name for name in codec.OUTPUT_BITS[variant] if name.startswith("SSR")]


def steps(options: dict, settings: dict) -> list[dict]:
    listed = [{"name": Message(N_("Loads connected, area safe (asked)")), "limits": Message(N_("the engineer confirms")),
               "run": _ask}]
    if temp_channels(codec.Variant(options.get("variant", "HM"))):
        listed.append({"name": Message(N_("Pt100 inputs in range")),
                       "limits": Message(N_("every Pt100 input reads 0 .. 200 °C within {settle:g} s (outside: sensor broken or "
                                            "not connected, 7.2.2)"), settle=settings["settle_s"]), "run": _pt100})
    for output in outputs(options):
        limits = (N_("on: Last, Si and Triac ok within {settle:g} s; three phases with a load, exactly two with P2 (4.3); off: "
                     "output off") if output == "SSR1-3" else N_("on: Last, Si and Triac ok within {settle:g} s; off: output off"))
        listed.append({"name": Message(N_("{output} on then off"), output=output),
                       "limits": Message(limits, settle=settings["settle_s"]),
                       "run": lambda ctx, o=output: _cycle(ctx, o)})
    for name in INPUTS:
        listed.append({"name": Message(N_("{input} toggled (asked)"), input=name),
                       "limits": Message(N_("where a test input is wired: each toggle seen in DigIn within {timeout:g} s"),
                                         timeout=settings["toggle_timeout_s"]),
                       "run": lambda ctx, n=name: _toggle(ctx, n)})
    return listed


def _on_off(value) -> Message:
    return Message(N_("unknown")) if value is None else (Message(N_("on")) if value else Message(N_("off")))


async def _toggle(ctx, name: str) -> None:
    if not await ctx.choose(Message(N_("Is a test input wired to {input}?"), input=name),
                            Message(N_("{input} skipped"), input=name)):
        ctx.skip(Message(N_("{input}: no test input wired (answered by {user})"), input=name, user=ctx.user))
    if not await ctx.wait(lambda: ctx.value(name) is not None, ctx.settings["settle_s"]):
        ctx.fail(Message(N_("{input}: no DigIn from the module"), input=name))
    before = ctx.value(name)
    for turn, expect in ((N_("Toggle {input} now (it reads {state}), then answer yes"), not before),
                         (N_("Toggle {input} back (it reads {state}), then answer yes"), before)):
        t0 = time.monotonic()
        await ctx.ask(Message(turn, input=name, state=_on_off(ctx.value(name))))
        seen = await ctx.wait(lambda e=expect: ctx.value(name) == e, ctx.settings["toggle_timeout_s"])
        ctx.measure(Message("{input} {state}", input=name, state=_on_off(expect)), _on_off(ctx.value(name)),
                    expect=_on_off(expect), fail=False)
        if not seen:
            stayed = (N_("{input} stayed {state} for {timeout:g} s after 'toggle now': is the test input wired to {input}, is "
                         "it supplied?") if expect != before else
                      N_("{input} stayed {state} for {timeout:g} s after 'toggle back': is the test input wired to {input}, is "
                         "it supplied?"))
            ctx.fail(Message(stayed, input=name, state=_on_off(ctx.value(name)), timeout=ctx.settings["toggle_timeout_s"]))
        ctx.measure(Message(N_("{input} {state}: seen after the answer"), input=name, state=_on_off(expect)),
                    round(time.monotonic() - t0, 2), "s", fail=False)


async def _ask(ctx) -> None:
    await ctx.ask(Message(N_("Are the loads connected and supplied, and is it safe to switch the mains outputs?")))
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
        ctx.fail(Message(N_("no reading of {inputs} within {settle:g} s: is the module served (temperatures come only while "
                            "DigOut arrives every 2 s)?"), inputs=", ".join(missing), settle=ctx.settings["settle_s"]))
    broken = []
    for name in names:
        word = codec.TempWord(int(ctx.entry(name)["raw"]))
        ctx.measure(name, word.celsius, "°C", low=codec.TEMP_MIN_RAW / 10, high=codec.TEMP_MAX_RAW / 10, fail=False)
        if not word.in_range:
            broken.append(Message(N_("{input} reads {celsius:.1f} °C"), input=name, celsius=word.celsius))
    if broken:
        ctx.fail(Message(N_("{readings}: outside the measuring range 0 .. 200 °C (7.2.2), the Pt100 is broken or not "
                            "connected; check its wiring and the sensor"), readings=joined(broken, "; ")))


def _point(ctx, name: str):
    return ctx.value(name)


def _state(point: str, value):
    """A point's state word (``ok``, ``fault``, ``blown``) as a measured value, worded as the point's value
    (app/device_words.py, pages/m3io.py); no value stays None."""
    return None if value is None else Message("{state}", state=Word(str(value), point))


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
        ctx.measure(Message(N_("Phases with a load (P2: two-phase load)")) if two_phase else Message(N_("Phases with a load")),
                    loaded, expect=2 if two_phase else 3, fail=False)
        if ctx.value(P_LOAD_CHECK) is not None:  # the point keeps its key; its name and state as the pages word them
            ctx.measure(Message(N_("SSR1-3 load check")), _state(P_LOAD_CHECK, ctx.value(P_LOAD_CHECK)),
                        expect=_state(P_LOAD_CHECK, "ok"), fail=False)
    for c in channels:
        if two_phase and _point(ctx, f"SSR{c} Last") is not True:
            ctx.note(Message(N_("SSR{channel}: no load, as P2 (two-phase load) says: its fuse and triac are not monitored "
                                "(7.2.3)"), channel=c))
            ctx.measure(Message(N_("SSR{channel} Last (load)"), channel=c), _point(ctx, f"SSR{c} Last"), fail=False)
            continue
        ctx.measure(Message(N_("SSR{channel} Last (load)"), channel=c), _point(ctx, f"SSR{c} Last"), expect=True, fail=False)
        ctx.measure(Message(N_("SSR{channel} Si (fuse)"), channel=c), _state(f"SSR{c} Si", _point(ctx, f"SSR{c} Si")),
                    expect=_state(f"SSR{c} Si", "ok"), fail=False)
        ctx.measure(f"SSR{c} Triac", _state(f"SSR{c} Triac", _point(ctx, f"SSR{c} Triac")), expect=_state(f"SSR{c} Triac", "ok"),
                    fail=False)
    temp = ctx.value(f"TEMP{channels[0]}")
    if temp is not None:
        ctx.measure(f"TEMP{channels[0]}", temp, "°C", fail=False)
    faults = ctx.value("Faults") or ()  # the module's faults in words (devices/m3io/adapter.py P_FAULTS)
    await ctx.invoke(f"{output} off")
    off = await ctx.wait(lambda: ctx.value(output) is False, 1.0)
    ctx.measure(Message(N_("{output} off again"), output=output), ctx.value(output), expect=False)
    if not healthy:
        bad = [Message("{name} {value}", name=v["name"], value=v["value"]) for v in ctx.step.values if not v["ok"]]
        why = joined(bad, "; ") if bad else Message(N_("no answer"))
        if faults:
            ctx.fail(Message(N_("{output}: {why} (module reports: {faults})"), output=output, why=why,
                             faults=joined(list(faults), "; ")))
        ctx.fail(Message("{output}: {why}", output=output, why=why))
    if not off:
        ctx.fail(Message(N_("{output} did not switch off"), output=output))


async def cleanup(ctx, settings: dict) -> None:
    """Every output off (never refused)."""
    for output in outputs(ctx.options):
        if ctx.value(output):
            await ctx.invoke(f"{output} off")
    await ctx.invoke("release control", {"reason": "checkout finished"})
