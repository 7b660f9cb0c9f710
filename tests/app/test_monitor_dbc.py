"""The bus monitor's DBC button: the download is a DBC of the bus's devices that cantools loads."""

from __future__ import annotations

import cantools
from nicegui import ui
from test_monitor import Env, env  # noqa: F401 - the monitor's simulated-user fixture
from webutil import eventually


async def test_dbc_button_downloads_the_bus_database(env: Env):  # noqa: F811
    user = env.user
    await user.open("/monitor/can1")
    await user.should_see("Bus monitor can1")
    user.find(kind=ui.button, content="DBC").click()
    await eventually(lambda: len(user.download.http_responses) == 1, what="one download")
    db = cantools.database.load_string(user.download.http_responses[0].content.decode(), database_format="dbc")
    names = {m.name for m in db.messages}
    assert any(n.startswith("gate_1") for n in names) and any(n.startswith("gate_2") for n in names), names
    lock = next(m for m in db.messages if m.name.startswith("gate_1"))
    assert lock.is_extended_frame and lock.frame_id == 0xA1284  # device ID 660100, 29-bit as on the bus
