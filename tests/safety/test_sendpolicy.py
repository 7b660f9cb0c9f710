"""The one send policy (issue 26): every raw send path asks the device types' policies.

Replay filters what a policy forbids or would confirm (26.1); the Modbus poll window applies the
line's device type to a unit that is not in the plant and confirms every write to a unit of no
known type (26.2) and names the parameter in the audit (32.9); the transmit list asks the mains
confirmation of an M3IO DigOut with an SSR on (32.15); LockRequestSource 0x80-0x87 asks the same
confirmation on every path (26.6).
"""

from __future__ import annotations

import asyncio
import contextlib
import sqlite3

import can
import pytest

from app import replay as rp
from app import transmit as tx
from app.can_bus import FrameRecord
from app.modbus_poll import ModbusPoll, NeedsConfirmation, PollError
from devices.hdlock.params import PARAMS as HDLOCK_PARAMS
from devices.sendpolicy import BusDevice, ModbusMessage, check_can, check_modbus
from tests.conftest import free_port, modbus_plant, running_plant, wait_for

LOCK_EXT = bytes.fromhex("4F 01 00 80")  # extended device 335 (section 6.4 example)


def _drain(listener: can.BusABC) -> list[can.Message]:
    got = []
    while (msg := listener.recv(0)) is not None:
        got.append(msg)
    return got


def _audit(runtime) -> list[tuple]:
    with contextlib.closing(sqlite3.connect(runtime.audit.path)) as db:
        return db.execute("select user, action, parameter, result from audit order by id").fetchall()


# -- pure ------------------------------------------------------------------------------------------------


def test_lock_request_source_door_ignored_is_confirmed_on_every_path():
    for address in (4, 1002):
        param = HDLOCK_PARAMS.get("holding", address)
        assert "ignores the door" in param.needs_confirmation(0x81)
        assert param.needs_confirmation(0x04) == ""
    lock = [BusDevice("lock", "hdlock", {"device_id": 335, "extended": True})]
    command = check_can(lock, 0x700, False, LOCK_EXT + bytes([0, 0, 0x81, 0]))  # cmdSetLockRequestSource 0x81
    assert command.allowed and any("ignores the door" in c for c in command.confirm)
    write = check_can(lock, 0x704, False, LOCK_EXT + bytes([0xEA, 0x03, 0x85, 0]))  # holding 1002 = 0x85
    assert write.allowed and any("ignores the door" in c for c in write.confirm)
    modbus = check_modbus([BusDevice("door", "hdlock", {"address": 1})], ModbusMessage(1, 6, 4, (0x80,)))
    assert any("ignores the door" in c for c in modbus.confirm)


def test_unknown_unit_gets_its_lines_type_or_a_confirmation():
    locks = [BusDevice("door-1", "hdlock", {"address": 1})]
    for address, value, word in ((32770, 1, "firmware"), (0, 65535, "factory"), (2003, 3, "system-command")):
        verdict = check_modbus(locks, ModbusMessage(5, 6, address, (value,)))
        assert word in verdict.refused, verdict
    unknown = check_modbus([], ModbusMessage(5, 6, 100, (1,)))
    assert unknown.allowed and "not a device of the plant" in unknown.question
    coils = check_modbus([], ModbusMessage(5, 5, 0, (1,)))
    assert coils.allowed and coils.confirm


def test_m3io_digout_with_an_ssr_is_mains():
    heater = [BusDevice("heater", "m3io", {"sw1": 0x1A, "variant": "HM"})]
    mains = check_can(heater, 0x422, False, b"\x03")  # LED + SSR1
    assert mains.kind == "mains" and "SSR1" in mains.question
    led = check_can(heater, 0x422, False, b"\x01")
    assert led.allowed and not led.confirm


# -- replay (26.1) ------------------------------------------------------------------------------------------


async def test_replay_keeps_forbidden_and_risky_frames_off_the_bus(can_rig):
    runtime, listener = can_rig
    t0 = 1000.0
    frames = [
        FrameRecord(t0 + 0.00, 0x123, False, 2, b"\x01\x02", "rx"),  # a frame of nobody's: sent
        FrameRecord(t0 + 0.01, 0x700, False, 5, b"\x00\x00\x00\x00\x02", "rx"),  # cmdFirmwareUpdateEnter
        FrameRecord(t0 + 0.02, 0x706, False, 6, LOCK_EXT + b"\x00\x00", "rx"),  # FWU erase sector
        FrameRecord(t0 + 0.03, 0x704, False, 8, LOCK_EXT + bytes([0x02, 0x80, 1, 0]), "rx"),  # 32770 = 1
        FrameRecord(t0 + 0.04, 0x06, False, 8, bytes.fromhex("E8 03 41 00 BE 03 00 01"), "rx"),  # Electrak enable
        FrameRecord(t0 + 0.05, 0x422, False, 1, b"\x02", "rx"),  # M3IO DigOut SSR1 on
        FrameRecord(t0 + 0.06, 0x703, False, 8, LOCK_EXT + bytes([0xE8, 0x03, 1, 0]), "rx"),  # a read: sent
    ]
    screening = await asyncio.to_thread(rp.screen, runtime.worker, "can1", frames)
    assert len(screening.blocked) == 5 and "firmware" in screening.text()
    replay = await rp.start_replay(runtime.worker, "can1", frames, name="probe.log", speed=10.0, session="s1",
                                  confirmed=True)
    assert await wait_for(lambda: replay.state == "done", timeout=5)
    assert replay.sent == 2 and replay.filtered == 5
    assert await wait_for(lambda: True, timeout=0.05) is True
    sent = {(m.arbitration_id, bytes(m.data)) for m in _drain(listener)}
    assert sent <= {(0x123, b"\x01\x02"), (0x703, LOCK_EXT + bytes([0xE8, 0x03, 1, 0]))}, sent
    assert (0x700, b"\x00\x00\x00\x00\x02") not in sent and (0x422, b"\x02") not in sent
    assert "kept off the bus" in replay.summary()


# -- transmit list (32.15) ------------------------------------------------------------------------------------


async def test_transmit_digout_with_mains_ssr_asks_first(can_rig):
    runtime, listener = can_rig
    tl = tx.transmit_list(runtime.worker, "can1", runtime.data_dir)
    await tl.load()
    row = await tl.add(tx.named_row("m3io", "heater", {"sw1": 0x1A, "variant": "HM"}, "DigOut", {"SSR1": True}), user="anna", role="engineer")
    _drain(listener)
    with pytest.raises(tx.NeedsConfirmation, match="mains"):
        await tl.send_once(row.key, user="anna", role="engineer")
    assert await wait_for(lambda: False, timeout=0.1) is False
    assert not [m for m in _drain(listener) if m.arbitration_id == 0x422 and m.data[0] & 0x7E]
    await tl.send_once(row.key, user="anna", role="engineer", confirmed=True)
    assert await wait_for(lambda: any(m.arbitration_id == 0x422 and m.data[0] == 0x02 for m in _drain(listener)), timeout=2)


async def test_transmit_named_rows_may_be_cyclic(can_rig):
    runtime, _listener = can_rig
    tl = tx.transmit_list(runtime.worker, "can1", runtime.data_dir)
    await tl.load()
    built = tx.named_row("hdlock", "lock", {"device_id": 335, "extended": True}, "register", {"operation": "holding", "register": 1000, "count": 1})
    row = await tl.add(tx.make_row(built.can_id, built.extended, built.data, 200, built.label), user="anna", role="engineer")
    await tl.start(row.key, user="anna", role="engineer", session="tab")
    assert await wait_for(lambda: tl.sent.get(row.key, 0) >= 2, timeout=3)
    await tl.stop(row.key, user="anna", role="engineer")


# -- Modbus poll window (26.2, 32.9) ---------------------------------------------------------------------------


@pytest.fixture
async def line(tmp_path):
    plant = modbus_plant(free_port(), locks=(("door-1", 1),), poll_period=0.2)
    async with running_plant(plant, tmp_path, ready=("door-1",), within_s=5, stop_within_s=10) as runtime:
        yield runtime, ModbusPoll(runtime.worker, "line1")


@pytest.mark.parametrize(("address", "value"), [(32770, 1), (0, 65535), (2003, 3)])
async def test_poll_refuses_firmware_and_factory_reset_on_a_unit_not_in_the_plant(line, address, value):
    runtime, poll = line
    with pytest.raises(PollError, match="unit 5"):
        await poll.write(5, address, [value], user="anna", role="engineer", confirmed=True)
    assert any(r.startswith("refused") for *_x, r in _audit(runtime))


async def test_poll_write_is_audited_by_parameter_name(line):
    runtime, poll = line
    with pytest.raises(NeedsConfirmation):
        await poll.write(1, 3000, [210], user="anna", role="engineer")
    await poll.write(1, 3000, [210], user="anna", role="engineer", confirmed=True)
    rows = [r for r in _audit(runtime) if r[1].startswith("Modbus poll") and r[3] == "ok"]
    assert rows and "LockRequestDelay" in rows[-1][2], rows
