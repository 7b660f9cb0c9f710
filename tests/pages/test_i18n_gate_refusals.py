"""The gate's refusal of a device the plant does not have and the refusals of adopting a discovered device, in the
page's language (issue 47): the command client's notification and the adopt dialog word them in German; the error
keeps its English (and is a ``KeyError`` or ``ValueError`` as before)."""

from __future__ import annotations

import pytest
from nicegui import ui
from plants import can_bus, hdlock_can, plant
from test_i18n_pages import german_locks, german_user
from webutil import dialog_button, eventually

from app import i18n
from app.message import said
from app.runtime import Runtime
from app.worker import UnknownDevice
from devices.commands import READ_PARAMETERS

pytestmark = pytest.mark.timeout(60)

DE = i18n.get("de")


async def test_a_device_the_plant_does_not_have_is_refused_in_german(tmp_path):
    from pages.command_client import run_command

    async with german_locks(tmp_path, "door-1") as (runtime, user):
        with pytest.raises(KeyError) as unknown:  # an UnknownDevice is a KeyError, as the gate's callers look it up
            await runtime.worker.gate.invoke("ghost", READ_PARAMETERS, user="anna", role="engineer")
        assert isinstance(unknown.value, UnknownDevice)
        assert unknown.value.args == ("no device named 'ghost' in this plant",)
        assert said(unknown.value, DE) == "kein Gerät namens 'ghost' in dieser Anlage"
        await user.open("/device/door-1")
        await user.should_see("HD-Lock door-1", retries=50)
        with user.client:
            assert await run_command("ghost", READ_PARAMETERS) == (False, None)
        await user.should_see(f"{READ_PARAMETERS}: kein Gerät namens 'ghost' in dieser Anlage", retries=20)
        assert not [m for m in user.notify.messages if "no device named" in m], user.notify.messages


async def test_adopting_a_discovered_device_under_a_name_taken_is_refused_in_german(tmp_path):
    from pages.discover import adopt_dialog

    runtime = Runtime(plant(can_bus(hdlock_can("gate", 660100))), simulate=True, data_dir=tmp_path)
    with pytest.raises(ValueError) as taken:
        runtime.worker.adopt(runtime.plant.devices["gate"])
    assert str(taken.value) == "a device named 'gate' exists already"
    assert said(taken.value, DE) == "ein Gerät namens 'gate' gibt es bereits"

    def adopt_page() -> None:
        adopt_dialog("can1", {"type": "hdlock", "device_id": 660200, "extended": True}, ui.row(), lambda name: None,
                     i18n.page_language())

    async with german_user(runtime) as user:
        ui.page("/adopt-de")(adopt_page)
        await user.open("/adopt-de")
        await user.should_see("Zur laufenden Anlage hinzufügen", retries=50)
        field = next(e for e in user.client.elements.values() if isinstance(e, ui.input))
        field.set_value("gate")
        dialog_button(user, "Zur laufenden Anlage hinzufügen").click()
        await user.should_see("Übernahme nicht möglich: ein Gerät namens 'gate' gibt es bereits", retries=50)
        await eventually(lambda: list(runtime.plant.devices) == ["gate"], timeout=2, what="nothing adopted")
