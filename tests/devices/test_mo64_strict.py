"""MO 64 against stricter units: a unit that naks optional queries (an RS485-only unit has no MAC
address, a unit may refuse error-memory levels), one that takes only one query form, answers that
come late, the token on a shared RS485 line between a setting's syn and its ack, and who may clear
the levels."""

from __future__ import annotations

import asyncio
import time

import httpx
import pytest
from conftest import alive, free_port, wait_for
from plants import device, mo64_rs485, mo64_tcp, plant_text
from scripts import RX, TX
from test_mo64_adapter import Mo64Script, answer, close_lines, make_adapter, query  # noqa: F401 - close_lines: autouse, closes the adapters made here
from webutil import simulated_user

from app.plant import parse_plant
from app.runtime import Runtime
from devices.mo64 import codec
from devices.mo64.adapter import UNAVAILABLE, CommandError

pytestmark = pytest.mark.timeout(60)


def tcp_plant(port: int, **device_options) -> str:
    return plant_text(mo64_tcp(port=port, timeout=0.3, device_options=device_options), name="strict")


LIVE = ("Gate state", "Position", "Barrier status", "LS", "Baum ab", "F_ereignis", "Service counter",
        "Maintenance counter", "Vehicle counter", "Loop-adjust counter A", "Operating hours")


async def test_a_unit_that_naks_optional_queries_shows_every_live_value_in_the_api_within_15_s(tmp_path):
    # 0x10: the MAC address (an RS485-only unit), 0x12: every error-memory level, 0x0B dec_bt
    plant = parse_plant(tcp_plant(free_port(), refuse_queries=[16, 18, 11]))
    runtime = Runtime(plant, simulate=True, data_dir=tmp_path / "data")
    async with simulated_user(runtime) as user:
        client: httpx.AsyncClient = user.http_client
        started = time.monotonic()
        values: dict = {}

        async def all_live() -> bool:
            response = await client.get("/api/devices/gate")
            assert response.status_code == 200, response.text
            values.update(response.json()["values"])
            return all(name in values and values[name]["value"] is not None for name in LIVE)

        end = started + 15
        while not await all_live():
            assert time.monotonic() < end, f"not within 15 s: {sorted(set(LIVE) - set(values))}"
            await asyncio.sleep(0.2)
        print(f"every live value in /api/devices after {time.monotonic() - started:.1f} s")
        # what the unit refused is said so, and the rest of the start-up reads went on
        assert await wait_for(lambda: "MAC address" in runtime.store.devices["gate"].points["Not available"].value, timeout=5)
        adapter = runtime.worker.adapters["gate"]
        assert await wait_for(lambda: adapter.state.points.get("Serial number") is not None
                              and adapter.state.points["Serial number"].value == 6400001, timeout=10)
        assert adapter.state.points["MAC address"].text == UNAVAILABLE
        assert await wait_for(lambda: len(adapter.state.points["Error memory levels not available"].value) == 10, timeout=10)
        assert "Open time" in adapter.state.points  # settings read although identity and error memory naked


async def test_a_refused_startup_read_is_retried_later_with_backoff():
    async with Mo64Script([
        (TX, query(codec.Q_GATE_STATE)), (RX, answer(0x0C, 5)),
        (TX, query(codec.Q_BARRIER_STATUS)), (RX, answer(0x07, {"status": 0, "more": b""})),
        (TX, query(codec.Q_BARRIER_POSITION)), (RX, answer(0x1D, 0)),
        (TX, query(codec.Q_SERVICE_COUNTER)), (RX, answer(0x0A, 1)),
        (TX, query(codec.Q_DEVICE)), (RX, answer(0x05, 5)),
        (TX, query(codec.Q_PROGRAM_VERSION)), (RX, answer(0x06, 1)),
        (TX, query(codec.Q_SERIAL_NUMBER)), (RX, answer(0x14, 7)),
        # the next cycle: live queries again, then the MAC (refused), then on
        (TX, query(codec.Q_GATE_STATE)), (RX, answer(0x0C, 5)),
        (TX, query(codec.Q_BARRIER_STATUS)), (RX, answer(0x07, {"status": 0, "more": b""})),
        (TX, query(codec.Q_BARRIER_POSITION)), (RX, answer(0x1D, 0)),
        (TX, query(codec.Q_MAINTENANCE_COUNTER)), (RX, answer(0x0B, 1)),
        (TX, query(codec.Q_MAC)), (RX, answer(codec.Reply.NAK)),
        (TX, query(codec.Q_OPERATING_HOURS)), (RX, answer(0x16, 9)),
        (TX, query(codec.Q_T_OPEN)), (RX, answer(0x0D, 1000)),
    ]) as script:
        adapter = make_adapter(script.port)
        await adapter.poll()
        await adapter.poll()
        script.done()
    assert list(adapter.state.points["Not available"].value) == ["MAC address"]
    read = adapter._reads[("query", codec.Q_MAC)]
    assert read["state"] == UNAVAILABLE and read["next"] > time.monotonic() + 5  # not asked again at once
    assert adapter.state.points["Gate state"].text == "closed"


async def test_query_form_document_first_then_the_short_form_and_the_choice_is_kept():
    document = codec.encode_frame(codec.encode_query(codec.Q_GATE_STATE, form="document"), codec.TCP)
    async with Mo64Script([
        (TX, document), (RX, answer(codec.Reply.NAK)),
        (TX, query(codec.Q_GATE_STATE)), (RX, answer(0x0C, 4)),
        (TX, query(codec.Q_BARRIER_POSITION)), (RX, answer(0x1D, 100)),  # the short form from now on
    ]) as script:
        adapter = make_adapter(script.port, query_form=None)
        await adapter.query(codec.Q_GATE_STATE)
        await adapter.query(codec.Q_BARRIER_POSITION)
        script.done()
    assert adapter.query_form == "short" and adapter.state.points["Query form"].value == "short"


@pytest.mark.parametrize("form", ["document", "short"])
async def test_twin_that_takes_one_query_form_only(form):
    from types import SimpleNamespace

    from devices.mo64.sim import Mo64TcpSim

    port = free_port()
    bus = SimpleNamespace(name="gate-bus", type="logited-tcp", options={"host": "127.0.0.1", "port": port})
    sim = Mo64TcpSim(bus, [SimpleNamespace(name="gate-1", options={"query_form": form})])
    await sim.start()
    try:
        adapter = make_adapter(port, query_form=None)
        await adapter.poll()
        assert adapter.query_form == form
        assert adapter.state.points["Gate state"].text == "closed"
    finally:
        adapter.line.close()
        await sim.stop()


async def test_error_memory_level_0_holds_the_newest_entry_read_from_the_twin():
    """5.1.23: "Bei jeder Veränderung der Fehlerflaggen ... Dabei wird der aktuelle Wert in den Fehlerspeicher[0]
    geschrieben": read through the queries the adapter sends, level 0 shows the latest change, level 1 the one before."""
    from types import SimpleNamespace

    from devices.mo64.sim import Mo64TcpSim

    port = free_port()
    bus = SimpleNamespace(name="gate-bus", type="logited-tcp", options={"host": "127.0.0.1", "port": port})
    sim = Mo64TcpSim(bus, [SimpleNamespace(name="gate-1", options={"query_form": "document"})])
    await sim.start()
    try:
        sim.twin.raise_fault(0x0001)
        sim.twin.raise_fault(0x0004)
        adapter = make_adapter(port, query_form=None)
        entries = await adapter.read_error_memory()
        assert [e["level"] for e in entries] == list(range(codec.ERROR_MEMORY_LEVELS))
        assert entries[0]["flags"] == 0x0005 and entries[1]["flags"] == 0x0001
    finally:
        adapter.line.close()
        await sim.stop()


async def test_a_late_answer_is_counted_late_not_as_change_monitoring():
    async with Mo64Script([
        (TX, query(codec.Q_GATE_STATE)),  # no answer in time ...
        (TX, query(codec.Q_BARRIER_POSITION)), (RX, answer(0x0C, 4)), (RX, answer(0x1D, 100)),  # ... then late
    ]) as script:
        adapter = make_adapter(script.port)
        with pytest.raises(Exception, match="no answer"):
            await adapter.query(codec.Q_GATE_STATE)
        await adapter.query(codec.Q_BARRIER_POSITION)
        script.done()
    assert not adapter.monitoring_active  # polling does not slow down for it
    assert adapter.late_answers == 1


async def test_safety_bits_show_within_one_poll_while_change_monitoring_delivers():
    from types import SimpleNamespace

    from devices.mo64.sim import Mo64TcpSim

    port = free_port()
    bus = SimpleNamespace(name="gate-bus", type="logited-tcp", options={"host": "127.0.0.1", "port": port})
    sim = Mo64TcpSim(bus, [SimpleNamespace(name="gate-1", options={"travel_s": 0.3})])
    await sim.start()
    try:
        adapter = make_adapter(port)
        for _ in range(12):  # every start-up read done
            await adapter.poll()
        await adapter.set_change_monitoring("s1", True)  # status mask stays 0: no status telegrams
        await adapter.command("s1", codec.Command.OPEN, confirmed=True)  # gate state and position change
        assert await wait_for(lambda: adapter.monitoring_active, timeout=5)
        for n in range(6):
            sim.twin.break_light_barrier(n % 2 == 0)
            await adapter.poll()
            assert adapter.state.points["LS"].value is (n % 2 == 0), f"cycle {n}: LS not shown"
    finally:
        adapter.line.close()
        await sim.stop()


async def test_assumed_selector_is_refused_until_verified_and_restore_skips_it():
    async with Mo64Script([
        (TX, codec.encode_frame(codec.encode_setting("t_prewarn_open", 80), codec.TCP)), (RX, answer(codec.Reply.SYN)),
        (RX, answer(codec.Reply.ACK)), (TX, query(codec.Q_T_PREWARN_OPEN)), (RX, answer(0x0E, 80)),
    ]) as script:
        adapter = make_adapter(script.port)
        with pytest.raises(CommandError, match="assumption"):
            await adapter.write_setting("s1", "t_prewarn_open", 80)
        with pytest.raises(CommandError, match="assumption"):
            await adapter.restore_entry("t_prewarn_close", 80)
        with pytest.raises(CommandError, match="assumption"):
            await adapter.restore_entry("maintenance_interval", 80)
        assert await adapter.write_setting("s1", "t_prewarn_open", 80, selector_verified=True) == 80
        script.done()
    assert adapter.verified_selectors == {"t_prewarn_open"}


# -- RS485: the token is held from the setting to its ack ----------------------------------------------
def rs485_plant(port: int) -> str:
    return plant_text(mo64_rs485(device("out-1", "mo64", "gates-485", address=16, refuse_queries=[16]), port=port),
                      name="gates")


async def test_rs485_token_is_not_passed_between_syn_and_ack():
    runtime = Runtime(parse_plant(rs485_plant(free_port())), simulate=True)
    await runtime.start()
    try:
        state = runtime.store.devices["out-1"]
        assert await wait_for(lambda: state.status == "online", timeout=10)
        sim = next(s for s in runtime.sim.servers if hasattr(s, "collisions"))
        twin = runtime.twins["out-1"]
        for n in range(6):
            value = 1000 + n
            await runtime.worker.gate.run(lambda v=value: runtime.worker.adapters["out-1"].write_setting("test", "t_open", v),
                                          device="out-1", describe="set open time", user="local", role="engineer")
            assert twin.settings["t_open"] == value
        print(f"collisions {sim.collisions}, token held at most {max(sim.hold_times_s) * 1000:.0f} ms")
        assert sim.collisions == 0
        assert sim.sent_without_token == 0
        assert max(sim.hold_times_s) < codec.TOKEN_PASS_LIMIT_S
    finally:
        await asyncio.wait_for(runtime.stop(), 10)


async def test_twin_garbles_an_answer_sent_in_another_masters_turn():
    """The twin's collision model must be able to fail the test above: a barrier's ack that comes after the
    tool passed the token collides with the other master's traffic."""
    from app.logited import LogitedRs485

    runtime = Runtime(parse_plant(rs485_plant(free_port())), simulate=True)
    await runtime.start()
    try:
        assert await wait_for(lambda: runtime.store.devices["out-1"].status == "online", timeout=10)
        sim = next(s for s in runtime.sim.servers if hasattr(s, "collisions"))
        line: LogitedRs485 = runtime.worker.lines["gates-485"]
        before = sim.collisions
        # the old behaviour: the exchange ends at syn (no interim), the token goes on, the ack comes later
        raw = codec.encode_frame(codec.encode_setting("t_open", 900), codec.RS485, da=16, sa=0)
        await line.transact(raw, lambda t: codec.decode_frame(t, codec.RS485).sa == 16, describe="set open time")
        assert await wait_for(lambda: sim.collisions > before, timeout=3)
    finally:
        await asyncio.wait_for(runtime.stop(), 10)


@pytest.mark.parametrize("line", ["tcp", "rs485"])
async def test_when_the_tool_stops_its_close_level_is_deactivated_and_acknowledged(line):
    """Issue 25.11: the worker's stop awaits the adapter's shutdown before it closes the line: the close
    level this tool set is deactivated in the barrier and the barrier's ack is received (on RS485 in the
    tool's own turn), not merely thrown at a closing line."""
    text = tcp_plant(free_port()) if line == "tcp" else rs485_plant(free_port())
    name = "gate" if line == "tcp" else "out-1"
    runtime = Runtime(parse_plant(text), simulate=True)
    await runtime.start()
    stopped = False
    try:
        worker = runtime.worker
        assert await wait_for(lambda: runtime.store.devices[name].status == "online", timeout=10)
        twin = runtime.twins[name]
        async with alive(worker, "s1", period_s=0.05):  # the browser stays alive: only the stop may release the level
            await worker.gate.invoke(name, "close activate", user="anna", role="engineer", session="s1", confirmed=True)
            assert twin.levels[codec.Command.CLOSE] and worker.adapters[name].holders() == {"s1"}
            await asyncio.wait_for(worker.stop(), 15)
            stopped = True
        assert not twin.levels[codec.Command.CLOSE]
        bus = runtime.store.buses[runtime.plant.devices[name].bus]
        deactivate = [t for t in bus.transactions if "the tool stops" in t.request]
        assert deactivate, [t.request for t in bus.transactions][-5:]
        framing = codec.TCP if line == "tcp" else codec.RS485
        assert codec.decode_answer(codec.decode_frame(bytes.fromhex(deactivate[-1].response_hex), framing),
                                   framing).reply is codec.Reply.ACK  # acknowledged by the barrier
        assert not [t for t in bus.transactions if t.request == "on close"]  # nothing left for the closing line
        assert any("deactivated (ack)" in e.text for e in runtime.store.devices[name].events)
        if line == "rs485":
            sim = next(s for s in runtime.sim.servers if hasattr(s, "collisions"))
            assert sim.sent_without_token == 0 and sim.collisions == 0  # sent and answered in the tool's turn
    finally:
        if not stopped:
            await asyncio.wait_for(runtime.worker.stop(), 15)
        await asyncio.wait_for(runtime.sim.stop(), 10)
