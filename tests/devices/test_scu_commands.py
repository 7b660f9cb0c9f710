"""The SCU's declared commands through the worker's gate (issue 26), against the twin; the audit rows of
the SCU (issue 32.9): a remote position names parameter, old and new; a release says the same in the
audit and in the events."""

from __future__ import annotations

import ast
import asyncio
from pathlib import Path

import pytest
import plants
from conftest import alive, free_port, running_plant, wait_for
from plants import scu_line

from app.gate import NeedsConfirmation
from app.plant import parse_plant
from app.worker import PermissionDenied
from devices.commands import CommandError, commands_of
from devices.scu import codec

pytestmark = pytest.mark.timeout(60)
F1 = int(codec.Function.F1)
ESTOP = int(codec.Function.EMERGENCY_STOP)


def plant_text(port: int) -> str:
    return plants.plant_text(scu_line("scu", port=port, actuators=[{"counts_per_mm": 10}, {}], baudrate=38400), name=None)


@pytest.fixture
async def scu(tmp_path):
    async with running_plant(parse_plant(plant_text(free_port())), tmp_path, stop_within_s=10) as runtime, \
            alive(runtime.worker, "s1"):
        adapter = runtime.worker.adapters["scu"]
        assert await wait_for(lambda: adapter.session == "open", 10), adapter.session_reason
        yield runtime, adapter, runtime.twins["scu"]


async def invoke(runtime, name, args=None, *, role="engineer", session="s1", confirmed=False):
    return await runtime.worker.gate.invoke("scu", name, args, user="anna" if role == "engineer" else "tablet", role=role,
                                            session=session, confirmed=confirmed)


async def audit_rows(runtime, text: str):
    await asyncio.sleep(0.05)  # stops are audited afterwards, from a queue
    return [r for r in await runtime.audit.aquery(device="scu") if text in r.action]


def test_the_scu_declares_its_commands_with_their_kinds():
    kinds = {name: c.kind for name, c in commands_of("scu").items()}
    assert kinds["go (RE)"] == kinds["jog (RE)"] == "motion"
    assert kinds["release emergency stop (RS 19)"] == "motion"
    for stop in ("stop (RS)", "function off (RS)", "jog stop (RS)", "emergency stop (RE 19)", "release control"):
        assert kinds[stop] == "stop", stop
    assert kinds["set remote speed"] == kinds["set remote position"] == "write"
    assert kinds["read data"] == "read"
    go = commands_of("scu")["go (RE)"]
    assert go.needs_control and "area is clear" in go.risk_text({"function": 0, "motion": 2, "ramp": 1})


def test_the_scu_page_invokes_commands_by_name_without_write_flags():
    tree = ast.parse((Path(__file__).resolve().parents[2] / "pages" / "scu.py").read_text())
    flags = [n.lineno for n in ast.walk(tree) if isinstance(n, ast.keyword) and n.arg == "write"]
    assert flags == [], f"write= flags in pages/scu.py at lines {flags}"
    declared = set(commands_of("scu"))
    named = {n.args[0].value for n in ast.walk(tree) if isinstance(n, ast.Call)
             and (getattr(n.func, "id", "") or getattr(n.func, "attr", "")) == "act"
             and n.args and isinstance(n.args[0], ast.Constant)}
    assert named and named <= declared, named - declared


async def test_go_needs_control_and_asks_that_the_area_is_clear(scu):
    runtime, adapter, twin = scu
    go = {"function": F1, "motion": int(codec.Motion.OUT), "ramp": 1}
    with pytest.raises(CommandError, match="take control"):
        await invoke(runtime, "go (RE)", go, confirmed=True)
    assert ("RE", F1) not in twin.function_log
    assert [r for r in await audit_rows(runtime, "go (RE)") if r.result.startswith("refused")]
    await invoke(runtime, "take control", {"user": "anna"})
    with pytest.raises(NeedsConfirmation, match="area is clear"):
        await invoke(runtime, "go (RE)", go)
    assert ("RE", F1) not in twin.function_log
    await invoke(runtime, "go (RE)", go, confirmed=True)
    assert await wait_for(lambda: twin.actuators[0].moving, 2)
    await invoke(runtime, "stop (RS)", role="viewer", session="v")  # anyone may stop, also without control
    assert not twin.actuators[0].moving and ("RS", F1) in twin.function_log


async def test_a_viewer_sends_nothing_but_stops(scu):
    runtime, adapter, twin = scu
    await invoke(runtime, "take control", {"user": "anna"})
    before = dict(twin.requests)
    for name, args in (("go (RE)", {"function": F1, "motion": 2, "ramp": 1}), ("jog (RE)", {"function": F1, "direction": 1, "ramp": 1}),
                       ("function on (RE)", {"function": 16}), ("set remote speed", {"function": 1, "speed": 50}),
                       ("set remote position", {"actuator": 1, "value": 100}), ("release emergency stop (RS 19)", {}),
                       ("take control", {"user": "tablet"}), ("open remote session", {}), ("release the SCU (RA)", {})):
        with pytest.raises(PermissionDenied):
            await invoke(runtime, name, args, role="viewer", session="s1", confirmed=True)
    await asyncio.sleep(0.3)  # time for a refused command to reach the unit: none may
    after = dict(twin.requests)
    assert {k: after.get(k, 0) - before.get(k, 0) for k in ("RE", "RS", "RT", "RA", "RO") if after.get(k, 0) != before.get(k, 0)} == {}
    await invoke(runtime, "emergency stop (RE 19)", role="viewer", session="v")
    assert twin.emergency_stop
    with pytest.raises(PermissionDenied):
        await invoke(runtime, "release emergency stop (RS 19)", role="viewer", session="v", confirmed=True)
    assert twin.emergency_stop and ("RS", ESTOP) not in twin.function_log


async def test_releasing_the_emergency_stop_asks_and_needs_control(scu):
    runtime, adapter, twin = scu
    await invoke(runtime, "emergency stop (RE 19)")
    with pytest.raises(CommandError, match="take control"):
        await invoke(runtime, "release emergency stop (RS 19)", confirmed=True)
    await invoke(runtime, "take control", {"user": "anna"})
    with pytest.raises(NeedsConfirmation, match="emergency stop"):
        await invoke(runtime, "release emergency stop (RS 19)")
    assert twin.emergency_stop
    await invoke(runtime, "release emergency stop (RS 19)", confirmed=True)
    assert not twin.emergency_stop


async def test_set_remote_position_is_audited_with_parameter_old_and_new(scu):
    runtime, adapter, twin = scu
    await invoke(runtime, "take control", {"user": "anna"})
    await invoke(runtime, "set remote position", {"actuator": 1, "value": 120.0, "mm": True})
    await invoke(runtime, "set remote position", {"actuator": 1, "value": 150.0, "mm": True})
    assert twin.remote_position[0] == 1500
    rows = await audit_rows(runtime, "set remote position A1")
    assert len(rows) == 2 and rows[0].result.startswith("ok")
    newest = rows[0]
    assert newest.parameter == "Remote Position A1 (0x3021)"
    assert "1200 counts" in newest.old and "120 mm" in newest.old and newest.new == "150 mm"
    await invoke(runtime, "set remote speed", {"function": 1, "speed": 40})
    speed = (await audit_rows(runtime, "set remote speed F1"))[0]
    assert speed.parameter.startswith("Remote Speed F1") and speed.new == "40 %"


async def test_a_release_without_an_answer_says_the_same_in_the_audit_and_the_events(scu):
    runtime, adapter, twin = scu
    twin.drop_line(True)  # RA unanswered
    result = await invoke(runtime, "release the SCU (RA)")
    assert adapter.session == "released"
    row = (await audit_rows(runtime, "release the SCU"))[0]
    event = [e for e in adapter.state.events if "SCU released" in e.text][-1]
    assert row.result.startswith("ok") and "without an acknowledged RA" in row.result, row.result
    assert "without an acknowledged RA" in event.text and "without an acknowledged RA" in result
    twin.drop_line(False)
    assert await wait_for(lambda: not twin.remote, 2)  # RC stopped with it: the unit's watchdog ended remote mode
