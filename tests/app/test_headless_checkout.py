"""Headless checkouts are no way around the operator (issue 40): ``commission checkout --answer yes`` answered
"area clear" and every mains and motion question itself, also with --no-sim on real buses (an MO 64 got its
open pulse with nobody present). Now --answer yes answers only for simulated devices; real equipment is asked
of the person at a terminal, whose held SPACE is the run's dead-man, and without a terminal the run does not
start.

"Real" here is a barrier this test serves on a loopback port as a separate twin, reached by a runtime that
simulates nothing: to the runtime it is equipment like any other."""

from __future__ import annotations

import asyncio
import contextlib
import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import free_port, wait_for
from test_mo64_strict import tcp_plant

from app.headless import HELD_GAP_S, TerminalPerson
from app.plant import parse_plant
from app.record_cli import checkout_devices
from app.runtime import Runtime, SimulatedPlant
from devices.mo64 import codec

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[2]


@contextlib.asynccontextmanager
async def real_barrier(tmp_path):
    """A runtime that simulates nothing, and a barrier twin of its own on the plant file's port."""
    plant = parse_plant(tcp_plant(free_port()))
    twins = SimulatedPlant(plant)
    assert not await twins.start()
    runtime = Runtime(plant, simulate=False, data_dir=tmp_path / "data")
    await runtime.start()
    try:
        assert await wait_for(lambda: runtime.store.devices["gate"].status == "online", timeout=15)
        assert runtime.twins == {}
        yield runtime, twins.twins["gate"]
    finally:
        await asyncio.wait_for(runtime.stop(), 15)
        await twins.stop()


class FakeKeys:
    """Key presses a test makes: SPACE held is a press every 40 ms (a terminal's auto-repeat)."""

    def __init__(self):
        self.on_key = None
        self._hold: asyncio.Task | None = None

    def start(self, on_key) -> None:
        self.on_key = on_key

    def stop(self) -> None:
        self.release()

    def press(self, key: str) -> None:
        self.on_key(key)

    def hold_space(self) -> None:
        async def repeat() -> None:
            while True:
                self.on_key(" ")
                await asyncio.sleep(0.04)

        self._hold = asyncio.get_running_loop().create_task(repeat())

    def release(self) -> None:
        if self._hold is not None:
            self._hold.cancel()
            self._hold = None


async def test_answer_yes_refuses_a_real_barrier_before_anything_moves(tmp_path):
    async with real_barrier(tmp_path) as (runtime, twin):
        lines: list[str] = []
        code = await checkout_devices(runtime, ["gate"], user="cli:test", role="engineer", answer="yes",
                                      out=lines.append)
        assert code == 2, lines
        assert "not started: gate is real equipment" in lines[0] and "--answer yes answers only for simulated" in lines[0]
        assert not any(c[1] == "pulse" for c in twin.commands), list(twin.commands)  # the boom did not move
        assert "gate" not in runtime.record.runs


def test_the_command_line_refuses_answer_yes_with_no_sim_before_it_connects(tmp_path):
    path = tmp_path / "plant.toml"
    path.write_text(tcp_plant(free_port()))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-m", "app.cli", "checkout", "--answer", "yes", "--no-sim", "--device", "gate",
                           "--plant", str(path), "--data-dir", str(tmp_path / "data")],
                          cwd=ROOT, env=env, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, (done.stdout, done.stderr)
    assert "not started: gate is real equipment" in done.stdout and "terminal" in done.stdout, done.stdout
    assert "waiting" not in done.stdout  # refused before connecting to anything


async def test_the_person_answers_by_holding_space_and_no_means_nothing_moves(tmp_path):
    async with real_barrier(tmp_path) as (runtime, twin):
        keys, lines = FakeKeys(), []
        person = TerminalPerson(runtime.worker, "cli-checkout-test", keys, out=lines.append)
        person.start()
        # one press is no answer (a key tapped by accident); n is no: the first step fails, nothing moves
        task = asyncio.create_task(checkout_devices(runtime, ["gate"], user="cli:test", role="engineer", answer="yes",
                                                    out=lines.append, person=person))
        assert await wait_for(lambda: any("hold SPACE to answer yes" in line for line in lines), timeout=15)
        keys.press(" ")
        await asyncio.sleep(HELD_GAP_S + 0.2)  # longer than a held key's repeat gap: the next press is a new one
        keys.press(" ")  # too late to be a held key: still no answer
        await asyncio.sleep(0.1)  # time for a wrongly taken answer to end the step: none may
        assert not task.done()
        keys.press("n")
        assert await asyncio.wait_for(task, 30) == 1
        assert any("real equipment: --answer yes does not answer for it" in line for line in lines), lines
        assert not any(c[1] == "pulse" for c in twin.commands)
        # held: every question is answered yes while SPACE is held, and the cycle runs
        lines.clear()

        def out(line: str) -> None:  # the person also does what a question asks (light barrier, loops) at the twin
            lines.append(line)
            if line.startswith("    ? Toggle "):
                twin.controls().invoke(f"toggle {line.split()[2]}")

        person.out = out
        keys.hold_space()
        code = await asyncio.wait_for(checkout_devices(runtime, ["gate"], user="cli:test", role="engineer",
                                                       answer="yes", out=out, person=person), 90)
        keys.release()
        assert code == 0, lines
        assert [c for c in twin.commands if c[1] == "pulse"][-2:] == [("open", "pulse"), ("close", "pulse")]
        assert sum("SPACE held" in line for line in lines) >= 3, lines  # asked before the cycle and before each pulse
        assert person.beats > 10


async def test_a_released_key_stops_what_the_persons_session_holds(tmp_path):
    async with real_barrier(tmp_path) as (runtime, twin):
        keys = FakeKeys()
        person = TerminalPerson(runtime.worker, "cli-checkout-hold", keys, out=lambda _text: None)
        person.start()
        keys.hold_space()
        await runtime.worker.gate.invoke("gate", "close activate", user="cli:test", role="engineer", session=person.session,
                                         confirmed=True)
        assert twin.levels[codec.Command.CLOSE]
        await asyncio.sleep(1.0)  # a second with SPACE held: the level must stay
        assert twin.levels[codec.Command.CLOSE], "held while SPACE is held"
        keys.release()
        released = asyncio.get_running_loop().time()
        assert await wait_for(lambda: not twin.levels[codec.Command.CLOSE], timeout=3)
        assert asyncio.get_running_loop().time() - released < 1.0
