"""The bus monitor of an SCU's RS232 line and of a LogiTed line (issue 42 item 11): telegrams decoded in the words of
their device pages (not "ACK, 53 data bytes", not "between others"). The pages and their filters:
tests/pages/test_monitor_lines_pages.py."""

from __future__ import annotations

import pytest
from test_monitor import demo_plant

from app.line_base import Transaction
from app.recording import lines
from app.worker import Worker
from devices.mo64 import codec as mo64
from devices.scu import adapter as scu_adapter
from devices.scu import codec as scu
from devices.scu import linewords as scu_words
from devices.scu import params as scu_params

pytestmark = pytest.mark.timeout(60)


@pytest.fixture(scope="module")
def worker() -> Worker:
    """The demo plant's worker, not started: adapters made, no line opened."""
    return Worker(demo_plant())


def line(request: bytes, answer: bytes, what: str = "x") -> Transaction:
    return Transaction(0.0, 0, what, request.hex(" ").upper(), answer.hex(" ").upper(), "", 1.0, "")


# -- the SCU's telegrams ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("request_", "answer", "words", "decoded"), [
    (scu.KEEP_ALIVE, scu.encode_answer(scu.RC, scu.ACK, b""), "RC keep-alive", "ACK"),
    (scu.encode_re(0, scu.Motion.OUT, scu.Ramp.DEFAULT), scu.encode_answer(scu.RE),
     "RE F1 Move to position Out, ramp default", "ACK"),
    (scu.encode_rs(0), scu.encode_answer(scu.RS), "RS F1", "ACK"),
    (scu.encode_re(scu.Function.EMERGENCY_STOP), scu.encode_answer(scu.RE), "RE F20 Emergency stop", "ACK"),
    (scu.encode_ro(1), scu.encode_answer(scu.RO), "RO Safety_ID 1", "ACK"),
    (scu.encode_rg(0x0011), scu.encode_answer(scu.RG, scu.ACK, (1200).to_bytes(4, "little", signed=True)),
     "RG 0x0011 Actual_Position Actuator 1", "Actual_Position Actuator 1 = 1200 counts"),
    (scu.encode_rg(0x00A1), scu.encode_answer(scu.RG, scu.ACK, (12).to_bytes(2, "little")),
     "RG 0x00A1 Strom A1", "Strom A1 = 1.2 A"),
    (scu.encode_rg(0x0120), scu.encode_answer(scu.RG, scu.ACK, b"\x01"),
     "RG 0x0120 Hand switch LEDs (LED HS)", "Hand switch LEDs (LED HS) = LED1 on, LED2 off"),
    (scu.encode_rg(0x0140), scu.encode_answer(scu.RG, scu.Status.PE), "RG 0x0140 Buzzer", "PE (Permission error): "),
])
def test_scu_telegrams_in_the_words_of_the_scu_page(worker: Worker, request_: bytes, answer: bytes, words: str,
                                                    decoded: str):
    text = lines.line_words(worker, "rs232-1").text(line(request_, answer))
    assert text.request == words
    assert text.decoded.startswith(decoded), text.decoded
    assert request_[:2].decode() in text.tags


def test_scu_cyclic_object_answers_by_its_definition(worker: Worker):
    decoder = scu_words.ScuLineDecoder(worker.plant.devices_on("rs232-1"), {})  # no adapter: it told no definition
    definition = scu_params.CyclicDefinition(read_ids=scu_adapter.CYCLIC_READ_IDS)
    values = {i: 0 for i in definition.read_ids if not scu_params.item(i).is_group}
    for group in definition.read_ids:
        if scu_params.item(group).is_group:
            values[group] = {f"0x{m:04X}": 0 for m in scu_params.item(group).members}
    values[0x0010]["0x0011"] = 1500
    data = definition.encode_read(values)
    before = decoder.text(line(scu.encode_rc(0), scu.encode_answer(scu.RC, scu.ACK, data)))
    assert "definition was not seen" in before.decoded  # says why it is not decoded, not "ACK, 53 data bytes"
    rt = decoder.text(line(scu.encode_rt(0x3001, definition.encode()), scu.encode_answer(scu.RT)))
    assert rt.request.startswith("RT 0x3001 CyclicObj 1 definition: reads 0x0010, 0x0170")
    after = decoder.text(line(scu.encode_rc(0), scu.encode_answer(scu.RC, scu.ACK, data), "RC keep-alive again"))
    assert after.request == "RC keep-alive with CyclicObj 1"
    assert after.decoded.startswith("Actual_Position, all actuators: A1 1500 counts, A2 0 counts"), after.decoded
    assert {"RC", "0x0010", "0x0011", "0x00D1"} <= after.tags  # a data ID filter finds the RC that carries it


# -- the MO 64's telegrams ----------------------------------------------------------------------------------------


def test_logited_tcp_telegrams_in_the_words_of_the_mo64_page(worker: Worker):
    decoder = lines.line_words(worker, "gate-tcp")
    frame = mo64.encode_frame
    pulse = decoder.text(line(frame(mo64.encode_command(mo64.Command.OPEN)), frame(mo64.encode_answer(mo64.Reply.ACK))))
    assert (pulse.request, pulse.decoded) == ("open pulse", "ack") and {"command", "reply"} <= pulse.tags
    gate = decoder.text(line(frame(mo64.encode_query(7)), frame(mo64.encode_answer(0x0C, 5))))
    assert (gate.request, gate.decoded) == ("query gate state", "Gate state = closed")
    assert {"query", "answer", "0x0C"} <= gate.tags
    heard = decoder.text(line(b"", frame(mo64.encode_answer(0x1D, 40)), "unsolicited"))
    assert (heard.request, heard.decoded) == ("unsolicited (change monitoring)", "Position = 40 %")


def test_logited_rs485_names_another_masters_telegrams(worker: Worker):
    decoder = lines.line_words(worker, "gates-485")
    address = worker.plant.devices["barrier-out-1"].options["address"]
    query = mo64.encode_frame(mo64.encode_query(7), mo64.RS485, da=address, sa=0x01)
    answer = mo64.encode_frame(mo64.encode_answer(0x0C, 5), mo64.RS485, da=0x01, sa=address)
    asked = decoder.text(line(b"", query, "between others"))
    told = decoder.text(line(b"", answer, "between others"))
    assert asked.request == "master 0x01 -> barrier-out-1: query gate state" and "other master" in asked.tags
    assert told.request == "barrier-out-1 -> master 0x01: answer" and told.decoded == "Gate state = closed"


def test_each_line_kind_declares_its_own_filters(worker: Worker):
    assert [f.key for f in lines.line_words(worker, "rs232-1").filters] == ["command", "data-id"]
    assert [f.key for f in lines.line_words(worker, "gate-tcp").filters] == ["telegram"]
    assert lines.line_words(worker, "line1") is None  # Modbus: unit, function and address (pages/monitor.py)
    assert scu_words.parse_data_id("11") == "0x0011" == scu_words.parse_data_id("0x0011")
    with pytest.raises(ValueError, match="hex"):
        scu_words.parse_data_id("xyz")

