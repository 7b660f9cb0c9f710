"""HD-Lock adapter against its twin over a real pymodbus RTU conversation on a localhost socket."""

from __future__ import annotations

import asyncio

import pytest
from conftest import modbus_plant, running_plant, spy_writes, wait_for

from app.modbus_line import LineException, LineTimeout
from app.runtime import Runtime
from app.worker import PermissionDenied
from devices.hdlock.adapter import P_ADDRESS, P_LINE_LOCKS, CommandError, discover
from devices.hdlock.params import PARAMS


@pytest.fixture
async def running(plant):
    async with running_plant(plant) as runtime:
        yield runtime


async def online(runtime, name="door-1"):
    state = runtime.store.devices[name]
    # the identity comes with the status of every poll, the settings in the same first poll just after it
    assert await wait_for(lambda: state.status == "online" and state.value("SerialNumber") is not None
                          and state.value("LockRequestDelay") is not None)
    return state


async def test_polling_reads_every_register(running):
    state = await online(running)
    expected = {p.label or p.name for p in PARAMS}
    # the settings come in several blocks of one poll (holding 32770 last): every one of them, not the first
    assert await wait_for(lambda: expected <= set(state.values()))
    values = state.values()
    assert values["SerialNumber"]["value"] == running.twins["door-1"].serial
    assert values["SettingsProximityThresholdUnlock"]["value"] == -30
    assert values["SettingsProximityThresholdUnlock"]["raw"] == 65506
    assert values["LockStatus"]["fields"]["BoltUnlocked"] == 1
    assert values["DoorState"]["name"] == "Door open"
    assert state.counters.timeouts == 0 and state.counters.exceptions == 0


async def test_door_closes_and_bolt_locks(running):
    state = await online(running)
    running.twins["door-1"].close_door()
    assert await wait_for(lambda: (state.value("LockStatus") or 0) & 0x0004, timeout=5)  # DoorInPosition
    assert await wait_for(lambda: (state.value("LockStatus") or 0) & 0x0100, timeout=5)  # BoltLocked
    # input registers are read before holding 1000 in a poll: BoltPosition follows one poll later
    assert await wait_for(lambda: state.value("BoltPosition") >= 100, timeout=2)
    assert await wait_for(lambda: state.value("StateMachineState") == 4, timeout=3)  # Locked
    assert any(sample["MotorCurrent"] for _, sample in state.history)


async def test_write_reads_back_and_marks_unsaved(running):
    state = await online(running)
    adapter = running.worker.adapters["door-1"]
    param = PARAMS.by_name["SettingsProximityThresholdUnlock"]
    assert await adapter.write_param(param, -25) == 65511
    assert running.twins["door-1"].holding[3004] == 65511
    assert state.value("SettingsProximityThresholdUnlock") == -25
    assert param.key in state.unsaved


async def test_save_and_restore(running):
    state = await online(running)
    adapter = running.worker.adapters["door-1"]
    twin = running.twins["door-1"]
    delay = PARAMS.by_name["LockRequestDelay"]
    await adapter.write_param(delay, 300)
    saves = twin.input[101]
    await adapter.save_settings()
    assert twin.input[101] == saves + 1 and not state.unsaved
    await adapter.write_param(delay, 999)
    await adapter.restore_settings()
    assert twin.holding[3000] == 300 and state.value("LockRequestDelay") == 300 and not state.unsaved
    twin.reset()  # power cycle keeps what was saved
    assert twin.holding[3000] == 300


async def test_refused_write_is_reported(running):
    state = await online(running)
    adapter = running.worker.adapters["door-1"]
    twin = running.twins["door-1"]
    twin.writable.discard(3000)  # this firmware protects the register: it acknowledges and keeps the value
    with pytest.raises(CommandError, match="refused by the firmware"):
        await adapter.write_param(PARAMS.by_name["LockRequestDelay"], 500)
    assert state.counters.write_errors == 1
    assert twin.holding[3000] == 200


async def test_invalid_entries_never_reach_the_bus(running):
    await online(running)
    adapter = running.worker.adapters["door-1"]
    writes = spy_writes(running.twins["door-1"])
    with pytest.raises(CommandError, match="outside"):
        await adapter.write_param(PARAMS.by_name["LockRequestDelay"], 70000)
    with pytest.raises(CommandError, match="cannot be written"):
        await adapter.write_param(PARAMS.by_name["LockStatus"], 1)
    with pytest.raises(CommandError, match="cannot be written"):
        await adapter.write_param(PARAMS.get("holding", 32770), 1)
    with pytest.raises(CommandError, match="needs confirmation"):
        await adapter.write_param(PARAMS.by_name["SettingsRemoveMagnet"], 1)
    # only the poll loop's requests went out meanwhile, no write
    assert all("write" not in t.request for t in running.store.buses["line1"].transactions)
    assert running.twins["door-1"].holding[3005] == 0
    assert writes == []  # the lock received no write at all


# Section 4.3 does not say whether the lock answers the write of 2003 at its old address:
# every Set-Address test runs against a twin that stays silent and one that answers.
ANSWER_MODES = pytest.mark.parametrize("answers", [False, True], ids=["silent-at-old-address", "answers-at-old-address"])


async def closed_and_locked(running, name: str):
    state = running.store.devices[name]
    running.twins[name].close_door()
    assert await wait_for(lambda: (state.value("LockStatus") or 0) & 0x0104 == 0x0104, timeout=5)
    return state


@ANSWER_MODES
async def test_set_address_accepted(running, answers):
    state = await online(running)
    twin = running.twins["door-1"]
    twin.answers_address_command = answers
    await closed_and_locked(running, "door-1")
    adapter = running.worker.adapters["door-1"]
    assert adapter.set_address_preview(0x010C, 0x0104)[0]
    outcome = await adapter.set_address(8, 0x010C, 0x0104)
    assert outcome.taken is True
    assert outcome.answered_old is answers
    assert "answers at address 8" in outcome.text
    assert twin.address == 8 and adapter.address == 8
    assert state.live(P_ADDRESS).value == 8
    assert PARAMS.get("holding", 103).key in state.unsaved
    assert state.counters.timeouts == 0  # the expected silence is no fault of the lock
    state.online = None
    assert await online(running)
    assert state.value("DeviceAddress") == 8


@ANSWER_MODES
async def test_set_address_refused(running, answers):
    state = await online(running)
    adapter = running.worker.adapters["door-1"]
    running.twins["door-1"].answers_address_command = answers
    # BoltLocked must be set, but the door is open and the bolt in
    accepted, result, _status = adapter.set_address_preview(0x0100, 0x0100)
    assert not accepted and result == 0x0100
    outcome = await adapter.set_address(16, 0x0100, 0x0100)
    assert outcome.taken is False
    assert "still answers at address 1" in outcome.text
    assert running.twins["door-1"].address == 1 and adapter.address == 1
    assert any("refused" in e.text for e in state.events)


async def test_set_address_lost_lock_is_reported(running):
    """No answer at the new address nor at the old one: say so, do not guess."""
    await online(running)
    adapter = running.worker.adapters["door-1"]
    twin = running.twins["door-1"]
    original = twin.write

    def write_then_vanish(address, value):
        result = original(address, value)
        if address == 2003:
            twin.silent = True  # e.g. the lock lost power right after the command
        return result

    twin.write = write_then_vanish
    with pytest.raises(CommandError, match="no answer at the new address 9 nor at the old address 1"):
        await adapter.set_address(9, 0, 0)
    assert adapter.address == 1


async def test_set_address_to_an_address_in_use_is_refused(running):
    """Section 2.2: every lock needs an address of its own; nothing is written."""
    await online(running)
    adapter = running.worker.adapters["door-1"]
    writes = spy_writes(running.twins["door-1"])
    with pytest.raises(CommandError, match="address 2 is already in use"):
        await adapter.set_address(2, 0, 0)
    with pytest.raises(CommandError, match="has address 1 already"):
        await adapter.set_address(1, 0, 0)
    assert writes == []


@ANSWER_MODES
async def test_twin_answers_the_address_command_only_when_switched_on(running, answers):
    await online(running)
    line = running.worker.lines["line1"]
    twin = running.twins["door-2"]
    twin.answers_address_command = answers
    for register, value in ((2000, 12), (2001, 0), (2002, 0)):
        await line.write_register(2, register, value)
    if answers:
        await line.write_register(2, 2003, 3)
    else:
        with pytest.raises(LineTimeout):
            await line.write_register(2, 2003, 3)
    assert twin.address == 12 and twin.holding[103] == 12


# -- broadcast address change (section 4.3, address 255) -----------------------------------------


KNOWN = {1: "door-1", 2: "door-2"}


async def test_broadcast_set_address_taken_by_the_lock_that_meets_the_condition(running):
    await online(running, "door-1")
    await online(running, "door-2")
    await closed_and_locked(running, "door-2")  # door-1 stays open: its bolt is in
    one, two = running.twins["door-1"], running.twins["door-2"]
    writes_1, writes_2 = spy_writes(one), spy_writes(two)
    adapter = running.worker.adapters["door-2"]
    outcome = await running.worker.gate.run(lambda: running.worker.adapters["door-2"].broadcast_set_address(9, 0x010C, 0x0104, KNOWN),
                                            device="door-2", describe="Broadcast Set Modbus Address (255)", user="local", role="engineer")
    assert outcome.taken and not outcome.collision
    assert (two.address, one.address) == (9, 1)
    assert adapter.address == 9  # the lock of this page moved: its adapter follows it
    assert outcome.moved == ["door-2"]
    assert f"serial {two.serial} answers at address 9" in outcome.text and "door-2" in outcome.text
    # both locks got the same four writes (parameters first, the command last), none answered
    assert writes_1 == writes_2 == [(2000, 9), (2001, 0x010C), (2002, 0x0104), (2003, 3)]
    assert any(t.unit == 255 and not t.error for t in running.store.buses["line1"].transactions)
    entries = running.audit.query(device="door-2", text="Broadcast")
    assert entries and entries[0].result == "ok"


async def test_broadcast_set_address_other_lock_moves(running):
    await online(running, "door-1")
    await online(running, "door-2")
    await closed_and_locked(running, "door-2")
    outcome = await running.worker.adapters["door-1"].broadcast_set_address(9, 0x010C, 0x0104, KNOWN)
    assert outcome.taken and outcome.moved == ["door-2"]
    assert running.worker.adapters["door-1"].address == 1  # door-1 did not move
    assert "door-2" in outcome.text and "plant file" in outcome.text


async def test_broadcast_set_address_collision_is_reported(running):
    await online(running, "door-1")
    await online(running, "door-2")
    # no condition: every lock takes address 9, and then they answer together
    outcome = await running.worker.adapters["door-1"].broadcast_set_address(9, 0, 0, KNOWN)
    assert outcome.collision and not outcome.taken
    assert sorted(outcome.moved) == ["door-1", "door-2"]
    assert "more than one lock" in outcome.text
    assert running.twins["door-1"].address == running.twins["door-2"].address == 9


async def test_broadcast_set_address_nobody_meets_the_condition(running):
    await online(running, "door-1")
    await online(running, "door-2")
    counters = running.store.devices["door-2"].counters
    timeouts, requests = counters.timeouts, counters.requests
    # BoltMovingIn must be set: neither lock is moving
    outcome = await running.worker.adapters["door-1"].broadcast_set_address(9, 0x0800, 0x0800, KNOWN)
    assert not outcome.taken and not outcome.collision and outcome.moved == []
    assert "no lock answers at address 9" in outcome.text
    assert running.twins["door-1"].address == 1 and running.twins["door-2"].address == 2
    # door-2 was polled meanwhile, and never right after a broadcast frame (turnaround delay)
    assert counters.requests > requests and counters.timeouts == timeouts


async def test_broadcast_set_address_to_a_known_or_used_address_is_refused(running):
    await online(running, "door-1")
    await online(running, "door-2")
    writes = spy_writes(running.twins["door-1"])
    adapter = running.worker.adapters["door-1"]
    with pytest.raises(CommandError, match="address 2 is door-2"):
        await adapter.broadcast_set_address(2, 0, 0, KNOWN)
    with pytest.raises(CommandError, match="address 2 is already in use"):
        await adapter.broadcast_set_address(2, 0, 0, {})  # not known, but it answers
    with pytest.raises(CommandError, match="outside 1..254"):
        await adapter.broadcast_set_address(255, 0, 0, KNOWN)
    assert writes == []


async def test_scan_results_reach_the_state_store(running):
    """Locks found by a scan of the line are listed on every lock of that line (for the broadcast count)."""
    state = await online(running)
    await running.worker.discover("line1", 1, 3)
    assert await wait_for(lambda: [d.address for d in (state.live(P_LINE_LOCKS).value if state.live(P_LINE_LOCKS) else ())] == [1, 2], timeout=3)


async def test_timeout_when_twin_silent_and_recovery(running):
    state = await online(running)
    twin = running.twins["door-1"]
    twin.silent = True
    assert await wait_for(lambda: state.status == "offline", timeout=5)
    assert state.counters.timeouts > 0
    assert "no answer" in state.last_error
    assert running.store.devices["door-2"].status == "online"  # the other lock keeps going
    twin.silent = False
    assert await wait_for(lambda: state.status == "online", timeout=5)


async def test_twin_server_stopped_and_back(running):
    state = await online(running)
    await running.sim.stop()
    assert await wait_for(lambda: state.status == "offline", timeout=8)
    await running.sim.start()
    assert await wait_for(lambda: state.status == "online", timeout=15)


async def test_crc_error_is_counted(running):
    state = await online(running)
    other = running.store.devices["door-2"]
    running.sim.servers[0].corrupt_next = 1  # the line's next answer, to whichever lock was asked
    assert await wait_for(lambda: state.counters.crc_errors + other.counters.crc_errors >= 1, timeout=5)
    assert await wait_for(lambda: state.status == "online" and other.status == "online", timeout=5)


async def test_modbus_exception_is_named(running):
    await online(running)
    line = running.worker.lines["line1"]
    counters = running.store.devices["door-1"].counters
    with pytest.raises(LineException, match="illegal data address"):
        await line.read_holding(1, 5, 1, counters)  # reserved register
    assert counters.exceptions == 1


async def test_unknown_address_times_out(running):
    line = running.worker.lines["line1"]
    with pytest.raises(LineTimeout):
        await line.read_holding(77, 103, 1)


async def test_viewer_cannot_write(running):
    await online(running)
    with pytest.raises(PermissionDenied):
        await running.worker.gate.run(lambda: running.worker.adapters["door-1"].write_param(PARAMS.by_name["LockRequestDelay"], 300),
                                      device="door-1", role="viewer", user="local")
    assert running.twins["door-1"].holding[3000] == 200


async def test_discover_broadcast_single_lock():
    plant = modbus_plant(locks=(("door-1", 7),))
    runtime = Runtime(plant, simulate=True)
    await runtime.sim.start()
    try:
        line = runtime.worker.lines["line1"]
        seen = []
        # the scanned range leaves out address 7: only the broadcast (section 5.6) can find the lock
        found = await discover(line, 1, 3, progress=lambda done, total: seen.append(done))
        assert found == [{"address": 7, "via": "broadcast"}]
        assert seen == [1, 2, 3]
        assert any(t.unit == 0 and not t.error for t in runtime.store.buses["line1"].transactions)
    finally:
        runtime.worker.lines["line1"].close()
        await runtime.sim.stop()


async def test_discover_scan_several_locks(running):
    await online(running)
    found = await running.worker.discover("line1", 1, 4)
    assert [f["address"] for f in found] == [1, 2]
    assert found[0]["serial"] == running.twins["door-1"].serial


async def test_nothing_is_held_for_a_browser_session(running):
    """The dead-man rule: HD-Lock commands are single writes; no session keeps anything running here."""
    await online(running)
    adapter = running.worker.adapters["door-1"]
    await adapter.write_param(PARAMS.by_name["LockRequestDelay"], 300)
    assert adapter.holders() == set()
    writes = spy_writes(running.twins["door-1"])
    adapter.session_lost("session-1", "the controlling browser disconnected")
    polled = running.store.devices["door-1"].counters.requests
    # let the poll loop run on after the lost session: it polls, it never writes
    assert await wait_for(lambda: running.store.devices["door-1"].counters.requests > polled + 2, timeout=5)
    assert writes == []  # nothing was undone or sent
    assert running.twins["door-1"].holding[3000] == 300
    assert not [e for e in running.store.devices["door-1"].events if "session-1" in e.text]


def _rtu(body: bytes) -> bytes:
    crc = 0xFFFF
    for byte in body:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return body + crc.to_bytes(2, "little")


async def test_answer_from_another_unit_is_an_address_conflict_not_a_crc_error():
    """A well-formed answer under another unit address: a second device on the line shares the address."""
    from app.modbus_line import ModbusLine
    from app.state import BusState
    from devices.live import Counters

    async def impostor(reader, writer):  # every read is answered, correctly sealed, by unit 9
        try:
            while request := await reader.read(8):
                count = int.from_bytes(request[4:6], "big")
                writer.write(_rtu(bytes([9, request[1], 2 * count]) + bytes(2 * count)))
                await writer.drain()
        except (ConnectionError, asyncio.CancelledError):
            pass

    server = await asyncio.start_server(impostor, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    state = BusState("line1", "modbus-rtu", f"socket://127.0.0.1:{port}")
    line = ModbusLine("line1", {"port": state.endpoint, "baudrate": 19200, "parity": "E", "stopbits": 1,
                                "timeout": 0.2, "retries": 0}, state)
    counters = Counters()
    try:
        with pytest.raises(Exception, match="answer from unit 9: address conflict on the line?") as caught:
            await line.read_holding(1, 103, 1, counters)
        assert not isinstance(caught.value, LineTimeout)
        assert counters.crc_errors == 0 and counters.timeouts == 0
        assert line.address_conflicts == {(1, 9): 1}
        assert "answer from unit 9" in state.transactions[-1].error
    finally:
        line.close()
        server.close()
        await server.wait_closed()


async def test_discover_sends_no_broadcast_where_several_locks_are_known(running):
    """26.8, section 5.6: every lock answers broadcast 0, so with two locks on the line their answers collide."""
    await online(running)
    await online(running, "door-2")
    transactions = running.store.buses["line1"].transactions
    before = len(transactions)
    found = await running.worker.discover("line1", 1, 3)
    assert [f["address"] for f in found] == [1, 2]
    assert not [t for t in list(transactions)[before:] if t.unit == 0]
