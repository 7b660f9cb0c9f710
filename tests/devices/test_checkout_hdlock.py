"""HD-Lock checkout against its twins (Modbus RTU and CAN), through the real adapters."""

from __future__ import annotations

import pytest

from devices.hdlock.params import PARAMS
from tests.conftest import wait_for
from tests.recordutil import demo_runtime, run_checkout

pytestmark = pytest.mark.timeout(180)


def _person(twin):
    """Answers as the person at the door would: opens and closes it on the twin when asked, yes to the rest."""
    async def ask(question: str) -> bool:
        if question.startswith("Toggle door now"):
            twin.controls().invoke("toggle door")  # the twin's declared control, as the record page offers it
        return True
    return ask


def _step(result: dict, name: str) -> dict:
    return next(s for s in result["steps"] if s["name"] == name)


async def test_hdlock_checkout_passes_on_modbus_and_can(tmp_path):
    async with demo_runtime(tmp_path, ("door-2", "gate-2")) as runtime:
        for name in ("door-2", "gate-2"):
            twin, state = runtime.twins[name], runtime.store.devices[name]
            assert await wait_for(lambda: state.raw(PARAMS.get("holding", 16)) is not None and twin.bolt > 100, 15)
            result = await run_checkout(runtime, name, ask=_person(twin))
            assert result["status"] == "passed", [(s["name"], s["reason"]) for s in result["steps"] if s["reason"]]
            lock = _step(result, "Lock")
            assert any(v["name"].startswith("Lock time") and v["ok"] for v in lock["values"])
            # the lock was locked at the start (factory IrsNotLine, input active, door closed): it was unlocked first
            assert any("unlocking first" in n for n in lock["notes"]), lock["notes"]
            limits = {v["name"]: v["value"] for v in lock["values"]}
            assert limits["LockMaximumTime (the lock's own, holding 16)"] == 1500
            assert limits["LockOkPosition (the lock's own, holding 11)"] == 100
            assert limits["RetryLockCounter"] == 0
            assert _step(result, "Door closed (asked)")["answers"][0]["by"] == "anna"
            refused = _step(result, "Lock request refused with the door open (asked)")
            assert refused["status"] == "passed" and any(v["value"] == "stayed in" for v in refused["values"])
            evidence = lock["evidence"]
            assert evidence["frames" if evidence["kind"] == "can" else "transactions"], "the step's traffic is kept"
            assert twin.holding[1002] == 4 and twin.holding[4] == 4  # the sources the lock had (IrsNotLine), written back
            assert not {"holding:4", "holding:1002"} & state.unsaved, "nothing the checkout undid is left unsaved"
        rows = await runtime.record.timeline("door-2", ("checkout",))
        assert rows and rows[0].data["status"] == "passed"


async def _bolted(runtime, holding: int):
    """door-2's twin, once the app has read its holding register ``holding`` and its bolt is out."""
    twin, state = runtime.twins["door-2"], runtime.store.devices["door-2"]
    assert await wait_for(lambda: state.raw(PARAMS.get("holding", holding)) is not None and twin.bolt > 100, 15)
    return twin


async def test_hdlock_checkout_fails_a_bolt_stuck_in_its_locked_end_position(tmp_path):
    """A lock that is locked and never leaves its end position: 'Lock' cannot pass without seeing movement."""
    async with demo_runtime(tmp_path, ("door-2",)) as runtime:
        twin = await _bolted(runtime, 26)
        twin.bolt_stuck = True
        result = await run_checkout(runtime, "door-2", ask=_person(twin))
        assert result["status"] == "failed"
        lock = _step(result, "Lock")
        assert lock["status"] == "failed", lock
        assert "did not leave its locked end position" in lock["reason"] and "UnlockMaximumTime 1500 ms" in lock["reason"]
        assert "Error unlocking" in lock["reason"] or "RetryUnlockCounter 1" in lock["reason"], lock["reason"]
        assert twin.holding[1002] == 4 and twin.holding[4] == 4


async def test_hdlock_checkout_fails_a_bolt_that_cannot_lock_with_the_error_state(tmp_path):
    """The lock's own LockMaximumTime passes, it reports an error state and counts a retry: 'Lock' fails with both."""
    async with demo_runtime(tmp_path, ("door-2",)) as runtime:
        twin = runtime.twins["door-2"]
        state = runtime.store.devices["door-2"]
        twin.write(1002, 0)  # unlocked, as the lock may be found
        assert await wait_for(lambda: state.raw(PARAMS.get("holding", 16)) is not None and twin.bolt == 0
                              and state.raw(PARAMS.get("input", 9)) == 2, 15)
        twin.bolt_stuck = True
        result = await run_checkout(runtime, "door-2", ask=_person(twin))
        lock = _step(result, "Lock")
        assert lock["status"] == "failed", lock
        assert "did not leave its unlocked end position" in lock["reason"], lock["reason"]
        assert "LockMaximumTime 1500 ms" in lock["reason"] and "RetryLockCounter 0 -> 1" in lock["reason"], lock["reason"]
        assert twin.input[12] >= 1
        assert twin.holding[1002] == 0  # written back as it was found


async def test_hdlock_checkout_fails_with_the_reason_when_the_door_is_open(tmp_path):
    async with demo_runtime(tmp_path, ("door-2",)) as runtime:
        runtime.twins["door-2"].open_door()
        state = runtime.store.devices["door-2"]
        assert await wait_for(lambda: state.value("Calculated proxi (normalized)") == 100, 10)  # wide open
        result = await run_checkout(runtime, "door-2", settings={"door_timeout_s": 2.0})
        assert result["status"] == "failed"
        door = next(s for s in result["steps"] if s["name"].startswith("Door in position"))
        assert door["status"] == "failed" and "not in position" in door["reason"]
        assert result["steps"][-1]["status"] == "skipped"


async def test_hdlock_checkout_fails_a_lock_that_bolts_with_the_door_open(tmp_path):
    """Section 3.2.2 condition 2, tested while it acts: a lock that bolts with the door open fails that step;
    a door said to be opened that the lock still sees in position fails it too, with its own reason."""
    async with demo_runtime(tmp_path, ("door-2",)) as runtime:
        twin = await _bolted(runtime, 16)
        twin.ignores_door = True
        result = await run_checkout(runtime, "door-2", ask=_person(twin))
        step = _step(result, "Lock request refused with the door open (asked)")
        assert _step(result, "Lock")["status"] == "passed" and step["status"] == "failed", step
        assert "the lock did not refuse" in step["reason"] and "moved out" in step["reason"], step["reason"]
        assert twin.holding[1002] == 4 and twin.holding[4] == 4
        twin.ignores_door = False

        async def door_stays(question: str) -> bool:  # "opened", but the strike plate stays in range
            return True
        result = await run_checkout(runtime, "door-2", ask=door_stays, settings={"door_timeout_s": 2.0})
        step = _step(result, "Lock request refused with the door open (asked)")
        assert step["status"] == "failed" and "still sees it in position" in step["reason"], [
            (s["name"], s["status"], s["reason"]) for s in result["steps"]]
