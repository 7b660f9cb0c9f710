"""CAN-M3IO: codec golden vectors (document sections 5.8, 7.2) and the adapter against the twins."""

from __future__ import annotations

import asyncio
import contextlib

import pytest
import plants
from conftest import wait_for
from plants import can_bus, device

from app.plant import parse_plant
from app.runtime import Runtime
from devices.m3io import codec
from devices.m3io import adapter as adapter_module
from devices.m3io.adapter import CommandError
from devices.m3io.codec import TempWord, Variant
from devices.m3io.sim import M3ioTwin

# -- codec -------------------------------------------------------------------------------------


def test_ids_sw1_off_example():
    """5.8.1: SW1 0x1A -> DigOut 0x3A0 + 0x1A * 5 = 0x422, 500 kbit/s."""
    ids = codec.derive_ids(0x1A)
    assert (ids.dig_out, ids.dig_in, ids.temp14, ids.temp56, ids.sync) == (0x422, 0x423, 0x424, 0x425, 0x426)
    assert ids.bitrate == 500_000 and not ids.addressed and ids.mdata is None


def test_ids_sw1_on_example():
    """5.8.2: SW1 0xCA (S7 on, S6 off, address 0x0A) -> DigOut 0x20A at 500 kbit/s."""
    ids = codec.derive_ids(0xCA)
    assert (ids.dig_out, ids.dig_in, ids.temp14, ids.temp56, ids.sync, ids.mdata) == (0x20A, 0x18A, 0x38A, 0x48A, 0x24A, 0x1CA)
    assert ids.bitrate == 500_000 and ids.addressed


def test_ids_sw1_on_s7_off_and_1_mbit():
    ids = codec.derive_ids(0xA3)  # S8, S6 on: 1 Mbit/s; S7 off table; address 3
    assert (ids.dig_out, ids.dig_in, ids.sync, ids.mdata, ids.bitrate) == (0x183, 0x203, 0x683, 0x703, 1_000_000)


@pytest.mark.parametrize(
    ("variant", "outputs", "byte"),
    [
        (Variant.HM, {"LED": True, "SSR1": True, "SSR6": True}, 0b0100_0011),
        (Variant.HMR, {"LED": True, "SSR1-3": True, "SSR4": True, "SSR6": True}, 0b0001_0111),
        (Variant.KM, {"LED": True}, 0b0000_0001),
    ],
)
def test_dig_out_layouts(variant, outputs, byte):
    assert codec.encode_dig_out(variant, outputs) == bytes([byte])
    decoded = codec.decode_dig_out(variant, bytes([byte]))
    assert {k for k, v in decoded.items() if v} == set(outputs)


def test_dig_out_unknown_output():
    with pytest.raises(codec.CodecError):
        codec.encode_dig_out(Variant.KM, {"SSR1": True})


def test_dig_in():
    assert codec.decode_dig_in(bytes([0xC5])) == {"E1": True, "E2": False, "E3": True, "E4": False, "E5": False, "E6": False}
    assert codec.encode_dig_in({"E1": True, "E3": True}) == bytes([0xC5])  # bits 6-7 read 1


@pytest.mark.parametrize(
    ("raw", "celsius", "in_range", "load", "triac", "fuse"),
    [
        (0xE0FA, 25.0, True, True, True, True),  # 250 = 25.0 C, Si Triac Last set, sb = vz = 0
        (0x1FFB, -0.5, False, False, False, False),  # -5 in 12-bit two's complement, vz and sb set: out of range
        (0x67D5, 200.5, False, True, True, False),  # 2005 > 2000: out of range; Si = 0
        (0x27D0, 200.0, True, True, False, False),
    ],
)
def test_temperature_word(raw, celsius, in_range, load, triac, fuse):
    word = TempWord(raw)
    assert word.celsius == celsius and word.in_range is in_range
    assert (word.load, word.triac, word.fuse) == (load, triac, fuse)
    if not in_range:
        assert word.text().startswith("out of range")


def test_temperature_word_sb_rule():
    assert TempWord.make(-5, True, True, True, addressed=False).raw == 0xFFFB  # sb = vz
    assert TempWord.make(250, True, True, True, addressed=True).raw == 0xF0FA  # sb = 1 in addressed mode
    assert TempWord.make(250, True, True, True, addressed=False).raw == 0xE0FA


@pytest.mark.parametrize(("serial", "raw"), [(33852, 0x843C), (42120023, 0x282B357)])
def test_serial_number_examples(serial, raw):
    payload = codec.encode_serial(serial)
    assert int.from_bytes(payload, "little") == raw
    assert codec.decode_serial(payload) == f"{serial:08d}"


def test_little_endian_example():
    """7.2.4.2: the 2-byte value 0x1234 goes into the payload as 0x34 (byte 1), 0x12 (byte 2)."""
    assert codec.encode_u16(0x1234) == bytes([0x34, 0x12])
    assert codec.decode_u16(bytes([0x34, 0x12])) == 0x1234
    frame = bytes([2, 2, 0x34, 0x12, 0xFF, 0xFF, 0xFF, 0xFF])
    assert codec.MData(2, 2, codec.encode_u16(0x1234)).encode() == frame
    assert codec.decode_u16(codec.MData.decode(frame).payload) == 0x1234
    assert codec.MData.decode(frame).encode() == frame


# 7.2.4.2.2: every product code of the table, with the variant it is (None: no CAN-M3IO)
PRODUCT_TABLE = [
    (0x0000, "MIO", None),
    (0x1000, "New KKD01", None),
    (0x2000, "KKD01", None),
    (0x2001, "KKD02", None),
    (0x2002, "ABB KKD01", None),
    (0x2003, "ABB KKD02", None),
    (0x3000, "HM01", Variant.HM),
    (0x3001, "KM01 (until 07.11.2013)", Variant.KM),
    (0x3002, "HMR01 (until 07.11.2013)", Variant.HMR),
    (0x3009, "KM01 (from 08.11.2013)", Variant.KM),
    (0x300A, "HMR01 (from 08.11.2013)", Variant.HMR),
]


@pytest.mark.parametrize(("code", "name", "variant"), PRODUCT_TABLE)
def test_product_codes(code, name, variant):
    frame = bytes([2, 2, code & 0xFF, code >> 8, 0xFF, 0xFF, 0xFF, 0xFF])  # MData area 2 index 2, LE, 0xFF-padded
    assert codec.MData(codec.AREA_READ_CONFIG, codec.CONFIG_PRODUCT, codec.encode_u16(code)).encode() == frame
    decoded = codec.decode_u16(codec.MData.decode(frame).payload)
    assert decoded == code
    assert codec.product_name(decoded) == name
    assert codec.product_variant(decoded) is variant
    assert codec.encode_u16(codec.decode_u16(frame[2:4])) == frame[2:4]


def test_product_table_is_complete():
    assert sorted(codec.PRODUCT_CODES) == [code for code, _, _ in PRODUCT_TABLE]
    assert "unknown" in codec.product_name(0x4242) and codec.product_variant(0x4242) is None


def test_variant_check():
    """The product code against the plant file's variant (HM and HMR use the same DigOut bits for other SSRs, 7.2.1)."""
    ok = codec.check_variant(Variant.HMR, True, 0x300A)
    assert ok.state == "ok" and ok.may_switch
    wrong = codec.check_variant(Variant.HM, True, 0x3002)
    assert wrong.state == "mismatch" and not wrong.may_switch
    assert "HMR01" in wrong.text and 'variant = "HMR"' in wrong.text and 'variant = "HM"' in wrong.text
    other = codec.check_variant(Variant.HM, True, 0x2000)
    assert other.state == "mismatch" and not other.may_switch and "KKD01" in other.text and "no CAN-M3IO" in other.text
    unread = codec.check_variant(Variant.HM, True, None)
    assert unread.state == "unchecked" and not unread.may_switch
    simple = codec.check_variant(Variant.HM, False, None)
    assert simple.state == "not possible" and simple.may_switch and "cannot be checked" in simple.text


def test_p2_goes_with_every_dig_out():
    """7.2.4: cfg is not stored; a reset shorter than a DigOut period is not visible, so P2 is repeated."""
    assert codec.cfg_with_dig_out(True) == bytes([0x80])
    assert codec.cfg_with_dig_out(False) is None


def test_mdata_padding():
    assert codec.MData(2, 2, b"\x00\x30").encode() == bytes([2, 2, 0x00, 0x30, 0xFF, 0xFF, 0xFF, 0xFF])
    assert codec.pad6(b"\x01") == b"\x01\xff\xff\xff\xff\xff"
    with pytest.raises(codec.CodecError):
        codec.encode_sync_request(4, 1, bytes(7))


def test_channel_monitor_transitions():
    """Section 7.2.3: no load -> unknown; after the first switch-on all three bits read 1; a blown
    fuse takes Last to 0 too and stays blown; a triac that does not conduct while on is defective."""
    m = codec.ChannelMonitor()
    m.update(TempWord.make(250, load=False, triac=False, fuse=False, addressed=False), switched_on=False)
    assert (m.fuse, m.triac) == ("unknown", "unknown")  # not a fault
    assert m.load.startswith("none")
    m.update(TempWord.make(250, True, True, True, False), switched_on=True)
    assert (m.fuse, m.triac, m.seen_ok) == ("ok", "ok", True)
    m.update(TempWord.make(250, load=False, triac=True, fuse=False, addressed=False), switched_on=True)
    assert m.fuse == "blown"  # Last went 0 with the fuse: remembered as blown
    m.update(TempWord.make(250, load=False, triac=True, fuse=True, addressed=False), switched_on=True)
    assert m.fuse == "blown"  # Si without a load means nothing
    m.update(TempWord.make(250, load=True, triac=False, fuse=True, addressed=False), switched_on=True)
    assert (m.fuse, m.triac) == ("ok", "defective")
    m.update(TempWord.make(250, load=True, triac=True, fuse=True, addressed=False), switched_on=False)
    assert m.triac == "not checked (off)"


def test_blown_fuse_follows_the_module_latch():
    """7.2.3: Si = 0 stays in the module until its 24 V are cut; Si = 1 with a load again means it was
    reset, so the fault is cleared (and the monitor says so once)."""
    m = codec.ChannelMonitor()
    m.update(TempWord.make(250, True, True, True, False), switched_on=True)
    m.update(TempWord.make(250, load=True, triac=True, fuse=False, addressed=False), switched_on=True)
    assert m.fuse == "blown" and m.cleared is None
    m.update(TempWord.make(250, load=False, triac=True, fuse=True, addressed=False), switched_on=True)
    assert m.fuse == "blown" and m.cleared is None
    m.update(TempWord.make(250, load=True, triac=True, fuse=True, addressed=False), switched_on=False)
    assert m.fuse == "ok" and not m.fuse_blown
    assert m.cleared is not None and "reset" in m.cleared
    m.update(TempWord.make(250, load=True, triac=True, fuse=True, addressed=False), switched_on=False)
    assert m.cleared is None  # reported once


def test_no_load_text_names_a_shorted_triac():
    """7.2.3: a triac with a permanent short circuit also reads Last = 0."""
    m = codec.ChannelMonitor()
    m.update(TempWord.make(250, load=False, triac=True, fuse=True, addressed=False), switched_on=False)
    assert "no load" in m.load and "no supply" in m.load and "short" in m.load and "triac" in m.load


def test_fuse_advice_from_table():
    assert codec.fuse_advice(Variant.HMR, 1) == "replace fuse SI3 (16 A, fast-acting 5x20 mm)"
    assert codec.fuse_advice(Variant.HM, 1) == "replace fuse SI3 (10 A, fast-acting 5x20 mm)"
    assert codec.fuse_advice(Variant.HM, 6).startswith("replace fuse SI8")


# -- the twin (document rules, no bus) ------------------------------------------------------------


def test_twin_hmr_two_phase_load_needs_p2():
    """4.3: with P2 exactly 2 of the 3 phases must report a load, without P2 all 3; else a load fault
    switches the whole group off. P2 is lost at reset (7.2.4)."""
    twin = M3ioTwin(Variant.HMR, 0xCA)
    twin.ssr[3].load = False  # a two-phase load
    twin.on_dig_out(codec.encode_dig_out(Variant.HMR, {"SSR1-3": True}))
    assert not any(twin.ssr[i].on for i in (1, 2, 3))  # load fault without P2
    twin.on_sync(codec.encode_sync_cfg(True))
    assert all(twin.ssr[i].on for i in (1, 2, 3))
    twin.ssr[2].load = False  # one phase only: a load fault with P2 too
    twin.apply()
    assert not any(twin.ssr[i].on for i in (1, 2, 3))
    twin.ssr[2].load = True
    twin.power_cycle()
    assert twin.cfg == 0
    twin.on_dig_out(codec.encode_dig_out(Variant.HMR, {"SSR1-3": True}))
    assert not any(twin.ssr[i].on for i in (1, 2, 3))  # P2 lost: the fault is back


def test_twin_keeps_si_latched_until_24v_cut():
    """7.2.3: Si = 0 is reset only by cutting the 24 V; the output is not switched meanwhile."""
    twin = M3ioTwin(Variant.HM, 0x1A)
    twin.on_dig_out(codec.encode_dig_out(Variant.HM, {"SSR1": True}))
    assert twin.ssr[1].on and twin.word(1).fuse
    twin.ssr[1].fuse_ok = False
    twin.apply()
    assert not twin.ssr[1].on and not twin.word(1).fuse
    twin.ssr[1].fuse_ok = True  # fuse replaced, 24 V still on
    twin.on_dig_out(codec.encode_dig_out(Variant.HM, {"SSR1": True}))
    assert not twin.ssr[1].on and not twin.word(1).fuse
    twin.power_cycle()
    assert twin.word(1).fuse and twin.word(1).load
    twin.on_dig_out(codec.encode_dig_out(Variant.HM, {"SSR1": True}))
    assert twin.ssr[1].on


def test_twin_shorted_triac_reads_no_load():
    """7.2.3: a triac with a permanent short circuit and a load attached reads Last = 0."""
    twin = M3ioTwin(Variant.HM, 0x1A)
    twin.ssr[4].triac_shorted = True
    assert not twin.word(4).load


# -- adapter + twins on a virtual bus --------------------------------------------------------------

SESSION = "tab-1"  # the NiceGUI client id of the page that switches


def plant_text() -> str:
    """An HM (SW1 0x1A) and an HMR (SW1 0xCA, serial 42120023) module on one simulated CAN bus."""
    return plants.plant_text(can_bus(device("hm", "m3io", "can3", variant="HM", sw1=0x1A),
                                     device("hmr", "m3io", "can3", variant="HMR", sw1=0xCA, serial=42120023),
                                     name="can3", bitrate=500000, poll_period=0.2), name=None)


async def _beat(worker, session: str) -> None:
    """The page's heartbeat: without it the worker's dead-man rule switches SESSION's outputs off."""
    while True:
        if hasattr(worker, "heartbeat"):
            worker.heartbeat(session)
        await asyncio.sleep(0.1)


@pytest.fixture
async def modules():
    runtime = Runtime(parse_plant(plant_text()), simulate=True)
    await runtime.start()
    beat = asyncio.create_task(_beat(runtime.worker, SESSION))
    for name in ("hm", "hmr"):  # the modules answer only while a master serves their watchdog (7.1)
        adapter = runtime.worker.adapters[name]
        assert await wait_for(lambda a=adapter: a.bus.state.connected, timeout=10), f"{adapter.bus.name} not open"
        await adapter.take_control(SESSION, "engineer")
        state = runtime.store.devices[name]
        assert await wait_for(lambda s=state: s.status == "online", timeout=10)
    try:
        yield runtime
    finally:
        beat.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await beat
        await asyncio.wait_for(runtime.stop(), 5)


async def test_watchdog_kept_alive_and_temperatures_flow(modules):
    adapter = modules.worker.adapters["hm"]
    twin = modules.twins["hm"]
    await asyncio.sleep(2.5)  # longer than the 2 s watchdog (section 7.1)
    assert twin.watchdog_alive
    assert modules.worker.can_buses["can3"].cyclic_running(adapter.key)
    assert adapter.temps[3].celsius == 23.5 and adapter.inputs is not None
    twin.toggle_input("E4")
    assert await wait_for(lambda: adapter.inputs["E4"], timeout=1)


async def test_outputs_drop_in_the_twin_when_the_worker_stops(modules):
    adapter = modules.worker.adapters["hm"]
    twin = modules.twins["hm"]
    adapter.set_output(SESSION, "SSR1", True)
    assert await wait_for(lambda: twin.ssr[1].on, timeout=1)
    await modules.worker.stop()  # no more DigOut
    assert await wait_for(lambda: not twin.ssr[1].on, timeout=3)
    assert not twin.watchdog_alive


async def test_fuse_triac_load_states(modules):
    adapter = modules.worker.adapters["hm"]
    twin = modules.twins["hm"]
    twin.ssr[3].load = False
    assert await wait_for(lambda: adapter.channels[3].load.startswith("none"), timeout=2)
    assert adapter.channels[3].fuse == "unknown"  # no load: not a fault
    adapter.set_output(SESSION, "SSR1", True)
    assert await wait_for(lambda: adapter.channels[1].triac == "ok", timeout=2)
    twin.ssr[1].fuse_ok = False
    assert await wait_for(lambda: adapter.channels[1].fuse == "blown", timeout=2)
    assert not twin.ssr[1].on
    assert "SSR1 fuse blown" in modules.store.devices["hm"].live("Faults").value
    adapter.set_output(SESSION, "SSR2", True)
    twin.ssr[2].triac_ok = False
    assert await wait_for(lambda: adapter.channels[2].triac == "defective", timeout=2)


async def test_blown_fuse_cleared_after_the_module_was_reset(modules):
    """Issue 10.6: the GUI follows the module's latch (7.2.3), with no help from the simulator page."""
    adapter = modules.worker.adapters["hm"]
    twin = modules.twins["hm"]
    state = modules.store.devices["hm"]
    adapter.set_output(SESSION, "SSR1", True)
    assert await wait_for(lambda: adapter.channels[1].triac == "ok", timeout=2)
    twin.ssr[1].fuse_ok = False
    assert await wait_for(lambda: adapter.channels[1].fuse == "blown", timeout=2)
    twin.ssr[1].fuse_ok = True  # replaced, but the 24 V were not cut: the module still reports Si = 0
    await asyncio.sleep(1.2)  # more than two 500 ms temperature/status telegrams (section 7.2.2) with Si = 0
    assert adapter.channels[1].fuse == "blown" and "SSR1 fuse blown" in state.live("Faults").value
    twin.power_cycle()  # 24 V cut
    assert await wait_for(lambda: adapter.channels[1].fuse == "ok", timeout=2)
    assert "SSR1 fuse blown" not in state.live("Faults").value
    assert any("SSR1" in e.text and "cleared" in e.text for e in state.events)
    assert await wait_for(lambda: twin.ssr[1].on, timeout=1)  # still commanded: the module switches it again


async def test_hmr_fault_switches_all_three_off(modules):
    adapter = modules.worker.adapters["hmr"]
    twin = modules.twins["hmr"]
    assert await wait_for(lambda: adapter.variant_check.may_switch, timeout=2)
    adapter.set_output(SESSION, "SSR1-3", True)
    assert await wait_for(lambda: all(twin.ssr[i].on for i in (1, 2, 3)), timeout=1)
    assert await wait_for(lambda: adapter.channels[2].triac == "ok", timeout=2)  # seen switched on with all bits 1
    twin.ssr[2].fuse_ok = False
    assert await wait_for(lambda: not any(twin.ssr[i].on for i in (1, 2, 3)), timeout=1)
    assert await wait_for(lambda: adapter.channels[2].fuse == "blown", timeout=2)
    assert adapter.temps[1].celsius == adapter.temps[2].celsius == adapter.temps[3].celsius  # t1-t3 carry TEMP1


async def test_p2_resent_after_reset(modules):
    adapter = modules.worker.adapters["hmr"]
    twin = modules.twins["hmr"]
    adapter.set_two_phase(True)
    assert await wait_for(lambda: twin.cfg == codec.P2, timeout=1)
    twin.powered = False
    twin.power_cycle()
    assert twin.cfg == 0
    state = modules.store.devices["hmr"]
    assert await wait_for(lambda: state.status != "online", timeout=4)  # silent long enough to be seen as gone
    twin.powered = True
    assert await wait_for(lambda: twin.cfg == codec.P2, timeout=3)


async def test_p2_in_force_within_1s_of_a_short_reset(modules):
    """Issue 10.5: a reset shorter than a DigOut period loses P2 (7.2.4) and nothing on the bus shows it;
    with a two-phase load the group must be back on within 1 s (4.3)."""
    adapter = modules.worker.adapters["hmr"]
    twin = modules.twins["hmr"]
    loop = asyncio.get_running_loop()
    twin.ssr[3].load = False  # three-phase output loaded on two phases
    assert await wait_for(lambda: adapter.variant_check.may_switch, timeout=2)
    adapter.set_two_phase(True)
    adapter.set_output(SESSION, "SSR1-3", True)
    assert await wait_for(lambda: twin.ssr[1].on and twin.ssr[2].on, timeout=1)
    back_after = []
    for pause in (0.05, 0.3, 0.45):
        twin.power_cycle()
        assert twin.cfg == 0 and not twin.ssr[1].on
        started = loop.time()
        assert await wait_for(lambda: twin.cfg == codec.P2 and twin.ssr[1].on and twin.ssr[2].on, timeout=1.0, interval=0.01)
        back_after.append(loop.time() - started)
        await asyncio.sleep(pause)  # the next reset falls at another point of the 500 ms DigOut period (SPEC-NOTES)
    print("P2 and SSR1-3 back after a short reset (s):", [round(t, 3) for t in back_after])
    assert not twin.ssr[3].on or not twin.ssr[3].load  # the unloaded phase reports no load


async def test_variant_mismatch_refuses_outputs():
    """Issue 10.7: the product code of an addressed module is compared with the plant file's variant."""
    runtime = Runtime(parse_plant(plant_text()), simulate=True)
    runtime.twins["hmr"].product = 0x3000  # the module on the bus is an HM01; the plant file says HMR
    await runtime.start()
    try:
        adapter = runtime.worker.adapters["hmr"]
        state = runtime.store.devices["hmr"]
        await adapter.take_control(SESSION, "engineer")  # the module answers once a master serves it
        assert await wait_for(lambda: adapter.variant_check.state == "mismatch", timeout=4)
        text = adapter.variant_check.text
        assert "HM01" in text and 'variant = "HM"' in text
        with pytest.raises(CommandError, match="HM01"):
            adapter.set_output(SESSION, "SSR4", True)
        await asyncio.sleep(0.6)  # longer than several DigOut periods: nothing switched it on
        assert not adapter.outputs["SSR4"] and not runtime.twins["hmr"].ssr[4].on
        assert any("HM01" in f for f in state.live("Faults").value)
        assert state.live("Variant check").value == "mismatch"
        adapter.set_output(SESSION, "SSR4", False)  # switching off is never refused
    finally:
        await asyncio.wait_for(runtime.stop(), 5)


async def test_variant_checked_again_after_the_module_was_gone(modules, monkeypatch):
    """A module exchanged for another variant: outputs off at once and refused."""
    monkeypatch.setattr(adapter_module, "OFFLINE_AFTER_S", 1.2)
    adapter = modules.worker.adapters["hmr"]
    twin = modules.twins["hmr"]
    assert await wait_for(lambda: adapter.variant_check.may_switch, timeout=2)
    adapter.set_output(SESSION, "SSR5", True)
    assert await wait_for(lambda: twin.ssr[5].on, timeout=1)
    twin.powered = False
    twin.power_cycle()
    twin.product = 0x3009  # a KM01 put in its place
    assert await wait_for(lambda: modules.store.devices["hmr"].online is False, timeout=3)
    twin.powered = True
    assert await wait_for(lambda: adapter.variant_check.state == "mismatch", timeout=3)
    assert not any(adapter.outputs.values()) and not adapter.holders()
    assert "KM01" in adapter.variant_check.text


async def test_variant_cannot_be_checked_in_simple_mode(modules):
    adapter = modules.worker.adapters["hm"]
    assert adapter.variant_check.state == "not possible" and adapter.variant_check.may_switch
    assert "cannot be checked" in modules.store.devices["hm"].live("Variant check").text


async def test_addressed_identity_and_customer_data(modules):
    adapter = modules.worker.adapters["hmr"]
    info = await adapter.read_identity()
    assert info["serial"] == "42120023" and info["product"] == "HMR01 (from 08.11.2013)" and info["version"] == "18.1"
    assert await adapter.read_customer(5) == b"\xff" * 6  # never written
    assert await adapter.write_customer(5, bytes([1, 2, 3])) == bytes([1, 2, 3, 0xFF, 0xFF, 0xFF])
    assert await adapter.read_customer(5) == bytes([1, 2, 3, 0xFF, 0xFF, 0xFF])
    modules.twins["hmr"].store_fails = True
    with pytest.raises(CommandError, match="instead of"):
        await adapter.write_customer(6, bytes([9, 9]))
    loads = await adapter.read_load_data()
    assert loads[4].celsius == 24.5 and loads[4].load


async def test_addressed_data_refused_without_s8(modules):
    with pytest.raises(CommandError, match="switch 8"):
        await modules.worker.adapters["hm"].read_identity()


async def test_bitrate_mismatch_is_flagged():
    text = plant_text().replace("bitrate = 500000", "bitrate = 1000000")
    runtime = Runtime(parse_plant(text), simulate=False)
    state = runtime.store.devices["hm"]
    assert state.live("Bit rate check").value == "mismatch"
    assert any("500 kbit/s" in e.text for e in state.events)


async def test_p2_read_back_in_addressed_mode(modules):
    """Issue 26.8: in addressed mode the module's dynamic configuration (area 2, index 15) is read back and its
    bit 7 compared with the P2 this tool sends; after a restart of the module it is sent again and read back again."""
    adapter = modules.worker.adapters["hmr"]
    twin = modules.twins["hmr"]
    state = modules.store.devices["hmr"]
    assert await wait_for(lambda: (state.live("P2 check").value == "verified"), timeout=3)
    adapter.set_two_phase(True)
    assert await wait_for(lambda: state.live("P2 check").value == "verified" and state.live("P2 check").raw == codec.P2,
                          timeout=3)
    twin.powered = False
    twin.power_cycle()
    assert await wait_for(lambda: state.status != "online", timeout=4)
    twin.powered = True
    assert await wait_for(lambda: twin.cfg == codec.P2 and state.status == "online", timeout=3)
    assert await wait_for(lambda: state.live("P2 check").value == "verified" and state.live("P2 check").raw == codec.P2,
                          timeout=4)
    assert "0x80" in state.live("P2 check").text


async def test_software_version_shown_as_an_assumed_decoding(modules):
    adapter = modules.worker.adapters["hmr"]
    await adapter.read_identity()
    state = modules.store.devices["hmr"]
    version = state.live("Software version")
    assert version.value == "18.1" and version.raw == 0x1201
    assert "assumed" in version.text and codec.VERSION_ASSUMPTION in version.text
    assert state.live("Identity").value.serial == "42120023" and "assumed decoding" in state.live("Identity").text
    assert state.live("Product").value == "HMR01 (from 08.11.2013)"
