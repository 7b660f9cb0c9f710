"""Two MO 64 on a shared RS485 line against the twin, through the worker: token passing with a
second master (held under 200 ms, nothing sent without the token), an open pulse to one barrier."""

from __future__ import annotations

import asyncio

import pytest
from conftest import free_port, wait_for
from plants import device, mo64_rs485, plant

from app.plant import Plant
from app.runtime import Runtime
from devices.mo64 import codec

pytestmark = pytest.mark.timeout(60)


def two_gates(port: int) -> Plant:
    return plant(mo64_rs485(device("out-1", "mo64", "gates-485", address=16, travel_s=0.6),
                            device("out-2", "mo64", "gates-485", address=17), port=port), name="gates")


async def test_shared_line_token_within_200_ms_and_an_open_pulse():
    runtime = Runtime(two_gates(free_port()), simulate=True)
    await runtime.start()
    try:
        states = runtime.store.devices
        assert await wait_for(lambda: all(states[n].status == "online" for n in ("out-1", "out-2")), timeout=10)
        adapter = runtime.worker.adapters["out-1"]
        await runtime.worker.gate.run(lambda: runtime.worker.adapters["out-1"].command("test", codec.Command.OPEN, codec.Function.PULSE, confirmed=True),
                                      device="out-1", describe="open pulse", user="local", role="engineer")
        twin = runtime.twins["out-1"]
        assert await wait_for(lambda: twin.position_pct == 100, timeout=10)
        assert await wait_for(lambda: (states["out-1"].entry("Gate state") or {}).get("value") == codec.GateState.OPEN, timeout=5)
        assert await wait_for(lambda: (states["out-1"].entry("Position") or {}).get("value") == 100, timeout=5)
        assert twin is not runtime.twins["out-2"] and runtime.twins["out-2"].position_pct == 0  # only the addressed barrier moved
        sim = next(s for s in runtime.sim.servers if hasattr(s, "hold_times_s"))
        holds = sim.hold_times_s
        line = runtime.worker.lines["gates-485"]
        print(f"token held by this tool: max {max(holds) * 1000:.1f} ms over {len(holds)} turns "
              f"(the tool's own count: max {max(line.token_holds_ms):.1f} ms); limit 200 ms")
        assert len(holds) >= 5 and max(holds) < codec.TOKEN_PASS_LIMIT_S
        assert sim.sent_without_token == 0
        assert adapter.state.counters.timeouts == 0
    finally:
        await asyncio.wait_for(runtime.stop(), 10)
