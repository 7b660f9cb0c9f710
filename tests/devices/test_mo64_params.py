"""MO 64 parameter model (devices/mo64/params.py): every EEPROM setting the document names, the configuration
flags bit by bit, the confirmation a safety flag names on every path (declared write, "set ..." command, raw
telegram), and the read-modify-write of one setting against the twin, with its strict modes (a refused assumed
selector, a slow EEPROM write)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_mo64_adapter import adapter_on_twin, close_lines  # noqa: F401 - close_lines: autouse, closes the adapters

from devices.commands import commands_of
from devices.mo64 import codec
from devices.mo64 import params as model
from devices.mo64.adapter import CommandError
from devices.mo64.control import EEPROM_RISK, meaning
from devices.mo64.params import KRAFT_RISK, LOOP_SAFETY_RISK, LS_TEST_RISK, PARAMS
from devices.mo64.policy import WRITE_PARAM
from devices.params import Access
from devices.registry import DEVICE_TYPES

pytestmark = pytest.mark.timeout(30)
KRAFT = PARAMS.by_name["Kraftüberwachung"]
LS_TEST = PARAMS.by_name["LS-Test"]
LOOP_MODE = PARAMS.by_name["Induktionsschleifen-Sichern-Modus"]


def test_every_setting_of_the_document_is_modelled_and_the_type_names_the_model():
    assert DEVICE_TYPES["mo64"].params is PARAMS
    keys = {p.setting_key for p in PARAMS if p.setting_key}
    assert keys == set(codec.SETTINGS)  # every setting telegram the directory knows has its named pieces
    assert len([p for p in PARAMS if p.writable]) == 30
    assert len([p for p in PARAMS if p.setting]) == 29  # the vehicle counter counts by itself: no setting
    assert {f"multi{n}" for n in range(1, 7)} <= set(PARAMS.by_name)
    for name in ("schleife_a", "schleife_b", "schleife_c", "Richtungslogik1", "Richtungslogik2", "dec_bt"):
        assert PARAMS.by_name[name].access is Access.R and not PARAMS.by_name[name].writable  # no setting telegram
    # the bits the document prints sit where it prints them (chapter 5.1.24)
    assert PARAMS.by_name["RtApl in Endlage blinken"].key == "config_flags:0"
    assert PARAMS.by_name["GnApl bei Zwischenstopp blinken"].key == "config_flags:24"  # konfig1 bits 9, 8
    assert PARAMS.by_name["Warnlicht in Endlage AUF blinken"].key == "config_flags:40"  # konfig2 bits 9, 8
    assert not PARAMS.by_name["Warnlicht in Endlage AUF blinken"].assumed and KRAFT.assumed  # unprinted: assumed


def test_no_two_pieces_of_a_setting_share_a_bit():
    for key in codec.SETTINGS:
        used: set[int] = set()
        for p in model.of_setting(key):
            bits = set(range(p.address, p.address + p.width))
            assert not bits & used, (key, p.name)
            used |= bits
        assert max(used) < 8 * codec.SETTING_VALUE_BYTES[codec.SETTINGS[key].telegram], key


def test_a_piece_replaced_keeps_the_other_bits_and_round_trips_through_the_telegram():
    flags = {"konfig0": 0x0005, "konfig1": 0x0ABC, "konfig2": 0x0300 | (1 << 11), "konfig3": 0x0001}
    number = model.setting_int("config_flags", flags)
    assert model.extract(KRAFT, number) == 1 and model.extract(LS_TEST, number) == 1
    cleared = model.replace(KRAFT, number, 0)
    value = model.setting_value("config_flags", cleared)
    assert value == {**flags, "konfig2": 0x0300}
    telegram = codec.encode_setting("config_flags", value)
    request = codec.decode_request(codec.Frame(telegram[0], telegram[1:]))
    assert model.setting_int("config_flags", request.value) == cleared
    relays = model.setting_int("multi_relays", [1, 0, 7, 0, 0, 2])
    assert [model.extract(PARAMS.by_name[f"multi{n}"], relays) for n in range(1, 7)] == [1, 0, 7, 0, 0, 2]
    assert PARAMS.by_name["multi3"].display(7) == "mode 7 (not named in the summary)"
    assert PARAMS.by_name["multi1"].display(1) == "fault (1)"


def test_times_are_seconds_in_steps_of_10_ms_up_to_655_s():
    t_open = PARAMS.by_name["t_offen"]
    assert t_open.validate(12.5) == 1250 and t_open.display(1250) == "12.5 s"
    with pytest.raises(ValueError, match="outside 0 .. 655"):
        t_open.validate(700)


@pytest.mark.parametrize(("param", "off", "words"), [
    (KRAFT, "ohne", ("Kraftüberwachung", "force monitoring")),
    (LS_TEST, "aus", ("LS-Test", "light-barrier test")),
    (LOOP_MODE, "Stopp", ("Induktionsschleifen-Sichern-Modus", "loop safety mode")),
])
def test_a_flag_that_switches_a_safety_function_off_asks_naming_it(param, off, words):
    raw = param.validate(off)
    question = param.needs_confirmation(raw)
    assert all(w in question for w in words)
    with pytest.raises(ValueError, match="needs confirmation"):
        param.prepare_write(off)
    assert param.prepare_write(off, confirmed=True) == raw
    on = next(k for k in param.enum if k != raw)
    assert param.needs_confirmation(on) == ""  # switching it on (or to the safer choice) asks nothing
    refused, risk = WRITE_PARAM.refuse_if(_written(param, raw), [], "gate"), WRITE_PARAM.risk_text(
        _written(param, raw))
    assert not refused and all(w in risk for w in words)


def _written(param, raw: int) -> dict:
    """The declared write's checked arguments for ``raw``: the value the parameter model accepts."""
    return {"param": param, "value": param.accept(param.decode(raw))}


def test_the_whole_setting_and_a_raw_telegram_ask_the_same_question():
    flags = {"konfig0": 0, "konfig1": 0, "konfig2": 0, "konfig3": 1}  # Kraftüberwachung ohne, LS-Test on
    telegram = codec.encode_setting("config_flags", flags)
    what = meaning(telegram)
    assert what.kind == "write" and KRAFT_RISK in what.risk and EEPROM_RISK in what.risk
    assert LS_TEST_RISK not in what.risk and LOOP_SAFETY_RISK not in what.risk
    safe = meaning(codec.encode_setting("config_flags", {**flags, "konfig2": 1 << 11}))
    assert safe.risk == EEPROM_RISK  # force monitoring on: only the wear
    command = commands_of("mo64")["set configuration flags"]
    risk = command.risk_text(command.checked_args(flags))
    assert KRAFT_RISK in risk and EEPROM_RISK in risk


def test_an_assumed_selector_asks_that_it_is_verified_and_a_read_only_value_is_refused():
    prewarn = PARAMS.by_name["Pre-warning before opening"]
    assert prewarn.selector_assumed
    assert "verified on this unit" in WRITE_PARAM.risk_text(_written(prewarn, 80))
    assert WRITE_PARAM.risk_text(_written(PARAMS.by_name["t_offen"], 80)) == ""  # named in 5.2.4.1
    with pytest.raises(ValueError, match="cannot be written"):
        PARAMS.by_name["schleife_a"].validate(1)


# -- against the twin: read-modify-write, read back, strict modes ---------------------------------------------
async def test_clearing_force_monitoring_needs_its_confirmation_and_keeps_every_other_bit():
    async with adapter_on_twin() as (sim, adapter):
        twin = sim.twin
        twin.settings["config_flags"] = {"konfig0": 0x0005, "konfig1": 0x0300, "konfig2": 0x0300 | (1 << 11),
                                         "konfig3": 0x0001}
        with pytest.raises(CommandError, match="needs confirmation: Kraftüberwachung"):
            await adapter.write_param(KRAFT, "ohne")
        assert twin.setting_writes == {}  # nothing sent
        assert await adapter.write_param(KRAFT, "ohne", confirmed=True, session="s1") == 0
        assert twin.settings["config_flags"] == {"konfig0": 0x0005, "konfig1": 0x0300, "konfig2": 0x0300,
                                                 "konfig3": 0x0001}
        assert twin.setting_writes == {"config_flags": 1} and adapter.eeprom_writes == {"s1": 1}
        assert adapter.state.raw(KRAFT) == 0 and adapter.state.raw(LS_TEST) == 1  # the store holds the model's values
        assert await adapter.write_param("config_flags:43", 1) == 1  # back on: asks nothing
        assert twin.settings["config_flags"]["konfig2"] == 0x0300 | (1 << 11)


async def test_a_backup_lists_the_model_and_each_piece_is_read_back():
    async with adapter_on_twin() as (sim, adapter):
        entries = {e["key"]: e for e in await adapter.backup_read()}
        assert entries["config_flags:43"]["text"] == "Stopp und öffnen (1)" and entries["config_flags:43"]["setting"]
        assert entries["t_open:0"]["value"] == 10.0 and entries["t_open:0"]["text"] == "10 s"
        assert not entries["dec_bt:0"]["writable"] and entries["loop_periods"]["raw"] == "00 00 00 00 00 00"
        assert not any(k.startswith("vehicle_counter") for k in entries)  # RAM only (chapter 5.2.5)
        sim.twin.strict.eeprom_write_s = 0.6  # a slow EEPROM (strict mode): syn, then ack after 0.6 s
        assert await adapter.write_param("multi_relays:16", 2) == 2
        assert sim.twin.settings["multi_relays"] == (1, 0, 2, 0, 0, 0)


async def test_a_refused_assumed_selector_writes_nothing_and_says_so():
    async with adapter_on_twin() as (sim, adapter):
        prewarn = PARAMS.by_name["Pre-warning before opening"]
        with pytest.raises(CommandError, match="assumption"):
            await adapter.write_param(prewarn, 0.8)  # not confirmed as verified on this unit
        sim.twin.strict.refuse_selectors = {"t_prewarn_open"}  # strict mode: the unit does not take the assumed selector
        with pytest.raises(CommandError, match="answered nak"):
            await adapter.write_param(prewarn, 0.8, confirmed=True)
        assert sim.twin.settings["t_prewarn_open"] == 50 and sim.twin.setting_writes == {}
        sim.twin.strict.refuse_selectors = set()
        assert await adapter.write_param(prewarn, 0.8, confirmed=True) == 80
        counter = PARAMS.by_name["Vehicle counter"]  # signed, RAM only: ack without syn, no EEPROM write counted
        assert counter.decode(await adapter.write_param(counter, -5, confirmed=True)) == -5
        assert sim.twin.vehicle_counter == -5 and "vehicle_counter" not in sim.twin.setting_writes


# -- every piece, any value: the other bits stay ---------------------------------------------------------------
WRITABLE = [p for p in PARAMS if p.setting_key and p.setting_key != "vehicle_counter"]


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(WRITABLE), st.integers(0, (1 << 64) - 1), st.data())
def test_writing_any_piece_changes_only_its_own_bits(param, before, data):
    key = param.setting_key
    width = 8 * codec.SETTING_VALUE_BYTES[codec.SETTINGS[key].telegram]
    before &= (1 << width) - 1
    if key == "t_open" or key.startswith("t_prewarn"):
        before = min(before & 0xFFFF, codec.TIME_MAX)
    low, high = param.limits()
    raw = param.encode(data.draw(st.sampled_from(sorted(param.enum)) if param.enum else
                                 st.integers(int(low / param.scale), int(high / param.scale)).map(lambda n: n * param.scale)))
    after = model.replace(param, before, raw)
    assert model.extract(param, after) == raw
    assert after & ~(param.mask << param.address) == before & ~(param.mask << param.address)
    value = model.setting_value(key, after)
    assert model.setting_int(key, value) == after  # what the telegram carries, back to the same number
