"""Bus monitor: decoding, filters, recordings in four formats, and the page with a simulated user.

Every CAN test uses its own python-can ``virtual`` channel and closes every bus it opens.
"""

from __future__ import annotations

import logging
import os
import time
import uuid
from collections.abc import AsyncIterator
from dataclasses import dataclass
from pathlib import Path

import can
import pytest
from conftest import free_port, wait_for
from nicegui import ui
from nicegui.elements.upload_files import SmallFileUpload
from nicegui.testing import User
from webutil import demo_plant_text, eventually, eventually_sync, simulated_user

from app import recording as rec
from app.can_bus import CanBus, CanBusState, FrameRecord
from app.modbus_line import Transaction, request_target
from app.plant import parse_plant
from app.runtime import Runtime
from app.worker import Worker
from devices.hdlock import codec
from devices.m3io import codec as m3io_codec

COMMAND_EXAMPLE = bytes.fromhex("4F 01 00 80 00 00 81 00")  # section 6.6.1.1: extended lock 335, source 0x81
GATE1 = 660100  # demo plant: gate-1, extended
GATE2 = 11  # demo plant: gate-2, standard


def unique_channel() -> str:
    """A channel of its own; the long number at the end is what ASC/BLF writers cannot store as is."""
    return f"monitor-test-{uuid.uuid4().hex[:10]}-{os.getpid()}{uuid.uuid4().int % 10**9:09d}"


def demo_plant(channel: str | None = None, line_port: int | None = None):
    """The demo plant with every CAN bus on a virtual channel of its own (can1 on ``channel``)."""
    text = demo_plant_text(line_port or free_port()).replace('channel = "demo-can1"', f'channel = "{channel or unique_channel()}"')
    for n in range(2, 10):
        text = text.replace(f'channel = "demo-can{n}"', f'channel = "{unique_channel()}"')
    return parse_plant(text)


def can1_codecs(worker: Worker) -> list:
    """The codecs in the order the monitor of can1 asks them: the bus's device types first."""
    return rec.can_codecs(d.type for d in worker.plant.devices_on("can1"))


def status_data(status: int = 0x0200, motor_pos: int = 0, proximity: int = 100, source: int = 4) -> bytes:
    return codec.encode_status(codec.StatusFrame(status, motor_pos, proximity, source))


@pytest.fixture
def worker() -> Worker:
    """The demo plant's worker, not started: adapters subscribed, no bus opened."""
    return Worker(demo_plant())


# -- decoding -----------------------------------------------------------------------------------------


def test_command_example_decodes(worker: Worker):
    text = rec.describe(0x700, False, COMMAND_EXAMPLE, worker.known_ids("can1"), can1_codecs(worker))
    assert text.startswith("HD-Lock Command")
    assert "335" in text and "ext" in text
    assert text.endswith("SET_LOCK_REQUEST_SOURCE value 129 (IrsAlways (door ignored))"), text


def test_status_of_known_lock_decodes(worker: Worker):
    known = worker.known_ids("can1")
    assert (True, GATE1) in known and (False, GATE2) in known
    text = rec.describe(GATE1, True, status_data(0x0117, 115), known, can1_codecs(worker))
    assert text.startswith("HD-Lock Status 0x0117"), text
    assert "BoltLocked" in text and "motorPos 115" in text
    answer = codec.encode_register_answer(codec.RegisterAnswer("holding", 3000, 200))
    assert rec.describe(GATE2, False, answer, known, can1_codecs(worker)) == "HD-Lock Holding register 3000 LockRequestDelay = 200 ms (0x00C8)"


def test_unknown_id_is_unknown(worker: Worker):
    known = worker.known_ids("can1")
    codecs = can1_codecs(worker)
    assert rec.describe(0x123, False, b"\x01\x02", known, codecs) == "unknown"
    assert rec.describe(GATE1, False, status_data(), known, codecs) == "unknown"  # same number, standard: another ID
    decoder = rec.FrameDecoder(known, codecs)
    assert decoder.record(FrameRecord(0, 0, False, 0, b"", "rx", is_error_frame=True)) == "error frame"
    assert decoder(0x7FF, False, b"") == "unknown"


def test_device_types_of_the_bus_decode_first(worker: Worker):
    """0x00B is HD-Lock gate-2 on can1, but an Electrak service response where Electraks are."""
    known = worker.known_ids("can1")
    answer = codec.encode_register_answer(codec.RegisterAnswer("holding", 3000, 200))
    assert rec.describe(GATE2, False, answer, known, rec.can_codecs(["hdlock"])).startswith("HD-Lock Holding register 3000")
    names = [m.__name__ for m in rec.can_codecs(["hdlock"])]
    assert names[0] == "devices.hdlock.codec" and "devices.electrak.codec" in names
    assert rec.can_codecs(["electrak"])[0].__name__ == "devices.electrak.codec"
    # a bus where an Electrak network is heard (status 0x07): 0x00B is its service response first
    from devices.electrak import codec as electrak_codec

    both = {(False, electrak_codec.STATUS_ID), (False, GATE2)}
    read_response = bytes.fromhex("10 21 04 00 2C 01 00 00")
    assert rec.describe(GATE2, False, read_response, both, rec.can_codecs(["electrak"])) == "Electrak service READ_RESPONSE 0x21 len 4 value 300"
    assert rec.describe(GATE2, False, answer, both, rec.can_codecs(["hdlock"])).startswith("HD-Lock Holding register 3000")


def test_ids_of_devices_in_a_file():
    frames = [
        FrameRecord(0.0, 0x1234, True, 8, status_data(), "rx"),
        FrameRecord(0.1, 0x700, False, 8, COMMAND_EXAMPLE, "tx"),
        FrameRecord(0.2, 0x321, False, 2, b"\x01\x02", "rx"),
    ]
    assert rec.ids_of_devices(frames) == {(True, 0x1234)}
    decoder = rec.FrameDecoder(rec.ids_of_devices(frames), rec.can_codecs(["hdlock"]))
    assert decoder.record(frames[0]).startswith("HD-Lock Status")
    assert decoder.record(frames[2]) == "unknown"


def test_formatting():
    assert rec.format_id(0x704, False) == "0x704"
    assert rec.format_id(0x000A1234, True) == "0x000A1234 (ext)"
    assert rec.format_data(b"\x4f\x01\x00") == "4F 01 00"
    assert rec.changed_bytes(b"\x00\x11\x22", 0b101) == [("00", True), ("11", False), ("22", True)]


# -- filters ------------------------------------------------------------------------------------------


def test_parse_id():
    assert rec.parse_id("") is None and rec.parse_id(None) is None and rec.parse_id("  ") is None
    assert rec.parse_id("704") == 0x704
    assert rec.parse_id("0x000A1284") == GATE1
    for bad in ("xyz", "0x", "20000000", "-1"):
        with pytest.raises(ValueError):
            rec.parse_id(bad)


def test_filter_by_id_range():
    flt = rec.FrameFilter(id_min=0x700, id_max=0x707)
    assert flt.active
    assert flt.matches(0x700, False, b"") and flt.matches(0x707, False, b"")
    assert not flt.matches(0x6FF, False, b"") and not flt.matches(0x708, False, b"")
    assert rec.FrameFilter(id_min=0x100).matches(GATE1, True, b"")
    assert not rec.FrameFilter(id_max=0x7FF).matches(GATE1, True, b"")
    assert not rec.FrameFilter().active and rec.FrameFilter().matches(1, False, b"")
    errors = rec.FrameFilter(errors_only=True)
    assert errors.matches(0, False, b"", is_error_frame=True) and not errors.matches(0x700, False, b"")


def test_filter_by_device(worker: Worker):
    gate1 = rec.FrameFilter(owner=rec.owner_of(worker.adapters["gate-1"]))
    gate2 = rec.FrameFilter(owner=rec.owner_of(worker.adapters["gate-2"]))
    to_gate1 = codec.encode_read(codec.DeviceId.make(GATE1), "holding", 3000, 2)
    to_gate2 = codec.encode_read(codec.DeviceId.make(GATE2), "holding", 3000, 2)
    broadcast = codec.encode_can_command(codec.BROADCAST_ID, codec.CanCommand.SET_LOCK_REQUEST_SOURCE, 4)
    assert gate1.matches(GATE1, True, status_data()) and not gate2.matches(GATE1, True, status_data())
    assert gate2.matches(GATE2, False, status_data()) and not gate1.matches(GATE2, False, status_data())
    assert gate1.matches(to_gate1.arbitration_id, False, to_gate1.data) and not gate2.matches(to_gate1.arbitration_id, False, to_gate1.data)
    assert gate2.matches(to_gate2.arbitration_id, False, to_gate2.data) and not gate1.matches(to_gate2.arbitration_id, False, to_gate2.data)
    assert gate1.matches(0x700, False, broadcast.data) and gate2.matches(0x700, False, broadcast.data)
    assert not gate1.matches(0x123, False, b"\x00")
    assert not gate1.matches(GATE1, True, b"", is_error_frame=True)

    class NoOwner:
        pass

    nothing = rec.FrameFilter(owner=rec.owner_of(NoOwner()))
    assert not nothing.matches(GATE1, True, status_data()) and not nothing.matches(0x700, False, broadcast.data)
    # both filters at once
    both = rec.FrameFilter(id_min=0x700, id_max=0x7FF, owner=rec.owner_of(worker.adapters["gate-1"]))
    assert both.matches(to_gate1.arbitration_id, False, to_gate1.data) and not both.matches(GATE1, True, status_data())


def test_newest_is_bounded_and_newest_first(worker: Worker):
    frames = [FrameRecord(float(i), 0x100 + i % 16, False, 1, bytes([i % 256]), "rx") for i in range(1000)]
    shown = rec.newest(frames, rec.FrameFilter(), 200)
    assert len(shown) == 200 and shown[0] is frames[-1] and shown[-1] is frames[800]
    only = rec.newest(frames, rec.FrameFilter(id_min=0x105, id_max=0x105), 10)
    assert [f.time for f in only] == [float(i) for i in range(997, 830, -16)][:10]
    assert all(f.arbitration_id == 0x105 for f in only)


# -- recording ----------------------------------------------------------------------------------------

SENT = [
    (0x700, False, COMMAND_EXAMPLE),
    (GATE1, True, status_data(0x0117, 115)),
    (0x123, False, b""),
    (0x1ABCDEF0, True, b"\x01\x02\x03"),
    (0x7FF, False, b"\xff" * 8),
    (0x0, True, b"\x00"),
]


async def _started_bus(channel: str) -> CanBus:
    bus = CanBus("rec", {"interface": "virtual", "channel": channel, "bitrate": 250000}, CanBusState("rec", "can", channel))
    await bus.start()
    assert await wait_for(lambda: bus.state.connected, 3), bus.state.last_error
    return bus


@pytest.mark.timeout(20)
@pytest.mark.parametrize("suffix", [".log", ".asc", ".blf", ".csv"])
async def test_recording_round_trip(tmp_path: Path, suffix: str):
    channel = unique_channel()
    bus = await _started_bus(channel)
    sender = can.Bus(interface="virtual", channel=channel)
    try:
        recording = rec.start_recording(bus.state, suffix, tmp_path, bus.options)
        assert rec.active_recording(bus.state) is recording and recording.path.parent == tmp_path
        assert recording.path.suffix == suffix and recording.path.name.startswith("rec-")
        with pytest.raises(rec.RecordingError, match="already"):
            rec.start_recording(bus.state, suffix, tmp_path)
        for can_id, ext, data in SENT:
            sender.send(can.Message(arbitration_id=can_id, is_extended_id=ext, data=data))
        assert await wait_for(lambda: bus.state.rx_frames == len(SENT), 5), f"received {bus.state.rx_frames}"
        assert bus.send(0x703, b"\x0b\x00\x00\x00\xb8\x0b\x02\x00")  # sent by us: recorded as well
        assert await wait_for(lambda: recording.frames == len(SENT) + 1, 5)  # the writer thread has them all
        stopped = rec.stop_recording(bus.state)
        assert stopped is recording and not recording.active and recording.error == ""
        assert bus.state.recorder is None and rec.stop_recording(bus.state) is None
        # frames after the stop do not reach the closed file
        sender.send(can.Message(arbitration_id=0x555, data=b"\x01"))
        assert await wait_for(lambda: bus.state.rx_frames == len(SENT) + 1, 5)
    finally:
        sender.shutdown()
        await bus.stop()
        rec.stop_recording(bus.state)

    expected = [(i, e, d, len(d)) for i, e, d in SENT] + [(0x703, False, b"\x0b\x00\x00\x00\xb8\x0b\x02\x00", 8)]
    reader = can.LogReader(recording.path)
    try:
        read = [(m.arbitration_id, m.is_extended_id, bytes(m.data), m.dlc) for m in reader]
    finally:
        reader.stop()
    assert read == expected
    # python-can's CSV format has no direction: every frame of a .csv file reads as received
    directions = ["rx"] * len(SENT) + ["rx" if suffix == ".csv" else "tx"]
    reader = can.LogReader(recording.path)
    try:
        assert ["rx" if m.is_rx else "tx" for m in reader] == directions
    finally:
        reader.stop()
    loaded = rec.read_log(recording.path)
    assert [(f.arbitration_id, f.is_extended_id, f.data, f.dlc) for f in loaded.frames] == expected
    assert [f.direction for f in loaded.frames] == directions
    assert loaded.frames[0].time <= loaded.frames[-1].time
    assert [f.name for f in rec.list_recordings(tmp_path)] == [recording.path.name]
    assert rec.recording_path(recording.path.name, tmp_path) == recording.path.resolve()
    with pytest.raises(rec.RecordingError):
        rec.recording_path("../" + recording.path.name, tmp_path / "sub")


def test_write_error_ends_the_recording_not_the_bus(tmp_path: Path):
    state = CanBusState("w", "can", "")
    bus = CanBus("w", {"interface": "virtual", "channel": unique_channel()}, state)  # never opened: dispatch only
    recording = rec.start_recording(state, ".log", tmp_path)
    bus.dispatch(can.Message(arbitration_id=0x100, data=b"\x01"))
    assert eventually_sync(lambda: recording.frames == 1)  # written by the recording's own thread
    recording.writer.file.close()  # the disk is gone
    bus.dispatch(can.Message(arbitration_id=0x101, data=b"\x02"))
    assert eventually_sync(lambda: recording.error)  # the writer thread ends the recording and says why
    bus.dispatch(can.Message(arbitration_id=0x102, data=b"\x03"))
    assert state.recorder is None and "recording stopped" in state.last_error
    assert not recording.active and recording.error and recording.frames == 1
    assert state.rx_frames == 3 and len(state.frames) == 3  # the monitor keeps going


def test_recording_refuses_unknown_format(tmp_path: Path):
    state = CanBusState("x", "can", "")
    with pytest.raises(rec.RecordingError, match="choose one of"):
        rec.start_recording(state, ".mf4", tmp_path)
    assert state.recorder is None


def test_recordings_dir_from_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setenv(rec.DIR_ENV, str(tmp_path / "rec"))
    assert rec.recordings_dir() == tmp_path / "rec"
    monkeypatch.delenv(rec.DIR_ENV)
    # without the variable and without a running plant: the user's data folder, never the working directory
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("COMMISSION_DATA_DIR", str(tmp_path / "userdata"))
    assert rec.recordings_dir() == tmp_path / "userdata" / "recordings"
    assert rec.recordings_dir() != Path.cwd() / "recordings"
    assert rec.list_recordings(tmp_path / "missing") == []


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("bad.blf", b"garbage" * 50, "cannot open as .blf"),
        ("bad.csv", b"a,b,c\n1,2,3\n", "not a valid .csv"),
        ("bad.log", b"(abc) can0 123#00\n", "not a valid .log"),
        ("empty.asc", b"hello\n", "no CAN frames"),
        ("binary.asc", b"\xff\xfe\x00\x81", "not a valid .asc"),
        ("notes.txt", b"hello", "unsupported file type .txt"),
    ],
)
def test_malformed_files_give_a_clear_error(tmp_path: Path, name: str, content: bytes, message: str):
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(rec.RecordingError, match=message) as info:
        rec.read_log(path)
    assert name in str(info.value)


def test_read_log_is_bounded(tmp_path: Path):
    path = tmp_path / "many.log"
    path.write_text("".join(f"({i / 1000:.6f}) can0 {0x100 + i % 5:03X}#{i % 256:02X}\n" for i in range(50)))
    loaded = rec.read_log(path, limit=20)
    assert len(loaded.frames) == 20 and loaded.truncated
    assert rec.read_log(path).truncated is False


# -- the page, with NiceGUI's simulated user ------------------------------------------------------------


# -- decoding through the parameter model, and the device of a frame -----------------------------------------

THRESHOLD_LOCK = 65476  # holding 3006 SettingsProximityThresholdLock, factory -60 (section 3.2.7), as the bus carries it


def test_hdlock_register_answer_over_can_is_named_and_signed(worker: Worker):
    """Section 6.5.4: a holding-register answer; 3006 is int16 (3.2.7): -60, not 65476."""
    answer = codec.encode_register_answer(codec.RegisterAnswer("holding", 3006, THRESHOLD_LOCK))
    assert answer == bytes.fromhex("01 01 BE 0B C4 FF")  # [1, 1, addrLo, addrHi, valLo, valHi], little-endian (6.2)
    text = rec.describe(GATE2, False, answer, worker.known_ids("can1"), can1_codecs(worker))
    assert "SettingsProximityThresholdLock = -60" in text, text
    assert "65476" not in text
    unlock = codec.encode_register_answer(codec.RegisterAnswer("holding", 3004, 65506))  # factory -30
    assert "SettingsProximityThresholdUnlock = -30" in rec.describe(GATE2, False, unlock, worker.known_ids("can1"), can1_codecs(worker))
    status = codec.encode_register_answer(codec.RegisterAnswer("holding", 1000, 0x0117))  # section 4.3 example status
    assert "LockStatus = LockRequest, ProximityInPlace, DoorInPosition, LockRequest (bit 4), BoltLocked" in rec.describe(
        GATE2, False, status, worker.known_ids("can1"), can1_codecs(worker))
    direction = codec.encode_register_answer(codec.RegisterAnswer("input", 11, 0xFFFF))  # input 11: -1 = always right-hinged
    assert "Direction = Always right-hinged (-1)" in rec.describe(GATE2, False, direction, worker.known_ids("can1"), can1_codecs(worker))


def test_hdlock_requests_over_can_are_named_and_signed(worker: Worker):
    write = codec.encode_write(codec.DeviceId.make(GATE2), 3006, THRESHOLD_LOCK)
    assert write.data == bytes.fromhex("0B 00 00 00 BE 0B C4 FF")
    text = rec.describe(0x704, False, write.data, worker.known_ids("can1"), can1_codecs(worker))
    assert text.startswith("HD-Lock Write Holding-Register -> lock 11") and "SettingsProximityThresholdLock = -60" in text, text
    read = codec.encode_read(codec.DeviceId.make(GATE2), "input", 104, 2)
    assert "104 SerialNumber count 2" in rec.describe(0x702, False, read.data, worker.known_ids("can1"), can1_codecs(worker))
    status = rec.describe(GATE1, True, status_data(0x0117, 115, 3, 4), worker.known_ids("can1"), can1_codecs(worker))
    assert "source 4 IrsNotLine" in status, status


def test_hdlock_register_answer_over_modbus_is_named_and_signed(worker: Worker):
    """The transaction log carries space, address and values; the monitor decodes them with the
    parameter model of the device at that unit and names the device."""
    assert request_target("read holding 3004+5") == ("holding", 3004, None)
    assert request_target("write holding 3006=65476") == ("holding", 3006, 65476)
    assert request_target("broadcast write holding 2000=8") == ("holding", 2000, 8)
    decoder = rec.TransactionDecoder(worker, "line1")
    read = Transaction(0, 1, "read holding 3004+5", "", "", "ReadHoldingRegisters: [65506, 0, 65476, 0, 0]", 3.0, "",
                       space="holding", address=3004, values=(65506, 0, THRESHOLD_LOCK, 0, 0))
    text = decoder.decoded(read)
    assert "SettingsProximityThresholdUnlock = -30" in text and "SettingsProximityThresholdLock = -60" in text, text
    assert "65476" not in text
    assert decoder.device(1) == "door-1 (unit 1)" and decoder.device(2) == "door-2 (unit 2)"
    assert decoder.device(0) == "broadcast (unit 0)" and decoder.device(7) == "unit 7"
    serial = Transaction(0, 2, "read input 104+2", "", "", "", 3.0, "", space="input", address=104, values=(0x000A, 0x1234))
    assert decoder.decoded(serial) == "SerialNumber = 660020"  # section 3.1 example: 0x000A1234
    write = Transaction(0, 1, "write holding 3006=65476", "", "", "", 3.0, "", space="holding", address=3006, values=(THRESHOLD_LOCK,))
    assert decoder.decoded(write) == "wrote SettingsProximityThresholdLock = -60 Inc"
    failed = Transaction(0, 1, "read holding 3006+1", "", "", "", None, "no answer within 0.5 s", space="holding", address=3006)
    assert decoder.decoded(failed) == ""
    # a line scan or a broadcast: no configured device at that unit, decoded with the line's (only) device type
    scan = Transaction(0, 7, "scan holding 103", "", "", "", 3.0, "", space="holding", address=103, values=(7,))
    assert decoder.decoded(scan) == "DeviceAddress = 7"
    broadcast = Transaction(0, 255, "broadcast write holding 2000=8", "", "", "", None, "", space="holding", address=2000, values=(8,))
    assert decoder.device(255) == "broadcast (unit 255)" and decoder.decoded(broadcast) == "wrote Parameter 0 = 8"


def test_m3io_temperature_frame_is_named_with_out_of_range(worker: Worker):
    """Section 7.2.2/7.2.3: TEMPx in 0.1 C, 12-bit two's complement; below 0 or above 200.0 C is
    "out of range"; Last/Si/Triac per SSR, fuse and triac unknown without a load; HMR t1-t3 carry TEMP1."""
    hm = m3io_codec.derive_ids(0x1A)
    words = [
        m3io_codec.TempWord.make(215, load=True, triac=True, fuse=True, addressed=False),
        m3io_codec.TempWord.make(-5, load=False, triac=False, fuse=False, addressed=False),
        m3io_codec.TempWord.make(2010, load=True, triac=True, fuse=False, addressed=False),
        m3io_codec.TempWord.make(2000, load=True, triac=False, fuse=True, addressed=False),
    ]
    data = m3io_codec.encode_temps(words)
    assert data[:4] == bytes.fromhex("D7 E0 FB 1F")  # 215 | Last | Triac | Si; -5 as 12-bit 0xFFB, sb = vz = 1 (simple mode)
    codecs = rec.describers(worker, "can3", ["m3io"])
    text = rec.describe(hm.temp14, False, data, worker.known_ids("can3"), codecs)
    assert text.startswith("M3IO TEMP1 21.5 °C · SSR1 load, fuse ok, triac ok"), text
    assert "TEMP2 out of range (-0.5 °C) · SSR2 no load: fuse, triac unknown" in text
    assert "TEMP3 out of range (201.0 °C) · SSR3 load, fuse blown" in text
    assert "TEMP4 200.0 °C · SSR4 load, fuse ok, triac not conducting" in text
    hmr = m3io_codec.derive_ids(0xCA)
    text = rec.describe(hmr.temp14, False, data, worker.known_ids("can3"), codecs)
    assert [part.split(" ")[0] for part in text.removeprefix("M3IO ").split("; ")] == ["TEMP1", "TEMP1", "TEMP1", "TEMP4"], text
    product = m3io_codec.MData(2, 2, m3io_codec.pad6(m3io_codec.encode_u16(0x300A))).encode()
    assert rec.describe(hmr.mdata, False, product, set(), codecs) == "M3IO MData read config product code: 0x300A HMR01 (from 08.11.2013)"
    serial = m3io_codec.MData(2, 1, m3io_codec.pad6(m3io_codec.encode_serial(33852))).encode()
    assert serial[2:6] == bytes.fromhex("3C 84 00 00")  # 7.2.4.2.2: 00033852 is sent as 0x843C, low byte first
    assert rec.describe(hmr.mdata, False, serial, set(), codecs).endswith("serial number: 00033852")


def test_device_column_names_the_sender_or_the_addressed_device(worker: Worker):
    decoder = rec.FrameDecoder(worker.known_ids("can1"), can1_codecs(worker), rec.device_owners(worker, "can1"))
    assert decoder.device(GATE1, True, status_data()) == "gate-1"
    assert decoder.device(GATE2, False, status_data()) == "gate-2"
    assert decoder.device(0x703, False, codec.encode_read(codec.DeviceId.make(GATE2), "holding", 3006).data) == "gate-2"
    assert decoder.device(0x700, False, COMMAND_EXAMPLE) == ""  # lock 335 (ext) is not in the plant
    broadcast = codec.encode_can_command(codec.BROADCAST_ID, codec.CanCommand.SET_LOCK_REQUEST_SOURCE, 4)
    assert decoder.device(0x700, False, broadcast.data) == "gate-1, gate-2"
    assert decoder.device(0x123, False, b"") == ""
    assert decoder.record_device(FrameRecord(0, 0, False, 0, b"", "rx", is_error_frame=True)) == ""
    m3io = rec.FrameDecoder(set(), [], rec.device_owners(worker, "can3"))
    assert m3io.device(m3io_codec.derive_ids(0x1A).temp14, False, bytes(8)) == "heater-hm"
    assert m3io.device(m3io_codec.derive_ids(0xCA).dig_out, False, b"\x00") == "heater-hmr"
    electrak = rec.FrameDecoder(set(), [], rec.device_owners(worker, "can2"))
    assert electrak.device(0x07, False, bytes(8)) == "lift"  # the network's status frames: the system, not one actuator


@dataclass
class Env:
    user: User
    runtime: Runtime


@pytest.fixture
async def env(caplog: pytest.LogCaptureFixture, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> AsyncIterator[Env]:
    """The demo plant (Modbus line on a free port, CAN bus on its own virtual channel), simulated."""
    monkeypatch.setenv(rec.DIR_ENV, str(tmp_path / "recordings"))
    runtime = Runtime(demo_plant(), simulate=True)
    try:
        async with simulated_user(runtime) as user:
            yield Env(user, runtime)
    finally:
        rec.stop_recording(runtime.store.buses["can1"])
    errors = [r for r in caplog.get_records("call") if r.levelno >= logging.ERROR]
    assert not errors, "unexpected ERROR logs: " + "; ".join(r.getMessage() for r in errors)


def id_of(row: dict) -> int:
    return int(row["id"].split()[0], 16)


def one(user: User, marker: str):
    elements = user.find(marker=marker).elements
    assert len(elements) == 1, f"{len(elements)} elements marked {marker!r}"
    return next(iter(elements))


@pytest.mark.timeout(60)
async def test_can_monitor_page(env: Env, tmp_path: Path):
    user = env.user
    await user.open("/monitor/can1")
    await user.should_see("Bus monitor can1")
    frames, overwrite = one(user, "frames"), one(user, "overwrite")

    def status_rows() -> None:
        decoded = [r["decoded"] for r in frames.rows]
        assert any(d.startswith("HD-Lock Status") for d in decoded), decoded[:5]
        ids = {r["id"] for r in overwrite.rows}
        assert {"0x000A1284 (ext)", "0x00B"} <= ids, ids
        devices = {r["id"]: r["device"] for r in overwrite.rows}
        assert devices["0x000A1284 (ext)"] == "gate-1" and devices["0x00B"] == "gate-2", devices
        assert all(r["device"] == "gate-1" for r in frames.rows if r["id"] == "0x000A1284 (ext)")

    await eventually(status_rows, timeout=10)
    assert len(frames.rows) <= 200

    def threshold_answer() -> None:  # a lock's answer to the register poll, by name and signed (3.2.7)
        rows = [r for r in frames.rows if "SettingsProximityThresholdLock = " in r["decoded"] and r["dir"] == "rx"]
        assert rows and all(r["device"] in ("gate-1", "gate-2") for r in rows)
        assert "SettingsProximityThresholdLock = -60" in rows[0]["decoded"], rows[0]["decoded"]

    await eventually(threshold_answer, timeout=10)
    await user.should_see("error-active", retries=30)
    await user.should_see(kind=ui.label, content="error frames 0")
    row = next(r for r in overwrite.rows if r["id"] == "0x000A1284 (ext)")
    first_count = row["count"]
    await eventually(lambda: next(r for r in overwrite.rows if r["id"] == "0x000A1284 (ext)")["count"] > first_count, timeout=5)

    # an error frame on the bus: counted, listed, and the only row with "Error frames only"
    channel = env.runtime.plant.buses["can1"].options["channel"]
    sender = can.Bus(interface="virtual", channel=channel)
    try:
        sender.send(can.Message(arbitration_id=0x20000004, is_extended_id=True, is_error_frame=True, data=bytes(8)))
    finally:
        sender.shutdown()
    await user.should_see(kind=ui.label, content="error frames 1", retries=30)
    user.find(kind=ui.switch, content="Error frames only").click()
    await eventually(lambda: len(frames.rows) == 1 and frames.rows[0]["err"] and frames.rows[0]["decoded"] == "error frame", timeout=3)
    assert frames.rows[0]["id"] == "error frame"
    user.find(kind=ui.switch, content="Error frames only").click()
    await eventually(lambda: len(frames.rows) > 1, timeout=3)

    # ID range: only the request IDs
    user.find(marker="id-from").type("700")
    user.find(marker="id-to").type("7FF")
    def in_range(rows: list[dict]) -> bool:
        return bool(rows) and all(0x700 <= id_of(r) <= 0x7FF for r in rows)

    await eventually(lambda: in_range(frames.rows) and in_range(overwrite.rows), timeout=5)
    assert all(not r["id"].endswith("(ext)") for r in frames.rows)
    user.find(marker="id-from").clear()
    user.find(marker="id-to").clear()
    # device: only gate-1's frames and the requests to it
    one(user, "device").set_value("gate-1")
    gate1 = rec.owner_of(env.runtime.worker.adapters["gate-1"])

    def only_gate1() -> None:
        assert frames.rows
        ids = {r["id"] for r in frames.rows}
        assert "0x00B" not in ids and "0x000A1286 (ext)" not in ids, ids
        assert all(r["id"] == "0x000A1284 (ext)" or r["id"].startswith("0x70") for r in frames.rows)
        assert {r["id"] for r in overwrite.rows} <= {"0x000A1284 (ext)", "0x700", "0x701", "0x702", "0x703", "0x704", "0x705"}

    await eventually(only_gate1, timeout=5)
    assert gate1(GATE1, True, b"")
    one(user, "device").set_value("")

    # pause: the list stops moving
    user.find(marker="pause").click()
    frozen = list(frames.rows)
    state = env.runtime.store.buses["can1"]
    received = state.rx_frames
    counters = one(user, "counters")
    # the counters go on (the page refreshes while paused) over frames that arrived after the pause
    await eventually(lambda: int(counters.text.split()[1]) >= received + 3, timeout=5)
    assert frames.rows == frozen
    user.find(marker="pause").click()
    await eventually(lambda: frames.rows != frozen, timeout=5)

    # record a few status frames in .asc, then open the file in the "recorded file" tab
    one(user, "format").set_value(".asc")
    user.find(marker="record").click()
    await user.should_see(kind=ui.label, content="recording can1-")
    state = env.runtime.store.buses["can1"]
    recording = rec.active_recording(state)
    assert recording is not None and recording.path.suffix == ".asc"
    await eventually(lambda: recording.frames >= 4 and recording.elapsed > 1.3, timeout=6)  # status every 1 s
    user.find(marker="stop").click()
    await eventually(lambda: rec.active_recording(state) is None and not recording.active, timeout=5)  # closed in a thread
    await user.should_see(f"Saved {recording.frames} frames")
    assert recording.path.parent == tmp_path / "recordings"
    await user.should_see(kind=ui.label, content=recording.path.name)  # in the list of recordings
    user.find(marker="download").click()
    response = await user.download.next()
    assert recording.path.name in str(response.request.url)

    upload = one(user, "upload")
    await upload.handle_uploads([SmallFileUpload(recording.path.name, "text/plain", recording.path.read_bytes())])
    await user.should_see(f"Opened {recording.path.name}")
    file_table, pages = one(user, "file-frames"), one(user, "file-pages")
    assert len(file_table.rows) == min(200, recording.frames)
    assert file_table.rows[0]["time"] == "0.000"
    assert pages.max == -(-recording.frames // 200)
    statuses = 0
    for number in range(1, pages.max + 1):  # a register read burst can fill a page
        pages.set_value(number)
        assert all(r["decoded"].startswith("HD-Lock") for r in file_table.rows)
        statuses += sum(r["decoded"].startswith("HD-Lock Status") for r in file_table.rows)
    assert statuses >= 1
    # the filters apply to the file too
    user.find(marker="id-from").type("B")
    user.find(marker="id-to").type("B")
    await eventually(lambda: one(user, "file-frames").rows and all(r["id"] == "0x00B" for r in one(user, "file-frames").rows), timeout=3)

    # malformed and unsupported files: a message, no crash
    await upload.handle_uploads([SmallFileUpload("broken.blf", "application/octet-stream", b"not a blf file" * 10)])
    await user.should_see("broken.blf: cannot open as .blf file")
    await upload.handle_uploads([SmallFileUpload("notes.txt", "text/plain", b"hello")])
    await user.should_see("notes.txt: unsupported file type .txt")
    await user.should_see(f"Opened {recording.path.name}")  # the last good file stays


@pytest.mark.timeout(30)
async def test_modbus_monitor_page(env: Env):
    user = env.user
    await user.open("/monitor/line1")
    await user.should_see("Bus monitor line1")
    table = one(user, "transactions")
    await eventually(lambda: any(r["request"].startswith("read") and r["rx"] for r in table.rows), timeout=10)
    await user.should_see(kind=ui.label, content="transactions buffered")

    def thresholds_decoded() -> None:  # the twin keeps the factory thresholds -30 / -60 (section 3.2.7)
        rows = [r for r in table.rows if r["request"].startswith("read holding 300") and r["device"] == "door-1 (unit 1)"]
        assert rows, [(r["device"], r["request"]) for r in table.rows[:5]]
        assert "SettingsProximityThresholdLock = -60" in rows[0]["decoded"], rows[0]["decoded"]
        assert "SettingsProximityThresholdUnlock = -30" in rows[0]["decoded"]

    await eventually(thresholds_decoded, timeout=10)
    assert {r["device"] for r in table.rows} <= {"door-1 (unit 1)", "door-2 (unit 2)", "broadcast (unit 0)"}

    # issue 32.14: filters by unit, function and address (the newest rows, of the buffer, that pass)
    (unit,) = [e for e in user.client.elements.values() if e.props.get("data-monitor") == "filter-unit"]
    (address,) = [e for e in user.client.elements.values() if e.props.get("data-monitor") == "filter-address"]
    (function,) = [e for e in user.client.elements.values() if e.props.get("data-monitor") == "filter-function"]
    unit.set_value("2")
    await eventually(lambda: table.rows and {r["device"] for r in table.rows} == {"door-2 (unit 2)"}, timeout=5)
    function.set_value(4)
    await eventually(lambda: table.rows and all(r["request"].startswith("read input") for r in table.rows), timeout=5)
    function.set_value(3)
    address.set_value("3005")  # inside "read holding 3000+9"
    await eventually(lambda: table.rows and {r["request"] for r in table.rows} == {"read holding 3000+9"}, timeout=5)
    address.set_value("70000")
    await eventually(lambda: "error" in address.props, timeout=5)


def test_id_table_evicts_the_least_recently_heard_id_in_constant_time():
    from app.can_bus import MAX_IDS

    state = CanBusState("flood", "can", "")
    bus = CanBus("flood", {"interface": "virtual", "channel": unique_channel()}, state)  # never opened: dispatch only
    bus.dispatch(can.Message(arbitration_id=0x123, is_extended_id=False, data=b"\x01"))
    for n in range(MAX_IDS - 1):
        bus.dispatch(can.Message(arbitration_id=0x10000 + n, is_extended_id=True, data=b"\x00\x00"))
    bus.dispatch(can.Message(arbitration_id=0x123, is_extended_id=False, data=b"\x02"))  # heard again: now the newest
    started = time.perf_counter()
    for n in range(MAX_IDS // 2):  # a flood of new IDs
        bus.dispatch(can.Message(arbitration_id=0x20000 + n, is_extended_id=True, data=b"\x00\x00"))
    per_frame_us = (time.perf_counter() - started) / (MAX_IDS // 2) * 1e6
    assert len(state.ids) == MAX_IDS
    assert (False, 0x123) in state.ids and (True, 0x10000) not in state.ids
    print(f"new-ID frame through dispatch with a full table: {per_frame_us:.1f} us")
    assert per_frame_us < 250  # was a scan of 4096 IDs per frame (about 300 us) before


def test_bus_load_is_averaged_and_its_peak_kept_when_frames_arrive_in_batches():
    """Issue 32.8: 200 frames/s, handed to the loop in batches (all of one second's frames in one half
    second, none in the next): the half-second figure jumps between 0 and twice the load, the average
    and the peak stay at the steady load."""
    import can

    from app import can_bus as cb

    state = cb.CanBusState("load-test", "can", "")
    bus = cb.CanBus("load-test", {"interface": "virtual", "channel": "load-test", "bitrate": 250_000}, state)  # never opened
    steady = 200 * cb.frame_bits(8, False) / 250_000 * 100  # 8.9 %
    t = 1000.0
    bus.stats.load_mark = (t, 0, 0)
    seen = []
    for step in range(1, 41):  # 20 s in half-second windows
        if step % 2:
            for i in range(200):
                bus.dispatch(can.Message(arbitration_id=0x7, is_extended_id=False, data=bytes(8), timestamp=t + i * 0.005))
        bus.stats.measure_load(now=t + step * cb.LOAD_PERIOD_S)
        seen.append(state.load_pct)
    assert max(seen) > 1.5 * steady and min(seen) == 0  # what the half-second figure does
    assert state.load_avg_pct == pytest.approx(steady, rel=0.15)
    assert state.load_peak_pct == pytest.approx(steady, rel=0.15)



def test_bus_load_after_a_long_pause_of_the_loop_is_a_figure_not_a_crash():
    """The loop measured the load last more than the averaging window ago (it was busy, or the bus was
    just reopened): the average is taken over the last span, never over no time at all."""
    from app import can_bus as cb

    state = cb.CanBusState("pause-test", "can", "")
    bus = cb.CanBus("pause-test", {"interface": "virtual", "channel": "pause-test", "bitrate": 250_000}, state)  # never opened
    bus.stats.load_mark = (1000.0, 0, 0)
    bus.stats.measure_load(now=1000.5)
    state.bits += 10_000
    bus.stats.measure_load(now=1000.5 + 3 * cb.LOAD_AVERAGE_S)
    assert state.load_avg_pct == pytest.approx(10_000 / (3 * cb.LOAD_AVERAGE_S) / 250_000 * 100)

# -- Modbus monitor: filters and export (issue 32.14) ------------------------------------------------------------


def _transaction(unit: int, hex_request: str, address: int | None, values: tuple[int, ...] = (), error: str = "") -> Transaction:
    return Transaction(time=0.0, unit=unit, request="read", request_hex=hex_request, response_hex="", decoded="",
                       rtt_ms=1.0, error=error, space="holding", address=address, values=values)


def test_modbus_filters_by_unit_function_and_any_register_asked():
    from pages.monitor import parse_address, parse_unit, transaction_function, transaction_matches

    read = _transaction(2, "02 03 0b b8 00 09 07 fe", 3000, tuple(range(9)))
    failed = _transaction(1, "01 04 00 64 00 06 31 e4", 100, error="timeout")
    assert transaction_function(read) == 3 and transaction_function(failed) == 4
    assert transaction_function(_transaction(1, "", None)) is None
    assert parse_unit("") is None and parse_unit(" 2 ") == 2
    assert parse_address("3000-3010") == (3000, 3010) and parse_address("0x10") == (16, 16)
    for bad in ("248", "x"):
        with pytest.raises(ValueError):
            parse_unit(bad)
    for bad in ("70000", "20-10", "a"):
        with pytest.raises(ValueError):
            parse_address(bad)
    assert transaction_matches(read, 2, 3, (3008, 3008))
    assert not transaction_matches(read, 2, 3, (3009, 3020))  # 3000 ... 3008 asked
    assert not transaction_matches(read, 1, None, None) and not transaction_matches(read, None, 4, None)
    assert transaction_matches(failed, None, 4, (100, 100))  # unanswered: its first register
    assert not transaction_matches(failed, None, None, (101, 200))


def test_modbus_export_is_csv_a_spreadsheet_does_not_run():
    import csv
    import io

    from pages.monitor import CSV_HEADER, transactions_csv

    row = {"date": "2026-11-24 10:00:00.000", "device": "=HYPERLINK(\"x\")", "unit": 1, "function": "03 read holding registers",
           "request": "read holding 3000+9", "tx": "01 03 0b b8 00 09 07 cd", "rx": "01 03 12 00 c8", "decoded": "a = -30",
           "rtt": "0.1", "error": ""}
    lines = list(csv.reader(io.StringIO(transactions_csv([row]))))
    assert lines[0] == CSV_HEADER
    assert lines[1][1] == "'=HYPERLINK(\"x\")" and lines[1][5] == "01 03 0b b8 00 09 07 cd" and len(lines) == 2
