"""The device policies' verdicts on the bus tools in German (issue 47): what devices/*/policy.py refuses, asks and names
(the HD-Lock's registers and CAN requests, the CAN-M3IO's DigOut, the Electrak's control telegram) in the Modbus poll's
write question and refusal, the transmit list's refusal and confirmation and the replay's screening, in the documents'
words (Holding-Register, Kapitel, nicht geschrieben, Steuertelegramm). The English stays as it was: the audit keeps it."""

from __future__ import annotations

import pytest
from nicegui import ui
from nicegui.testing.user_interaction import UserInteraction
from test_backup_page import emit
from test_i18n_pages import by_testid, english_on, german_demo, german_locks, german_user
from webutil import dialog_button, eventually

from app import i18n
from app.message import said
from devices.m3io import codec as m3io_codec
from devices.params import Accepted
from devices.sendpolicy import BusDevice, check_can

pytestmark = pytest.mark.timeout(60)

DE = i18n.get("de")
NEVER_WRITTEN_DE = ("Unit 1: SettingsRevision (Holding-Register 0): ein Dekrement stellt die Werkseinstellung wieder her, "
                    "ein Inkrement speichert (Kapitel 3.2): nie geschrieben")
DOOR_IGNORED_DE = "Mit LockRequestSource 0x80-0x87 ignoriert das Schloss die Tür (Kapitel 3.2.2"


def _field(user, kind, label: str):
    return next(e for e in user.client.elements.values() if isinstance(e, kind) and e.props.get("label") == label)


async def test_the_modbus_polls_refusal_and_question_of_a_locks_register_in_german(tmp_path):
    """The Modbus poll's write card (pages/bus_poll.py): a register the HD-Lock never has written is refused in German,
    and a write of LockRequestSource 0x80 asks the lock's risk in German under the register's name; the audit keeps
    the English."""
    async with german_locks(tmp_path, "door-1") as (runtime, user):
        await user.open("/monitor/line1/poll")
        await user.should_see("Holding-Register oder Coils schreiben", retries=50)
        address, values = _field(user, ui.number, "Adresse"), _field(user, ui.input, "Wert(e)")
        address.value, values.value = 0, "1"
        user.find(kind=ui.button, content="Schreiben").click()
        await eventually(lambda: NEVER_WRITTEN_DE in user.notify.messages, timeout=10, what="the refusal in German")
        address.value, values.value = 4, "128"
        user.find(kind=ui.button, content="Schreiben").click()
        await user.should_see(DOOR_IGNORED_DE, retries=50)
        await user.should_see("Dies schreibt door-1 LockRequestSource (HR4) (Holding-Register 4) = ", retries=5)
        dialog_button(user, "Abbrechen").click()
        assert not [m for m in user.notify.messages if "never written" in m or "holding 0" in m], user.notify.messages
        rows = await runtime.audit.aquery(limit=20)
        refused = [r for r in rows if "SettingsRevision" in (r.result or "")]
        assert refused and all("(holding 0)" in r.result and "Kapitel" not in r.result for r in refused), rows


async def test_the_transmit_lists_refusal_and_confirmation_in_german(tmp_path, monkeypatch):
    """The transmit list (pages/bus_transmit.py): an HD-Lock command the document does not have is refused in German;
    a CAN-M3IO DigOut that switches an SSR on asks its mains risk in German before it is sent."""
    async with german_demo(tmp_path, monkeypatch) as (runtime, user):
        await user.open("/monitor/can1/transmit")
        await user.should_see("Frame als Bytes", retries=50)
        _field(user, ui.input, "ID (hex)").value = "700"
        _field(user, ui.input, "Daten (Hex-Bytes)").value = "00 00 00 00 09"
        _field(user, ui.number, "DLC").value = 5
        UserInteraction(user, {by_testid(user, "transmit-add")}, None).click()
        await user.should_see("HD-Lock Command 9 steht nicht im Dokument (Kapitel 6.6.1): nicht gesendet", retries=50)
        assert not [m for m in user.notify.messages if "not in the document" in m], user.notify.messages

        heater = runtime.worker.plant.devices["heater-hmr"]
        dig_out = m3io_codec.derive_ids(int(heater.options["sw1"])).dig_out
        data = m3io_codec.encode_dig_out(m3io_codec.Variant.HMR, {"SSR4": True})
        await user.open("/monitor/can3/transmit")
        await user.should_see("Frame als Bytes", retries=50)
        _field(user, ui.input, "ID (hex)").value = f"{dig_out:X}"
        _field(user, ui.input, "Daten (Hex-Bytes)").value = data.hex(" ")
        _field(user, ui.number, "DLC").value = len(data)
        UserInteraction(user, {by_testid(user, "transmit-add")}, None).click()
        table = by_testid(user, "transmit-table")
        await eventually(lambda: table.rows, timeout=5, what="the row added")
        emit(table, "send", table.rows[0]["key"])
        await user.should_see("heater-hmr: DigOut schaltet SSR4 ein: Netzspannung an der Last bzw. den Lasten "
                              "(Kapitel 7.2.1).", retries=50)
        dialog_button(user, "Abbrechen").click()
        assert not runtime.worker.extra_holders["transmit:can3"].sent  # nothing sent: the question answered Abbrechen
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))


async def test_the_replays_screening_words_the_policies_reasons_in_german(tmp_path):
    """The replay page (pages/bus_replay.py): the frames the send policy keeps off, each with the device policy's
    reason in German (an HD-Lock firmware-update request, an Electrak control telegram with enable set)."""
    import can
    from test_replay_page import replay_runtime

    from app import recording as rec

    runtime = replay_runtime(tmp_path, "replay-verdicts-de")
    writer = rec.WRITERS[".log"][0](runtime.data_dir / "recordings" / "can9-kept.log")
    kept = {3: (0x706, bytes(8)), 5: (0x006, bytes([0, 0, 0, 0, 0, 0, 0, 1]))}
    for i in range(12):
        can_id, data = kept.get(i, (0x300 + i, bytes([i])))
        writer.on_message_received(can.Message(timestamp=100 + i * 0.01, arbitration_id=can_id, is_extended_id=False,
                                               data=data))
    writer.stop()
    async with german_user(runtime) as user:
        await user.open("/monitor/can9/replay")
        await user.should_see("Wiedergabe auf can9", retries=50)
        _field(user, ui.select, "Aufzeichnungen im Datenordner").set_value("can9-kept.log")
        await user.should_see("2 Frame(s) werden nicht gesendet", retries=50)
        await user.should_see("ist eine Firmware-Update-Anfrage (Kapitel 6.6.7, nicht für Anwender): nie gesendet")
        await user.should_see("Ein Electrak-Steuertelegramm mit gesetzter Freigabe fährt die Aktuatoren")
        found = english_on(user)
        assert found == [], "\n".join(map(str, found))


def test_every_familys_verdicts_keep_their_english_and_say_it_in_german():
    """What devices/*/policy.py words, one of each family: the English as the audit keeps it, the German a page shows."""
    from devices.electrak import policy as electrak
    from devices.hdlock import policy as hdlock
    from devices.m3io import policy as m3io
    from devices.mo64 import params as mo64_params
    from devices.mo64 import policy as mo64
    from devices.scu import policy as scu

    lift = [BusDevice("lift", "electrak", {})]
    short = check_can(lift, 0x006, False, bytes(3))
    assert short.question == ("Electrak control telegram of 3 bytes: the document defines 8 (target, current limit, speed, "
                              "control bits); what the actuators do with it is not known.")
    assert said(short.question, DE).startswith("Electrak-Steuertelegramm mit 3 Bytes: das Dokument legt 8 fest")
    assert said(short.name, DE) == "Electrak-Steuertelegramm (zu kurz)"
    override = check_can(lift, 0x006, False, bytes([0, 0, 0, 0, 0, 0, 0, 0x02]))
    assert said(override.question, DE).startswith("Override/Reset setzt die Zahl der Aktuatoren")
    assert str(hdlock.register_verdict(60000, 1).refused) == "holding 60000 is not in the register map of the HD-Lock: not written"
    assert said(hdlock.register_verdict(60000, 1).refused, DE) == ("Holding-Register 60000 steht nicht in der Registertabelle "
                                                                  "des HD-Lock: nicht geschrieben")
    assert said(hdlock.ADDRESS_RISK, DE).startswith("Set Modbus Address (Kapitel 4.3): ist die Bedingung erfüllt")
    sync = check_can([BusDevice("heater", "m3io", {"sw1": 26, "variant": "HM"})], m3io_codec.derive_ids(26).sync, False,
                     bytes([m3io_codec.AREA_WRITE_CUSTOMER, 1, 2]))
    assert sync.question == "heater: Sync area 4 writes the module's customer data (section 7.2.4)."
    assert said(sync.question, DE) == "heater: Sync Bereich 4 schreibt die Kundendaten des Moduls (Kapitel 7.2.4)."
    assert said(m3io.THREE_PHASE_RISK, DE).startswith("Der Drehstromausgang schaltet 400 V")
    assert said(scu.ESTOP_RELEASE_RISK, DE).startswith("NOT-HALT aufheben (RS 19, Tabelle 8)?")
    go = scu._go_risk({"function": 0, "motion": 2})  # noqa: SLF001 - the declared risk of go (RE)
    assert go.startswith("F1 starts motion (Move to position Out). Check that the area is clear")
    assert said(go, DE).startswith("F1 startet eine Bewegung (")
    read_only = mo64_params.PARAMS.by_name["schleife_a"]  # a value no setting telegram writes (chapter 5.2)
    refused, _ = mo64._write_verdict(Accepted(read_only, 0))  # noqa: SLF001 - the declared write's verdict
    assert refused == "schleife_a is read only: no setting telegram is named for it (chapter 5.2)"
    assert said(refused, DE) == "schleife_a ist nur lesbar: für ihn ist kein Einstelltelegramm genannt (Kapitel 5.2)"
    assert said(electrak.MOTION_REFUSED, DE).endswith("(Halten zum Fahren, ein sichtbarer Stopp)")
