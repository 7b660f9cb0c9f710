"""HD-Lock over CAN: codec golden vectors (section 6) and the adapter against twins on a virtual bus."""

from __future__ import annotations

import asyncio

import can
import pytest
import plants
from conftest import free_udp_port, running_plant, sim_process, wait_for
from plants import bus, hdlock_can, plant_text, table

from app.plant import DeviceConfig, parse_plant
from app.runtime import Runtime
from devices.hdlock import codec
from devices.hdlock.adapter import P_FWU, P_STATUS_FRAME, CommandError
from devices.hdlock.params import PARAMS

# -- codec -------------------------------------------------------------------------------------


def test_set_lock_request_source_example():
    """Section 6.6.1.1: 0x700 4F 01 00 80 00 00 81 00 = extended device 335, IrsAlways."""
    frame = codec.encode_can_command(codec.DeviceId.make(335, True), codec.CanCommand.SET_LOCK_REQUEST_SOURCE, 0x81)
    assert (frame.arbitration_id, frame.is_extended_id) == (0x700, False)
    assert frame.data == bytes.fromhex("4F 01 00 80 00 00 81 00")
    req = codec.decode_request(frame)
    assert req.target == codec.DeviceId(335, True) and req.a == 0 and req.b == 0x81
    assert "SET_LOCK_REQUEST_SOURCE value 129" in codec.describe_request(frame)


def test_set_device_address_example():
    """Section 6.6.2: old extended 154 -> new standard 11: 0x701 9A 00 00 80 0B 00 00 00."""
    frame = codec.encode_set_device_address(codec.DeviceId.make(154, True), codec.DeviceId.make(11))
    assert frame.arbitration_id == 0x701
    assert frame.data == bytes.fromhex("9A 00 00 80 0B 00 00 00")
    req = codec.decode_request(frame)
    assert req.new_id == codec.DeviceId(11, False)


@pytest.mark.parametrize(
    ("value", "extended", "u32"),
    [
        (335, True, 0x8000014F),  # extended below 0x7FF needs the flag
        (11, None, 0x0000000B),  # standard
        (0x800, None, 0x80000800),  # above 0x7FF: extended automatically
        (660020, None, 0x800A1234),  # factory default: the serial number, extended
    ],
)
def test_extended_rule(value, extended, u32):
    device = codec.DeviceId.make(value, extended)
    assert device.to_u32() == u32
    assert codec.DeviceId.from_u32(u32) == device


def test_broadcast_is_standard_zero():
    frame = codec.encode_can_command(codec.BROADCAST_ID, codec.CanCommand.SET_CAN_BAUDRATE, 9)
    assert frame.data == bytes.fromhex("00 00 00 00 01 00 09 00")


def test_status_frame_decoding():
    # status 0x0117, motorPos 115, proximity 3 << 6 + source 4
    data = bytes.fromhex("00 00 17 01 73 00 C4 00")
    frame = codec.decode_lock_frame(data)
    assert frame == codec.StatusFrame(0x0117, 115, 3, 4)
    assert frame.bits["BoltLocked"] and frame.bits["DoorInPosition"] and not frame.bits["BoltUnlocked"]
    assert codec.encode_status(frame) == data


def test_status_word_with_a_source_that_ignores_the_door():
    """26.8: the lock sends (proximity << 6) + LockRequestSource; 0x80-0x87 carry 0x80 = 2 << 6 into the
    proximity bits. ForceActive (status bit 7) is set exactly for those sources: 0x80 is taken off (SPEC-NOTES)."""
    word = (100 << 6) + 0x81
    data = bytes([0, 0]) + (0x0117 | codec.FORCE_ACTIVE).to_bytes(2, "little") + (115).to_bytes(2, "little") + word.to_bytes(2, "little")
    frame = codec.decode_lock_frame(data)
    assert (frame.proximity, frame.lock_request_source) == (100, 0x81)
    assert codec.encode_status(frame) == data
    plain = codec.decode_lock_frame(codec.encode_status(codec.StatusFrame(0x0117, 115, 100, 0x04)))
    assert (plain.proximity, plain.lock_request_source) == (100, 0x04)


@pytest.mark.parametrize("command", [2, 3, 4])
def test_five_byte_firmware_update_commands_are_named_not_malformed(command):
    """Section 6.6.1: cmdFirmwareUpdateEnter, cmdBootloaderUpdateEnter and cmdUpdateLeave are 5 bytes long."""
    frame = codec.CanFrame(codec.CAN_COMMAND, bytes([0x0B, 0, 0, 0, command]))
    request = codec.decode_request(frame)
    assert (request.kind, request.a, request.target.value) == (codec.CAN_COMMAND, command, 11)
    text = codec.describe_request(frame)
    assert codec.CanCommand(command).name in text and "malformed" not in text and "never sent" in text
    from devices.sendpolicy import check_can

    verdict = check_can([], codec.CAN_COMMAND, False, frame.data)
    assert verdict.refused and codec.CanCommand(command).name in verdict.refused


def test_register_answers():
    assert codec.decode_lock_frame(bytes.fromhex("00 01 68 00 0A 00")) == codec.RegisterAnswer("input", 104, 10)
    assert codec.decode_lock_frame(bytes.fromhex("01 01 BC 0B E2 FF")) == codec.RegisterAnswer("holding", 3004, 65506)
    answer = codec.RegisterAnswer("holding", 1002, 0x81)
    assert codec.decode_lock_frame(codec.encode_register_answer(answer)) == answer


def test_fwu_status():
    frame = codec.decode_lock_frame(bytes.fromhex("01 00 01 00 00 00"))
    assert frame == codec.FwuStatusFrame(flashing=True, application=False)
    assert "boot loader" in codec.describe_lock_frame(bytes.fromhex("01 00 01 00 00 00"))


@pytest.mark.parametrize("data", ["00", "00 00 01 02", "00 01 02", "07 07 00 00 00 00"])
def test_malformed_lock_frames(data):
    with pytest.raises(codec.CodecError):
        codec.decode_lock_frame(bytes.fromhex(data))


def test_firmware_update_is_never_encoded():
    for command in (codec.CanCommand.FIRMWARE_UPDATE_ENTER, codec.CanCommand.BOOTLOADER_UPDATE_ENTER, codec.CanCommand.UPDATE_LEAVE):
        with pytest.raises(codec.CodecError):
            codec.encode_can_command(codec.DeviceId.make(1), command, 0)
    with pytest.raises(codec.CodecError):
        codec.encode_write(codec.DeviceId.make(1), 32770, 1)
    with pytest.raises(codec.CodecError):
        codec.encode_can_command(codec.DeviceId.make(1), codec.CanCommand.SET_CAN_BAUDRATE, 12)


def test_read_and_write_requests():
    target = codec.DeviceId.make(11)
    assert codec.encode_read(target, "input", 50, 14).data == bytes.fromhex("0B 00 00 00 32 00 0E 00")
    assert codec.encode_read(target, "holding", 1000, 11).arbitration_id == 0x703
    write = codec.encode_write(target, 3004, 65506)
    assert (write.arbitration_id, write.data) == (0x704, bytes.fromhex("0B 00 00 00 BC 0B E2 FF"))
    assert codec.encode_write(target, 3000, 200, silent=True).arbitration_id == 0x705


def test_monitor_descriptions():
    locks = {(True, 660100)}
    assert codec.describe_frame(0x703, False, codec.encode_read(codec.DeviceId.make(11), "holding", 1000, 11).data, locks).startswith(
        "HD-Lock Read Holding-Register -> lock 11"
    )
    assert "Status 0x0117" in codec.describe_frame(660100, True, bytes.fromhex("00 00 17 01 73 00 C4 00"), locks)
    assert codec.describe_frame(0x123, False, b"\x00", locks) is None


# -- adapter against the twins on a virtual bus ---------------------------------------------------


def can_plant(interface: str = "virtual", channel: str | None = None, **bus_options) -> str:
    """Two locks (device IDs 660100 and 11) and a simulated spare (660102) on one CAN bus."""
    locks = (hdlock_can("gate-1", 660100), hdlock_can("gate-2", 11, serial=660101),
             table("sim_device", name="spare", type="hdlock", bus="can1", device_id=660102))
    return plant_text(bus("can1", "can", *locks, interface=interface, channel=channel or plants.channel("test-can"),
                          bitrate=250000, poll_period=0.5, timeout=0.3, simulate=True, **bus_options), name=None)


@pytest.fixture
async def running():
    async with running_plant(parse_plant(can_plant())) as runtime:
        yield runtime


async def online(runtime, name="gate-1"):
    state = runtime.store.devices[name]
    assert await wait_for(
        lambda: state.status == "online" and None not in (state.value("SerialNumber"), state.value("SettingsProximityOffsetRight")),
        timeout=6,
    )
    return state


async def test_status_and_registers_over_can(running):
    state = await online(running)
    assert state.value("SerialNumber") == 660100
    assert state.live(P_STATUS_FRAME).value.status == state.value("LockStatus")
    assert state.value("SettingsProximityThresholdUnlock") == -30
    gate2 = await online(running, "gate-2")
    assert gate2.value("SerialNumber") == 660101
    assert state.counters.timeouts == 0 and state.counters.malformed == 0


async def test_door_closing_seen_in_status_frames(running):
    state = await online(running)
    running.twins["gate-1"].close_door()
    assert await wait_for(lambda: state.live(P_STATUS_FRAME).value.bits["BoltLocked"], timeout=6)
    assert state.live(P_STATUS_FRAME).value.motor_pos >= 100
    assert state.live(P_STATUS_FRAME).value.proximity < 30


async def test_unknown_lock_is_discovered_and_adopted(running):
    await online(running)
    assert await wait_for(lambda: (True, 660102) in running.worker.discovered["can1"], timeout=3)
    entry = running.worker.discovered["can1"][(True, 660102)]
    assert entry["type"] == "hdlock" and entry["extended"]
    running.worker.adopt(DeviceConfig("spare", "hdlock", "can1", {"device_id": 660102, "extended": True}))
    assert (True, 660102) not in running.worker.discovered["can1"]
    state = await online(running, "spare")
    assert state.value("SerialNumber") == 660102


async def test_write_with_echo_and_save(running):
    state = await online(running)
    adapter = running.worker.adapters["gate-1"]
    twin = running.twins["gate-1"]
    assert await adapter.write_param(PARAMS.by_name["SettingsProximityThresholdLock"], -55) == 65481
    assert twin.holding[3006] == 65481 and PARAMS.by_name["SettingsProximityThresholdLock"].key in state.unsaved
    await adapter.save_settings()
    assert twin.input[101] == 1 and not state.unsaved


async def test_protected_register_echo_is_reported(running):
    await online(running)
    adapter = running.worker.adapters["gate-1"]
    running.twins["gate-1"].writable.discard(3000)
    with pytest.raises(CommandError, match="refused by the firmware"):
        await adapter.write_param(PARAMS.by_name["LockRequestDelay"], 500)


async def test_set_lock_request_source_command(running):
    """cmdSetLockRequestSource is verified against holding 4, the source the lock uses (section 6.5.1)."""
    state = await online(running)
    adapter = running.worker.adapters["gate-1"]
    twin = running.twins["gate-1"]
    await adapter.set_lock_request_source(0x81)
    assert twin.holding[4] == 0x81
    assert twin.holding[1002] == 4  # its own register: the command does not write it
    assert running.twins["gate-2"].holding[4] == 4  # only the target
    assert state.value("LockRequestSource (HR4)") == 0x81
    assert PARAMS.get("holding", 4).key in state.unsaved  # volatile until Save-Settings (section 3)
    # the status frame reports holding 4 (0x80 taken off the proximity with ForceActive, SPEC-NOTES), and the bolt follows it
    twin.set_line_input(False)  # IrsAlways does not need the input, nor the door (0x80)
    assert await wait_for(lambda: state.live(P_STATUS_FRAME).value.lock_request_source == 0x81, timeout=3)
    assert state.live(P_STATUS_FRAME).value.proximity == twin.input[7]
    assert await wait_for(lambda: state.live(P_STATUS_FRAME).value.bits["BoltLocked"], timeout=4)


async def test_set_lock_request_source_refused_is_reported(running):
    """A lock that keeps its source (holding 4) makes the command fail, even if 1002 holds the value."""
    await online(running)
    adapter = running.worker.adapters["gate-1"]
    twin = running.twins["gate-1"]
    twin.holding[1002] = 0x81  # 1002 already says 0x81 ...
    twin.writable.discard(4)  # ... but this lock does not take the command
    with pytest.raises(CommandError, match="reads 0x04 after the command, not 0x81"):
        await adapter.set_lock_request_source(0x81)
    assert twin.holding[4] == 4


async def test_broadcast_reaches_every_lock(running):
    await online(running)
    await running.worker.adapters["gate-1"].set_lock_request_source(0x01, broadcast=True)
    assert await wait_for(lambda: all(t.holding[4] == 0x01 for t in running.twins.values()), timeout=2)
    assert all(t.holding[1002] == 4 for t in running.twins.values())


def test_twin_keeps_holding_4_and_1002_apart():
    """Section 3.2 lists 4 and 1002 as two RW registers; 6.5.1 names 4 as the one in use, and 3.2.2 names 1002
    as the register that controls the bolt: a write of 1002 becomes the source in use, a write of 4 leaves 1002."""
    from devices.hdlock.sim import HdLockTwin

    twin = HdLockTwin(door_closed=False)
    assert twin.holding[4] == twin.holding[1002] == 4  # factory 0x04 IrsNotLine
    twin.write(1002, 0x81)
    for _ in range(20):
        twin.step(0.05)
    assert twin.holding[1002] == 0x81 and twin.holding[4] == 0x81
    assert twin.bolt > 0  # 0x81 IrsAlways, door ignored: the bolt goes out with the door open
    twin.write(4, 0x01)
    twin.step(0.05)
    assert twin.holding[4] == 0x01 and twin.holding[1002] == 0x81


def test_twin_command_keeps_only_the_low_byte_over_a_reset():
    """Section 6.6.1.1: only the LSB is stored for good; the MSB is 0 after a reset.

    Section 3: a holding-register change is volatile until Save-Settings, this one too.
    """
    from devices.hdlock.sim import HdLockTwin

    twin = HdLockTwin()
    twin.set_lock_request_source(0x0181)
    assert twin.holding[4] == 0x0181
    twin.reset()
    assert twin.holding[4] == 0x04  # not saved: the saved value comes back
    twin.set_lock_request_source(0x0181)
    twin.write(codec.REG_COMMAND, codec.SystemCommand.SAVE_SETTINGS)
    twin.reset()
    assert twin.holding[4] == 0x81
    twin.set_lock_request_source(0x08)  # not in the table of section 6.6.1.1: refused
    assert twin.holding[4] == 0x81


async def test_set_device_address_then_answers_under_new_id(running):
    state = await online(running)
    adapter = running.worker.adapters["gate-1"]
    assert await adapter.set_device_address(12) is True
    assert running.twins["gate-1"].device_id == codec.DeviceId(12, False)
    assert adapter.device_id == codec.DeviceId(12, False)
    before = state.counters.responses
    assert await wait_for(lambda: state.counters.responses > before + 20, timeout=4)


async def test_set_bitrate_leaves_the_bus(running):
    state = await online(running, "gate-2")
    await running.worker.adapters["gate-2"].set_can_bitrate(9)  # 500 kbit/s
    assert await wait_for(lambda: running.twins["gate-2"].can_bitrate == 500_000, timeout=2)
    assert await wait_for(lambda: state.status in ("stale", "offline"), timeout=6)
    assert running.store.devices["gate-1"].status == "online"


async def test_fwu_status_is_shown(running):
    state = await online(running)
    running.twins["gate-1"].fwu_mode = True
    assert await wait_for(lambda: state.live(P_FWU) is not None and state.live(P_FWU).value is not None, timeout=3)
    assert not state.live(P_FWU).value.flashing


async def test_malformed_frame_is_counted_not_fatal(running):
    state = await online(running)
    with can.Bus(interface="virtual", channel=running.plant.buses["can1"].options["channel"]) as other:
        other.send(can.Message(arbitration_id=660100, is_extended_id=True, data=bytes.fromhex("05 05 01")))
    assert await wait_for(lambda: state.counters.malformed == 1, timeout=2)
    assert "malformed" in state.last_error
    assert await wait_for(lambda: state.status == "online", timeout=2)


async def test_interface_that_cannot_open_is_reported():
    plant = parse_plant(plant_text(plants.bus("c", "can", hdlock_can("g", 5, "c"), interface="socketcan", channel="nocan7"),
                                   name=None))
    runtime = Runtime(plant, simulate=False)
    await runtime.start()
    try:
        bus = runtime.store.buses["c"]
        assert await wait_for(lambda: bus.last_error.startswith("cannot open socketcan nocan7"), timeout=3)
        assert await wait_for(lambda: runtime.store.devices["g"].status == "offline", timeout=3)
    finally:
        await runtime.stop()


async def test_across_processes_on_udp_multicast(tmp_path):
    """`commission sim` serves the twins on udp_multicast; this process is the GUI side."""
    port = free_udp_port()  # found at run time: another bus or test on this machine cannot share it
    text = can_plant("udp_multicast", "239.74.163.2", port=port)
    path = tmp_path / "plant.toml"
    path.write_text(text)
    with sim_process(path) as (_proc, line):
        assert "simulating can1" in line
        runtime = Runtime(parse_plant(text), simulate=False)
        await runtime.start()
        try:
            state = runtime.store.devices["gate-2"]
            assert await wait_for(lambda: state.value("SerialNumber") == 660101, timeout=10)
            await runtime.worker.adapters["gate-2"].write_param(PARAMS.by_name["LockRequestDelay"], 250)
            assert state.value("LockRequestDelay") == 250
            # our own requests come back on udp_multicast and are filtered, not decoded as frames
            assert runtime.store.buses["can1"].rx_frames > 0
            assert all(r.direction == "tx" for r in runtime.store.buses["can1"].frames if r.arbitration_id in range(0x700, 0x708))
            assert await wait_for(lambda: (True, 660102) in runtime.worker.discovered["can1"], timeout=3)
        finally:
            await runtime.stop()


async def test_a_write_is_checked_against_its_own_echo_not_a_read_in_flight(running):
    """A read of a register (a poll's) and a write of it overlap. The lock answers a read and echoes a write alike
    (section 6.6.5); the write took the read's answer, the old value, for its echo and was reported refused: "the lock
    answered 200 ms instead of 250 ms" (a fresh-clone run on a loaded machine, 2026-11-29)."""
    state = await online(running, "gate-2")
    adapter = running.worker.adapters["gate-2"]
    param = PARAMS.by_name["LockRequestDelay"]
    before = state.value("LockRequestDelay")
    new = 300 if before == 250 else 250
    key = ("holding", param.address)
    read = asyncio.create_task(adapter._request(codec.encode_read(adapter.device_id, "holding", param.address), [key]))
    await asyncio.sleep(0)  # the read is sent and waits for its answer: no frame is taken in before the write below
    assert key in adapter._waiting and not adapter._waiting[key].done()
    await adapter.write_param(param, new)
    assert state.value("LockRequestDelay") == new
    assert (await read)[key] == before
