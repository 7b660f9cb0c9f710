"""MO 64 adapter: scripted conversations on a LogiTed TCP line (expected requests in order, each
answered with scripted telegrams, as python-canopen's test_sdo), and the dead-man rule."""

from __future__ import annotations

import asyncio
import contextlib
import time
from types import SimpleNamespace

import pytest
from conftest import free_port
from scripts import PAUSE, RX, TX, Script

from app.logited import LogitedTcp
from app.state import BusState
from devices.live import DeviceState
from devices.mo64 import codec
from devices.mo64.adapter import BUSY_TEXT, CommandError, Mo64Adapter, NeedsConfirmation

pytestmark = pytest.mark.timeout(30)

def tcp(telegram: bytes) -> bytes:
    return codec.encode_frame(telegram, codec.TCP)


def answer(answer_type: int, value=None) -> bytes:
    return tcp(codec.encode_answer(answer_type, value))


ACK, NAK, BUSY, SYN = (answer(r) for r in (codec.Reply.ACK, codec.Reply.NAK, codec.Reply.BUSY, codec.Reply.SYN))


def query(index: int, level: int | None = None) -> bytes:
    return tcp(codec.encode_query(index, level))


class Mo64Script(Script):
    """A LogiTed TCP peer speaking MO 64 telegrams (tests/scripts.py)."""

    def __init__(self, steps: list[tuple[str, object]]):
        super().__init__(steps, lambda: codec.FrameSplitter(codec.TCP))


_made: list[Mo64Adapter] = []


@pytest.fixture(autouse=True)
async def close_lines():
    yield
    while _made:
        _made.pop().line.close()
    await asyncio.sleep(0)


def make_adapter(port: int, query_form: str | None = "short") -> Mo64Adapter:
    opts = {"host": "127.0.0.1", "port": port, "timeout": 0.5, "poll_period": 1.0, "simulate": False}
    line = LogitedTcp("gate-bus", opts, BusState("gate-bus", "logited-tcp", f"127.0.0.1:{port}"))
    config = SimpleNamespace(name="gate-1", type="mo64", bus="gate-bus", options={})
    adapter = Mo64Adapter(config, DeviceState("gate-1", "mo64", "gate-bus"), line)
    adapter.query_form = query_form  # the scripts speak the short form; None: the adapter finds it out
    _made.append(adapter)
    return adapter


async def test_setting_write_busy_then_syn_ack_and_read_back():
    set_t_open = tcp(codec.encode_setting("t_open", 1500))
    async with Mo64Script([
        (TX, set_t_open), (RX, BUSY),
        (TX, set_t_open), (RX, SYN), (PAUSE, 0.05), (RX, ACK),
        (TX, query(codec.Q_T_OPEN)), (RX, answer(0x0D, 1500)),
    ]) as script:
        adapter = make_adapter(script.port)
        with pytest.raises(CommandError, match=BUSY_TEXT):
            await adapter.write_setting("s1", "t_open", 1500)
        assert adapter.eeprom_writes.get("s1", 0) == 0  # busy: nothing written
        assert await adapter.write_setting("s1", "t_open", 1500) == 1500
        script.done()
    assert adapter.eeprom_writes["s1"] == 1
    assert adapter.state.points["Open time"].text.startswith("15 s")
    assert adapter.last_reply == "set open time: ack"


async def test_syn_and_ack_in_one_segment_are_both_taken():
    set_mask = tcp(codec.encode_setting("maintenance_interval", 5000))
    async with Mo64Script([
        (TX, set_mask), (RX, SYN + ACK),
        (TX, query(codec.Q_MAINTENANCE_INTERVAL)), (RX, answer(0x1A, 5000)),
    ]) as script:
        adapter = make_adapter(script.port)
        assert await adapter.write_setting("s1", "maintenance_interval", 5000, selector_verified=True) == 5000
        script.done()


async def test_setting_nak_is_a_failed_write():
    async with Mo64Script([(TX, tcp(codec.encode_setting("t_open", 10))), (RX, SYN), (RX, NAK)]) as script:
        adapter = make_adapter(script.port)
        with pytest.raises(CommandError, match="nak"):
            await adapter.write_setting("s1", "t_open", 10)
        script.done()
    assert adapter.state.counters.write_errors == 1


async def test_query_answered_with_nak():
    async with Mo64Script([(TX, query(codec.Q_GATE_STATE)), (RX, NAK)]) as script:
        adapter = make_adapter(script.port)
        with pytest.raises(CommandError, match="gate state with nak"):
            await adapter.query(codec.Q_GATE_STATE)
        script.done()
    assert "Gate state" not in adapter.state.points


async def test_unsolicited_telegram_between_request_and_answer_is_published_with_an_event():
    async with Mo64Script([
        (TX, query(codec.Q_GATE_STATE)), (RX, answer(0x1D, 42)), (RX, answer(0x0C, codec.GateState.OPENING)),
    ]) as script:
        adapter = make_adapter(script.port)
        got = await adapter.query(codec.Q_GATE_STATE)
        script.done()
    assert got.type == 0x0C
    assert adapter.state.points["Gate state"].text == "opening"
    assert adapter.state.points["Position"].value == 42
    assert any("change reported: barrier position" in e.text for e in adapter.state.events)
    # change monitoring was never armed (its flags not read, factory 0): this is no monitoring telegram
    assert not adapter.monitoring_active and adapter.unexpected_telegrams == 1


async def test_position_unknown_for_minus_one():
    async with Mo64Script([(TX, query(codec.Q_BARRIER_POSITION)), (RX, answer(0x1D, -1))]) as script:
        adapter = make_adapter(script.port)
        await adapter.query(codec.Q_BARRIER_POSITION)
        script.done()
    point = adapter.state.points["Position"]
    assert point.value is None and point.text == "unknown"


async def test_every_motion_needs_its_own_confirmation_and_pulse_is_no_holder():
    open_pulse = bytes.fromhex("55 03 01 01 00 B8 B4")  # SPEC-NOTES golden vector
    async with Mo64Script([(TX, open_pulse), (RX, ACK), (TX, open_pulse), (RX, NAK)]) as script:
        adapter = make_adapter(script.port)
        with pytest.raises(NeedsConfirmation):
            await adapter.command("s1", codec.Command.OPEN)
        assert await adapter.command("s1", codec.Command.OPEN, confirmed=True) == "ack"
        assert adapter.holders() == set()
        with pytest.raises(NeedsConfirmation):  # the confirmation was for that one pulse (issue 42 item 6)
            await adapter.command("s1", codec.Command.OPEN)
        with pytest.raises(CommandError, match="nak"):
            await adapter.command("s1", codec.Command.OPEN, confirmed=True)
        script.done()
    assert adapter.last_reply == "open pulse: nak"


def _level_on_and_off(command: codec.Command) -> list:
    """The script of ``command``'s level activated and deactivated again, each acknowledged."""
    activate = tcp(codec.encode_command(command, codec.Function.ACTIVATE))
    deactivate = tcp(codec.encode_command(command, codec.Function.DEACTIVATE))
    return [(TX, activate), (RX, ACK), (TX, deactivate), (RX, ACK)]


async def test_session_lost_deactivates_its_close_level_at_once():
    async with Mo64Script(_level_on_and_off(codec.Command.CLOSE)) as script:
        adapter = make_adapter(script.port)
        await adapter.command("s1", codec.Command.CLOSE, codec.Function.ACTIVATE, confirmed=True)
        assert adapter.holders() == {"s1"}
        assert [h.command for h in adapter.state.points["Levels set by this tool"].value] == ["close"]
        started = time.monotonic()
        adapter.session_lost("s1", "the controlling browser disconnected")
        await asyncio.wait_for(adapter.stopped(), 1.0)
        assert time.monotonic() - started < 0.5  # app.worker.DEADMAN_BOUND_S
        script.done()
    assert adapter.holders() == set() and adapter.levels == {}
    assert any("dead-man" in e.text for e in adapter.state.events)


async def test_open_level_is_shown_but_not_released_by_the_dead_man_and_cleared_on_request():
    async with Mo64Script(_level_on_and_off(codec.Command.OPEN)) as script:
        adapter = make_adapter(script.port)
        await adapter.command("s1", codec.Command.OPEN, codec.Function.ACTIVATE, confirmed=True)
        assert adapter.holders() == set()
        adapter.session_lost("s1", "gone")
        await adapter.stopped()
        assert [h.command for h in adapter.state.points["Levels set by this tool"].value] == ["open"]
        with pytest.raises(NeedsConfirmation):
            await adapter.clear_levels("s2")  # asks first: the boom may close
        assert await adapter.clear_levels("s2", confirmed=True) == ["open"]
        script.done()
    assert adapter.levels == {}


async def test_backup_reads_the_settings_and_restore_writes_one():
    steps = []
    values = {"t_open": 1000, "t_prewarn_open": 100, "t_prewarn_close": 200, "change_monitoring": 0,
              "maintenance_interval": 50000, "status_mask": 0, "multi_relays": [1, 0, 0, 0, 0, 2],
              "config_flags": [0, 1, 0, 0]}
    for key, setting in codec.SETTINGS.items():
        if not setting.backup:
            continue
        value = values[key]
        if key == "config_flags":
            value = dict(zip(("konfig0", "konfig1", "konfig2", "konfig3"), value))
        if key == "status_mask":
            value = {"mask": 0, "more": b""}
        steps += [(TX, query(setting.query)), (RX, answer(setting.query + 5, value))]
    steps += [(TX, query(codec.Q_INDUCTION_LOOPS)), (RX, answer(0x12, [1, 2, 3])),
              (TX, query(codec.Q_DIRECTION_LOGICS)), (RX, answer(0x13, [5, 6])),
              (TX, query(codec.Q_DEC_BT)), (RX, answer(0x10, (1 << 31) | 0b100110)),
              (TX, query(codec.Q_LOOP_PERIODS)), (RX, answer(0x1B, bytes.fromhex("10 27 20 4e 00 00")))]
    steps += [(TX, tcp(codec.encode_setting("multi_relays", [1, 0, 0, 0, 0, 3]))), (RX, SYN), (RX, ACK),
              (TX, query(codec.Q_MULTI_RELAYS)), (RX, answer(0x19, [1, 0, 0, 0, 0, 3]))]
    async with Mo64Script(steps) as script:
        adapter = make_adapter(script.port)
        entries = await adapter.backup_read()
        by_key = {e["key"]: e for e in entries}
        # each setting by the parameter model's name and key (devices/mo64/params.py): space = setting, address = bit
        assert not any(k.startswith("vehicle_counter") for k in by_key)  # RAM only (chapter 5.2.5)
        assert by_key["config_flags:16"]["name"] == "GnApl bei Vorwarnung vor dem Öffnen blinken"
        assert by_key["config_flags:16"]["value"] == 1  # konfig1 = 1: its bits 1, 0
        assert [by_key[f"multi_relays:{8 * n}"]["raw"] for n in range(6)] == [1, 0, 0, 0, 0, 2]
        assert not by_key["induction_loops:0"]["writable"]
        assert by_key["dec_bt:0"]["value"] == (1 << 31) | 0b100110 and not by_key["dec_bt:0"]["writable"]
        assert by_key["loop_periods"]["value"] == "10 27 20 4e 00 00"  # layout not in the summary: raw
        await adapter.restore_entry("multi_relays", [1, 0, 0, 0, 0, 3])
        with pytest.raises(CommandError, match="not restored"):
            await adapter.restore_entry("vehicle_counter", 5)
        script.done()


# -- against the twin (devices/mo64/sim.py) ----------------------------------------------------------
def twin_bus(port: int):
    bus = SimpleNamespace(name="gate-bus", type="logited-tcp",
                          options={"host": "127.0.0.1", "port": port, "timeout": 0.5, "poll_period": 0.2})
    dev = SimpleNamespace(name="gate-1", type="mo64", bus="gate-bus", options={"travel_s": 0.6})
    return bus, dev


@contextlib.asynccontextmanager
async def adapter_on_twin():
    """The adapter on a LogiTed TCP line to the MO 64 twin on a free port: yields (twin server, adapter)."""
    from devices.mo64.sim import Mo64TcpSim

    port = free_port()
    bus, dev = twin_bus(port)
    sim = Mo64TcpSim(bus, [dev])
    await sim.start()
    try:
        adapter = make_adapter(port)
        try:
            yield sim, adapter
        finally:
            adapter.line.close()
    finally:
        await sim.stop()


async def test_twin_tcp_open_pulse_goes_opening_then_open_at_100_percent():
    async with adapter_on_twin() as (_sim, adapter):
        await adapter.poll()
        assert adapter.state.points["Gate state"].text == "closed"
        assert await adapter.command("s1", codec.Command.OPEN, confirmed=True) == "ack"
        seen = []
        end = time.monotonic() + 5
        while time.monotonic() < end:
            await adapter.query(codec.Q_GATE_STATE)
            seen.append(adapter.state.points["Gate state"].text)
            if seen[-1] == "open":
                break
            await asyncio.sleep(0.05)
        await adapter.query(codec.Q_BARRIER_POSITION)
        assert "opening" in seen and seen[-1] == "open", seen
        assert adapter.state.points["Position"].value == 100


async def test_twin_backup_and_restore_writes_only_the_changed_setting():
    async with adapter_on_twin() as (sim, adapter):
        before = {e["key"]: e for e in await adapter.backup_read()}
        await adapter.write_setting("s1", "t_open", 700)
        await adapter.write_setting("s1", "multi_relays", [2, 0, 0, 0, 0, 0])
        sim.twin.setting_writes.clear()
        now = {e["key"]: e for e in await adapter.backup_read()}
        changed = [k for k, e in before.items() if e["writable"] and now[k]["raw"] != e["raw"]]
        assert sorted(changed) == ["multi_relays:0", "t_open:0"]  # the parameter model's keys
        for key in changed:
            await adapter.write_param(key, before[key]["value"], session="restore")
        assert sim.twin.setting_writes == {"t_open": 1, "multi_relays": 1}
        after = {e["key"]: e["raw"] for e in await adapter.backup_read()}
        assert after == {k: e["raw"] for k, e in before.items()}
        assert adapter.eeprom_writes["s1"] == 2 and adapter.eeprom_writes["restore"] == 2
