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
