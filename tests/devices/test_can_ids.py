"""CAN IDs each device type sends and receives, and the plant loader refusing overlaps on one bus.

Golden checks (issue 10, item 15): an HD-Lock with device ID 11 uses 0x0B, the Electrak service
answer; an M3IO with SW1 0x85 puts MData on 0x705 inside the HD-Lock request block and Sync on
0x685 inside the Electrak internal range 0x600-0x6FF.
"""

from __future__ import annotations

import itertools

import pytest
from plants import ELECTRAK_ACTUATORS, can_bus, device, table

from app.plant import DEMO_PLANT, PLANTS_DIR, PlantError, load_plant, parse_plant
from devices.registry import DEVICE_TYPES

_channels = itertools.count()


def bus(name: str = "can1") -> str:
    """A CAN bus without its devices (five lines: the refusals name the line of a device)."""
    return can_bus(name=name, channel_name=f"ids-{name}-{next(_channels)}", simulate=None)


def electrak(name: str = "lift", bus_name: str = "can1") -> str:
    return device(name, "electrak", bus_name, actuators=list(ELECTRAK_ACTUATORS[:1]))


def lock(name: str = "gate", device_id: int = 11, bus_name: str = "can1", kind: str = "device") -> str:
    return table(kind, name=name, type="hdlock", bus=bus_name, device_id=device_id)


def m3io(name: str = "io", sw1: int = 0x85, bus_name: str = "can1") -> str:
    return device(name, "m3io", bus_name, variant="HM", sw1=sw1)


def uses(type_name: str, **options) -> tuple:
    return DEVICE_TYPES[type_name].can_id_uses(options, "can")


def ids_of(found) -> set[int]:
    return {i for use in found for i in range(use.first, use.last + 1)}


# -- what each device type declares ---------------------------------------------------------------


def test_electrak_declares_its_fixed_ids_and_internal_range():
    found = uses("electrak", actuators=[])
    assert ids_of(found) == {0x06, 0x07, 0x0A, 0x0B} | set(range(0x600, 0x700))
    words = {use.first: use.use for use in found}
    assert "control" in words[0x06] and "status" in words[0x07]
    assert "service request" in words[0x0A] and "service answer" in words[0x0B]
    assert "internal" in words[0x600]
    assert all(not use.extended for use in found)


def test_hdlock_declares_its_request_block_and_its_own_id():
    standard = uses("hdlock", device_id=11)
    assert ids_of([u for u in standard if u.shared]) == set(range(0x700, 0x708))
    own = [u for u in standard if not u.shared]
    assert [(u.first, u.extended, u.sender) for u in own] == [(0x0B, False, "device")]
    assert "device ID 11" in own[0].use
    words = {u.first: u.use for u in standard}
    assert words[0x705].startswith("Silent Write Holding-Register")
    factory = [u for u in uses("hdlock", device_id=660100) if not u.shared]  # serial number: extended
    assert [(u.first, u.extended) for u in factory] == [(660100, True)]
    forced = [u for u in uses("hdlock", device_id=335, extended=True) if not u.shared]
    assert [(u.first, u.extended) for u in forced] == [(335, True)]
    assert DEVICE_TYPES["hdlock"].can_id_uses({"address": 1}, "modbus-rtu") == ()


@pytest.mark.parametrize(
    ("sw1", "expected"),
    [
        # section 5.8.1: 0x3A0 + 5 * SW1; the document's example SW1 0x1A -> DigOut 0x422
        (0x1A, {"DigOut": 0x422, "DigIn": 0x423, "Temp1-4": 0x424, "Temp5-6": 0x425, "Sync": 0x426}),
        # section 5.8.2: S7 on, address 0x0A; the document's example SW1 0xCA -> DigOut 0x20A
        (0xCA, {"DigOut": 0x20A, "DigIn": 0x18A, "Temp1-4": 0x38A, "Temp5-6": 0x48A, "Sync": 0x24A, "MData": 0x1CA}),
        # S7 off, address 5: the SW1 0x85
        (0x85, {"DigOut": 0x185, "DigIn": 0x205, "Temp1-4": 0x385, "Temp5-6": 0x405, "Sync": 0x685, "MData": 0x705}),
    ],
)
def test_m3io_declares_the_ids_of_its_switch(sw1, expected):
    found = uses("m3io", variant="HM", sw1=sw1)
    assert {u.use.split()[1]: u.first for u in found} == expected
    senders = {u.use.split()[1]: u.sender for u in found}
    assert senders["DigOut"] == senders["Sync"] == "master" and senders["DigIn"] == "device"


def test_id_formatting():
    from devices.registry import format_can_ids

    assert format_can_ids(0x0B, 0x0B, False) == "0x0B"
    assert format_can_ids(0x600, 0x6FF, False) == "0x600-0x6FF"
    assert format_can_ids(660100, 660100, True) == "0x000A1284 (ext)"


# -- the loader refuses overlaps, naming both devices, the ID and its use in each ---------------------


def refused(text: str) -> str:
    with pytest.raises(PlantError) as err:
        parse_plant(text)
    return str(err.value)


def test_lock_with_device_id_11_collides_with_the_electrak_service_answer():
    message = refused(bus() + electrak() + lock(device_id=11))
    assert "'gate'" in message and "'lift'" in message
    assert "0x0B" in message
    assert "HD-Lock device ID 11" in message and "Electrak service answer" in message
    assert message.startswith("<plant>:11:")  # the line of the later device


def test_m3io_sw1_0x85_mdata_inside_the_hdlock_request_block():
    message = refused(bus() + lock(device_id=1) + m3io(sw1=0x85))
    assert "'io'" in message and "'gate'" in message
    assert "0x705" in message and "MData" in message and "Silent Write Holding-Register" in message


def test_m3io_sw1_0x85_sync_inside_the_electrak_internal_range():
    message = refused(bus() + electrak() + m3io(sw1=0x85))
    assert "'io'" in message and "'lift'" in message
    assert "0x685" in message and "Sync" in message and "Electrak internal traffic" in message


def test_order_in_the_file_does_not_matter():
    message = refused(bus() + m3io(sw1=0x85) + electrak())
    assert "0x685" in message and "'io'" in message and "'lift'" in message


def test_two_m3io_modules_on_one_id():
    """S7 on, address 1: DigIn 0x181, DigOut 0x201; S7 off, address 1: DigOut 0x181, DigIn 0x201 (section 5.8.2)."""
    message = refused(bus() + m3io("io-a", 0xC1) + m3io("io-b", 0x81))
    assert "0x181" in message and "'io-a'" in message and "'io-b'" in message
    assert "DigOut" in message and "DigIn" in message


def test_lock_id_inside_its_own_request_block():
    message = refused(bus() + lock(device_id=0x703))
    assert "0x703" in message and "Read Holding-Register" in message and "HD-Lock device ID 1795" in message


def test_simulated_devices_on_the_bus_count_too():
    message = refused(bus() + electrak() + lock("spare", 11, kind="sim_device"))
    assert "'spare'" in message and "0x0B" in message


def test_what_may_share_a_bus_loads():
    # locks share the request block; an extended ID never collides with a standard one
    parse_plant(bus() + lock("a", 1) + lock("b", 2) + lock("c", 660000))
    parse_plant(bus() + electrak() + lock(device_id=660100) + m3io(sw1=0x1A))  # M3IO on 0x422-0x426
    # the same IDs on two buses are no overlap
    parse_plant(bus("can1") + bus("can2") + electrak(bus_name="can1") + lock(device_id=11, bus_name="can2"))
    load_plant(DEMO_PLANT)
    load_plant(PLANTS_DIR / "example.toml")
