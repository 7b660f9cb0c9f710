"""The simulation card's refusal of a value (``SimParam.check`` of devices/simcontrols.py) in the page's language
(issue 47): the parameter by its label as the card shows it, the value as typed; the refusal keeps its English."""

from __future__ import annotations

import pytest
from nicegui import ui
from plants import can_bus, m3io_can, plant
from test_i18n_pages import german_user

from app import i18n
from app.message import said
from app.runtime import Runtime
from devices.simcontrols import SimParam

pytestmark = pytest.mark.timeout(60)

DE = i18n.get("de")


def test_a_refused_value_keeps_its_english_and_comes_in_german():
    channel = SimParam("channel", "SSR", 1, 1, 6)
    with pytest.raises(ValueError) as outside:
        channel.check("9")
    assert str(outside.value) == "SSR: 9 is outside 1 .. 6"
    assert said(outside.value, DE) == "SSR: 9 liegt außerhalb von 1 .. 6"
    with pytest.raises(ValueError) as letters:
        channel.check("four")
    assert str(letters.value) == "SSR: 'four' is not a whole number"
    assert said(letters.value, DE) == "SSR: 'four' ist keine ganze Zahl"
    with pytest.raises(ValueError) as amps:
        SimParam("amps", "extra load [A]", 0, 0, 25).check(2.5)
    assert said(amps.value, DE) == "Zusatzlast [A]: 2.5 ist keine ganze Zahl"


async def test_the_simulation_card_refuses_a_value_in_german(tmp_path):
    runtime = Runtime(plant(can_bus(m3io_can("io", variant="HMR", sw1=0x9A), name="can3")), simulate=True, data_dir=tmp_path)
    async with german_user(runtime) as user:
        await user.open("/device/io")
        await user.should_see("CAN-M3IO io (HMR)", retries=50)
        await user.should_see("Sicherung auslösen")
        fields = [e for e in user.client.elements.values() if e.props.get("data-testid") == "sim-channel"]
        for text, said_de in (("9", "SSR: 9 liegt außerhalb von 1 .. 6"), ("vier", "SSR: 'vier' ist keine ganze Zahl")):
            for field in fields:
                field.set_value(text)
            user.find(kind=ui.button, content="Sicherung auslösen").click()
            await user.should_see(said_de, retries=20)
        assert not [m for m in user.notify.messages if "is outside" in m or "whole number" in m], user.notify.messages
        assert all(ssr.fuse_ok for ssr in runtime.twins["io"].ssr.values())  # refused: nothing blown


def test_an_actions_words_keep_their_english_and_come_in_german():
    """``SimControls.describe``: the audit's words of an action other than a switch (its name, its parameters' names) as
    the twins declare them, and in German as the catalog words them (context simulation)."""
    from devices.m3io.codec import Variant
    from devices.m3io.sim import M3ioTwin
    from devices.mo64.twin import Mo64Twin

    module = M3ioTwin(Variant.HMR, 0x9A).controls()
    blow = module.describe("blow fuse", {"channel": 4})
    assert blow == "blow fuse channel=4" and said(blow, DE) == "Sicherung auslösen Kanal=4"
    toggle = module.describe("toggle E3")
    assert toggle == "toggle E3" and said(toggle, DE) == "E3 umschalten"
    temperature = module.describe("set temperature", {"channel": 2, "tenths": 300})
    assert said(temperature, DE) == "Temperatur setzen Kanal=2 Zehntel=300"
    barrier = Mo64Twin().controls()
    toggle_loop = barrier.describe("toggle loop-B")
    assert toggle_loop == "toggle loop-B" and said(toggle_loop, DE) == "Schleife-B umschalten"
    assert barrier.describe("loop B occupied", {"on": True}) == "loop B occupied on"  # a switch: as the twin declares it
    fault = barrier.describe("raise fault", {"flags": 2})
    assert fault == "raise fault flags=0x2" and said(fault, DE) == "Fehler auslösen Flaggen=0x2"


async def test_the_simulation_card_names_an_action_in_german(tmp_path):
    """An action the card cannot run (the audit log cannot be written: nothing is done) is named in the card's
    words: Simulation: Sicherung auslösen Kanal=4, not the audit's blow fuse channel=4."""
    runtime = Runtime(plant(can_bus(m3io_can("io", variant="HMR", sw1=0x9A), name="can3")), simulate=True, data_dir=tmp_path)
    async with german_user(runtime) as user:
        await user.open("/device/io")
        await user.should_see("CAN-M3IO io (HMR)", retries=50)
        await user.should_see("Sicherung auslösen")

        async def unwritable(**row):
            raise OSError("disk full")

        runtime.worker.audit.arecord = unwritable
        for field in (e for e in user.client.elements.values() if e.props.get("data-testid") == "sim-channel"):
            field.set_value("4")
        user.find(kind=ui.button, content="Sicherung auslösen").click()
        await user.should_see("Simulation: Sicherung auslösen Kanal=4 abgelehnt: das Audit-Log kann nicht geschrieben werden", retries=20)
        assert not [m for m in user.notify.messages if "blow fuse" in m], user.notify.messages
        assert all(ssr.fuse_ok for ssr in runtime.twins["io"].ssr.values())  # nothing done
