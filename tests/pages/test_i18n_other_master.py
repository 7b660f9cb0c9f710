"""Taking control while another master sends, in the page's language (issue 47): the M3IO's and the Electrak's refusal
(devices/m3io/control.py, devices/electrak/control.py) keeps its English and comes in German, also as the M3IO page's
notification; the release reasons these modules give stay in the device's event log as written."""

from __future__ import annotations

import asyncio
import time

import pytest
from nicegui import ui
from plants import can_bus, m3io_can, plant
from test_i18n_pages import german_user

from app import i18n
from app.message import said
from app.runtime import Runtime
from devices.electrak import codec as electrak_codec
from devices.electrak.control import ElectrakControl
from devices.m3io.codec import Variant
from devices.m3io.control import M3ioControl

pytestmark = pytest.mark.timeout(60)

DE = i18n.get("de")


def test_the_m3ios_refusals_while_another_master_is_heard_in_german():
    core = M3ioControl(Variant.HM, 0x3A5)
    core.listen_left(0.0, 0)
    listening = core.take("a", "anna", 0.2, 0.0, 0).refused
    assert listening == "still listening for another master on the bus (0.4 s): try again"
    assert said(listening, DE) == "hört noch auf einen anderen Master auf dem Bus (0,4 s): erneut versuchen"
    core.foreign_dig_out(1.0)
    refused = core.take("a", "anna", 1.5, 0.0, 0).refused
    assert refused == ("another master serves this module (a PLC or another master: DigOut 0x3A5 or the module's answers "
                       "heard within 2 s): taking control would fight it. Stop that master and try again.")
    assert said(refused, DE) == ("ein anderer Master bedient dieses Modul (eine SPS oder ein anderer Master: DigOut 0x3A5 "
                                 "oder Antworten des Moduls innerhalb von 2 s gehört): die Steuerung zu übernehmen hieße, "
                                 "gegen ihn zu arbeiten. Diesen Master anhalten und erneut versuchen.")


def test_the_electraks_refusals_while_another_sender_is_heard_in_german():
    core = ElectrakControl(electrak_codec.Limits.of([electrak_codec.Actuator("HD24", "B026", 300.0)] * 2), 2)
    core.bus_opened(0.0)
    listening = core.take("a", "anna", 0.1, 0.0).refused
    assert said(listening, DE) == "zuerst 0,3 s auf einen anderen Sender von 0x06 hören: gleich erneut versuchen"
    core.foreign_control(1.0)
    refused = core.take("a", "anna", 1.1, 0.0).refused
    assert refused.startswith("control telegrams 0x06 from another sender are on the bus (a PLC, or an actuator whose ")
    assert said(refused, DE) == ("Steuertelegramme 0x06 eines anderen Senders sind auf dem Bus (eine SPS oder ein Aktuator "
                                 "mit aktiver manueller Steuerleitung): die Steuerung zu übernehmen hieße, gegen ihn zu "
                                 "arbeiten. Diesen Sender anhalten (oder die Steuerleitung freigeben) und erneut versuchen.")


async def test_the_m3io_page_refuses_control_while_another_master_is_heard_in_german(tmp_path):
    runtime = Runtime(plant(can_bus(m3io_can("io", variant="HMR", sw1=0x9A), name="can3")), simulate=True, data_dir=tmp_path)
    async with german_user(runtime) as user:
        await user.open("/device/io")
        await user.should_see("CAN-M3IO io (HMR)", retries=50)
        adapter = runtime.worker.adapters["io"]

        async def plc() -> None:  # a PLC's DigOut every 100 ms, as the adapter hears it
            while True:
                adapter.core.foreign_dig_out(time.monotonic())
                await asyncio.sleep(0.1)

        sender = asyncio.create_task(plc())
        try:
            await asyncio.sleep(0)
            user.find(kind=ui.button, content="Steuerung übernehmen").click()
            await user.should_see("ein anderer Master bedient dieses Modul (eine SPS oder ein anderer Master: DigOut 0x",
                                  retries=50)
            assert adapter.controller is None
        finally:
            sender.cancel()
        assert not [m for m in user.notify.messages if "another master" in m], user.notify.messages
