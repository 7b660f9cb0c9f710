"""Helpers of the commissioning-record tests: the demo plant on free ports, a checkout run."""

from __future__ import annotations

import contextlib
import re
import uuid
from pathlib import Path

from app.plant import parse_plant
from app.runtime import Runtime
from tests.conftest import free_port, wait_for

DEMO = Path(__file__).resolve().parent.parent / "plants" / "demo.toml"


def demo_plant(devices: tuple[str, ...] | None = None):
    """The demo plant on free TCP ports and CAN channels of its own; only ``devices`` (and their buses)."""
    text = DEMO.read_text()
    tag = uuid.uuid4().hex[:6]
    text = re.sub(r"127\.0\.0\.1:50\d\d", lambda m: f"127.0.0.1:{free_port()}", text)
    text = re.sub(r"^port = 5040$", f"port = {free_port()}", text, flags=re.M)
    text = re.sub(r'channel = "(demo-can\d)"', lambda m: f'channel = "{m.group(1)}-{tag}"', text)
    plant = parse_plant(text)
    if devices is not None:
        for name in [n for n in plant.devices if n not in devices]:
            del plant.devices[name]
        buses = {plant.devices[n].bus for n in devices}
        for name in [b for b in plant.buses if b not in buses]:
            del plant.buses[name]
        for name in [n for n, d in plant.sim_devices.items() if d.bus not in buses]:
            del plant.sim_devices[name]
    return plant


@contextlib.asynccontextmanager
async def demo_runtime(tmp_path, devices: tuple[str, ...] | None = None, online: bool = True):
    runtime = Runtime(demo_plant(devices), simulate=True, data_dir=tmp_path / "data")
    await runtime.start()
    try:
        if online:
            names = list(runtime.store.devices)
            assert await wait_for(lambda: all(runtime.store.devices[n].status == "online" for n in names), 20), \
                {n: runtime.store.devices[n].status for n in names}
        yield runtime
    finally:
        await runtime.stop()


async def run_checkout(runtime, device: str, *, answer: bool = True, settings: dict | None = None, user: str = "anna",
                       ask=None, act: bool = False):
    """Run ``device``'s checkout; every question answered ``answer``, or by ``ask(question)`` where given.
    ``act``: answered yes, a request to act on the simulated device ("Toggle door now: ...") is carried
    out on its twin first, as the record page offers it (else nobody acts, as a person who only says yes)."""
    if ask is None:
        async def ask(question: str) -> bool:
            if answer and act:
                await act_on_twin(runtime, device, question, user)
            return answer

    run = runtime.record.new_run(device, user=user, role="engineer", ask=ask, settings=settings)
    return await run.run()


async def act_on_twin(runtime, device: str, question: str, user: str = "anna") -> bool:
    """Do what a "Toggle <control> now ..." question asks on the device's twin (its declared control)."""
    from app.record_cli import sim_action

    controls = runtime.sim_controls(device)
    words = question.split()
    if controls is None or len(words) < 2 or words[0] != "Toggle":
        return False
    action = f"toggle {words[1]}"
    if not any(a.name == action for a in controls.actions):
        return False
    await sim_action(runtime, f"{device}:{action}", user=user, role="engineer")
    return True
