"""DBC export (issue 17 item 4): the demo plant's CAN buses written through cantools, loaded back
(strict), and the twins' frames decoded to the values the device codecs (and so the adapters) give."""

from __future__ import annotations

import argparse
from pathlib import Path

import cantools
import pytest

from app import dbc
from app.plant import load_plant
from devices.electrak import codec as electrak
from devices.electrak.sim import ElectrakNetworkTwin
from devices.hdlock import codec as hdlock
from devices.hdlock.sim import HdLockTwin
from devices.m3io import codec as m3io
from devices.m3io.sim import M3ioTwin

DEMO = Path(__file__).resolve().parents[2] / "plants" / "demo.toml"


@pytest.fixture(scope="module")
def plant():
    return load_plant(DEMO)


def _db(plant, bus: str):
    return cantools.database.load_string(dbc.dbc_text(plant, bus), database_format="dbc", strict=True)


def test_ids_and_extended_flags(plant):
    can1 = _db(plant, "can1")
    gate1 = can1.get_message_by_name("gate_1_HDLock")
    assert (gate1.frame_id, gate1.is_extended_frame) == (660100, True)  # device ID above 0x7FF: extended (6.6.2)
    gate2 = can1.get_message_by_name("gate_2_HDLock")
    assert (gate2.frame_id, gate2.is_extended_frame) == (11, False)
    assert "BO_ 2148143748 gate_1_HDLock" in dbc.dbc_text(plant, "can1")  # DBC's extended flag: bit 31 of the ID
    assert "spare" not in dbc.dbc_text(plant, "can1")  # only devices of the plant file
    can3 = _db(plant, "can3")
    for name, sw1 in (("heater_hm", 0x1A), ("heater_hmr", 0xCA)):
        ids = m3io.derive_ids(sw1)
        want = {f"{name}_DigOut": ids.dig_out, f"{name}_DigIn": ids.dig_in, f"{name}_Temp1_4": ids.temp14,
                f"{name}_Temp5_6": ids.temp56, f"{name}_Sync": ids.sync}
        if ids.mdata is not None:
            want[f"{name}_MData"] = ids.mdata  # addressed mode (S8 on) only
        assert {m.name: m.frame_id for m in can3.messages if m.name.rsplit("_", 2)[0] == name or m.name.rsplit("_", 1)[0] == name} == want
        assert not any(m.is_extended_frame for m in can3.messages)
    assert can3.get_message_by_name("heater_hm_DigOut").frame_id == 0x422  # SPEC-NOTES check values
    assert can3.get_message_by_name("heater_hmr_DigOut").frame_id == 0x20A
    assert {m.name: m.frame_id for m in can1.messages if m.name.startswith("HDLock_")} == {
        f"HDLock_{codec_name.replace(' ', '').replace('-', '')}": can_id for can_id, codec_name in hdlock.CAN_REQUEST_NAMES.items()}
    can2 = _db(plant, "can2")
    assert {m.name: m.frame_id for m in can2.messages} == {
        "lift_Control": 0x06, "lift_Status": 0x07, "lift_ServiceRequest": 0x0A, "lift_ServiceResponse": 0x0B}


def test_hdlock_twin_frames_decode_like_the_codec(plant):
    msg = _db(plant, "can1").get_message_by_name("gate_1_HDLock")
    twin = HdLockTwin(serial=660100, door_closed=True)
    frames = []
    for _ in range(40):  # the bolt moves out: status words change
        twin.step(0.05)
        status = hdlock.StatusFrame(twin.holding[1000], twin.holding[1001], twin.input[7], twin.holding[hdlock.REG_LOCK_REQUEST_SOURCE])
        frames.append(hdlock.encode_status(status))  # as HdLockCanSim.status_data builds it
    frames.append(hdlock.encode_status(hdlock.StatusFrame(0x0117, 1234, 1000, 0x85)))  # a source beyond 6 bits
    assert len({f[2:4] for f in frames}) >= 2
    for data in frames:
        want = hdlock.decode_lock_frame(data)
        got = msg.decode(data, decode_choices=False)
        assert got["FrameKind"] == 0
        assert sum(got[f"LockStatus_{n.replace(' (bit 4)', '_bit4')}"] << bit for bit, n in hdlock.LOCK_STATUS_NAMES.items()) \
            == want.status & sum(1 << b for b in hdlock.LOCK_STATUS_NAMES)
        assert (got["MotorPos"], got["Proximity"], got["LockRequestSource"]) == (want.motor_pos, want.proximity, want.lock_request_source)
    answer = hdlock.encode_register_answer(hdlock.RegisterAnswer("holding", 3005, 1))  # 6 bytes (6.5.4)
    assert msg.decode(answer, allow_truncated=True) == {"FrameKind": "HoldingRegisterAnswer", "HoldingRegisterAddress": 3005, "HoldingRegisterValue": 1}
    answer = hdlock.encode_register_answer(hdlock.RegisterAnswer("input", 104, 0x000A))
    assert msg.decode(answer, allow_truncated=True)["InputRegisterValue"] == 10


def test_m3io_twin_frames_decode_like_the_codec(plant):
    db = _db(plant, "can3")
    for name, variant, sw1 in (("heater_hm", m3io.Variant.HM, 0x1A), ("heater_hmr", m3io.Variant.HMR, 0xCA)):
        twin = M3ioTwin(variant, sw1)
        twin.toggle_input("E2")
        twin.toggle_input("E6")
        twin.temps_tenths[4] = -55  # out of range below 0
        twin.temps_tenths[5] = 1999
        got = db.get_message_by_name(f"{name}_DigIn").decode(twin.dig_in())
        assert got == {k: int(v) for k, v in m3io.decode_dig_in(twin.dig_in()).items()}
        for can_id, data in twin.temp_frames():
            words = m3io.decode_temps(data, len(data) // 2)
            message = db.get_message_by_frame_id(can_id)
            got = message.decode(data)
            first = 1 if can_id == twin.ids.temp14 else 5
            for n, word in enumerate(words, start=first):
                assert got[f"T{n}_Temp"] == pytest.approx(word.celsius)
                assert (got[f"T{n}_Last"], got[f"T{n}_Triac"], got[f"T{n}_Si"], got[f"T{n}_sb"]) == \
                    (word.load, word.triac, word.fuse, word.sb)
        outputs = {n: i % 2 == 0 for i, n in enumerate(m3io.OUTPUT_BITS[variant])}
        data = m3io.encode_dig_out(variant, outputs)
        got = db.get_message_by_name(f"{name}_DigOut").decode(data)
        assert {k: bool(v) for k, v in got.items() if k != "REQ"} == {k.replace("-", "_"): v for k, v in outputs.items()}
        assert db.get_message_by_name(f"{name}_DigOut").encode({**{k.replace("-", "_"): int(v) for k, v in outputs.items()}, "REQ": 0}) == data


def test_electrak_twin_frames_decode_like_the_codec(plant):
    db = _db(plant, "can2")
    status = db.get_message_by_name("lift_Status")
    twin = ElectrakNetworkTwin([electrak.Actuator("HD24", "B026", 300), electrak.Actuator("HD24", "B026", 300)])
    twin.on_control(electrak.ControlFrame(150.0, 0.0, 20.0, enable=True), 0.0)
    frames = []
    for i in range(1, 30):
        twin.on_control(electrak.ControlFrame(150.0, 0.0, 20.0, enable=True), i * 0.1)
        twin.step(0.1, i * 0.1)
        frames += [twin.status(a).encode() for a in twin.actuators]
    assert len(set(frames)) > 5
    for data in frames:
        want = electrak.StatusFrame.decode(data)
        got = status.decode(data)
        assert (round(got["Position"], 1), round(got["Current"], 1), round(got["Speed"], 1)) == \
            (want.position_mm, want.current_a, want.speed_mm_s)
        assert sorted(n for n, _ in electrak.MOTION_FLAGS.values() if got[n.replace(" ", "_")]) == sorted(want.motion_names)
        assert sorted(n for n, *_ in electrak.ERROR_FLAGS.values() if got[n.replace(" ", "_")]) == sorted(want.error_names)
    control = db.get_message_by_name("lift_Control")
    example = bytes.fromhex("E8034100BE030001")  # the document's control example
    got = control.decode(example)
    assert (got["TargetPosition"], got["CurrentLimit"], got["Enable"]) == (100.0, 6.5, 1)  # SPEC-NOTES: position, current
    assert got["TargetSpeed"] == pytest.approx(95.8)
    frame = electrak.ControlFrame(123.4, 5.0, 12.3, enable=True, override=True)
    assert control.encode({"TargetPosition": 123.4, "CurrentLimit": 5.0, "TargetSpeed": 12.3, "Enable": 1, "Override": 1}) == frame.encode()
    service = db.get_message_by_name("lift_ServiceResponse")
    answer = electrak.ServiceMessage(electrak.ServiceType.READ_RESPONSE, 0x20, 4, 250)
    assert service.decode(answer.encode()) == {"Type": "READ_RESPONSE", "Specifier": 0x20, "Length": 4, "Payload": 250}


def test_dbc_text_takes_the_worker(plant):
    class FakeWorker:
        def __init__(self, plant):
            self.plant = plant

    assert dbc.dbc_text(FakeWorker(plant), "can2") == dbc.dbc_text(plant, "can2")
    with pytest.raises(dbc.DbcError, match="line1 is a modbus-rtu bus"):
        dbc.dbc_text(plant, "line1")
    with pytest.raises(dbc.DbcError, match="no bus named 'nope'"):
        dbc.dbc_text(plant, "nope")


def test_command_line(tmp_path: Path, capsys: pytest.CaptureFixture):
    parser = argparse.ArgumentParser(prog="commission")
    dbc.add_parser(parser.add_subparsers(dest="command"))
    out = tmp_path / "can3.dbc"
    args = parser.parse_args(["dbc", "--plant", str(DEMO), "--bus", "can3", "--out", str(out)])
    assert args.func is dbc.run and dbc.run(args) == 0
    assert "wrote" in capsys.readouterr().out
    db = cantools.database.load_file(out, strict=True)
    assert len(db.messages) == 11  # 2 x (DigOut, DigIn, 2 temperature frames, Sync) + the HMR's MData
    bad = parser.parse_args(["dbc", "--plant", str(DEMO), "--bus", "rs232-1", "--out", str(tmp_path / "x.dbc")])
    assert dbc.run(bad) == 2 and "CAN buses only" in capsys.readouterr().err
    assert not (tmp_path / "x.dbc").exists()


def test_hdlock_request_frames_decode_like_the_codec(plant):
    """26.8: the requests of section 6.6 (0x700-0x707) are in the DBC once per bus, whatever the number of locks."""
    db = _db(plant, "can1")
    target = hdlock.DeviceId.make(335, True)
    write = hdlock.encode_write(target, 3000, 250)
    got = db.decode_message(write.arbitration_id, bytes(write.data))
    assert (got["TargetDeviceId"], got["TargetExtended"], got["RegisterAddress"], got["Value"]) == (335, 1, 3000, 250)
    read = hdlock.encode_read(target, "holding", 1000, 3)
    got = db.decode_message(read.arbitration_id, bytes(read.data))
    assert (got["TargetDeviceId"], got["RegisterAddress"], got["Count"]) == (335, 1000, 3)
    new = hdlock.encode_set_device_address(hdlock.DeviceId.make(11), hdlock.DeviceId.make(0x1A2B))
    got = db.decode_message(new.arbitration_id, bytes(new.data))
    assert (got["TargetDeviceId"], got["NewDeviceId"], got["NewExtended"]) == (11, 0x1A2B, 1)
    assert sum(1 for m in db.messages if m.frame_id == hdlock.CAN_COMMAND) == 1


def test_m3io_sync_and_mdata_frames_and_no_temperatures_for_a_km(tmp_path):
    text = DEMO.read_text() + '\n[[device]]\nname = "relay-km"\ntype = "m3io"\nbus = "can3"\nvariant = "KM"\nsw1 = 0x1C\n'
    path = tmp_path / "plant.toml"
    path.write_text(text)
    db = _db(load_plant(path), "can3")
    names = {m.name for m in db.messages}
    assert "relay_km_DigOut" in names and "relay_km_Sync" in names
    assert not {"relay_km_Temp1_4", "relay_km_Temp5_6"} & names  # a KM has no Pt100 inputs (section 4.1)
    ids = m3io.derive_ids(0xCA)
    got = db.decode_message(ids.sync, m3io.encode_sync_request(m3io.AREA_READ_CONFIG, m3io.CONFIG_SERIAL) + bytes(6),
                            decode_choices=False)
    assert (got["Area"], got["Index"]) == (m3io.AREA_READ_CONFIG, m3io.CONFIG_SERIAL)
    answer = bytes([m3io.AREA_READ_CONFIG, m3io.CONFIG_SERIAL]) + (42120023).to_bytes(4, "little") + b"\xff\xff"
    got = db.decode_message(ids.mdata, answer, decode_choices=False)
    assert (got["Area"], got["Index"], got["Payload"] & 0xFFFFFFFF) == (2, 1, 42120023)
    hm = m3io.derive_ids(0x1A)
    assert db.decode_message(hm.sync, m3io.encode_sync_cfg(True), decode_choices=False, allow_truncated=True)["P2"] == 1
