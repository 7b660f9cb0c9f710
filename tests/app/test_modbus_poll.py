"""The generic Modbus poll against the HD-Lock twin: every data format, writes checked against the parameter model."""

from __future__ import annotations

import contextlib
import sqlite3
import struct

import pytest

from app.modbus_poll import (
    BACKOFF_MAX_S,
    MAX_WINDOWS,
    ModbusPoll,
    NeedsConfirmation,
    PollError,
    PollSpec,
    PollWindows,
    format_register,
    pair_f32,
    pair_i32,
    pair_u32,
    rows_for,
)
from app.runtime import Runtime
from app.worker import PermissionDenied
from tests.conftest import free_port, modbus_plant, running_plant, wait_for

SERIAL = 0x3FC00000  # input 104 = 0x3FC0 (high word), 105 = 0x0000: float 1.5 high word first


@pytest.fixture
async def line(tmp_path):
    plant = modbus_plant(free_port(), locks=(("door-1", 1),), poll_period=0.2)
    plant.devices["door-1"].options["serial"] = SERIAL
    async with running_plant(plant, tmp_path, ready=("door-1",), within_s=5, stop_within_s=10) as runtime:
        yield runtime, ModbusPoll(runtime.worker, "line1")


def _audit(runtime) -> list[tuple[str, str, str]]:
    with contextlib.closing(sqlite3.connect(runtime.audit.path)) as db:
        return db.execute("select user, action, result from audit order by id").fetchall()


# -- formats (pure) ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("raw", "fmt", "text"),
    [(65506, "unsigned", "65506"), (65506, "signed", "-30"), (65506, "hex", "0xFFE2"), (65506, "binary", "11111111 11100010"),
     (0x0117, "binary", "00000001 00010111"), (0x7FFF, "signed", "32767"), (0x8000, "signed", "-32768")],
)
def test_register_formats(raw, fmt, text):
    assert format_register(raw, fmt) == text


def test_pairs_both_word_orders():
    assert pair_f32(0x3FC0, 0x0000, "ABCD") == 1.5
    assert pair_f32(0x0000, 0x3FC0, "CDAB") == 1.5
    assert pair_f32(0x4049, 0x0FDB, "ABCD") == pytest.approx(3.14159274)
    assert pair_u32(0x0001, 0x0002, "ABCD") == 0x00010002 and pair_u32(0x0001, 0x0002, "CDAB") == 0x00020001
    assert pair_i32(0xFFFF, 0xFFFE, "ABCD") == -2 and pair_i32(0xFFFE, 0xFFFF, "CDAB") == -2


def test_spec_limits():
    PollSpec(1, 3, 0, 125).check()
    for bad in (PollSpec(1, 5, 0, 1), PollSpec(1, 3, 0, 126), PollSpec(1, 1, 0, 2001), PollSpec(255, 3, 0, 1),
                PollSpec(1, 3, 65535, 2), PollSpec(1, 3, 0, 1, period_s=0.05)):
        with pytest.raises(PollError):
            bad.check()


# -- against the twin ------------------------------------------------------------------------------


async def test_poll_every_format_from_known_registers(line):
    runtime, poll = line
    spec = PollSpec(1, 4, 104, 2, period_s=0.2)
    result = await poll.poll_once(spec)
    assert result.error == "" and result.values == [0x3FC0, 0x0000]
    poll.spec = spec
    row = poll.rows()[0]
    assert "SerialNumber" in row.name or "Serial" in row.name
    assert row.cells["unsigned"] == str(0x3FC0) and row.cells["hex"] == "0x3FC0"
    assert row.cells["binary"] == "00111111 11000000"
    assert row.cells["u32 ABCD"] == str(SERIAL)
    assert row.cells["u32 CDAB"] == str(0x00003FC0)
    assert row.cells["f32 ABCD"] == "1.5"
    assert float(row.cells["f32 CDAB"]) == pytest.approx(struct.unpack(">f", struct.pack(">HH", 0x0000, 0x3FC0))[0])
    # signed: holding 3004, factory -30 (section 3.2.7)
    result = await poll.poll_once(PollSpec(1, 3, 3004, 1))
    cells = rows_for(PollSpec(1, 3, 3004, 1), result.values)[0].cells
    assert (cells["unsigned"], cells["signed"], cells["hex"]) == ("65506", "-30", "0xFFE2")


async def test_running_poll_does_not_starve_the_devices(line):
    runtime, poll = line
    counters = runtime.store.devices["door-1"].counters
    poll.start(PollSpec(1, 3, 1000, 1, period_s=0.2))
    try:
        before = counters.responses
        assert await wait_for(lambda: poll.polls >= 5, timeout=5)
        assert counters.responses > before + 10  # the lock's own poll went on meanwhile
        assert poll.errors == 0 and poll.last.values
        assert runtime.worker.lines["line1"].tool_requests >= 5
    finally:
        poll.stop()


async def test_errors_are_shown_not_raised(line):
    _runtime, poll = line
    result = await poll.poll_once(PollSpec(7, 3, 0, 1))  # nobody at unit 7
    assert result.error and poll.errors == 1
    result = await poll.poll_once(PollSpec(1, 3, 60000, 2))  # illegal data address
    assert "exception" in result.error


@pytest.mark.parametrize(
    ("address", "values", "reason"),
    [(0, [1], "never written"), (10, [1], "MFR"), (32770, [1], "never written"), (3008, [0, 0], "holding 3009 is not in the register map"),
     (50000, [1], "not in the register map")],
)
async def test_protected_registers_refused(line, address, values, reason):
    runtime, poll = line
    twin = runtime.twins["door-1"]
    before = dict(twin.holding)
    with pytest.raises(PollError, match=reason):
        await poll.write(1, address, values, user="anna", role="engineer", confirmed=True)
    assert twin.holding == before
    assert any(r.startswith("refused") and reason in r for _u, _a, r in _audit(runtime))


async def test_known_register_write_confirmed_and_audited(line):
    runtime, poll = line
    twin = runtime.twins["door-1"]
    with pytest.raises(NeedsConfirmation, match="LockRequestDelay"):
        await poll.write(1, 3000, [250], user="anna", role="engineer")
    assert twin.holding[3000] != 250
    await poll.write(1, 3000, [250], user="anna", role="engineer", confirmed=True)
    assert twin.holding[3000] == 250
    with pytest.raises(NeedsConfirmation, match="security risk|Security|security"):
        await poll.write(1, 3005, [1], user="anna", role="engineer")
    assert any(a.startswith("Modbus poll line1: write unit 1 holding 3000") and r == "ok" for _u, a, r in _audit(runtime))


async def test_viewer_cannot_write(line):
    runtime, poll = line
    twin = runtime.twins["door-1"]
    with pytest.raises(PermissionDenied):
        await poll.write(1, 3000, [250], user="tablet", role="viewer", confirmed=True)
    assert twin.holding[3000] != 250
    assert any(u == "tablet" and r.startswith("refused") for u, _a, r in _audit(runtime))


async def test_multi_register_write_to_unknown_unit(line):
    _runtime, poll = line
    # no device at unit 9: no confirmation needed; nobody answers, so the write fails with the line's error
    with pytest.raises(Exception, match="unit 9"):
        await poll.write(9, 100, [1, 2], user="anna", role="engineer")


# -- issue 32.14 ------------------------------------------------------------------------------------------------


def test_byte_swapped_orders():
    """Besides ABCD and CDAB, devices send 32-bit values with the bytes of each word swapped (BADC, DCBA)."""
    assert pair_u32(0x0201, 0x0403, "BADC") == 0x01020304
    assert pair_u32(0x0403, 0x0201, "DCBA") == 0x01020304
    assert pair_f32(0xC03F, 0x0000, "BADC") == 1.5 and pair_f32(0x0000, 0xC03F, "DCBA") == 1.5
    assert pair_i32(0xFFFF, 0xFEFF, "BADC") == -2
    row = rows_for(PollSpec(1, 3, 0, 2), [0xC03F, 0x0000])[0]
    assert row.cells["f32 BADC"] == "1.5"


async def test_address_fields_offer_0_to_65535_and_follow_the_counting(tmp_path):
    """32.14: the fields said "allowed 0 .. 65536"; 0-based addresses end at 65535, 1-based ones run 1 .. 65536."""
    from nicegui import ui
    from webutil import simulated_user

    runtime = Runtime(modbus_plant(free_port(), locks=(("door-1", 1),)), simulate=True, data_dir=tmp_path)
    async with simulated_user(runtime) as user:
        await user.open("/monitor/line1/poll")
        await user.should_see("Start address")
        start = next(e for e in user.find(ui.number).elements if e.props.get("label") == "Start address")
        assert start.props.get("hint") == "allowed 0 .. 65535"
        start.set_value(65536)
        assert not start.validate()
        base = next(e for e in user.find(ui.select).elements
                    if e.props.get("label") == "Addresses" and "poll-write-base" not in str(e.props.get("data-testid")))
        base.set_value(1)
        assert start.props.get("hint") == "allowed 1 .. 65536" and start.validate()


async def test_coil_writes_go_through_the_send_policy(line):
    runtime, poll = line
    # unit 1 is an HD-Lock: it has no coils (section 5), refused by its policy and audited
    with pytest.raises(PollError, match="no coils"):
        await poll.write_coils(1, 0, [True], user="anna", role="engineer", confirmed=True)
    # unit 9 is on an all-HD-Lock line: checked as an HD-Lock, refused too
    with pytest.raises(PollError, match="no coils"):
        await poll.write_coils(9, 0, [True, False], user="anna", role="engineer", confirmed=True)
    refused = [a for _u, a, r in _audit(runtime) if r.startswith("refused") and "coil" in a]
    assert len(refused) >= 2 and "function 05" in refused[0] and "function 15" in refused[1]


# -- issue 32.14: several poll windows at once ------------------------------------------------------------


async def test_windows_take_turns_and_a_silent_unit_does_not_starve_the_others(line):
    """Three windows on one line, one of them asking a unit nobody answers: the two others keep their pace,
    the silent one backs off, and the devices' own poll goes on between them."""
    runtime, _poll = line
    counters = runtime.store.devices["door-1"].counters
    windows = PollWindows(runtime.worker, "line1")
    silent, holding, inputs = windows.add(), windows.add(), windows.add()
    assert [w.number for w in windows.windows] == [1, 2, 3]
    silent.start(PollSpec(7, 3, 0, 1, period_s=0.2))  # nobody at unit 7: each try costs the 0.2 s timeout
    holding.start(PollSpec(1, 3, 3000, 2, period_s=0.2))
    inputs.start(PollSpec(1, 4, 104, 2, period_s=0.2))
    before = counters.responses
    try:
        assert await wait_for(lambda: holding.polls >= 8 and inputs.polls >= 8, timeout=8), \
            (holding.polls, inputs.polls, silent.polls)
        assert holding.errors == 0 and inputs.errors == 0
        assert inputs.rows()[0].name.endswith("SerialNumber (word 1 of 2)")
        assert silent.timeouts >= 2 and silent.silent >= 2
        assert silent.polls < holding.polls / 2, (silent.polls, holding.polls)  # backed off, not every 0.2 s
        assert counters.responses > before + 5  # the lock's own poll went on between the windows
        assert holding.last_answer is not None and silent.last_answer is None
    finally:
        windows.stop()
    assert windows.running == 0


def test_a_silent_window_backs_off_up_to_a_bound():
    window = ModbusPoll.__new__(ModbusPoll)
    spec = PollSpec(7, 3, 0, 1, period_s=0.2)
    window.silent = 0
    assert window.interval_s(spec) == 0.2
    window.silent = 3
    assert window.interval_s(spec) == pytest.approx(1.6)
    window.silent = 20
    assert window.interval_s(spec) == BACKOFF_MAX_S
    window.silent = 1
    assert window.interval_s(PollSpec(7, 3, 0, 1, period_s=30)) == 30  # never faster than its own period


async def test_windows_are_numbered_and_bounded(line):
    runtime, _poll = line
    windows = PollWindows(runtime.worker, "line1")
    opened = [windows.add() for _ in range(MAX_WINDOWS)]
    with pytest.raises(PollError, match=f"at most {MAX_WINDOWS}"):
        windows.add()
    opened[1].start(PollSpec(1, 3, 1000, 1))
    windows.remove(opened[1])
    assert not opened[1].running and len(windows.windows) == MAX_WINDOWS - 1
    assert windows.add().number == MAX_WINDOWS + 1  # a new window never takes an open one's number


async def test_a_window_tells_its_page_of_every_answer(line):
    """The page shows each answer as it comes (not at its next timer tick), a broken listener does not end the poll."""
    _runtime, poll = line
    heard = []
    poll.listeners += [lambda: heard.append(poll.polls), lambda: 1 / 0]
    await poll.poll_once(PollSpec(1, 3, 1000, 1))
    await poll.poll_once(PollSpec(7, 3, 0, 1))  # no answer: told too
    assert heard == [1, 2]
