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


def _assert_refused(text: str, line: int, words: str) -> None:
    """``text`` is refused with an error that names its ``line`` and says ``words``."""
    with pytest.raises(PlantError) as err:
        parse_plant(text, None)
    assert f"<plant>:{line}:" in str(err.value)
    assert words in str(err.value)


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        (BUS + device(bus="line9"), 8, "unknown bus 'line9'"),
        (BUS + device() + device(), 10, "duplicate device name 'door-1'"),
        (BUS + device(address=300), 9, "address 300 is outside 1..254"),
        (BUS + device(dtype="toaster"), 7, "unknown type 'toaster'"),
        (BUS + device("a", 1) + device("b", 1), 10, "address 1 is already used by 'a'"),
        (BUS.replace('"modbus-rtu"', '"fieldbus"'), 3, "unknown type 'fieldbus'"),
        (BUS + 'baudrate = "fast"\n', 5, "baudrate must be a whole number (without quotes), not 'fast'"),
        (BUS + "colour = 3\n", 5, "unknown key 'colour'"),
        (BUS + BUS, 5, "duplicate bus name 'line1'"),
    ],
)
def test_errors_name_line_and_problem(text, line, words):
    _assert_refused(text, line, words)


def test_not_toml():
    with pytest.raises(PlantError, match="not valid TOML"):
        parse_plant("[[bus]\nname=")


def test_missing_file(tmp_path):
    with pytest.raises(PlantError, match="cannot read the plant file"):
        load_plant(tmp_path / "nope.toml")


CAN = '[[bus]]\nname = "can1"\ntype = "can"\ninterface = "virtual"\nchannel = "c1"\n'


@pytest.mark.parametrize(
    ("text", "line", "words"),
    [
        # item 3: every key checked, values in range
        (CAN + "bitrat = 250000\n", 6, "unknown key 'bitrat'; did you mean 'bitrate'"),
        (CAN + "poll_perod = 1\n", 6, "did you mean 'poll_period'"),
        (CAN + "simualte = true\n", 6, "did you mean 'simulate'"),
        (BUS + "poll_period = -1\n", 5, "poll_period must be a number of seconds above 0"),
        (BUS + "poll_period = nan\n", 5, "poll_period must be a number of seconds above 0"),
        (BUS + "timeout = nan\n", 5, "timeout must be a number of seconds above 0"),
        (BUS + "timeout = inf\n", 5, "timeout must be a number of seconds above 0"),
        (BUS + "retries = -1\n", 5, "retries -1 is outside 0..10"),
        (BUS + "baudrate = 0\n", 5, "baudrate 0 is not one of"),
        (BUS + "stopbits = 7\n", 5, "stopbits must be 1 or 2"),
        (BUS + "bytesize = 12\n", 5, "bytesize must be 7 or 8"),
        (BUS + 'simulate = "yes"\n', 5, "simulate must be true or false (without quotes)"),
        (CAN + "poll_period = nan\n", 6, "poll_period must be a number of seconds above 0"),
        (CAN + '[bus.can_options]\nbitrate = 500000\n', 7, "bitrate belongs in the [[bus]] table"),
        ('[[bus]]\nname = "t"\ntype = "logited-tcp"\nhost = "h"\nport = 70000\n', 5, "port 70000 is outside 1..65535"),
        # item 4: single brackets, wrong types, misspelt keys, unknown sections at their line
        ('name = "x"\n\n[bus]\nname = "l"\ntype = "modbus-rtu"\n', 3, "write [[bus]] (double brackets)"),
        (BUS + '\n[device]\nname = "d"\n', 6, "write [[device]] (double brackets)"),
        ("plant_view = 1\n", 1, "[plant_view] must be a table"),
        (BUS + "\n[[devices]]\nname = 'd'\n", 6, "unknown section [[devices]]; did you mean [[device]]"),
        (BUS + device().replace("address = 1", "adress = 1"), 9, "unknown key 'adress'; did you mean 'address'"),
        (BUS + device().replace("address = 1", 'address = "1"'), 9, "address must be a number"),
        # item 5: a simulated line needs an endpoint the twins can serve
        (BUS.replace("socket://127.0.0.1:5020", "/dev/ttyUSB0") + "simulate = true\n", 5, "simulate = true needs"),
        (CAN.replace('"virtual"', '"socketcan"') + "simulate = true\n", 6, "simulate = true needs"),
        # item 2: two udp_multicast buses on one port hear each other
        (CAN.replace('"virtual"', '"udp_multicast"').replace('"c1"', '"239.74.163.2"') + "port = 43200\n"
         + CAN.replace('"virtual"', '"udp_multicast"').replace('"c1"', '"239.74.163.3"').replace('"can1"', '"can2"') + "port = 43200\n",
         12, "port 43200 is already used by bus 'can1'"),
    ],
)
def test_every_mistake_names_its_line_and_the_fix(text, line, words):
    _assert_refused(text, line, words)


def test_can_options_reach_python_can_and_common_keys_stay_checked():
    plant = parse_plant(CAN + "bitrate = 500000\n[bus.can_options]\nreceive_own_messages = false\n")
    options = plant.buses["can1"].options
    assert options["receive_own_messages"] is False and options["bitrate"] == 500000


def test_simulated_udp_multicast_buses_get_their_own_ports():
    text = "".join(
        CAN.replace('"virtual"', '"udp_multicast"').replace('"c1"', f'"239.74.163.{i}"').replace('"can1"', f'"can{i}"')
        + "simulate = true\n" for i in (2, 3, 4)
    )
    plant = parse_plant(text)
    ports = [bus.options["port"] for bus in plant.buses.values()]
    assert len(set(ports)) == 3 and all(1024 < p < 65536 and p != 43113 for p in ports)
    assert [b.options["port"] for b in parse_plant(text).buses.values()] == ports  # the same in the sim and the GUI process


def test_shipped_plants_pass_every_check():
    for path in PLANTS_DIR.glob("*.toml"):
        load_plant(path)
