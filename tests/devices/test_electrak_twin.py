"""The Electrak HD twin as the document describes it, stepped in simulated time (no bus)."""

from __future__ import annotations

from devices.electrak import codec
from devices.electrak.params import PARAMS, password_of
from devices.electrak.sim import ElectrakNetworkTwin

DT = 0.01


def network(*actuators: tuple[str, str, float]) -> ElectrakNetworkTwin:
    return ElectrakNetworkTwin([codec.Actuator(m, g, s) for m, g, s in actuators] or [codec.Actuator("HD24", "B026", 300)])


def run(twin: ElectrakNetworkTwin, control: codec.ControlFrame | None, seconds: float, start: float = 0.0) -> float:
    """Send ``control`` every 100 ms and step the physics for ``seconds``; returns the end time."""
    now = start
    next_control = start
    while now < start + seconds - 1e-9:
        if control is not None and now >= next_control - 1e-9:
            twin.on_control(control, now)
            next_control += codec.CONTROL_PERIOD_S
        now += DT
        twin.step(DT, now)
    return now


def go(target: float, speed: float = 20.0, current: float = 0.0) -> codec.ControlFrame:
    return codec.ControlFrame(target, current, speed, enable=True)


def test_moves_toward_the_target():
    twin = network()
    run(twin, go(50.0), 4.0)
    assert abs(twin.actuators[0].position_mm - 50.0) < 0.2 and twin.actuators[0].errors == 0


# -- voltage and temperature faults ("Fehler-Flags" bits 2 and 3) -------------------------------


def test_voltage_fault_blocks_a_new_motion_until_cleared():
    twin = network()
    twin.actuators[0].voltage_fault = True
    now = run(twin, go(100.0), 1.0)
    assert twin.actuators[0].position_mm == 0.0 and twin.actuators[0].errors & 0x04
    twin.actuators[0].voltage_fault = False
    run(twin, go(100.0), 1.0, now)
    assert twin.actuators[0].position_mm > 5.0 and not twin.actuators[0].errors & 0x04


def test_temperature_fault_lets_a_running_motion_go_on_for_10_s_only():
    twin = network(("HD24", "B026", 300), ("HD24", "B026", 300))
    control = go(300.0, speed=6.0)  # slow: 50 s for the whole stroke
    now = run(twin, control, 1.0)
    twin.actuators[1].temperature_fault = True  # one device suffices
    now = run(twin, control, 9.5, now)
    moving_at = twin.actuators[0].position_mm
    assert twin.actuators[0].motion & 1 and twin.actuators[1].errors & 0x08
    now = run(twin, control, 1.0, now)
    assert twin.actuators[0].position_mm - moving_at < 6.0 * 0.6  # stopped at 10 s
    stopped_at = twin.actuators[0].position_mm
    now = run(twin, control, 1.0, now)
    assert twin.actuators[0].position_mm == stopped_at and twin.actuators[0].motion == 0
    now = run(twin, go(20.0, speed=6.0), 1.0, now)  # a new request is not allowed either
    assert twin.actuators[0].position_mm == stopped_at
    twin.actuators[1].temperature_fault = False
    run(twin, go(20.0, speed=6.0), 1.0, now)
    assert twin.actuators[0].position_mm < stopped_at


# -- backdrive ("Rücklauf erkannt") -------------------------------------------------------------


def test_a_load_that_backdrives_a_stopped_actuator_raises_backdrive():
    twin = network()
    now = run(twin, go(100.0, speed=32.0), 5.0)
    assert abs(twin.actuators[0].position_mm - 100.0) < 0.2 and not twin.actuators[0].errors & 0x10
    twin.set_backdrive(-2.0)  # a static load pushes the rod in at 2 mm/s
    now = run(twin, codec.ControlFrame(100.0, 0, 32.0), 1.0, now)
    assert twin.actuators[0].errors & 0x10 and twin.actuators[0].position_mm < 99.5
    twin.set_backdrive(0.0)
    now = run(twin, codec.ControlFrame(100.0, 0, 32.0), 0.5, now)
    assert twin.actuators[0].errors & 0x10  # stays until ...
    run(twin, go(120.0, speed=32.0), 0.5, now)
    assert not twin.actuators[0].errors & 0x10  # ... the next commanded motion (assumption, codec.ERROR_FLAGS)
    assert "Assumption" in codec.ERROR_FLAGS[4][2]


def test_a_commanded_motion_is_no_backdrive():
    twin = network()
    run(twin, go(100.0, speed=32.0), 5.0)
    assert not twin.actuators[0].errors & 0x10


# -- the parameter flag, per model ("Parameterfehler") -------------------------------------------


def test_parameter_flag_per_model_current():
    twin = network(("HD24", "B026", 300), ("HD48", "B026", 300))
    run(twin, go(100.0, speed=20.0, current=10.0), 0.5)  # HD24 allows 12.5 A, HD48 6.5 A
    assert not twin.actuators[0].errors & 0x01 and twin.actuators[1].errors & 0x01
    assert all(a.position_mm == 0.0 for a in twin.actuators)  # one flag stops every device


def test_parameter_flag_per_gearing_speed():
    twin = network(("HD24", "B017", 300), ("HD24", "B026", 300))
    run(twin, go(100.0, speed=40.0), 0.5)  # B017 allows 11-58 mm/s, B026 6-32 mm/s
    assert not twin.actuators[0].errors & 0x01 and twin.actuators[1].errors & 0x01


def test_parameter_flag_per_stroke():
    twin = network(("HD24", "B026", 300), ("HD24", "B026", 150))
    run(twin, go(200.0), 0.5)
    assert not twin.actuators[0].errors & 0x01 and twin.actuators[1].errors & 0x01


# -- Saturated ------------------------------------------------------------------------------------


def test_saturated_when_the_load_limits_the_speed():
    twin = network()
    now = run(twin, go(250.0, speed=32.0), 1.0)
    assert not twin.actuators[0].motion & 0x04
    twin.set_load(6.0)
    run(twin, go(250.0, speed=32.0), 1.0, now)
    a = twin.actuators[0]
    assert a.motion & 0x04 and a.speed_mm_s < 32.0


# -- service answers per actuator ------------------------------------------------------------------


def test_every_actuator_answers_for_itself():
    twin = network(("HD24", "B026", 300), ("HD24", "B026", 300), ("HD24", "B026", 300))
    unlock = codec.password_request(password_of(PARAMS.by_name["Soft start time"]))
    assert [m.type for m in twin.on_service(unlock)] == [codec.ServiceType.WRITE_CONFIRMATION] * 3
    twin.actuators[2].service.values[0x01] = 777
    twin.actuators[1].service_silent = True
    answers = twin.on_service(codec.read_request(0x01, 2))
    assert [m.value for m in answers] == [300, 777]


def test_save_lengths_and_the_bitrate_at_power_up():
    twin = network()
    a = twin.actuators[0]
    assert twin.on_service(codec.save_request(1))[0].error_code == codec.ERROR_WRONG_SIZE  # strict: the table's length
    assert twin.on_service(codec.save_request(4))[0].type == codec.ServiceType.WRITE_CONFIRMATION
    assert twin.on_service(codec.ServiceMessage(0x02, codec.SAVE_SPECIFIER, 1, 0))[0].error_code == codec.ERROR_WRONG_ID
    twin.on_service(codec.password_request(password_of(PARAMS.by_name["Bit rate"])))
    twin.on_service(codec.write_request(0x04, 1, 3))
    assert a.bitrate == 500_000 and twin.on_service(codec.read_request(0x04, 1))[0].value == 3
    twin.power_cycle()
    assert a.bitrate == 500_000  # not saved: lost
    twin.on_service(codec.password_request(password_of(PARAMS.by_name["Bit rate"])))
    twin.on_service(codec.write_request(0x04, 1, 3))
    twin.on_service(codec.save_request(4))
    twin.power_cycle()
    assert a.bitrate == 250_000 and twin.present == []  # it left the 500 kbit/s bus


def test_a_timeout_below_the_control_period_keeps_the_flag_set():
    twin = network()
    twin.actuators[0].service.values[0x06] = 50
    run(twin, go(100.0), 1.0)
    assert twin.actuators[0].errors & 0x20 and twin.actuators[0].position_mm < 1.0
