"""The bus monitor pages of an SCU's RS232 line and of a LogiTed line (issue 42 item 11), with NiceGUI's simulated
user on the demo plant: telegrams in the words of their device pages (not "ACK, 53 data bytes", not "between
others"), and filters of their own kind (command letters and data ID; telegram type) instead of Modbus's unit,
function and address."""

from __future__ import annotations

import pytest
from nicegui import ui
from test_monitor import Env, env  # noqa: F401 - the monitor's simulated-user fixture
from webutil import eventually

pytestmark = pytest.mark.timeout(60)


def marked(user, name: str) -> list[ui.element]:
    return [e for e in user.client.elements.values() if e.props.get("data-monitor") == name]


async def test_scu_monitor_decodes_and_filters_by_command_and_data_id(env: Env):  # noqa: F811
    user = env.user
    await user.open("/monitor/rs232-1")
    await user.should_see("Bus monitor rs232-1")
    (table,) = marked(user, "transactions")
    assert not marked(user, "filter-unit") and not marked(user, "filter-function") and not marked(user, "filter-address")

    def cyclic_decoded() -> None:
        rows = [r for r in table.rows if r["request"] == "RC keep-alive with CyclicObj 1" and r["rx"]]
        assert rows, [r["request"] for r in table.rows[:5]]
        assert rows[0]["decoded"].startswith("Actual_Position, all actuators: A1 "), rows[0]["decoded"]
        assert not any(" data bytes" in r["decoded"] for r in table.rows)

    await eventually(cyclic_decoded, timeout=15)
    (command,) = marked(user, "filter-command")
    (data_id,) = marked(user, "filter-data-id")
    command.set_value("RG")
    await eventually(lambda: table.rows and all(r["request"].startswith("RG 0x") for r in table.rows), timeout=5)
    read = table.rows[0]
    name = read["request"].split(" ", 2)[2]
    assert read["decoded"].startswith(name), (read["request"], read["decoded"])
    command.set_value("")
    data_id.set_value("0011")  # actuator 1's position: the cyclic object that carries its block
    await eventually(lambda: table.rows and all("CyclicObj 1" in r["request"] or "0x001" in r["request"]
                                                for r in table.rows), timeout=5)
    data_id.set_value("xyz")
    await eventually(lambda: "error" in data_id.props, timeout=5)


async def test_logited_monitors_decode_and_filter_by_telegram_type(env: Env):  # noqa: F811
    user = env.user
    await user.open("/monitor/gates-485")
    await user.should_see("Bus monitor gates-485")
    (table,) = marked(user, "transactions")
    assert not marked(user, "filter-unit") and not marked(user, "filter-address")
    (kind,) = marked(user, "filter-telegram")
    await eventually(lambda: any(r["decoded"].startswith("Gate state = ") for r in table.rows), timeout=15)
    assert not any(r["request"] == "between others" for r in table.rows)
    kind.set_value("0x0C")
    await eventually(lambda: table.rows and all(r["decoded"].startswith("Gate state = ") for r in table.rows), timeout=5)
    kind.set_value("query")
    await eventually(lambda: table.rows and all("query " in r["request"] for r in table.rows), timeout=5)
    await user.open("/monitor/gate-tcp")
    await user.should_see("Bus monitor gate-tcp")
    (table,) = marked(user, "transactions")
    await eventually(lambda: any(r["request"] == "query gate state" and r["decoded"] == "Gate state = closed"
                                 for r in table.rows), timeout=15)
