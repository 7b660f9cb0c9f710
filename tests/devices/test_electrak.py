"""Electrak HD (SY2): codec golden vectors and the adapter against its twin on a virtual CAN bus."""

from __future__ import annotations

import asyncio

import pytest
import plants
from conftest import wait_for
from plants import ELECTRAK_ACTUATORS, electrak_bus

from app.plant import PlantError, parse_plant
from app.runtime import Runtime
from app.worker import PermissionDenied
from devices.electrak import codec
from devices.electrak.adapter import CommandError, ControlBusy
from devices.electrak.params import PARAMS

# -- codec -------------------------------------------------------------------------------------


def test_control_example():
    """E8 03 41 00 BE 03 00 01: 100.0 mm, 6.5 A, enable (0x03BE = 95.8 mm/s, see SPEC-NOTES)."""
    data = bytes.fromhex("E8 03 41 00 BE 03 00 01")
    frame = codec.ControlFrame.decode(data)
    assert frame.position_mm == 100.0 and frame.current_a == 6.5 and frame.enable and not frame.override
    assert frame.speed_mm_s == 95.8
    assert frame.encode() == data


def test_control_bits_and_range():
    assert codec.ControlFrame(0, 0, 1, enable=False, override=True).encode()[7] == 0x02
    with pytest.raises(codec.CodecError):
        codec.ControlFrame(7000, 0, 1).encode()


@pytest.mark.parametrize(
    ("message", "data"),
    [
        (codec.password_request(0xE5F6A7B8), "01 FF 04 00 B8 A7 F6 E5"),  # unlock soft start
        (codec.write_request(0x01, 2, 500), "01 01 02 00 F4 01 00 00"),  # soft start 500 ms
        (codec.save_request(), "01 F0 04 00 00 00 00 00"),  # save in the table's form (length 4); example's: test_electrak_service
    ],
)
def test_service_examples(message, data):
    assert message.encode() == bytes.fromhex(data)
    assert codec.ServiceMessage.decode(bytes.fromhex(data)) == message


@pytest.mark.parametrize(("code", "name"), [(0xFF01, "OBJECT_NOT_FOUND/INCORRECT_PASSWORD"), (0xFF02, "WRONG_SIZE"),
                                           (0xFF04, "INCORRECT_PERMISSION"), (0xFF08, "WRONG_ID")])
def test_error_responses(code, name):
    answer = codec.ServiceMessage.decode(bytes([0x13, 0x01, 0x02, 0]) + code.to_bytes(4, "little"))
    assert answer.error_code == code and answer.error_name == name


def test_status_flags():
    frame = codec.StatusFrame.decode(bytes.fromhex("F4 01 0F 00 C8 00 05 22"))
    assert (frame.position_mm, frame.current_a, frame.speed_mm_s) == (50.0, 1.5, 20.0)
    assert frame.motion_names == ["Extending", "Saturated"]
    assert frame.error_names == ["Current overload", "Message timeout"]
    assert codec.StatusFrame.decode(frame.encode()) == frame


def test_limits_by_model_and_gearing():
    limits = codec.Limits.of([codec.Actuator("MD12", "B017", 300), codec.Actuator("HD48", "B026", 200)])
    assert (limits.stroke_mm, limits.current_a, limits.speed_min, limits.speed_max) == (200, 6.5, 11, 32)
    assert limits.check(100, 0, 20) == []
    assert len(limits.check(250, 7, 5)) == 3


def test_plant_validation():
    with pytest.raises(PlantError, match="gearing 'B999'"):
        parse_plant(plant_text(actuators=[{"model": "HD24", "gearing": "B999", "stroke_mm": 300}]))


# -- adapter + twin ------------------------------------------------------------------------------



def plant_text(actuators=ELECTRAK_ACTUATORS) -> str:
    return plants.plant_text(electrak_bus(actuators=actuators, simulate=True), name=None)


BEATING = ("s1", "a", "b", "browser-1")  # sessions whose browser stays alive (the dead-man rule)


async def beat(runtime, sessions=BEATING) -> None:
    """What a live page does: confirm several times a second that the browser is alive."""
    while True:
        for session in sessions:
            runtime.worker.heartbeat(session)
        await asyncio.sleep(0.1)


async def start_lift(text: str | None = None):
    runtime = Runtime(parse_plant(text or plant_text()), simulate=True)
    await runtime.start()
    adapter = runtime.worker.adapters["lift"]
    state = runtime.store.devices["lift"]
    configured = len(adapter.actuators)
    assert await wait_for(lambda: state.status == "online" and state.live("Devices heard").value == configured, timeout=4)
    return runtime, adapter, state, runtime.twins["lift"]


async def drive(adapter, session: str, position_mm: float, speed_mm_s: float, current_a: float) -> None:
    """``session`` takes control as an engineer and sends the actuators towards ``position_mm``."""
    await adapter.take_control(session, "engineer")
    adapter.set_command(session, position_mm, speed_mm_s, current_a)
    adapter.go(session)


@pytest.fixture
async def lift():
    runtime, adapter, state, twin = await start_lift()
    beating = asyncio.create_task(beat(runtime))
    try:
        yield runtime, adapter, state, twin
    finally:
        beating.cancel()
        await asyncio.wait_for(runtime.stop(), 5)


async def test_move_to_target_and_arrive(lift):
    _runtime, adapter, state, twin = lift
    await drive(adapter, "s1", 30.0, 32.0, 0)
    assert await wait_for(lambda: state.live("Motion flags").value & 1, timeout=2)  # extending
    assert await wait_for(lambda: abs((adapter.position_mm() or 0) - 30.0) < 0.2 and state.live("Motion flags").value == 0, timeout=6)
    assert all(abs(a.position_mm - 30.0) < 0.2 for a in twin.actuators)
    assert state.live("Error flags").value == 0
    # the chart's samples: from the start to the end position (the sample at the end may come a moment after arrival)
    assert await wait_for(lambda: max(s["Position"] for _, s in state.history) >= 29.8, timeout=2)
    positions = [s["Position"] for _, s in state.history]
    assert positions[0] < 1 and max(positions) >= 29.8


async def test_overload_trips_and_clears(lift):
    _runtime, adapter, state, twin = lift
    await drive(adapter, "s1", 200.0, 32.0, 3.0)
    assert await wait_for(lambda: state.live("Motion flags").value & 1 and (adapter.position_mm() or 0) > 1.0, timeout=3)  # extending
    twin.set_load(4.0)  # 0.8 A no-load + 4 A > 3 A limit
    assert await wait_for(lambda: state.live("Error flags").value & 0x02, timeout=2)
    stopped = adapter.position_mm()
    await asyncio.sleep(0.3)  # three status periods (0x07 every 100 ms) with the overload flag set
    assert abs(adapter.position_mm() - stopped) < 0.3  # no motion while set
    twin.set_load(0.0)
    adapter.stop("s1")  # dropping the enable bit clears it
    assert await wait_for(lambda: not state.live("Error flags").value & 0x02, timeout=2)


async def test_overload_cleared_by_moving_back(lift):
    _runtime, adapter, state, twin = lift
    await drive(adapter, "s1", 200.0, 32.0, 3.0)
    assert await wait_for(lambda: state.live("Motion flags").value & 1 and (adapter.position_mm() or 0) > 1.0, timeout=3)  # extending
    twin.set_load(4.0)
    assert await wait_for(lambda: state.live("Error flags").value & 0x02, timeout=2)
    twin.set_load(0.0)
    adapter.set_command("s1", 0.0, 32.0, 3.0)
    assert await wait_for(lambda: not state.live("Error flags").value & 0x02 and state.live("Motion flags").value & 2, timeout=2)


async def test_timeout_flag_when_control_stops(lift):
    runtime, adapter, state, twin = lift
    await adapter.take_control("s1", "engineer")
    assert await wait_for(lambda: not state.live("Error flags").value & 0x20, timeout=2)
    adapter.set_command("s1", 250.0, 20.0, 0)
    adapter.go("s1")
    assert await wait_for(lambda: state.live("Motion flags").value & 1, timeout=2)  # extending
    runtime.worker.can_buses["can2"].stop_cyclic(adapter.key)  # the keep-alive dies
    assert await wait_for(lambda: state.live("Error flags").value & 0x20, timeout=1)
    moving_at = adapter.position_mm()
    await asyncio.sleep(0.4)  # four status periods (0x07 every 100 ms) after the 250 ms message timeout
    assert abs(adapter.position_mm() - moving_at) < 0.5  # motion stopped


async def test_release_sends_enable_cleared_and_stops_keepalive(lift):
    runtime, adapter, state, twin = lift
    await drive(adapter, "browser-1", 250.0, 20.0, 0)
    assert await wait_for(lambda: state.live("Motion flags").value & 1, timeout=2)  # extending
    assert adapter.release_control("browser-1", "released: the controlling browser disconnected")
    assert not runtime.worker.can_buses["can2"].cyclic_running(adapter.key)
    assert await wait_for(lambda: twin.control is not None and not twin.control.enable, timeout=1)
    assert await wait_for(lambda: state.live("Motion flags").value == 0, timeout=1)
    assert any("disconnected" in e.text for e in state.events)


async def test_only_one_session_controls(lift):
    _runtime, adapter, _state, _twin = lift
    await adapter.take_control("a", "alice")
    with pytest.raises(ControlBusy, match="alice"):
        await adapter.take_control("b", "bob")
    with pytest.raises(ControlBusy):
        adapter.go("b")
    adapter.release_control("a")
    await adapter.take_control("b", "bob")


async def test_parameter_flag_for_bad_values(lift):
    runtime, adapter, state, _twin = lift
    await adapter.take_control("s1", "engineer")
    with pytest.raises(CommandError, match="outside"):
        adapter.set_command("s1", 400.0, 20.0, 0)  # refused before it reaches the bus
    adapter.release_control("s1")
    bus = runtime.worker.can_buses["can2"]
    for _ in range(5):  # another master on the bus sends 99 mm/s, outside B026's 6..32 mm/s
        bus.send(codec.CONTROL_ID, codec.ControlFrame(100, 0, 99, enable=True).encode())
        await asyncio.sleep(0.05)  # a master repeating its control telegram (the document: every 100 ms)
    assert await wait_for(lambda: state.live("Error flags").value & 0x01, timeout=1)


async def test_too_few_devices_and_override(lift):
    _runtime, adapter, state, twin = lift
    await adapter.take_control("s1", "engineer")
    twin.remove(1)
    assert await wait_for(lambda: state.live("Devices heard").value == 1 and state.live("Error flags").value & 0x80, timeout=2)
    adapter.override("s1", True, confirmed=True)  # the risk (one actuator of a pair may then move alone) confirmed
    assert await wait_for(lambda: not state.live("Error flags").value & 0x80, timeout=1)


async def test_service_password_write_readback_save(lift):
    _runtime, adapter, state, twin = lift
    soft_start = PARAMS.by_name["Soft start time"]
    assert await adapter.read_param(soft_start) == 300
    assert await adapter.write_param(soft_start, 500) == 500
    assert twin.service.values[0x01] == 500 and soft_start.key in state.unsaved
    await adapter.save_parameters()
    assert twin.service.saved[0x01] == 500 and not state.unsaved
    assert state.live("Service answers").value == 2  # both actuators answered


async def test_service_errors_by_name(lift):
    _runtime, adapter, _state, twin = lift
    with pytest.raises(CommandError, match="INCORRECT_PERMISSION"):
        await adapter._service(codec.read_request(0x06, 2))  # no password written
    await adapter._service(codec.password_request(0x9A8B7C6D))
    with pytest.raises(CommandError, match="WRONG_SIZE"):
        await adapter._service(codec.read_request(0x06, 4))
    with pytest.raises(CommandError, match="OBJECT_NOT_FOUND/INCORRECT_PASSWORD"):
        await adapter._service(codec.password_request(0x12345678))
    with pytest.raises(CommandError, match="WRONG_ID"):
        await adapter._service(codec.ServiceMessage(0x05, 0x01, 2, 0))


async def test_bitrate_needs_confirmation(lift):
    _runtime, adapter, _state, _twin = lift
    with pytest.raises(CommandError, match="needs confirmation"):
        await adapter.write_param(PARAMS.by_name["Bit rate"], 3)


async def test_viewer_cannot_drive(lift):
    runtime, _adapter, _state, _twin = lift

    async def take(a):
        await a.take_control("v", "viewer")

    with pytest.raises(PermissionDenied):
        await runtime.worker.gate.run(lambda: take(runtime.worker.adapters["lift"]),
                                      device="lift", role="viewer", user="local")
    assert runtime.worker.adapters["lift"].controller is None


async def test_chart_target_only_while_the_actuators_are_driven_to_it(lift):
    """Issue 32 item 16: the chart showed a target the actuators were not going to (idle, enable cleared)."""
    _runtime, adapter, state, twin = lift

    def targets(since: float) -> list:
        return [values.get("Drive target") for t, values in state.history_since(60) if t > since]

    import time

    start = time.time()
    await asyncio.sleep(0.3)  # three control periods (100 ms) while idle: no target may be drawn
    assert targets(start) and all(t is None for t in targets(start))  # idle: no target drawn
    assert adapter.idle() and "expected while idle" in state.point("Error flags")["text"]
    await adapter.take_control("s1", "engineer")
    assert not adapter.idle()
    adapter.set_command("s1", 120.0, 20.0, 0)
    mark = time.time()
    await asyncio.sleep(0.3)  # three control periods: set but not enabled, no target may be drawn
    assert all(t is None for t in targets(mark))  # set but not enabled: nothing goes there
    adapter.go("s1")
    mark = time.time()
    assert await wait_for(lambda: 120.0 in targets(mark), timeout=1)
    adapter.stop("s1")
    mark = time.time()
    await asyncio.sleep(0.3)  # three control periods after the stop: no target may be drawn
    assert targets(mark) and all(t is None for t in targets(mark))


def test_gearings_without_a_common_speed_are_refused():
    """26.8: one control telegram carries one speed for every actuator; B017 (11-58 mm/s) and B160 (1-5 mm/s)
    share none, so the network cannot be driven."""
    with pytest.raises(codec.CodecError, match="no speed"):
        codec.Limits.of([codec.Actuator("HD24", "B017", 300), codec.Actuator("HD24", "B160", 300)])
    with pytest.raises(PlantError, match="no speed"):
        parse_plant(plant_text(actuators=[{"model": "HD24", "gearing": "B017", "stroke_mm": 300},
                                          {"model": "HD24", "gearing": "B160", "stroke_mm": 300}]))
    assert codec.Limits.of([codec.Actuator("HD24", "B026", 300), codec.Actuator("HD24", "B045", 300)]).speed_max == 19


def test_a_status_telegram_is_one_change_for_the_readers_with_every_point_of_it():
    """Every point of a status telegram 0x07 comes with it, at its arrival, as one change of the device record
    (one version step), however many points it carries; a telegram like the one before says the same."""
    import types

    from devices.electrak.adapter import P_HEARD, P_MOTION, P_POSITION, ElectrakAdapter
    from devices.live import DeviceState

    class Bus:
        name, options = "can2", {"bitrate": 500000}
        state = types.SimpleNamespace(last_error="", reconnects=0, connected=True)

        def subscribe(self, *args) -> None:
            pass

    config = types.SimpleNamespace(name="lift", options={"actuators": [dict(a) for a in ELECTRAK_ACTUATORS]})
    state = DeviceState("lift", "electrak", "can2")
    adapter = ElectrakAdapter(config, state, Bus())
    data = codec.StatusFrame(120.5, 1.2, 0.0, 0, 1 << 5).encode()
    for _ in range(2):  # the second telegram is like the first: the same points, a new time
        version = state.version
        adapter.on_status(types.SimpleNamespace(data=data, timestamp=0.0))
        assert state.version == version + 1
        position = state.points[P_POSITION]
        assert (position.value, position.unit, position.raw) == (120.5, "mm", [1205])
        assert state.points["Message timeout"].value is True and state.points["Extending"].value is False
        assert state.points[P_MOTION].text == "none" and state.points[P_HEARD].value == 0
        assert position.time == state.points["Message timeout"].time == state.last_seen
        assert "(expected while idle" in state.points["Error flags"].text
