"""A parameter write is checked once, by the parameter model, and the result carried along (issue 44).

The entry becomes the stored value in :meth:`devices.params.Param.accept` (its :meth:`~devices.params.Param.validate`);
the gate's arguments carry what it accepted, and the send policy and the adapter take that. Counted here for an
HD-Lock's LockRequestDelay on the page's path, the API's and the raw telegrams' of the bus tools (a Modbus poll
window's write, a CAN write frame of the transmit list): exactly one validation per write.
"""

from __future__ import annotations

from collections.abc import AsyncIterator

import pytest
from conftest import modbus_plant
from nicegui import ui
from nicegui.testing import User
from nicegui.testing.user_interaction import UserInteraction
from webutil import eventually, simulated_user

from app.modbus_poll import ModbusPoll
from app.runtime import Runtime
from devices.commands import WRITE_PARAMETER
from devices.hdlock import codec
from devices.hdlock.params import PARAMS
from devices.params import Param
from devices.sendpolicy import BusDevice, check_can

pytestmark = pytest.mark.timeout(40)
DELAY = PARAMS.by_name["LockRequestDelay"]


@pytest.fixture
def validations(monkeypatch) -> list[object]:
    """The entries the parameter model checked for LockRequestDelay, one per validation."""
    checked: list[object] = []
    real = Param.validate

    def counted(self: Param, value):
        if self is DELAY:
            checked.append(value)
        return real(self, value)

    monkeypatch.setattr(Param, "validate", counted)
    return checked


@pytest.fixture
async def lock() -> AsyncIterator[tuple[User, Runtime]]:
    runtime = Runtime(modbus_plant(locks=(("door-1", 1),)), simulate=True)
    async with simulated_user(runtime) as user:
        state = runtime.store.devices["door-1"]
        await eventually(lambda: state.status == "online" and state.raw(DELAY) is not None, timeout=10,
                         what="door-1 online with its holding registers read")
        yield user, runtime


async def test_the_page_checks_an_entry_once(lock, validations):
    user, runtime = lock
    await user.open("/device/door-1")
    await user.should_see("HD-Lock door-1")
    (entry,) = [e for e in user.client.elements.values() if e.props.get("data-param") == "LockRequestDelay"]
    assert isinstance(entry, ui.number)
    validations.clear()
    entry.value = 250
    UserInteraction(user, {entry}, None).trigger("keydown.enter")
    await eventually(lambda: runtime.store.devices["door-1"].raw(DELAY) == 250, what="Enter writes")
    assert validations == [250]


async def test_the_api_checks_an_entry_once(lock, validations):
    _user, runtime = lock
    validations.clear()
    await runtime.worker.gate.invoke("door-1", WRITE_PARAMETER, {"param": "LockRequestDelay", "value": "260"},
                                     user="anna", role="engineer", confirmed=True)
    assert runtime.twins["door-1"].holding[DELAY.address] == 260
    assert validations == ["260"]


async def test_a_raw_telegram_is_checked_once_as_the_declared_write(lock, validations):
    _user, runtime = lock
    poll = ModbusPoll(runtime.worker, "line1")
    validations.clear()
    await poll.write(1, DELAY.address, [270], user="anna", role="engineer", confirmed=True)
    assert runtime.twins["door-1"].holding[DELAY.address] == 270
    assert len(validations) == 1
    validations.clear()
    target = codec.DeviceId.make(335, True)
    frame = codec.encode_write(target, DELAY.address, 280)
    verdict = check_can([BusDevice("door-2", "hdlock", {"device_id": 335, "extended": True})],
                        frame.arbitration_id, frame.is_extended_id, bytes(frame.data))
    assert verdict.allowed and len(validations) == 1
