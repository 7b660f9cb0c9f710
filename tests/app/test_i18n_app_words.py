"""What app/ words for the record page, the overview and the replacement notice, in the reader's language (issue 47): a
twin action's answer, an identity's keys, the discovery rules and a flood's notice, and where a known identity came
from, also as read back from the replacement watch's file after a restart; each keeps the English it always had."""

from __future__ import annotations

import json

import can
import pytest
from plants import can_bus, hdlock_can, modbus_plant, plant

from app import i18n
from app.message import said
from app.record_cli import sim_action
from app.replace import IDENTITY_FILE, source_message
from app.runtime import Runtime
from app.worker import Worker
from devices.hdlock import codec

pytestmark = pytest.mark.timeout(60)

DE, EN = i18n.get("de"), i18n.get("en")


def test_the_discovery_rules_and_a_floods_notice_in_german():
    worker = Worker(plant(can_bus(hdlock_can("gate", 660100), simulate=None), name=None))
    rule, = worker.discovery_summary("can1")["rules"]
    assert rule == "HD-Lock: 3 status frames about 1 s apart"
    assert said(rule, DE) == "HD-Lock: 3 Status-Frames im Abstand von etwa 1 s"
    status = codec.encode_status(codec.StatusFrame(0x0200, 0, 100, 4))
    for n in range(100):  # more new IDs of a lock's form within a second than a plant powers up at once
        worker.discovery.frame("can1", can.Message(arbitration_id=0x10000 + n, data=status, is_extended_id=True,
                                                   timestamp=1_700_000_000.0 + n * 1e-3))
    flood = worker.discovery_summary("can1")["flood"]
    assert flood.startswith("flood of new CAN IDs since ") and flood.endswith(
        " (over 64 new IDs a second): nothing is listed until it has been quiet for 10 s")
    assert said(flood, DE).startswith("Flut neuer CAN-IDs seit ") and said(flood, DE).endswith(
        " (über 64 neue IDs pro Sekunde): nichts wird gelistet, bis es 10 s lang ruhig war")


def test_an_identitys_keys_come_from_the_catalog():
    from app.report import identity_rows

    d = {"type": "hdlock", "bus": "line1", "address": "address 1", "status": "online",
         "identity": {"serial": 660020, "FirmwareVersion": 57, "HardwareVersion": 3}}
    assert [k for k, _v in identity_rows(d)] == ["type", "bus", "address", "serial", "FirmwareVersion", "HardwareVersion",
                                                  "status"]
    assert [k for k, _v in identity_rows(d, DE)][3:6] == ["Seriennummer", "Firmware-Version", "Hardware-Version"]
    assert [k for k, _v in identity_rows(d, EN)] == [k for k, _v in identity_rows(d)]


def test_where_a_known_identity_came_from_is_read_back_as_its_message():
    for english, german in (("approved set", "abgenommener Satz"), ("first seen", "zuerst gesehen"),
                            ("replacement by anna", "Ersatz durch anna")):
        source = source_message(english)
        assert source == english and said(source, DE) == german and said(source, EN) == english
    assert source_message("typed by hand") == "typed by hand" and source_message(None) == ""


async def test_the_replacement_watch_reads_where_an_identity_came_from_back_after_a_restart(tmp_path):
    runtime = Runtime(modbus_plant(), simulate=False, data_dir=tmp_path)  # no twin: its identity would be taken afresh
    known = {"identity": {"serial": 1, "FirmwareVersion": 1}, "time": 1.0, "source": "replacement by anna"}
    (tmp_path / IDENTITY_FILE).write_text(json.dumps({runtime.plant.name: {"door-1": known}}))
    await runtime.start()
    try:
        source = runtime.replacements.known["door-1"]["source"]
        assert source == "replacement by anna" and said(source, DE) == "Ersatz durch anna"
    finally:
        await runtime.stop()


async def test_a_twin_actions_answer_keeps_its_english_and_comes_in_german(tmp_path):
    runtime = Runtime(modbus_plant(), simulate=True, data_dir=tmp_path)
    await runtime.start()
    try:
        answer = await sim_action(runtime, "door-1:toggle door", user="anna", role="engineer")
        assert answer == "door-1: simulation: toggle door" and said(answer, DE) == "door-1: Simulation: door umgeschaltet"
        audit = await runtime.audit.aquery(device="door-1")
        assert any(a.action == "simulation: toggle door" for a in audit), [a.action for a in audit]  # as it was written
        with pytest.raises(ValueError) as refused:
            await sim_action(runtime, "nope:toggle door", user="anna", role="engineer")
        assert said(refused.value, DE) == "--sim-action 'nope:toggle door': 'nope' ist kein simuliertes Gerät dieser Anlage"
    finally:
        await runtime.stop()
