"""The bus tool pages for a viewer (NiceGUI simulated user, login required): no transmit list, no writes."""

from __future__ import annotations

from plants import can_bus, channel, modbus_line, plant
from test_auth import login

from app.runtime import Runtime
from app.users import UserStore
from webutil import simulated_user


def _plant():
    return plant(modbus_line(poll_period=0.2), can_bus(channel_name=channel("txp"), simulate=None), name=None)


async def test_viewer_never_sees_the_transmit_list_nor_writes(tmp_path):
    store = UserStore(tmp_path / "users.toml")
    store.add("anna", "engineer", "correct horse")
    store.add("tablet", "viewer", "battery staple")
    runtime = Runtime(_plant(), simulate=True, data_dir=tmp_path, auth_required=True)
    async with simulated_user(runtime) as user:
        await login(user, "tablet", "battery staple")
        await user.open("/monitor/can1/transmit")
        await user.should_see("The transmit list is for engineers")
        await user.should_not_see("Frame as bytes")
        await user.should_not_see("Stop all")
        assert "transmit:can1" not in runtime.worker.extra_holders  # not even created for a viewer
        await user.open("/monitor/line1/poll")
        await user.should_see("Writes are for engineers")
        await user.should_not_see("function 16 (multiple)")
