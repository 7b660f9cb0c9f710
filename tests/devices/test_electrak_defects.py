"""Electrak HD defects of issue 40: override/reset, area clear, raw frames judged like the declared commands.

Each test here failed on the code before the Electrak's control core (devices/electrak/control.py) and the
policy's decoding of raw frames (devices/electrak/policy.py)."""

from __future__ import annotations

import asyncio

import pytest
from conftest import wait_for
from test_electrak import beat, lift, start_lift  # noqa: F401 (fixture)

from app.gate import NeedsConfirmation
from devices.commands import commands_of
from devices.electrak import codec
from devices.electrak.adapter import CommandError
from devices.sendpolicy import BusDevice, check_can

LIFT = BusDevice("lift", "electrak", {"actuators": [{"model": "HD24", "gearing": "B026", "stroke_mm": 300}] * 2})


def verdict(can_id: int, data: str, devices=(LIFT,)):
    return check_can(list(devices), can_id, False, bytes.fromhex(data))


# -- override/reset asks, on every path ---------------------------------------------------------------


def test_a_raw_override_frame_is_not_a_stop_and_asks_its_risk():
    found = verdict(codec.CONTROL_ID, "E8 03 00 00 BE 00 00 02")  # override/reset only
    assert found.allowed and found.kind != "stop"
    assert found.confirm and "expect" in found.question and "alone" in found.question
    for bare in ([], [LIFT]):  # 0x06 is the Electrak's on every CAN bus
        assert check_can(bare, codec.CONTROL_ID, False, bytes.fromhex("00 00 00 00 60 00 00 02")).confirm


def test_only_enable_and_override_both_cleared_is_a_stop():
    stop = verdict(codec.CONTROL_ID, "E8 03 00 00 BE 00 00 00")
    assert stop.allowed and stop.kind == "stop" and not stop.confirm
    assert verdict(codec.CONTROL_ID, "E8 03 00 00 BE 00 00 01").refused  # enable: the page only
    assert verdict(codec.CONTROL_ID, "E8 03 00 00 BE 00 00 03").refused
    assert verdict(codec.CONTROL_ID, "E8 03 00 00 BE 00 00 04").kind == "stop"  # the other bits mean nothing


def test_the_declared_override_names_its_risk():
    override = commands_of("electrak")["override"]
    risk = override.risk_text({"active": True})
    assert "expect" in risk and "alone" in risk
    assert override.risk_text({"active": False}) == ""  # clearing it asks nothing


async def test_override_without_confirmation_is_refused_by_the_adapter(lift):  # noqa: F811
    _runtime, adapter, _state, twin = lift
    await adapter.take_control("s1", "engineer")
    twin.remove(1)
    with pytest.raises(CommandError, match="confirmation"):
        adapter.override("s1", True)
    assert not adapter.command.override


async def test_override_through_the_gate_asks_first(lift):  # noqa: F811
    runtime, adapter, _state, _twin = lift
    await adapter.take_control("s1", "engineer")
    with pytest.raises(NeedsConfirmation, match="alone"):
        await runtime.worker.gate.invoke("lift", "override", {"active": 1}, user="engineer", role="engineer", session="s1")
    assert not adapter.command.override
    await runtime.worker.gate.invoke("lift", "override", {"active": 1}, user="engineer", role="engineer", session="s1",
                                     confirmed=True)
    assert adapter.command.override


async def test_go_is_refused_after_an_override_while_an_actuator_is_missing(lift):  # noqa: F811
    """The issue's sequence: actuator 2 disconnected, override/reset, Go: actuator 1 moved alone from 14.3 to 41.3 mm."""
    _runtime, adapter, state, twin = lift
    await adapter.take_control("s1", "engineer")
    twin.remove(1)
    assert await wait_for(lambda: state.live("Devices heard").value == 1 and state.live("Error flags").value & 0x80, timeout=3)
    adapter.override("s1", True, confirmed=True)
    assert await wait_for(lambda: not state.live("Error flags").value & 0x80, timeout=1)
    adapter.set_command("s1", 40.0, 20.0, 0)
    with pytest.raises(CommandError, match="1 of the 2.*Reconnect"):
        adapter.go("s1")
    with pytest.raises(CommandError, match="Reconnect"):
        adapter.jog("s1", +1)
    start = twin.actuators[0].position_mm
    await asyncio.sleep(0.4)  # four control periods: the refused go must move nothing
    assert twin.actuators[0].position_mm == start and not adapter.command.enable


# -- Go and jog ask that the area is clear ------------------------------------------------------------


def test_go_and_jog_ask_that_the_area_is_clear():
    commands = commands_of("electrak")
    for name, args in (("go", {}), ("jog", {"direction": 1, "speed_mm_s": 10.0})):
        assert "area is clear" in commands[name].risk_text(args), name


async def test_go_through_the_gate_asks_that_the_area_is_clear(lift):  # noqa: F811
    runtime, adapter, _state, _twin = lift
    await adapter.take_control("s1", "engineer")
    adapter.set_command("s1", 40.0, 20.0, 0)
    with pytest.raises(NeedsConfirmation, match="area is clear"):
        await runtime.worker.gate.invoke("lift", "go", None, user="engineer", role="engineer", session="s1")
    assert not adapter.command.enable


# -- raw service writes are the parameter they amount to ----------------------------------------------


@pytest.mark.parametrize("value", [100, 199, 1001, 65535])
def test_a_raw_timeout_write_out_of_range_is_refused_with_the_range(value):
    data = bytes([0x01, 0x06, 0x02, 0x00]) + value.to_bytes(4, "little")
    found = check_can([LIFT], codec.SERVICE_REQUEST_ID, False, data)
    assert found.refused and "200" in found.refused and "1000" in found.refused and "Timeout" in found.refused


def test_a_raw_timeout_write_in_range_asks_what_the_declared_write_asks():
    above = check_can([LIFT], codec.SERVICE_REQUEST_ID, False, bytes.fromhex("01 06 02 00 2C 01 00 00"))  # 300 ms
    assert above.allowed and any("keep moving" in c for c in above.confirm)
    default = check_can([LIFT], codec.SERVICE_REQUEST_ID, False, bytes.fromhex("01 06 02 00 FA 00 00 00"))  # 250 ms
    assert default.allowed and not any("keep moving" in c for c in default.confirm)


def test_a_raw_bit_rate_write_outside_the_table_is_refused():
    found = check_can([LIFT], codec.SERVICE_REQUEST_ID, False, bytes.fromhex("01 04 01 00 01 00 00 00"))
    assert found.refused and "Bit rate" in found.refused
    ok = check_can([LIFT], codec.SERVICE_REQUEST_ID, False, bytes.fromhex("01 04 01 00 03 00 00 00"))
    assert ok.allowed and any("bit rate" in c for c in ok.confirm)


# -- frames the actuators send are never sent by this tool ---------------------------------------------


@pytest.mark.parametrize("can_id", [codec.STATUS_ID, codec.SERVICE_RESPONSE_ID, 0x600, 0x685, 0x6FF])
def test_device_sent_frames_are_refused(can_id):
    for devices in ([LIFT], []):
        found = check_can(devices, can_id, False, bytes(8))
        assert found.refused and "never" in found.refused, hex(can_id)
    assert check_can([LIFT], can_id, True, bytes(8)).allowed  # the extended ID of the same number is not the Electrak's
