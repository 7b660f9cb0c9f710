"""Plant-file loader: the shipped plants load; mistakes are named with file and line."""

import pytest

from app.plant import DEMO_PLANT, PLANTS_DIR, PlantError, load_plant, parse_plant

BUS = '[[bus]]\nname = "line1"\ntype = "modbus-rtu"\nport = "socket://127.0.0.1:5020"\n'


def device(name="door-1", address=1, bus="line1", dtype="hdlock"):
    return f'[[device]]\nname = "{name}"\ntype = "{dtype}"\nbus = "{bus}"\naddress = {address}\n'


def test_shipped_plants_load():
    demo = load_plant(DEMO_PLANT)
    assert demo.buses["line1"].simulated
    assert {d.type for d in demo.devices.values()} == {"hdlock", "electrak", "m3io", "scu", "mo64"}
    assert demo.sim_devices["spare-lock"].bus == "can1"
    example = load_plant(PLANTS_DIR / "example.toml")
    assert example.buses["rs485-doors"].options["port"] == "/dev/ttyUSB0"
    assert not example.buses["rs485-doors"].simulated


def test_defaults_filled_in():
    plant = parse_plant(BUS + device())
    options = plant.buses["line1"].options
    assert options["baudrate"] == 19200 and options["parity"] == "E" and options["timeout"] == 0.5


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        (BUS + device(bus="line9"), 8, "unknown bus 'line9'"),
        (BUS + device() + device(), 10, "duplicate device name 'door-1'"),
        (BUS + device(address=300), 9, "address 300 is outside 1..254"),
        (BUS + device(dtype="toaster"), 7, "unknown type 'toaster'"),
        (BUS + device("a", 1) + device("b", 1), 10, "address 1 is already used by 'a'"),
        (BUS.replace('"modbus-rtu"', '"fieldbus"'), 3, "unknown type 'fieldbus'"),
        (BUS + 'baudrate = "fast"\n', 5, "'baudrate' has the wrong type"),
        (BUS + "colour = 3\n", 5, "unknown key 'colour'"),
        (BUS + BUS, 5, "duplicate bus name 'line1'"),
    ],
)
def test_errors_name_line_and_problem(text, line, words):
    with pytest.raises(PlantError) as err:
        parse_plant(text, None)
    assert f"<plant>:{line}:" in str(err.value)
    assert words in str(err.value)


def test_not_toml():
    with pytest.raises(PlantError, match="not valid TOML"):
        parse_plant("[[bus]\nname=")


def test_missing_file(tmp_path):
    with pytest.raises(PlantError, match="cannot read the plant file"):
        load_plant(tmp_path / "nope.toml")
