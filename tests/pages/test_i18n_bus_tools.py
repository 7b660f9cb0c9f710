"""What app/ words itself on the bus tools, in German (issue 47): a recording's and a recorded file's errors, the
transmit list's and the Modbus poll's refusals and the send policy's questions, a replay's question, screening and
summary, the overview's bus line and the server's pages for an unknown bus. The English stays as it was (the audit
rows keep it)."""

from __future__ import annotations

import pytest
from nicegui import ui
from nicegui.elements.upload_files import SmallFileUpload
from test_i18n_pages import by_testid, english_on, german_demo, german_locks, german_user, shown_texts
from webutil import eventually

pytestmark = pytest.mark.timeout(60)


async def test_a_recorded_files_errors_in_german(tmp_path, monkeypatch):
    """The CAN monitor's file tab (pages/can_files.py): a file of no known format and a broken BLF file, said in German
    with where reading stopped."""
    async with german_demo(tmp_path, monkeypatch) as (runtime, user):
        await user.open("/monitor/can1")
        await user.should_see("Busmonitor can1", retries=50)
        upload = next(iter(user.find(marker="upload").elements))
        await upload.handle_uploads([SmallFileUpload("notes.txt", "text/plain", b"hello")])
        await user.should_see("notes.txt: Dateityp .txt wird nicht unterstützt", retries=50)
        await upload.handle_uploads([SmallFileUpload("broken.blf", "application/octet-stream", b"not a blf file" * 10)])
        await user.should_see("broken.blf: kann nicht als .blf-Datei geöffnet werden (Byte-Offset", retries=50)
        assert not [m for m in user.notify.messages if "cannot open" in m or "unsupported" in m], user.notify.messages
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))


async def test_a_replays_refused_upload_in_german(tmp_path):
    """The replay page (pages/bus_replay.py): an upload named '..' is refused in German."""
    from test_replay_page import replay_runtime

    runtime = replay_runtime(tmp_path, "replay-upload-de")
    async with german_user(runtime) as user:
        await user.open("/monitor/can9/replay")
        await user.should_see("Wiedergabe auf can9", retries=50)
        upload = user.find(kind=ui.upload).elements.pop()
        await upload.handle_uploads([SmallFileUpload("..", "text/plain", b"(1700000000.000000) can0 301#01\n")])
        await user.should_see("'..' ist kein Dateiname für eine Aufzeichnung (z. B. trace.log)", retries=50)
        assert english_on(user) == []


async def test_the_modbus_polls_question_and_refusal_in_german(tmp_path):
    """The Modbus poll's write card (pages/bus_poll.py): a write to a unit that is not in the plant asks in German,
    with the send policy's note of the type it was checked as (devices/sendpolicy.py); the device policy's own name of
    the register stays as it declares it."""
    from app import i18n

    async with german_locks(tmp_path, "door-1") as (runtime, user):
        await user.open("/monitor/line1/poll")
        await user.should_see("Holding-Register oder Coils schreiben", retries=50)
        unit_label = i18n.get("de").pgettext("Modbus", "Unit")
        unit = next(e for e in user.client.elements.values() if isinstance(e, ui.number) and e.props.get("label") == unit_label)
        unit.value = 9
        user.find(kind=ui.button, content="Schreiben").click()
        await user.should_see("Unit 9 steht nicht in der Anlagendatei: geprüft als hdlock", retries=50)
        question = next(t for t in shown_texts(user) if "steht nicht in der Anlagendatei" in t)
        assert question.startswith("Dies schreibt Unit 9 ") and question.endswith(" Schreiben?"), question
        assert "This writes" not in question and "Write?" not in question, question


async def test_the_transmit_lists_refusal_in_german(tmp_path, monkeypatch):
    """The transmit list (pages/bus_transmit.py): a frame of nine data bytes is refused in German (app/transmit.py)."""
    from nicegui.testing.user_interaction import UserInteraction

    async with german_demo(tmp_path, monkeypatch) as (runtime, user):
        await user.open("/monitor/can1/transmit")
        await user.should_see("Frame als Bytes", retries=50)
        data = next(e for e in user.client.elements.values() if isinstance(e, ui.input) and e.props.get("label") == "Daten (Hex-Bytes)")
        data.value = "01 02 03 04 05 06 07 08 09"
        UserInteraction(user, {by_testid(user, "transmit-add")}, None).click()
        await user.should_see("9 Datenbytes: ein klassischer CAN-Frame trägt 0..8", retries=50)
        assert not [m for m in user.notify.messages if "classic CAN frame" in m], user.notify.messages


async def test_a_replays_screening_question_and_summary_in_german(tmp_path):
    """The replay page (pages/bus_replay.py) words what app/replay.py says in German: the frames the send policy keeps
    off (the device policy's own reason stays as it declares it), the question, and a stopped replay's summary."""
    import can
    from test_replay_page import replay_runtime

    from app import recording as rec

    runtime = replay_runtime(tmp_path, "replay-screen-de")
    writer = rec.WRITERS[".log"][0](runtime.data_dir / "recordings" / "can9-slow.log")
    for i in range(20):  # 0x706: an HD-Lock firmware-update request, never sent
        writer.on_message_received(can.Message(timestamp=100 + i * 0.5, arbitration_id=0x706 if i == 3 else 0x300 + i,
                                               is_extended_id=False, data=bytes([i])))
    writer.stop()
    async with german_user(runtime) as user:
        await user.open("/monitor/can9/replay")
        await user.should_see("Wiedergabe auf can9", retries=50)
        choice = next(e for e in user.client.elements.values() if e.props.get("label") == "Aufzeichnungen im Datenordner")
        choice.set_value("can9-slow.log")
        await user.should_see("1 Frame(s) werden nicht gesendet: 1 x HD-Lock", retries=50)
        user.find("Wiedergabe starten").click()
        await user.should_see("19 aufgezeichnete(n) Frame(s) von can9-slow.log auf can9 wiedergeben", retries=50)
        await user.should_see(". 1 Frame(s) werden nicht gesendet: 1 x HD-Lock")
        user.find("19 Frames senden").click()
        status = by_testid(user, "replay-status")
        await eventually(lambda: "läuft: " in status.text, timeout=10, what="the replay running")
        user.find(kind=ui.button, content="Stopp").click()
        await eventually(lambda: "gestoppt: " in status.text and "(gestoppt von " in status.text, timeout=10,
                         what="the stopped replay's summary")
        assert "von 20 Frames gesendet" in status.text, status.text
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))


async def test_the_overviews_bus_line_words_the_can_controllers_state_in_german(tmp_path, monkeypatch):
    """The overview's line of a CAN bus (pages/overview.py) says the controller's state as the CAN monitor's badge
    does: fehleraktiv, not the store's error-active."""
    async with german_demo(tmp_path, monkeypatch) as (runtime, user):
        await user.open("/")
        await eventually(lambda: any(t.startswith("verbunden · fehleraktiv · ") for t in shown_texts(user)), timeout=15,
                         what="a CAN bus's line in German")
        assert not [t for t in shown_texts(user) if "error-active" in t]


async def test_the_pages_of_an_unknown_bus_device_and_tool_in_german(tmp_path):
    """The server's pages for what the plant does not have (server/__init__.py), in German."""
    async with german_locks(tmp_path) as (runtime, user):
        await user.open("/monitor/nowhere")
        await user.should_see("Unbekannter Bus", retries=50)
        await user.should_see("Die Anlage hat keinen Bus namens 'nowhere'.")
        assert english_on(user) == []
        await user.open("/monitor/line1/juggle")
        await user.should_see("Unbekannte Seite", retries=50)
        await user.should_see("Es gibt kein Werkzeug 'juggle' für einen Bus namens 'line1'.")
        await user.should_see("Zurück zur Übersicht")
        assert english_on(user) == []
        await user.open("/device/nobody")
        await user.should_see("Unbekanntes Gerät", retries=50)
        await user.should_see("Die Anlage hat kein Gerät namens 'nobody'.")
        assert english_on(user) == []


async def test_the_line_monitors_own_words_of_a_transaction_in_german(tmp_path):
    """The monitor of a Modbus line (pages/monitor.py): the words app/recording adds to a transaction (the device at a
    unit) in German; the parameter model's names and values as they are."""
    from test_i18n_pages import marked_table

    async with german_locks(tmp_path, "door-1") as (runtime, user):
        await user.open("/monitor/line1")
        await user.should_see("Busmonitor line1", retries=50)
        table = marked_table(user, "transactions")
        await eventually(lambda: any(r["device"] == "door-1 (Unit 1)" for r in table.rows), timeout=15,
                         what="a transaction of door-1 in German")
        assert not [r["device"] for r in table.rows if "(unit " in r["device"]], [r["device"] for r in table.rows]
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))


def test_the_decoders_own_words_in_german():
    """What app/recording words around the device's names and values: a register's words, a write, a remote request,
    a failed decode; the English as before."""
    from app import i18n
    from app import recording as rec
    from app.can_bus import FrameRecord
    from app.message import said
    from devices.hdlock.params import PARAMS

    de = i18n.get("de")
    text = rec.describe_registers(PARAMS, "holding", 60000, list(range(20)))  # no register of the HD-Lock there
    assert str(text).endswith("... 4 more") and said(text, de).endswith("... 4 weitere"), said(text, de)
    remote = FrameRecord(1.0, 0x123, False, 0, b"", "rx", False, True)
    decoded = rec.FrameDecoder(codecs=[]).record(remote)
    assert decoded == "remote request" and said(decoded, de) == "Remote-Anforderung"
