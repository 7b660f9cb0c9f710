"""The HD-Lock's send rules whatever the path (issue 40 item 3): a raw register write (Modbus poll window,
transmit list, replay, restore) is judged as the declared parameter write it amounts to, on the value as
the lock stores it; what a lock sends is never sent by this tool.

Properties (hypothesis, every holding register of the map and every 16-bit value):

- the raw write's verdict (Modbus 06, CAN 0x704/0x705, cmdSetLockRequestSource for holding 4) equals the
  declared parameter write's verdict on the value as the lock stores it (the low byte of LockRequestSource,
  section 6.6.1.1): refused alike, and asking the same confirmation;
- nothing the send policy forbids is allowed from any path: a frame under a lock's device ID (its status,
  its answers, section 6.5), firmware-update requests and commands, never-written registers.
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from devices.commands import WRITE_PARAMETER, CommandError, commands_of
from devices.hdlock import codec
from devices.hdlock.params import DOOR_IGNORED_WARNING, PARAMS
from devices.sendpolicy import BusDevice, ModbusMessage, check_can, check_modbus

LOCK = BusDevice("door-1", "hdlock", {"device_id": 335, "extended": True})
LOCK_STD = BusDevice("door-2", "hdlock", {"device_id": 11, "extended": False})
CAN_BUS = [LOCK, LOCK_STD]
LINE = [BusDevice("door-1", "hdlock", {"address": 1})]
TARGET = codec.DeviceId.make(335, True)
HOLDING = sorted({p.address for p in PARAMS.space("holding")} | {a for p in PARAMS.space("holding") for a in p.addresses})
SETTINGS = settings(derandomize=True, max_examples=300, deadline=None)


def declared(address: int, stored: int) -> tuple[bool, str]:
    """The declared parameter write (page, API, restore) of the value the lock stores: (refused, question)."""
    param = PARAMS.get("holding", address)
    if param is None:
        return True, ""
    command = commands_of("hdlock")[WRITE_PARAMETER]
    try:
        values = command.checked_args({"param": param, "value": param.decode(stored)})
    except CommandError:
        return True, ""
    if command.refuse_if(values, LINE, "door-1"):
        return True, ""
    return False, command.risk_text(values)


def modbus_raw(address: int, word: int) -> tuple[bool, str]:
    verdict = check_modbus(LINE, ModbusMessage(1, 6, address, (word,)))
    return not verdict.allowed, verdict.question


def can_raw(address: int, word: int, silent: bool = False) -> tuple[bool, str]:
    data = (TARGET.to_u32().to_bytes(4, "little") + address.to_bytes(2, "little") + word.to_bytes(2, "little"))
    verdict = check_can(CAN_BUS, codec.CAN_SILENT_WRITE_HOLDING if silent else codec.CAN_WRITE_HOLDING, False, data)
    return not verdict.allowed, verdict.question


def source_command(word: int) -> tuple[bool, str]:
    """cmdSetLockRequestSource (0x700, section 6.6.1.1) with the 16-bit value in bytes 6-7: a write of holding 4."""
    data = TARGET.to_u32().to_bytes(4, "little") + bytes([codec.CanCommand.SET_LOCK_REQUEST_SOURCE, 0]) + word.to_bytes(2, "little")
    verdict = check_can(CAN_BUS, codec.CAN_COMMAND, False, data)
    return not verdict.allowed, verdict.question


# -- the defects, each as it was found ----------------------------------------------------------------------


@pytest.mark.parametrize("word", [0x0181, 0x8085, 0xFF80])
def test_door_ignored_source_with_a_high_byte_asks_its_confirmation(word):
    """Bytes 81 01: the lock keeps the low byte 0x81 (door ignored); the whole word 0x0181 is no 0x80-0x87."""
    for refused, question in (source_command(word), can_raw(1002, word), can_raw(4, word), modbus_raw(1002, word),
                              modbus_raw(4, word)):
        assert not refused and DOOR_IGNORED_WARNING in question


@pytest.mark.parametrize(("address", "word"), [(3001, 9), (3002, 11), (1002, 0x50), (4, 0x50), (3005, 2), (3003, 2)])
def test_raw_register_writes_check_the_value_table(address, word):
    """Raw writes skipped the value table (3001 = 9 and 1002 = 0x50 were sent): refused like the declared write."""
    assert declared(address, word)[0]
    assert modbus_raw(address, word)[0], "Modbus poll window"
    assert can_raw(address, word)[0], "CAN transmit list / replay"
    assert can_raw(address, word, silent=True)[0], "CAN silent write"
    verdict = check_modbus(LINE, ModbusMessage(1, 16, address, (word,)))
    assert verdict.refused and "not one of" in verdict.refused, verdict


def test_set_lock_request_source_outside_the_table_is_refused():
    assert source_command(0x50)[0] and source_command(0x08)[0]
    assert not source_command(0x04)[0] and source_command(0x04)[1] == ""


@pytest.mark.parametrize("data", ["00 00 17 01 73 00 C4 00",  # status (section 6.5.1)
                                  "01 01 EA 03 04 00",  # holding-register answer (6.5.4)
                                  "01 00 01 00 00 00"])  # FWU status (6.5.2)
@pytest.mark.parametrize(("device_id", "extended"), [(335, True), (11, False)])
def test_frames_a_lock_sends_are_never_sent(data, device_id, extended):
    """Replay and the transmit list impersonated locks: a frame under a lock's device ID is the lock's own."""
    verdict = check_can(CAN_BUS, device_id, extended, bytes.fromhex(data))
    assert verdict.refused and "sends" in verdict.refused, verdict
    other = check_can(CAN_BUS, 0x123, False, bytes.fromhex(data))
    assert other.allowed


# -- properties: one rule whatever the path ---------------------------------------------------------------------


@SETTINGS
@given(address=st.sampled_from(HOLDING), word=st.integers(0, 0xFFFF))
def test_raw_write_verdict_equals_the_declared_write_on_the_stored_value(address, word):
    expected = declared(address, codec.stored_value(address, word))
    assert modbus_raw(address, word) == expected
    assert can_raw(address, word) == expected
    assert can_raw(address, word, silent=True) == expected


@SETTINGS
@given(word=st.integers(0, 0xFFFF))
def test_set_lock_request_source_is_judged_as_the_write_of_holding_4(word):
    assert source_command(word) == declared(codec.REG_LOCK_REQUEST_SOURCE, codec.stored_value(codec.REG_LOCK_REQUEST_SOURCE, word))


@SETTINGS
@given(address=st.integers(0, 0xFFFF).filter(lambda a: PARAMS.get("holding", a) is None), word=st.integers(0, 0xFFFF))
def test_registers_outside_the_map_are_never_written(address, word):
    assert modbus_raw(address, word)[0] and can_raw(address, word)[0]


@SETTINGS
@given(can_id=st.sampled_from(sorted(codec.CAN_REQUEST_IDS)), data=st.binary(min_size=0, max_size=8))
def test_nothing_the_policy_forbids_is_allowed_from_any_path(can_id, data):
    verdict = check_can(CAN_BUS, can_id, False, data)
    if can_id in (codec.CAN_FWU_ERASE, codec.CAN_FWU_WRITE):
        assert verdict.refused
    if can_id == codec.CAN_COMMAND and len(data) >= 5 and data[4] in (2, 3, 4):
        assert verdict.refused
    if can_id in (codec.CAN_WRITE_HOLDING, codec.CAN_SILENT_WRITE_HOLDING) and len(data) >= 8:
        address, word = int.from_bytes(data[4:6], "little"), int.from_bytes(data[6:8], "little")
        refused, question = declared(address, codec.stored_value(address, word))
        assert (not verdict.allowed) == refused
        if not refused:
            assert question in verdict.question
    if verdict.allowed and can_id == codec.CAN_COMMAND and len(data) >= 5 and data[4] == 0:
        word = int.from_bytes(data[6:8], "little") if len(data) >= 8 else 0
        assert codec.stored_value(4, word) in PARAMS.get("holding", 4).enum


@SETTINGS
@given(device=st.sampled_from(CAN_BUS), data=st.binary(min_size=0, max_size=8))
def test_no_frame_under_a_locks_device_id_is_allowed(device, data):
    ident = codec.DeviceId.make(device.options["device_id"], device.options["extended"])
    assert check_can(CAN_BUS, ident.value, ident.extended, data).refused


SAFETY_PROPERTIES = {"hdlock": [test_raw_write_verdict_equals_the_declared_write_on_the_stored_value,
                                test_set_lock_request_source_is_judged_as_the_write_of_holding_4,
                                test_registers_outside_the_map_are_never_written,
                                test_nothing_the_policy_forbids_is_allowed_from_any_path,
                                test_no_frame_under_a_locks_device_id_is_allowed]}


# -- Set Device Address (section 6.6.2) over the twins ---------------------------------------------------------

@pytest.fixture
async def can_locks():
    """Two locks of the plant (gate-1 660100, gate-2 11) and a spare heard on the bus but not in the plant (660102)."""
    from conftest import running_plant
    from test_hdlock_can import can_plant, online

    from app.plant import parse_plant

    async with running_plant(parse_plant(can_plant())) as runtime:
        await online(runtime, "gate-2")
        yield runtime


async def test_set_device_address_refuses_an_id_heard_on_the_bus(can_locks):
    """Issue 40: the spare lock's ID (on the bus, not in the plant) was accepted; afterwards two locks had it."""
    from devices.hdlock.adapter import CommandError

    adapter, twins = can_locks.worker.adapters["gate-2"], can_locks.twins
    spare = codec.DeviceId.make(660102, True)
    with pytest.raises(CommandError, match="heard on the bus"):
        await adapter.set_device_address(spare.value, True)
    assert twins["gate-2"].device_id == codec.DeviceId(11, False) and adapter.device_id == codec.DeviceId(11, False)
    assert [t.name for t in twins.values() if t.device_id == spare] == ["spare"]


async def test_set_device_address_counts_only_the_same_lock_as_success(can_locks):
    """A status frame under the new ID from another lock is no proof: the serial number must be this lock's."""
    from devices.hdlock.adapter import CommandError

    adapter, twins = can_locks.worker.adapters["gate-2"], can_locks.twins
    twins["gate-2"].keeps_device_id = True  # fault injection: the lock does not take the new ID
    twins["spare"].silent = True  # not heard while this tool listens on the new ID...
    send = adapter._send

    def send_then_spare_talks(frame):
        send(frame)
        if frame.arbitration_id == codec.CAN_SET_DEVICE_ADDRESS:
            twins["spare"].silent = False  # ...and answering under it right after the command
    adapter._send = send_then_spare_talks
    with pytest.raises(CommandError, match="serial"):
        await adapter.set_device_address(660102, True)
    assert adapter.device_id == codec.DeviceId(11, False)
    twins["gate-2"].keeps_device_id = False
    twins["spare"].device_id = codec.DeviceId.make(660105, True)
    assert await adapter.set_device_address(12) is True
    assert twins["gate-2"].device_id == adapter.device_id == codec.DeviceId(12, False)
