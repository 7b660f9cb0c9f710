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
            assert result["steps"][1]["evidence"]["frames"], "the step's CAN frames are kept"
            steps = {s["name"]: s for s in result["steps"]}
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
