"""The bus monitor's log of a line: a telegram's decoding is made when the log line is first read, not for
every telegram of a line nobody looks at; what it says is the same."""

from __future__ import annotations

import dataclasses

from app.line_base import LineBase, Transaction
from app.logited import LogitedTcp
from app.state import BusState


def test_a_log_line_is_decoded_when_read_and_once():
    line = LineBase("l", {}, BusState("l", "serial", "x"))
    calls: list[int] = []
    entry = line._record("RC", "52 43", "52 43 06", lambda: calls.append(1) or "ACK", 1.5, "")
    assert calls == []  # nothing decoded yet
    assert entry.decoded == "ACK" and entry.decoded == "ACK" and calls == [1]
    assert isinstance(entry, Transaction) and dataclasses.asdict(entry)["decoded"] == "ACK"
    assert line._record("RC", "", "", "text as given", None, "timeout").decoded == "text as given"
    failing = line._record("RC", "", "", lambda: 1 / 0, None, "")
    assert failing.decoded.startswith("cannot decode: division by zero")


def test_a_logited_line_decodes_its_telegrams_for_the_monitor_when_read():
    line = LogitedTcp("gate", {"host": "127.0.0.1", "port": 1, "timeout": 0.5}, BusState("gate", "logited-tcp", "x"))
    described: list[bytes] = []
    line.describe = lambda telegram: described.append(telegram) or f"{len(telegram)} bytes"
    line._hear(b"\x55\x02\x01\x00\x00\x00")
    assert described == []
    entry = line.state.transactions[-1]
    assert entry.decoded == "6 bytes" and described == [b"\x55\x02\x01\x00\x00\x00"]
    assert entry.response_hex == "55 02 01 00 00 00" and entry.request == "unsolicited"
