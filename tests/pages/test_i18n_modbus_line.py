"""The Modbus line's own words in German (issue 47): its diagnoses (app/modbus_line.py: a timeout, an exception answer
with its code's name, a CRC error, an answer from another unit) where a user meets them, a device's last error on its
page and in the overview's tile, the bus monitor's error column, the Modbus poll's window and the HD-Lock's failed
write in the command client's notification; and the words of a request (``read holding 3000+9``: HR lesen 3000+9, the
registers as the pages name them beside a parameter) in the monitor's rows and inside a diagnosis. The store, the
transaction log and the event log keep the English (request_target() parses the request's)."""

from __future__ import annotations

import pytest
from nicegui import ui
from nicegui.testing.user_interaction import UserInteraction
from test_i18n_pages import by_testid, english_on, german_locks, marked_table, shown_texts
from webutil import eventually

from app import i18n
from app.message import Message, said
from app.modbus_line import EXCEPTION_NAMES, read_words, request_target, write_words
from devices.commands import WRITE_PARAMETER

pytestmark = pytest.mark.timeout(60)

DE = i18n.get("de")


def shows(user, *pieces: str) -> bool:
    return any(all(piece in text for piece in pieces) for text in shown_texts(user))


async def test_a_silent_locks_timeout_in_german_on_its_page_the_overview_and_the_monitor(tmp_path):
    """door-2 stops answering: its page, its overview tile and the monitor's rows say the line's timeout in German, the
    monitor's rows the requests too; the store keeps the English."""
    async with german_locks(tmp_path, "door-1", "door-2") as (runtime, user):
        state = runtime.store.devices["door-2"]
        runtime.twins["door-2"].silent = True
        await eventually(lambda: state.status == "offline", timeout=15, what="door-2 offline")
        assert str(state.last_error).startswith("unit 2: no answer within "), state.last_error  # the English as it was

        await user.open("/device/door-2")
        await eventually(lambda: shows(user, "Unit 2: keine Antwort innerhalb von ", " s (Zeitüberschreitung)"),
                         timeout=10, what="the lock's last error in German")
        assert not shows(user, "no answer within")

        await user.open("/")
        await eventually(lambda: shows(user, "Unit 2: keine Antwort innerhalb von "), timeout=10,
                         what="the tile's last error in German")
        assert not shows(user, "no answer within")

        await user.open("/monitor/line1")
        await user.should_see("Busmonitor line1", retries=50)
        table = marked_table(user, "transactions")
        await eventually(lambda: table.rows, timeout=15, what="the line's transactions")
        requests = {r["request"] for r in table.rows}
        assert any(r.startswith("HR lesen ") for r in requests), requests
        assert any(r.startswith("IR lesen ") for r in requests), requests
        assert not [r for r in table.rows if r["request"].startswith(("read ", "write "))]
        next(e for e in user.client.elements.values() if isinstance(e, ui.switch) and e.text == "Nur Fehler").value = True
        await eventually(lambda: any(r["device"] == "door-2 (Unit 2)" and r["error"].startswith("keine Antwort innerhalb von ")
                                     for r in table.rows), timeout=15, what="a timeout of door-2 in the monitor in German")
        assert not [r for r in table.rows if "no answer" in r["error"]]
        log = list(runtime.store.buses["line1"].transactions)
        assert any(str(t.error).startswith("no answer within ") for t in log)  # the log keeps the English
        assert all(str(t.request).startswith(("read ", "write ")) for t in log)
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))


async def test_the_modbus_polls_exception_and_timeout_in_german(tmp_path):
    """The Modbus poll's window (pages/bus_poll.py): an address the lock does not have is answered with exception 02,
    said in German with the code's name and the request's words; a unit nobody answers times out in German. The
    monitor shows the poll's request and its exception in German."""
    async with german_locks(tmp_path, "door-1") as (runtime, user):
        await user.open("/monitor/line1/poll")
        await user.should_see("Fenster 1", retries=50)
        card = by_testid(user, "poll-window-1")

        def field(kind: type, label: str) -> ui.element:
            return next(e for e in card.descendants() if isinstance(e, kind) and e.props.get("label") == label)

        field(ui.number, DE.pgettext("Modbus", "Unit")).value = 1
        field(ui.number, DE.gettext("Start address")).value = 60000
        field(ui.number, DE.gettext("Count")).value = 2
        UserInteraction(user, {by_testid(user, "poll-start")}, None).click()
        error = by_testid(user, "poll-error")
        await eventually(lambda: error.text == "Unit 1: HR abfragen 60000+2: Exception 0x02 (unzulässige "
                                               "Datenadresse)", timeout=10, what=error.text)
        assert "exception 0x02 (illegal data address)" in {t.error for t in runtime.store.buses["line1"].transactions}

        UserInteraction(user, {by_testid(user, "poll-stop")}, None).click()
        field(ui.number, DE.pgettext("Modbus", "Unit")).value = 9
        field(ui.number, DE.gettext("Start address")).value = 0
        UserInteraction(user, {by_testid(user, "poll-start")}, None).click()
        await eventually(lambda: error.text.startswith("Unit 9: keine Antwort innerhalb von "), timeout=10, what=error.text)
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))

        await user.open("/monitor/line1")
        await user.should_see("Busmonitor line1", retries=50)
        table = marked_table(user, "transactions")
        await eventually(lambda: any(r["request"] == "HR abfragen 60000+2" and
                                     r["error"] == "Exception 0x02 (unzulässige Datenadresse)" for r in table.rows),
                         timeout=10, what="the poll's exception in the monitor in German")


async def test_the_hdlocks_failed_write_says_the_lines_diagnosis_in_german(tmp_path):
    """A lock that answers every write with exception 04: the command client's notification says the adapter's failure
    and the line's diagnosis in German (devices/hdlock/adapter.py); the error keeps its English."""
    from pages.command_client import run_command

    async with german_locks(tmp_path, "door-1") as (runtime, user):
        runtime.twins["door-1"].refuse_writes = True
        await user.open("/device/door-1")
        await user.should_see("HD-Lock door-1", retries=50)
        with user.client:
            ok, _result = await run_command("door-1", WRITE_PARAMETER, args={"param": "LockRequestDelay", "value": 420})
        assert not ok
        await eventually(lambda: any(m.endswith("Schreiben von LockRequestDelay fehlgeschlagen: Unit 1: HR schreiben 3000=420: "
                                                "Exception 0x04 (Gerätefehler)") for m in user.notify.messages),
                         timeout=10, what=user.notify.messages)
        assert not [m for m in user.notify.messages if "failed" in m or "device failure" in m], user.notify.messages


def test_the_lines_words_keep_their_english_and_say_it_in_german():
    """Each diagnosis and request word of the line, English as stored (request_target() still finds the register),
    German as a page shows it."""
    from app.i18n import N_

    read = read_words("holding", 3000, 9)
    assert read == "read holding 3000+9" and said(read, DE) == "HR lesen 3000+9"
    assert request_target(read) == ("holding", 3000, None)
    assert said(read_words("input", 104, 2), DE) == "IR lesen 104+2"
    write = write_words(3006, 65476)
    assert request_target(write) == ("holding", 3006, 65476) and said(write, DE) == "HR schreiben 3006=65476"
    broadcast = Message(N_("broadcast write holding {address}={value}"), address=2000, value=8)
    assert request_target(broadcast) == ("holding", 2000, 8)
    assert said(broadcast, DE) == "Broadcast: HR schreiben 2000=8"
    scan = Message(N_("scan holding {address}"), address=103)
    assert request_target(scan) == ("holding", 103, None) and said(scan, DE) == "Suchlauf HR 103"

    for code, name in EXCEPTION_NAMES.items():
        assert DE.gettext(name) != name, (code, name)
    conflict = Message(N_("unit {unit}: {error}"), unit=3,
                       error=Message(N_("answer from unit {other}: address conflict on the line?"), other=9))
    assert conflict == "unit 3: answer from unit 9: address conflict on the line?"
    assert said(conflict, DE) == "Unit 3: Antwort von Unit 9: Adresskonflikt auf der Leitung?"
    crc = Message(N_("CRC or framing error in the answer"))
    assert said(crc, DE) == "CRC- oder Rahmenfehler in der Antwort"
    timeout = Message(N_("no answer within {timeout} s"), timeout=0.5)
    assert timeout == "no answer within 0.5 s" and said(timeout, DE) == "keine Antwort innerhalb von 0,5 s (Zeitüberschreitung)"
