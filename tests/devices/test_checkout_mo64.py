"""MO 64 checkout against its twin (LogiTed TCP), through the real adapter and the declared commands."""

from __future__ import annotations

import asyncio

import pytest

from devices.mo64.codec import Q_ERROR_MEMORY, GateState
from tests.conftest import wait_for
from tests.recordutil import demo_runtime, run_checkout

pytestmark = pytest.mark.timeout(180)

FAST = {"safety_seen_s": 5.0}


def _engineer(twin, dead_loops: str = ""):
    """Answers as the person at the barrier would, acting on the twin as asked (its declared controls):
    ready at the light barrier (interrupts it once the boom closes), frees it, occupies and frees loops
    (``dead_loops``: occupied, but their detector never sees it)."""
    async def ask(question: str) -> bool:
        words = question.split()
        if words[0] == "Toggle" and words[1] not in [f"loop-{x}" for x in dead_loops]:
            twin.controls().invoke(f"toggle {words[1]}")  # the twin's declared control, as the record page offers it
        return True
    return ask


async def _short_t_open(runtime, name: str, ticks: int) -> None:
    """t_offen on the twin, read by the adapter as it is now (the checkout takes it from the device)."""
    runtime.twins[name].settings["t_open"] = ticks
    await runtime.worker.adapters[name].read_settings()


async def test_mo64_checkout_passes_and_an_interrupted_light_barrier_fails_the_close(tmp_path):
    async with demo_runtime(tmp_path, ("barrier-in",)) as runtime:
        twin = runtime.twins["barrier-in"]
        twin.travel_s = 0.8  # a quick boom: the steps wait on what the barrier reports, not on its speed
        await _short_t_open(runtime, "barrier-in", 150)  # 1.5 s
        result = await run_checkout(runtime, "barrier-in", ask=_engineer(twin), settings=FAST)
        assert result["status"] == "passed", [(s["name"], s["reason"], s["notes"]) for s in result["steps"] if s["reason"]]
        steps = {s["name"]: s for s in result["steps"]}
        answer = steps["Area clear (asked)"]["answers"][0]
        assert answer["by"] == "anna" and "area is clear" in answer["question"]
        opening = steps["Open"]
        assert any("opening at" in n and "open at" in n for n in opening["notes"]), opening["notes"]
        assert any(v["name"] == "open pulse to open seen" and v["ok"] for v in opening["values"])
        assert opening["evidence"]["transactions"], "the step's LogiTed traffic is kept"
        barrier = steps["Light barrier reverses a closing boom (asked)"]
        assert barrier["status"] == "passed" and any(v["name"] == "LS reported while the boom closed" and v["value"] is True
                                                     for v in barrier["values"])
        loops = steps["Induction loops (asked)"]
        assert loops["status"] == "passed" and {v["name"] for v in loops["values"]} >= {"Loop A occupied seen",
                                                                                        "Loop B occupied seen"}
        assert not any("loop C" in a["question"] for a in loops["answers"]), "loop C is switched off (0x12)"
        assert steps["Automatic closing (t_offen)"]["status"] == "passed"
        assert twin.gate == GateState.CLOSED
        assert steps["Error memory unchanged"]["status"] == "passed"

        # the light barrier is interrupted as the boom is to close: it must not close (chapter 5.1.7, LS)
        run = runtime.record.new_run("barrier-in", user="anna", role="engineer", ask=_engineer(twin),
                                     settings={**FAST, "close_time_max_s": 3.0})
        task = asyncio.create_task(run.run())
        assert await wait_for(lambda: run.current.name == "Close", 60)
        twin.break_light_barrier()  # a closing boom reverses and is held open
        result = await task
        assert result["status"] == "failed"
        close = next(s for s in result["steps"] if s["name"] == "Close")
        assert close["status"] == "failed" and "light barrier interrupted (LS)" in close["reason"], close["reason"]
        assert result["steps"][-1]["status"] == "skipped"
        twin.break_light_barrier(False)


async def test_mo64_checkout_fails_a_light_barrier_that_never_reports(tmp_path):
    """The light barrier is checked while it acts: one that never reports fails its step with the reason."""
    async with demo_runtime(tmp_path, ("barrier-in",)) as runtime:
        twin = runtime.twins["barrier-in"]
        twin.travel_s = 0.8  # a quick boom: the steps wait on what the barrier reports, not on its speed
        twin.strict.light_barrier_dead = True
        result = await run_checkout(runtime, "barrier-in", ask=_engineer(twin), settings=FAST)
        assert result["status"] == "failed"
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert step["name"] == "Light barrier reverses a closing boom (asked)", step
        assert "LS never reported" in step["reason"], step["reason"]
        twin.strict.light_barrier_dead = False
        twin.break_light_barrier(False)


async def test_mo64_checkout_without_automatic_closing_and_error_memory(tmp_path):
    """t_offen = 0 switches automatic closing off (5.2.4.1): an open boom is closed by command and the
    automatic-closing step is not available; a unit refusing every error-memory level is not available
    there, never "unchanged"; an end position within the tolerance passes."""
    async with demo_runtime(tmp_path, ("barrier-in",)) as runtime:
        twin = runtime.twins["barrier-in"]
        twin.travel_s = 0.8  # a quick boom: the steps wait on what the barrier reports, not on its speed
        await _short_t_open(runtime, "barrier-in", 0)
        twin.strict.refuse_queries.add(Q_ERROR_MEMORY)
        twin.open_end_pct = 99.0  # its open limit switch stops the boom at 99 %
        state = runtime.store.devices["barrier-in"]
        twin._start_open()
        assert await wait_for(lambda: (state.entry("Gate state") or {}).get("value") == GateState.OPEN, 15)
        result = await run_checkout(runtime, "barrier-in", ask=_engineer(twin), settings=FAST)
        assert result["status"] == "passed", [(s["name"], s["reason"]) for s in result["steps"]]
        steps = {s["name"]: s for s in result["steps"]}
        assert any("automatic closing is off" in n for n in steps["Light barrier, loops, no fault"]["notes"])
        auto = steps["Automatic closing (t_offen)"]
        assert auto["status"] == "not available" and "t_offen = 0" in auto["reason"], auto
        for name in ("Error memory before", "Error memory unchanged"):
            assert steps[name]["status"] == "not available" and "refuses every error-memory level" in steps[name]["reason"]
        opened = next(v for v in steps["Open"]["values"] if v["name"] == "Position")
        assert opened["value"] == 99 and opened["ok"], opened


async def test_mo64_checkout_fails_on_a_fault_event_and_says_so(tmp_path):
    async with demo_runtime(tmp_path, ("barrier-in",)) as runtime:
        twin = runtime.twins["barrier-in"]
        twin.travel_s = 0.8  # a quick boom: the steps wait on what the barrier reports, not on its speed
        twin.raise_fault(0x0004)
        state = runtime.store.devices["barrier-in"]
        assert await wait_for(lambda: (state.entry("F_ereignis") or {}).get("value") is True, 10)
        result = await run_checkout(runtime, "barrier-in", ask=_engineer(twin))
        assert result["status"] == "failed"
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert step["name"] == "Light barrier, loops, no fault" and "fault event (F_ereignis)" in step["reason"], step
        assert ("open", "pulse") not in list(twin.commands), "nothing moved"


async def test_mo64_checkout_fails_a_loop_that_never_reports(tmp_path):
    async with demo_runtime(tmp_path, ("barrier-in",)) as runtime:
        twin = runtime.twins["barrier-in"]
        twin.travel_s = 0.8  # a quick boom: the steps wait on what the barrier reports, not on its speed
        result = await run_checkout(runtime, "barrier-in", ask=_engineer(twin, dead_loops="B"), settings={"safety_seen_s": 2.0})
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert step["name"] == "Induction loops (asked)", step
        assert "loop B was to be occupied, but the barrier did not report it" in step["reason"], step["reason"]
        assert any(v["name"] == "Loop A occupied seen" and v["ok"] for v in step["values"])
