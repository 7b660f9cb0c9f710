"""MO 64 declared commands (issue 26) against the twin, through the worker's gate: every page action is a
declared command, its kind and risk come from devices/mo64/policy.py, the adapter runs what the gate
confirmed without asking again, and a viewer gets nothing but reads and stops."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from conftest import free_port, running_plant, wait_for
from test_mo64_strict import tcp_plant

from app.gate import NeedsConfirmation
from app.plant import parse_plant
from app.worker import PermissionDenied
from devices.commands import commands_of
from devices.mo64 import codec
from devices.mo64.adapter import CommandError

pytestmark = pytest.mark.timeout(60)
PAGE = Path(__file__).resolve().parents[2] / "pages" / "mo64.py"
OPEN, CLOSE, REVERSE = codec.Command.OPEN, codec.Command.CLOSE, codec.Command.REVERSE


@pytest.fixture
async def runtime(tmp_path):
    async with running_plant(parse_plant(tcp_plant(free_port())), tmp_path / "data", ready=("gate",), within_s=10,
                             stop_within_s=15) as runtime:
        adapter = runtime.worker.adapters["gate"]
        assert await wait_for(lambda: "Open time" in adapter.state.points, timeout=10)
        yield runtime


def invoke(runtime, name, args=None, *, role="engineer", session="s1", confirmed=False):
    return runtime.worker.gate.invoke("gate", name, args, user=role, role=role, session=session, confirmed=confirmed)


async def test_a_viewer_gets_only_reads_and_stops_and_the_barrier_is_untouched(runtime):
    twin = runtime.twins["gate"]
    await invoke(runtime, "close activate", confirmed=True)  # an engineer's level, for the stops to act on
    settings, levels = dict(twin.settings), dict(twin.levels)
    refused = []
    for command in commands_of("mo64").values():
        # "write parameter" takes a parameter of the model and a value (no range of its own): the first setting
        args = ({"param": "t_open:0", "value": 1} if command.name == "write parameter"
                else {a.name: a.low for a in command.args})
        if command.kind in ("read", "stop"):
            continue
        with pytest.raises(PermissionDenied):
            await invoke(runtime, command.name, args, role="viewer", session="tablet", confirmed=True)
        refused.append(command.name)
    assert twin.settings == settings and twin.levels == levels  # nothing reached the barrier
    assert not runtime.worker.lines["gate-bus"].released
    assert {"open pulse", "close activate", "open deactivate", "clear levels", "set open time",
            "set pre-warning before opening", "change monitoring", "release the connection",
            "take the connection back", "write parameter"} <= set(refused)
    # what a viewer may: read the error memory, and release a close level (a stop, as the dead-man rule does)
    await invoke(runtime, "read error memory", role="viewer", session="tablet")
    await invoke(runtime, "close deactivate", role="viewer", session="tablet")
    assert not twin.levels[CLOSE]


async def test_clear_levels_asks_the_declared_risk_once_and_then_deactivates_in_the_barrier(runtime):
    twin = runtime.twins["gate"]
    await invoke(runtime, "close activate", confirmed=True)
    assert twin.levels[CLOSE]
    with pytest.raises(NeedsConfirmation) as question:  # the gate asks the declaration's risk
        await invoke(runtime, "clear levels")
    assert "open level released lets the boom close" in question.value.question
    assert twin.levels[CLOSE]  # nothing sent before the answer
    result = await invoke(runtime, "clear levels", confirmed=True)  # answered: the adapter asks nothing more
    assert "close" in result
    assert not twin.levels[CLOSE] and runtime.worker.adapters["gate"].levels == {}


async def test_motion_asks_that_the_area_is_clear_and_a_close_level_is_released_without(runtime):
    twin = runtime.twins["gate"]
    with pytest.raises(NeedsConfirmation, match="nobody stands under it"):
        await invoke(runtime, "open pulse")
    with pytest.raises(NeedsConfirmation, match="lets the boom close"):
        await invoke(runtime, "open deactivate")
    assert await invoke(runtime, "reverse activate", confirmed=True) == "ack"
    assert twin.levels[REVERSE]
    assert await invoke(runtime, "reverse deactivate", session="another") == "ack"  # a stop: asks nothing
    assert not twin.levels[REVERSE]
    assert "another" not in runtime.worker.adapters["gate"].motion_confirmed  # releasing confirmed no motion


async def test_assumed_selector_write_is_declared_with_its_flag_and_its_risk(runtime):
    twin = runtime.twins["gate"]
    adapter = runtime.worker.adapters["gate"]
    before = twin.settings["t_prewarn_open"]
    with pytest.raises(CommandError, match="assumption"):  # no statement, never verified: refused, nothing sent
        await invoke(runtime, "set pre-warning before opening", {"value": before + 50}, confirmed=True)
    assert twin.settings["t_prewarn_open"] == before
    with pytest.raises(NeedsConfirmation) as question:
        await invoke(runtime, "set pre-warning before opening", {"value": before + 50, "selector_verified": True})
    assert "verified on this unit" in question.value.question and "EEPROM" in question.value.question
    result = await invoke(runtime, "set pre-warning before opening", {"value": before + 50, "selector_verified": True},
                          confirmed=True)
    assert twin.settings["t_prewarn_open"] == before + 50 and "read back" in result and "->" in result
    assert "t_prewarn_open" in adapter.verified_selectors
    with pytest.raises(NeedsConfirmation) as question:  # verified now: the wear is still asked, the selector no more
        await invoke(runtime, "set pre-warning before opening", {"value": before})
    assert "verified on this unit" not in question.value.question
    with pytest.raises(Exception, match="outside"):  # the declared range (0 .. 65500)
        await invoke(runtime, "set open time", {"value": 65501}, confirmed=True)
    await invoke(runtime, "set multi-relay modes", dict(zip((f"multi{n}" for n in range(1, 7)), (1, 0, 0, 0, 0, 0))),
                 confirmed=True)
    assert list(twin.settings["multi_relays"]) == [1, 0, 0, 0, 0, 0]


def test_the_page_invokes_every_command_by_a_declared_name():
    tree = ast.parse(PAGE.read_text())
    declared = set(commands_of("mo64"))
    def called(node: ast.Call) -> str:  # act(...), view.act(...), run_command(...)
        return getattr(node.func, "id", "") or getattr(node.func, "attr", "")

    calls = [n for n in ast.walk(tree) if isinstance(n, ast.Call) and called(n) in ("act", "run_command")]
    assert calls
    for call in calls:
        assert not any(k.arg == "write" for k in call.keywords), f"line {call.lineno}: a write= flag"
        assert not any(isinstance(a, ast.Lambda) for a in call.args), f"line {call.lineno}: an adapter callable"
        first = call.args[0] if called(call) == "act" else call.args[1]
        if isinstance(first, ast.Constant):
            assert first.value in declared, f"line {call.lineno}: {first.value!r} is not declared"
