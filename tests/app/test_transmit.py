"""The engineer's CAN transmit list: once and cyclic on a virtual bus, refusals by name, dead-man stop, saved list."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import sqlite3
import time

import can
import pytest

from app.transmit import (
    TransmitError,
    forbidden_reason,
    named_row,
    make_row,
    parse_bytes,
    transmit_list,
)
from app.worker import DEADMAN_BOUND_S, PermissionDenied
from tests.conftest import alive, wait_for

SESSION = "tx-tab"
LOCK = {"device_id": 335, "extended": True}


async def _frames(listener: can.BusABC, can_id: int, seconds: float) -> list[can.Message]:
    got, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        msg = listener.recv(0)
        if msg is None:
            await asyncio.sleep(0.002)
        elif msg.arbitration_id == can_id:
            got.append(msg)
    return got


def _audit(runtime) -> list[tuple[str, str, str]]:
    with contextlib.closing(sqlite3.connect(runtime.audit.path)) as db:
        return db.execute("select user, action, result from audit order by id").fetchall()


# -- pure rules ----------------------------------------------------------------------------------


def test_rows_are_checked():
    assert parse_bytes("01 02 ff") == b"\x01\x02\xff" == parse_bytes("0102FF")
    with pytest.raises(TransmitError):
        parse_bytes("01 02 03 04 05 06 07 08 09")
    with pytest.raises(TransmitError, match="11-bit"):
        make_row(0x800, False, b"")
    make_row(0x1FFFFFFF, True, b"")
    with pytest.raises(TransmitError, match="DLC"):
        make_row(0x100, False, b"\x01", dlc=2)
    with pytest.raises(TransmitError, match="cycle time"):
        make_row(0x100, False, b"", period_ms=5)
    with pytest.raises(TransmitError, match="cycle time"):
        make_row(0x100, False, b"", period_ms=10_001)


@pytest.mark.parametrize(
    ("can_id", "data", "name"),
    [
        (0x706, b"\x4f\x01\x00\x80\x00\x00", "FWU erase sector"),
        (0x707, b"\x4f\x01\x00\x80\x00\x00\x00\x00", "FWU write flash"),
        (0x700, b"\x00\x00\x00\x00\x02", "FIRMWARE_UPDATE_ENTER"),
        (0x700, b"\x4f\x01\x00\x80\x03\x00\x00\x00", "BOOTLOADER_UPDATE_ENTER"),
        (0x700, b"\x4f\x01\x00\x80\x04\x00", "UPDATE_LEAVE"),
        (0x704, b"\x4f\x01\x00\x80\x02\x80\x01\x00", "FwUpdateCommandRegister"),
        (0x705, b"\x4f\x01\x00\x80\x00\x00\x01\x00", "SettingsRevision"),
    ],
)
def test_forbidden_frames_are_named(can_id, data, name):
    assert name in forbidden_reason(can_id, False, data)


def test_allowed_frames_pass():
    # section 6.6.1 example: cmdSetLockRequestSource IrsAlways to extended device 335
    assert forbidden_reason(0x700, False, bytes.fromhex("4F 01 00 80 00 00 81 00")) is None
    assert forbidden_reason(0x706, True, b"") is None  # an extended 0x706 is not the lock's request block
    row = named_row("hdlock", "lock", LOCK, "register", {"operation": "holding", "register": 1000, "count": 1})
    assert (row.can_id, row.extended, row.data.hex(" ")) == (0x703, False, "4f 01 00 80 e8 03 01 00")
    assert "LockStatus" in row.label
    with pytest.raises(TransmitError):
        named_row("hdlock", "lock", LOCK, "register", {"operation": "write", "register": 32770, "count": 1})
    dig = named_row("m3io", "heater", {"sw1": 0x1A, "variant": "HM"}, "DigOut", {"LED": True, "SSR1": True})
    assert (dig.can_id, dig.data) == (0x422, b"\x03")


# -- against the bus ---------------------------------------------------------------------------------


async def _can1_list(runtime):
    """The transmit list of can1, loaded from the runtime's data folder."""
    tl = transmit_list(runtime.worker, "can1", runtime.data_dir)
    await tl.load()
    return tl


async def _cyclic_row(runtime, can_id: int, data: bytes, period_ms: int):
    """can1's transmit list with a cyclic row of ``can_id`` added by an engineer; the list and the row."""
    tl = await _can1_list(runtime)
    return tl, await tl.add(make_row(can_id, False, data, period_ms=period_ms), user="anna", role="engineer")


async def test_send_once_and_audit(can_rig):
    runtime, listener = can_rig
    tl = await _can1_list(runtime)
    row = await tl.add(named_row("hdlock", "lock", LOCK, "register", {"operation": "input", "register": 104, "count": 2}), user="anna", role="engineer")
    await tl.send_once(row.key, user="anna", role="engineer")
    got = await _frames(listener, 0x702, 0.3)
    assert [bytes(m.data) for m in got] == [bytes.fromhex("4F 01 00 80 68 00 02 00")]
    actions = [a for _u, a, r in _audit(runtime) if r == "ok"]
    assert any(a.startswith("transmit once on can1: 0x702") for a in actions)


async def test_cyclic_row_keeps_its_period_and_stops(can_rig):
    runtime, listener = can_rig
    tl, row = await _cyclic_row(runtime, 0x321, b"\xaa\x55", 20)
    async with alive(runtime.worker, SESSION):
        await tl.start(row.key, user="anna", role="engineer", session=SESSION)
        got = await _frames(listener, 0x321, 1.0)
        assert 35 <= len(got) <= 65  # about 50 frames in 1 s at 20 ms
        gaps = [b.timestamp - a.timestamp for a, b in itertools.pairwise(got)]
        assert sorted(gaps)[len(gaps) // 2] == pytest.approx(0.020, abs=0.008)
        await tl.stop(row.key, user="anna", role="engineer")
        await _frames(listener, 0x321, 0.05)
        assert await _frames(listener, 0x321, 0.2) == []
    actions = [a for _u, a, _r in _audit(runtime)]
    assert any("start 0x321" in a for a in actions) and any("stop 0x321" in a for a in actions)


@pytest.mark.parametrize(("can_id", "data"), [(0x706, b"\x00" * 6), (0x700, b"\x00\x00\x00\x00\x02")])
async def test_forbidden_refused_by_name_and_audited(can_rig, can_id, data):
    runtime, listener = can_rig
    tl = await _can1_list(runtime)
    with pytest.raises(TransmitError, match="firmware-update"):
        await tl.add(make_row(can_id, False, data), user="anna", role="engineer")
    # a list edited on disk is checked again when sending
    row = make_row(can_id, False, data)
    tl.rows.append(row)
    with pytest.raises(TransmitError, match="firmware-update"):
        await tl.send_once(row.key, user="anna", role="engineer")
    assert await _frames(listener, can_id, 0.2) == []
    refused = [(a, r) for _u, a, r in _audit(runtime) if r.startswith("refused")]
    assert len(refused) == 2 and all("firmware-update" in r for _a, r in refused)


async def test_viewer_refused(can_rig):
    runtime, listener = can_rig
    tl = await _can1_list(runtime)
    row = await tl.add(make_row(0x123, False, b"\x01", period_ms=50), user="anna", role="engineer")
    with pytest.raises(PermissionDenied):
        await tl.send_once(row.key, user="tablet", role="viewer")
    with pytest.raises(PermissionDenied):
        await tl.start(row.key, user="tablet", role="viewer", session=SESSION)
    with pytest.raises(PermissionDenied):
        await tl.add(make_row(0x124, False, b""), user="tablet", role="viewer")
    assert await _frames(listener, 0x123, 0.2) == []
    assert not tl.running
    assert sum(1 for u, _a, r in _audit(runtime) if u == "tablet" and r.startswith("refused")) == 3


async def test_cyclic_rows_stop_when_the_session_is_lost(can_rig):
    runtime, listener = can_rig
    tl, row = await _cyclic_row(runtime, 0x222, b"\x01", 10)
    async with alive(runtime.worker, SESSION):
        await tl.start(row.key, user="anna", role="engineer", session=SESSION)
        assert len(await _frames(listener, 0x222, 0.5)) > 20  # kept alive by the heartbeat
    frozen = time.monotonic()  # the browser stops confirming
    assert await wait_for(lambda: not tl.running, timeout=2)
    stopped_after = time.monotonic() - frozen
    await _frames(listener, 0x222, 0.05)
    assert await _frames(listener, 0x222, 0.2) == []
    assert stopped_after <= DEADMAN_BOUND_S
    assert await wait_for(lambda: any("stopped: dead-man" in a for _u, a, _r in _audit(runtime)), timeout=2)


async def test_closed_session_stops_its_rows(can_rig):
    runtime, _listener = can_rig
    tl = await _can1_list(runtime)
    row = await tl.add(make_row(0x223, False, b"", period_ms=100), user="anna", role="engineer")
    runtime.worker.heartbeat("other")
    await tl.start(row.key, user="anna", role="engineer", session="other")
    runtime.worker.session_closed("other")
    assert not tl.running and not runtime.worker.can_buses["can1"].cyclic_running(f"transmit can1 {row.key}")


async def test_list_saved_per_bus_and_restored(can_rig):
    runtime, _listener = can_rig
    tl = await _can1_list(runtime)
    await tl.add(make_row(0x1ABCDEF, True, b"\x01\x02", period_ms=250, label="x"), user="anna", role="engineer")
    await tl.add(named_row("m3io", "heater", {"sw1": 0x1A, "variant": "HM"}, "DigOut", {"LED": True}), user="anna", role="engineer")
    assert (runtime.data_dir / "transmit-can1.json").exists()
    runtime.worker.remove_holder("transmit:can1")
    again = transmit_list(runtime.worker, "can1", runtime.data_dir)
    assert again is not tl
    await again.load()
    assert [(r.can_id, r.extended, r.data, r.period_ms) for r in again.rows] == [
        (0x1ABCDEF, True, b"\x01\x02", 250), (0x422, False, b"\x01", None)]


def test_electrak_enable_refused_on_every_can_bus():
    # 0x06 is an ID the Electrak reserves on every CAN bus (its fixed IDs): a replayed or typed control
    # telegram with enable drives any network that listens, configured in the plant or not
    control = bytes.fromhex("E8 03 41 00 BE 03 00 01")  # enable set (section example)
    assert "Electrak" in forbidden_reason(0x06, False, control, [("electrak", {})])
    assert "Electrak" in forbidden_reason(0x06, False, control, [("m3io", {})])
    assert forbidden_reason(0x06, False, control[:7] + b"\x00", [("electrak", {})]) is None  # enable clear: stops
