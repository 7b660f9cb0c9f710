"""What the parameter models word themselves, in German where the pages show it (issue 47): a parameter's risk text
in the question before a write, the allowed values a text parameter words itself, and a refusal that names the
parameter by the model's own name with the sentence around it translated."""

from __future__ import annotations

import pytest
from test_i18n_pages import german_user
from test_m3io_params import _plant_file
from webutil import dialog_button, eventually, switch_starting

from app import i18n
from app.message import said
from app.plant import load_plant
from app.runtime import Runtime
from devices.electrak.params import PARAMS as ELECTRAK_PARAMS
from devices.electrak.params import refusal

pytestmark = pytest.mark.timeout(60)


async def test_the_p2_switch_asks_its_risk_in_german(tmp_path):
    """The M3IO's P2 (section 4.3): the question names what P2 switches off in German."""
    runtime = Runtime(load_plant(_plant_file(tmp_path)), simulate=True, data_dir=tmp_path / "data")
    async with german_user(runtime) as user:
        await eventually(lambda: runtime.store.devices["io-b"].status == "online", timeout=15, what="io-b online")
        await user.open("/device/io-b")
        await user.should_see("Drehstromausgang mit 2-poliger Last (P2)", retries=100)
        switch = switch_starting(user, "Drehstromausgang")
        await eventually(lambda: switch.enabled, timeout=10, what="the P2 switch enabled")
        switch.set_value(True)
        await user.should_see("eine Drehstromlast, die eine Phase verloren hat", retries=50)
        await user.should_not_see("a three-phase load that lost one phase")
        dialog_button(user, "Abbrechen").click()
        await eventually(lambda: switch.value is False, timeout=5, what="the switch back off")


async def test_the_project_editor_words_a_records_allowed_bytes_in_german(tmp_path):
    runtime = Runtime(load_plant(_plant_file(tmp_path)), simulate=True, data_dir=tmp_path / "data")
    async with german_user(runtime) as user:
        await user.open("/project/io-a")
        await user.should_see("zulässig: 1 bis 6 Bytes hexadezimal, z. B. 01 02 0a (mit ff auf 6 Bytes aufgefüllt)",
                              retries=50)


def test_a_refusal_keeps_the_models_name_and_words_its_sentence():
    timeout = ELECTRAK_PARAMS.by_name["Timeout"]
    reason = refusal(timeout, 150)
    assert reason.startswith("Timeout 150 ms is below 200 ms, twice the control period of 100 ms")  # English as it was
    assert said(reason, i18n.get("de")).startswith("Timeout 150 ms liegt unter 200 ms, der doppelten Steuerperiode von "
                                                   "100 ms")


async def test_the_electrak_timeout_asks_and_refuses_in_german(tmp_path):
    """Timeout (document 004): above 250 ms the question names the timeout's risk in German."""
    from nicegui.testing.user_interaction import UserInteraction
    from plants import electrak_bus, plant
    from test_i18n_pages import german_page
    from webutil import by_testid

    async with german_page(tmp_path, plant(electrak_bus()), "lift", "Electrak-HD-Netzwerk lift") as (runtime, user):
        state = runtime.store.devices["lift"]
        await eventually(lambda: all(state.raw(p) is not None for p in ELECTRAK_PARAMS), timeout=10,
                         what="service parameters read")
        entry = by_testid(user, "entry-06")
        entry.value = 300
        UserInteraction(user, {entry}, None).trigger("keydown.enter")
        await user.should_see("Über der Voreinstellung von 250 ms bewegen sich die Aktuatoren so lange weiter", retries=50)
        await user.should_not_see("keep moving for that long")
        dialog_button(user, "Abbrechen").click()
