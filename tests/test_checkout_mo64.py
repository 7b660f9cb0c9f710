"""MO 64 checkout against its twin (LogiTed TCP), through the real adapter and the declared commands."""

from __future__ import annotations

import asyncio

import pytest

from devices.mo64.codec import GateState
from tests.conftest import wait_for
from tests.recordutil import demo_runtime, run_checkout

pytestmark = pytest.mark.timeout(120)


async def test_mo64_checkout_passes_and_an_interrupted_light_barrier_fails_the_close(tmp_path):
    async with demo_runtime(tmp_path, ("barrier-in",)) as runtime:
        twin = runtime.twins["barrier-in"]
        result = await run_checkout(runtime, "barrier-in")
        assert result["status"] == "passed", [(s["name"], s["reason"]) for s in result["steps"]]
        steps = {s["name"]: s for s in result["steps"]}
        answer = steps["Area clear (asked)"]["answers"][0]
        assert answer["by"] == "anna" and "area is clear" in answer["question"]
        opening = steps["Open"]
        assert any("opening at" in n and "open at" in n for n in opening["notes"]), opening["notes"]
        assert any(v["name"] == "open pulse to open seen" and v["ok"] for v in opening["values"])
        assert opening["evidence"]["transactions"], "the step's LogiTed traffic is kept"
        assert [c for c in twin.commands][-2:] == [("open", "pulse"), ("close", "pulse")]
        assert twin.gate == GateState.CLOSED
        assert steps["Error memory unchanged"]["status"] == "passed"

        # the light barrier is interrupted as the boom is to close: it must not close (chapter 5.1.7, LS)
        run = runtime.record.new_run("barrier-in", user="anna", role="engineer", ask=_yes,
                                     settings={"close_time_max_s": 3.0})
        task = asyncio.create_task(run.run())
        assert await wait_for(lambda: run.current.name == "Close", 30)
        twin.break_light_barrier()  # a closing boom reverses and is held open
        result = await task
        assert result["status"] == "failed"
        close = next(s for s in result["steps"] if s["name"] == "Close")
        assert close["status"] == "failed" and "light barrier interrupted (LS)" in close["reason"], close["reason"]
        assert result["steps"][-1]["status"] == "skipped"
        twin.break_light_barrier(False)


async def test_mo64_checkout_fails_on_a_fault_event_and_says_so(tmp_path):
    async with demo_runtime(tmp_path, ("barrier-in",)) as runtime:
        twin = runtime.twins["barrier-in"]
        twin.raise_fault(0x0004)
        state = runtime.store.devices["barrier-in"]
        assert await wait_for(lambda: (state.entry("F_ereignis") or {}).get("value") is True, 10)
        result = await run_checkout(runtime, "barrier-in")
        assert result["status"] == "failed"
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert step["name"] == "Light barrier, loops, no fault" and "fault event (F_ereignis)" in step["reason"], step
        assert ("open", "pulse") not in list(twin.commands), "nothing moved"


async def _yes(question: str) -> bool:
    return True
