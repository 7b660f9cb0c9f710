"""A switch of a twin's simulation card as the audit says it (``SimControls.describe``: its name and state, "strong magnet
on") in the reader's language where it is shown (the gate's refusal in the command client, the record page's and
``commission checkout``'s answer to ``--sim-action``): every switch of every twin of the demo plant; the audit keeps
the English."""

from __future__ import annotations

import pytest

from app import i18n
from app.message import said
from app.record_cli import sim_action
from tests.recordutil import demo_runtime

pytestmark = pytest.mark.timeout(90)

DE, EN = i18n.get("de"), i18n.get("en")


async def test_every_switch_of_the_demo_plants_twins_is_worded_in_german_and_kept_in_english(tmp_path):
    async with demo_runtime(tmp_path, online=False) as runtime:
        switches = {
            (device, action.name): controls.describe(action.name, {"on": on})
            for device in runtime.store.devices
            if (controls := runtime.sim_controls(device)) is not None
            for action in controls.actions
            if action.switch
            for on in (True,)
        }
        assert len({name for _device, name in switches}) >= 15, switches  # the locks', actuators', SCU's, barriers' switches
        DE.missing.clear()
        for (device, name), text in switches.items():
            assert text == f"{name} on", (device, text)  # the audit's words, as before
            assert said(text, EN) == f"{name} on"
            german = said(text, DE)
            assert german.endswith(" ein") and name not in german, (device, name, german)
        assert not DE.missing, DE.missing
        assert said(runtime.sim_controls("door-1").describe("strong magnet", {"on": False}), DE) == "starker Magnet aus"
        assert said(runtime.sim_controls("barrier-in").describe("loop A occupied", {"on": True}), DE) == "Schleife A belegt ein"
        answer = await sim_action(runtime, "door-1:strong magnet:on=on", user="anna", role="engineer")
        assert answer == "door-1: simulation: strong magnet on"
        assert said(answer, DE) == "door-1: Simulation: starker Magnet ein", said(answer, DE)
        rows = await runtime.audit.aquery(device="door-1")
        assert any(r.action == "simulation: strong magnet on" for r in rows), [r.action for r in rows]  # as written
