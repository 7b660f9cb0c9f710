"""What the adapters word themselves, in German on the device pages (issue 47): the MO 64's last answer, the
Electrak's service answers, the HD-Lock's CAN status frame and the outcome of an address change, the SCU's data
directory and service values. The English of each stays as it was (the store, the event log and the tests of the
device pages keep it)."""

from __future__ import annotations

import pytest
from nicegui import ui
from nicegui.testing.user_interaction import UserInteraction
from test_i18n_pages import german_locks, german_page, german_user, shown_texts
from webutil import by_testid, eventually

from app import i18n
from app.message import said
from app.runtime import Runtime
from devices.hdlock import codec as hdlock_codec
from devices.hdlock.adapter import status_frame_text

pytestmark = pytest.mark.timeout(60)


def shown(user, *pieces: str) -> bool:
    return any(all(piece in text for piece in pieces) for text in shown_texts(user))


async def test_the_mo64_page_words_the_barriers_last_answer_in_german(tmp_path):
    """After a pulse the last answer reads ``öffnen Impuls: ack`` (the document's tele_ack stays as it is)."""
    from plants import mo64_tcp, plant

    runtime = Runtime(plant(mo64_tcp()), simulate=True, data_dir=tmp_path)
    async with german_user(runtime) as user:
        adapter = runtime.worker.adapters["gate"]
        await eventually(lambda: "Gate state" in adapter.state.points, timeout=15, what="the barrier")
        await user.open("/device/gate")
        await user.should_see("Torzustand: Schranke ist geschlossen", retries=100)
        UserInteraction(user, {by_testid(user, "pulse-open")}, None).click()
        await eventually(lambda: any(isinstance(e, ui.button) and e.props.get("label") == "Senden"
                                     for e in user.client.elements.values()), timeout=5, what="the question")
        assert any(isinstance(e, ui.label) and e.text == "öffnen Impuls?" for e in user.client.elements.values())  # the title
        send = {e for e in user.client.elements.values() if isinstance(e, ui.button) and e.props.get("label") == "Senden"}
        UserInteraction(user, send, None).click()
        await eventually(lambda: by_testid(user, "reply").text == "letzte Antwort: öffnen Impuls: ack", timeout=5,
                         what=by_testid(user, "reply").text)
        assert adapter.last_reply == "open pulse: ack"  # the adapter's English as it was


async def test_the_electrak_page_words_the_service_answers_in_german(tmp_path):
    """The page's first reads of the service parameters: ``Lesen 0x..`` and each answer's ``Wert ..``."""
    from plants import electrak_bus, plant

    async with german_page(tmp_path, plant(electrak_bus()), "lift", "Electrak-HD-Netzwerk lift") as (runtime, user):
        await eventually(lambda: shown(user, "letztes Servicetelegramm: Lesen 0x", "Antwort 1: Wert "), timeout=15,
                         what="the last service telegram in German")
        assert not shown(user, "answer 1: value") and not shown(user, ": read 0x")
        report = runtime.store.devices["lift"].live("Last service telegram")  # a later read or write by now
        assert report.shown.startswith(("read 0x", "write 0x")), report.shown  # the store keeps the English


def test_the_service_problems_and_answers_word_themselves_in_german():
    from devices.electrak import codec

    de = i18n.get("de")
    request = codec.read_request(0x0A, 2)
    answer = codec.ServiceMessage(codec.ServiceType.WRITE_CONFIRMATION, 0x0A, 2)
    problems = codec.answer_problems(request, [answer], 2)
    assert problems == ["answer 1: confirmed", "1 of 2 actuators did not answer"]
    assert [said(p, de) for p in problems] == ["Antwort 1: bestätigt", "1 von 2 Aktuatoren haben nicht geantwortet"]


def test_the_hdlock_status_frame_words_its_source_as_the_page_does():
    frame = hdlock_codec.StatusFrame(status=0x0001, motor_pos=12, proximity=3, lock_request_source=0x80)
    text = status_frame_text(frame)
    assert text == "Status 0x0001 · motorPos 12 Inc · proximity 3 Inc · LockRequestSource 0x80 IrsNever (door ignored)"
    assert said(text, i18n.get("de")).endswith("LockRequestSource 0x80 IrsNever (Tür ignoriert)")


async def test_the_hdlock_can_status_card_words_the_source_in_german(tmp_path):
    from plants import can_bus, hdlock_can, plant

    async with german_page(tmp_path, plant(can_bus(hdlock_can("gate-1", 11))), "gate-1", "HD-Lock gate-1") as (runtime, user):
        runtime.twins["gate-1"].set_lock_request_source(0x80)
        await eventually(lambda: shown(user, "LockRequestSource 0x80 IrsNever (Tür ignoriert)"), timeout=10,
                         what="the status frame's source in German")


async def test_the_hdlock_page_words_an_address_change_in_german(tmp_path):
    """Set Modbus Address: the notification says where the lock answers now, in German."""
    async with german_locks(tmp_path, "door-1") as (runtime, user):
        await user.open("/device/door-1")
        await user.should_see("HD-Lock door-1", retries=50)
        number = next(e for e in user.client.elements.values() if isinstance(e, ui.number)
                      and e.props.get("label") == "Neue Adresse" and "data-testid" not in e.props)
        number.value = 8  # P1 = P2 = 0: no condition
        user.find(kind=ui.button, content="Set Modbus Address senden").click()
        await eventually(lambda: any(isinstance(e, ui.button) and e.props.get("label") == "Senden"
                                     for e in user.client.elements.values()), timeout=5, what="the question")
        send = {e for e in user.client.elements.values() if isinstance(e, ui.button) and e.props.get("label") == "Senden"}
        UserInteraction(user, send, None).click()
        await eventually(lambda: any("das Schloss antwortet jetzt an Adresse 8 (keine Antwort auf den Befehl an Adresse 1, "
                                     "wie erwartet)" in m for m in user.notify.messages), timeout=30,
                         what=str(user.notify.messages))


async def test_the_scu_page_words_the_data_directory_and_service_values_in_german(tmp_path):
    """The data directory's comments (table 6's Kommentar) and a group's name; the service table's error counters in the
    document's words (Linearantriebfehler, Spitzenstrom erreicht, Kurzschluss-Detektionen)."""
    from plants import plant, scu_line

    async with german_page(tmp_path, plant(scu_line()), "lift", "Ewellix SCU lift") as (runtime, user):
        directory = next(e for e in user.client.elements.values() if isinstance(e, ui.table)
                         and any(c["name"] == "comment" for c in e.columns))
        rows = {row["id"]: row for row in directory.rows}
        assert rows["0x00A1"]["name"] == "Strom A1"  # the document's own name
        assert rows["0x00A1"]["comment"] == "Wert: 0 ... 1000, Einheit: Festkomma 0,1 A, Bereich: 0 ... 100 A"
        assert rows["0x0080"]["name"] == "Fehlerzähler der Antriebe und Gesamt-Überstrom"
        await eventually(lambda: not by_testid(user, "read-service").props.get("disable"), timeout=15,
                         what="the service read enabled")
        UserInteraction(user, {by_testid(user, "read-service")}, None).click()
        service = by_testid(user, "service-table")
        await eventually(lambda: any(row["id"] == "0x0080" for row in service.rows), timeout=20, what="the service rows")
        counters = next(row for row in service.rows if row["id"] == "0x0080")
        assert counters["name"] == "Fehlerzähler der Antriebe und Gesamt-Überstrom"
        assert "0x0081: Linearantriebfehler 0, Spitzenstrom erreicht 0, Kurzschluss-Detektionen 0" in counters["value"]


async def test_the_scu_page_words_why_the_remote_session_ended_in_german(tmp_path):
    """The session's reason (devices/scu/control.py) after RA, on the SCU page: in German; the store keeps the English."""
    from plants import plant, scu_line

    async with german_page(tmp_path, plant(scu_line()), "lift", "Ewellix SCU lift") as (runtime, user):
        await runtime.worker.adapters["lift"].release_scu()
        await eventually(lambda: shown(user, "an den Handschalter abgegeben (RA); Remote-Betrieb erneut öffnen, um zu fahren"),
                         timeout=10, what="the session's reason in German")
        assert not shown(user, "released to the hand switch")
        reason = runtime.store.devices["lift"].live("Session reason")
        assert reason.value == "released to the hand switch (RA); open the session again to drive it"
