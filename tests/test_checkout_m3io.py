"""M3IO checkout against its twins (HM and HMR on a virtual CAN bus), through the real adapters."""

from __future__ import annotations

import pytest

from tests.recordutil import demo_runtime, run_checkout

pytestmark = pytest.mark.timeout(120)


async def test_m3io_checkout_passes_and_a_blown_fuse_fails_its_step(tmp_path):
    # the modules answer once a master serves their watchdog: the checkout takes control itself
    async with demo_runtime(tmp_path, ("heater-hm", "heater-hmr"), online=False) as runtime:
        for name in ("heater-hm", "heater-hmr"):
            result = await run_checkout(runtime, name)
            assert result["status"] == "passed", [(s["name"], s["reason"]) for s in result["steps"]]
            assert result["steps"][1]["evidence"]["frames"], "the step's CAN frames are kept"
        assert not any(runtime.worker.adapters["heater-hm"].outputs.values())

        runtime.twins["heater-hm"].ssr[3].fuse_ok = False
        result = await run_checkout(runtime, "heater-hm")
        assert result["status"] == "failed"
        step = next(s for s in result["steps"] if s["status"] == "failed")
        assert step["name"].startswith("SSR3") and "Si (fuse) blown" in step["reason"], step["reason"]
        assert not any(runtime.worker.adapters["heater-hm"].outputs.values()), "every output is off after the failure"
