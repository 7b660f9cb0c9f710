"""M3IO checkout against its twins (HM and HMR on a virtual CAN bus), through the real adapters."""

from __future__ import annotations

import pytest

from tests.recordutil import demo_runtime, run_checkout

pytestmark = pytest.mark.timeout(120)


async def test_m3io_checkout_passes_and_a_blown_fuse_fails_its_step(tmp_path):
    # the modules answer once a master serves their watchdog: the checkout takes control itself
    async with demo_runtime(tmp_path, ("heater-hm", "heater-hmr"), online=False) as runtime:
        for name in ("heater-hm", "heater-hmr"):
            result = await run_checkout(runtime, name, ask=_engineer(runtime.twins[name], wired=("E1", "E2")))
            assert result["status"] == "passed", [(s["name"], s["reason"]) for s in result["steps"]]
            steps = {s["name"]: s for s in result["steps"]}
            first = next(s for s in result["steps"] if s["name"].startswith("SSR"))
            assert first["evidence"]["frames"], "the step's CAN frames are kept"
            assert steps["Pt100 inputs in range"]["status"] == "passed"
            assert steps["E1 toggled (asked)"]["status"] == "passed" and steps["E2 toggled (asked)"]["status"] == "passed"
            assert [v["value"] for v in steps["E1 toggled (asked)"]["values"] if v["name"] in ("E1 on", "E1 off")] == ["on", "off"]
            e3 = steps["E3 toggled (asked)"]
            assert e3["status"] == "skipped" and "no test input wired (answered by anna)" in e3["reason"]
            assert e3["answers"][0]["by"] == "anna" and e3["answers"][0]["answer"] == "no"
        assert not any(runtime.worker.adapters["heater-hm"].outputs.values())

        # E4 said to be wired, but nothing changes at the input: its step fails with the reason
        result = await run_checkout(runtime, "heater-hm", ask=_engineer(runtime.twins["heater-hm"], wired=("E4",), dead=("E4",)),
                                    settings={"toggle_timeout_s": 1.0})
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert step["name"] == "E4 toggled (asked)" and "E4 stayed off" in step["reason"], step["reason"]

        runtime.twins["heater-hm"].ssr[3].fuse_ok = False
        result = await run_checkout(runtime, "heater-hm", ask=_engineer(runtime.twins["heater-hm"], wired=()))
        assert result["status"] == "failed"
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert step["name"].startswith("SSR3") and "Si (fuse) blown" in step["reason"], step["reason"]
        assert not any(runtime.worker.adapters["heater-hm"].outputs.values()), "every output is off after the failure"


def _engineer(twin, wired: tuple[str, ...], dead: tuple[str, ...] = ()):
    """Answers as the engineer at the module would: a test input wired to ``wired`` (toggled on the
    twin when asked; ``dead`` ones are wired but never change), yes to every other question."""
    async def ask(question: str) -> bool:
        for name in [f"E{n}" for n in range(1, 7)]:
            if question == f"Is a test input wired to {name}?":
                return name in wired
            if question.startswith(f"Toggle {name} ") and name not in dead:
                twin.toggle_input(name)
        return True
    return ask


async def test_m3io_checkout_two_phase_hmr_passes_with_p2_and_fails_without(tmp_path):
    """4.3: an HMR whose three-phase output carries a two-phase load (phase 3 without load) is correct
    with P2 on, and its single outputs SSR4-6 are each tested; the same wiring without P2 is a load fault."""
    async with demo_runtime(tmp_path, ("heater-hmr",), online=False) as runtime:
        twin, adapter = runtime.twins["heater-hmr"], runtime.worker.adapters["heater-hmr"]
        twin.ssr[3].load = False  # wired for two phases
        adapter.set_two_phase(True)
        result = await run_checkout(runtime, "heater-hmr", ask=_engineer(twin, wired=()))
        assert result["status"] == "passed", [(s["name"], s["reason"]) for s in result["steps"]]
        steps = {s["name"]: s for s in result["steps"]}
        for name in ("SSR4 on then off", "SSR5 on then off", "SSR6 on then off"):
            assert steps[name]["status"] == "passed" and any(v["name"] == f"{name[:4]} Triac" for v in steps[name]["values"])
        group = steps["SSR1-3 on then off"]
        assert any("SSR3: no load, as P2" in n for n in group["notes"]), group["notes"]
        assert any(v["name"].startswith("Phases with a load") and v["value"] == 2 and v["ok"] for v in group["values"])

        adapter.set_two_phase(False)  # the same module, the tool told three phases: the module refuses to switch
        result = await run_checkout(runtime, "heater-hmr", ask=_engineer(twin, wired=()), settings={"settle_s": 2.0})
        assert result["status"] == "failed"
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert step["name"] == "SSR1-3 on then off" and "Phases with a load 2" in step["reason"], step["reason"]
        assert not any(adapter.outputs.values())


async def test_m3io_checkout_fails_a_pt100_out_of_range(tmp_path):
    """7.2.2: a reading outside 0-200 °C is a broken or unconnected sensor, not a value to leave out."""
    async with demo_runtime(tmp_path, ("heater-hm",), online=False) as runtime:
        twin = runtime.twins["heater-hm"]
        twin.set_temperature(4, 204.7)  # an open Pt100 reads past the top of the range
        result = await run_checkout(runtime, "heater-hm", ask=_engineer(twin, wired=()))
        assert result["status"] == "failed"
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert step["name"] == "Pt100 inputs in range", step
        assert "TEMP4 reads 204.7 °C" in step["reason"] and "broken or not connected" in step["reason"], step["reason"]
        assert not any(runtime.worker.adapters["heater-hm"].outputs.values()), "nothing was switched on"
