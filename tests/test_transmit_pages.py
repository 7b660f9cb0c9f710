"""The bus tool pages for a viewer (NiceGUI simulated user, login required): no transmit list, no writes."""

from __future__ import annotations

import uuid

from test_auth import login

from app.plant import parse_plant
from app.runtime import Runtime
from app.users import UserStore
from tests.conftest import free_port
from webutil import simulated_user


def _plant():
    return parse_plant(
        f'[[bus]]\nname = "line1"\ntype = "modbus-rtu"\nport = "socket://127.0.0.1:{free_port()}"\nsimulate = true\n'
        'timeout = 0.2\nretries = 0\npoll_period = 0.2\n'
        '[[device]]\nname = "door-1"\ntype = "hdlock"\nbus = "line1"\naddress = 1\n'
        f'[[bus]]\nname = "can1"\ntype = "can"\ninterface = "virtual"\nchannel = "txp-{uuid.uuid4().hex[:10]}"\n'
    )


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
