"""CAN-M3IO: codec golden vectors (document sections 5.8, 7.2) and the adapter against the twins."""

from __future__ import annotations

import asyncio
import itertools

import pytest
from conftest import wait_for

from app.plant import parse_plant
from app.runtime import Runtime
from devices.m3io import codec
from devices.m3io.adapter import CommandError
from devices.m3io.codec import TempWord, Variant

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


def test_product_codes():
    assert codec.product_name(0x3000) == "HM01"
    assert codec.product_name(0x300A).startswith("HMR01")
    assert codec.product_name(0x3009).startswith("KM01")
    assert "unknown" in codec.product_name(0x4242)


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
    assert (m.load, m.fuse, m.triac) == ("none (no load or no supply)", "unknown", "unknown")  # not a fault
    m.update(TempWord.make(250, True, True, True, False), switched_on=True)
    assert (m.fuse, m.triac, m.seen_ok) == ("ok", "ok", True)
    m.update(TempWord.make(250, load=False, triac=True, fuse=False, addressed=False), switched_on=True)
    assert m.fuse == "blown"  # Last went 0 with the fuse: remembered as blown
    m.update(TempWord.make(250, load=True, triac=True, fuse=True, addressed=False), switched_on=True)
    assert m.fuse == "blown"  # latched until the 24 V are cut
    m.reset()
    m.update(TempWord.make(250, load=True, triac=False, fuse=True, addressed=False), switched_on=True)
    assert (m.fuse, m.triac) == ("ok", "defective")
    m.update(TempWord.make(250, load=True, triac=True, fuse=True, addressed=False), switched_on=False)
    assert m.triac == "not checked (off)"


def test_fuse_advice_from_table():
    assert codec.fuse_advice(Variant.HMR, 1) == "replace fuse SI3 (16 A, fast-acting 5x20 mm)"
    assert codec.fuse_advice(Variant.HM, 1) == "replace fuse SI3 (10 A, fast-acting 5x20 mm)"
    assert codec.fuse_advice(Variant.HM, 6).startswith("replace fuse SI8")


# -- adapter + twins on a virtual bus --------------------------------------------------------------

_n = itertools.count()


def plant_text() -> str:
    return (
        f'[[bus]]\nname = "can3"\ntype = "can"\ninterface = "virtual"\nchannel = "m3-{next(_n)}-{id(object())}"\n'
        'bitrate = 500000\npoll_period = 0.2\nsimulate = true\n'
        '[[device]]\nname = "hm"\ntype = "m3io"\nbus = "can3"\nvariant = "HM"\nsw1 = 0x1A\n'
        '[[device]]\nname = "hmr"\ntype = "m3io"\nbus = "can3"\nvariant = "HMR"\nsw1 = 0xCA\nserial = 42120023\n'
    )


@pytest.fixture
async def modules():
    runtime = Runtime(parse_plant(plant_text()), simulate=True)
    await runtime.start()
    for name in ("hm", "hmr"):
        state = runtime.store.devices[name]
        assert await wait_for(lambda s=state: s.status == "online", timeout=4)
    try:
        yield runtime
    finally:
        await asyncio.wait_for(runtime.stop(), 5)


async def test_watchdog_kept_alive_and_temperatures_flow(modules):
    adapter = modules.worker.adapters["hm"]
    twin = modules.twins["hm"]
    await asyncio.sleep(2.5)  # longer than the 2 s watchdog
    assert twin.watchdog_alive
    assert modules.worker.can_buses["can3"].cyclic_running(adapter.key)
    assert adapter.temps[3].celsius == 23.5 and adapter.inputs is not None
    twin.toggle_input("E4")
    assert await wait_for(lambda: adapter.inputs["E4"], timeout=1)


async def test_outputs_drop_in_the_twin_when_the_worker_stops(modules):
    adapter = modules.worker.adapters["hm"]
    twin = modules.twins["hm"]
    adapter.set_output("SSR1", True)
    assert await wait_for(lambda: twin.ssr[1].on, timeout=1)
    await modules.worker.stop()  # no more DigOut
    assert await wait_for(lambda: not twin.ssr[1].on, timeout=3)
    assert not twin.watchdog_alive


async def test_outputs_off_when_the_last_engineer_leaves(modules):
    worker = modules.worker
    adapter = worker.adapters["hm"]
    worker.session_opened("browser-1")
    adapter.set_output("SSR2", True)
    assert await wait_for(lambda: modules.twins["hm"].ssr[2].on, timeout=1)
    worker.session_closed("browser-1")
    assert not any(adapter.outputs.values())
    assert await wait_for(lambda: not modules.twins["hm"].ssr[2].on, timeout=1)
    assert any("no engineer session" in e.text for e in modules.store.devices["hm"].events)
    assert worker.can_buses["can3"].cyclic_running(adapter.key)  # DigOut goes on: inputs keep coming


async def test_fuse_triac_load_states(modules):
    adapter = modules.worker.adapters["hm"]
    twin = modules.twins["hm"]
    twin.ssr[3].load = False
    assert await wait_for(lambda: adapter.channels[3].load.startswith("none"), timeout=2)
    assert adapter.channels[3].fuse == "unknown"  # no load: not a fault
    adapter.set_output("SSR1", True)
    assert await wait_for(lambda: adapter.channels[1].triac == "ok", timeout=2)
    twin.ssr[1].fuse_ok = False
    assert await wait_for(lambda: adapter.channels[1].fuse == "blown", timeout=2)
    assert not twin.ssr[1].on
    assert "SSR1 fuse blown" in modules.store.devices["hm"].info["faults"]
    adapter.set_output("SSR2", True)
    twin.ssr[2].triac_ok = False
    assert await wait_for(lambda: adapter.channels[2].triac == "defective", timeout=2)


async def test_hmr_fault_switches_all_three_off(modules):
    adapter = modules.worker.adapters["hmr"]
    twin = modules.twins["hmr"]
    adapter.set_output("SSR1-3", True)
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
    await asyncio.sleep(2.8)  # silent long enough to be seen as gone
    twin.powered = True
    assert await wait_for(lambda: twin.cfg == codec.P2, timeout=3)


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
    assert state.info["bitrate_mismatch"]
    assert any("500 kbit/s" in e.text for e in state.events)
