"""The language of a browser and of the command line, numbers and times per language, and the plant view's device
words in German (issue 47)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from app import cli, i18n
from app.i18n import N_
from app.message import Message
from pages.plant_view import operator_words, state_words

DE, EN = i18n.get("de"), i18n.get("en")
ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("header, code", [
    ("de-DE,de;q=0.9,en;q=0.8", "de"),
    ("en-US,en;q=0.9,de;q=0.8", "en"),
    ("fr-FR, de;q=0.5, en;q=0.4", "de"),
    ("fr-FR", "en"),
    ("", "en"),
    (None, "en"),
    ("de;q=0, en", "en"),
    ("DE-at", "de"),
])
def test_the_browser_language_follows_accept_language(header, code):
    assert i18n.accept_language(header) == code


@pytest.mark.parametrize("argv, environ, code", [
    (["--lang", "de"], {}, "de"),
    (["--lang=de", "sim"], {"LANG": "en_US.UTF-8"}, "de"),
    (["--lang", "en"], {"LANG": "de_DE.UTF-8"}, "en"),
    ([], {"LANG": "de_DE.UTF-8"}, "de"),
    ([], {"LANG": "C.UTF-8"}, "en"),
    ([], {"LANGUAGE": "fr:de", "LANG": "fr_FR.UTF-8"}, "de"),
    ([], {"LC_ALL": "en_GB.UTF-8", "LANG": "de_DE.UTF-8"}, "en"),
    ([], {}, "en"),
])
def test_the_command_line_follows_lang_and_its_option(argv, environ, code):
    assert i18n.cli_language(argv, environ) == code


def test_numbers_and_times_are_written_the_languages_way():
    assert DE.number(1234.5, 1) == "1.234,5" and EN.number(1234.5, 1) == "1,234.5"
    assert DE.number(21.5) == "21,5" and DE.number(3) == "3"
    assert "{v:.1f} of {f:g} mm".format(v=DE.value(12.25), f=DE.value(300)) == "12,2 of 300 mm"
    assert "{v:.2f}|{v}|{n}|{n:d}".format(v=DE.value(0.5), n=DE.value(1500)) == "0,50|0,5|1.500|1.500"
    assert DE.value(0.5) == 0.5 and DE.value(3) + 1 == 4  # still numbers for a tile's conditions and bars
    assert DE.age(5) == "vor 5 s" and EN.age(5) == "5 s ago" and DE.age(9000) == "vor 2,5 h"
    assert DE.clock(0).count(":") == 2 and len(DE.clock(0)) == 8
    assert DE.numbers_in("T1 21.5 °C, 192.168.1.1, V1.2") == "T1 21,5 °C, 192.168.1.1, V1.2"


def test_device_words_in_german_keep_their_value_for_the_tiles_conditions():
    DE.missing.clear()  # what this test words, not what a German page of another test in this process met
    entry = {"value": "closed", "text": "closed", "name": None, "unit": "", "quality": "good", "time": 0.0}
    words = operator_words(entry, DE, "Gate state")
    assert words["value"] == "closed" and words["text"].startswith("clos")  # conditions compare the device's word
    assert "gate: {text}".format(**words) == "gate: Schranke ist geschlossen"
    assert "{text}".format(**operator_words(dict(entry, value="open", text="open"), DE, "Session")) == "aktiv"
    temp = {"value": 21.5, "text": "21.5 °C", "name": None, "unit": "°C", "quality": "good", "time": 0.0}
    assert "{text}".format(**operator_words(temp, DE, "TEMP1")) == "21,5 °C"
    hot = dict(temp, value=None, text="out of range (250.3)")
    assert "{text}".format(**operator_words(hot, DE, "TEMP1")) == "Messbereichsüberschreitung (250,3)"
    supply = {"value": 7, "text": "0x7: mains connected, battery connected, charge controller on", "name": None}
    assert "{text}".format(**operator_words(supply, DE, "Battery Mains")) == \
        "Netz angeschlossen, Akku angeschlossen, Laderegler ein"
    assert DE.phrase("SSR3 fuse blown") == "SSR3: Sicherung (Si) defekt"
    assert EN.phrase("SSR3 fuse blown") == "SSR3 fuse blown" and EN.phrase("boom off (Baum ab)") == "boom off (Baum ab)"
    assert not DE.missing


def test_a_tiles_state_in_german():
    assert state_words("offline", [], None, DE)[1:] == ("OFFLINE", "nie gehört")
    assert state_words("stale", [], 63.0, DE)[1:] == ("VERALTET", "zuletzt gehört vor 63 s")
    assert state_words("good", ["x"], 0.0, DE)[:2] == ("fault", "STÖRUNG")
    assert state_words("stale", [], 63.0)[1:] == ("STALE", "last heard 63 s ago")  # English without a language


def test_the_command_line_help_in_german(capsys):
    try:
        assert cli.main(["--lang", "de", "--help"]) == 0
    except SystemExit as exit_:
        assert exit_.code == 0
    finally:
        cli.set_language("en")
    out = capsys.readouterr().out
    assert out.startswith("Aufruf: commission")
    for words in ("Optionen:", "Beispiele:", "diese Hilfe zeigen und beenden", "Anlagendatei (Vorgabe: die eingebaute Demo-Anlage)",
                  "Sprache der Meldungen und dieser Hilfe"):
        assert words in out
    for english in ("usage:", "options:", "examples:", "show this help message", "plant file (default"):
        assert english not in out
    assert cli.build_parser().format_help().startswith("usage: commission")  # the language was set back


SUBCOMMANDS = ("sim", "backup", "restore", "user", "dbc", "report", "approve", "checkout", "sign", "verify", "apply", "check",
               "export", "view")


def _help_texts(locations: tuple[str, ...]) -> set[str]:
    """The catalog's texts of these modules (their help among them), as English shows them."""
    from babel.messages.pofile import read_po

    with open(ROOT / "locale" / "messages.pot", "rb") as f:
        template = read_po(f)
    return {m.id for m in template if isinstance(m.id, str) and len(m.id) > 12 and " " in m.id
            and any(path in locations for path, _line in m.locations)}


@pytest.mark.parametrize("command", SUBCOMMANDS)
def test_every_subcommands_help_in_german(command, capsys):
    english = _help_texts(("app/cli.py", "app/dbc.py", "app/report.py", "app/record_cli.py", "app/verify.py", "app/batch.py",
                           "app/project.py", "app/mcap_export.py"))
    try:
        with pytest.raises(SystemExit) as exit_:
            cli.main(["--lang", "de", command, "--help"])
    finally:
        cli.set_language("en")
    assert exit_.value.code == 0
    out = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    assert out.startswith("Aufruf: commission") and "Optionen:" in out
    shown = [text for text in english if " ".join(text.split()) in out]
    assert not shown, f"English in commission {command} --help: {shown}"


def test_the_command_lines_messages_in_german(capsys, tmp_path):
    try:
        assert cli.main(["--lang", "de", "--host", "0.0.0.0", "--data-dir", str(tmp_path)]) == 2
    finally:
        cli.set_language("en")
    err = capsys.readouterr().err
    assert "lausche nicht auf 0.0.0.0" in err and "commission user add NAME --role engineer" in err


def test_argparses_refusals_in_german(capsys):
    try:
        with pytest.raises(SystemExit) as exit_:
            cli.main(["--lang", "de", "restore"])
    finally:
        cli.set_language("en")
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "commission restore: Fehler: folgende Argumente fehlen: --device, file" in err and err.startswith("Aufruf:")
    with pytest.raises(SystemExit):
        cli.main(["--port", "x"])
    assert "commission: error: argument --port: invalid int value: 'x'" in capsys.readouterr().err  # English as it was


def test_whole_numbers_keep_their_digits():
    assert DE.phrase("bit 09: not in table 10", "Error code") == "Bit 09: nicht in Tabelle 10"
    assert DE.numbers_in("08:05:09 0x0A 12.50 mm") == "08:05:09 0x0A 12,50 mm"


def test_the_shared_widgets_word_ranges_and_qualities_per_language():
    from pages.widgets import number_text, quality_note, range_text

    assert range_text(0.5, 250000, "mm") == "allowed 0.5 .. 250,000 mm"  # English as it always was
    assert range_text(0.5, 250000, "mm", lang=EN) == "allowed 0.5 .. 250,000 mm"
    assert range_text(0.5, 250000, "mm", lang=DE) == "zulässig 0,5 .. 250.000 mm"
    assert range_text(-2 ** 31, 500, "mm", lang=DE) == "zulässig bis 500 mm"
    assert number_text(65535, DE) == "65535"  # register numbers keep their digits
    assert quality_note("stale", 12) == "stale 12 s ago"
    assert quality_note("stale", 12, DE) == "veraltet, vor 12 s"
    assert quality_note("offline", 180, DE) == "offline, zuletzt vor 3 min"
    assert quality_note("unknown", None, DE) == "nicht gelesen"


def test_the_record_commands_say_in_german_why_a_run_does_not_start():
    from app import record_cli

    try:
        cli.set_language("de")
        one, two = record_cli.real_without_person(["gate"]), record_cli.real_without_person(["gate", "lift"])
    finally:
        cli.set_language("en")
    assert one.startswith("commission: nicht gestartet: gate ist eine echte Anlage") and "LEERTASTE" in one
    assert two.startswith("commission: nicht gestartet: gate, lift sind echte Anlagen")
    assert record_cli.real_without_person(["gate"]).startswith("commission: not started: gate is real equipment")


def _english_pieces(modules: tuple[str, ...]) -> set[str]:
    """The words of the catalog's texts of these modules between their fields, as English prints them (the pieces
    long enough to be English of their own: "is missing from the archive", not "file")."""
    from babel.messages.pofile import read_po

    with open(ROOT / "locale" / "messages.pot", "rb") as f:
        template = read_po(f)
    pieces = set()
    for m in template:
        if isinstance(m.id, str) and any(path in modules for path, _line in m.locations):
            pieces.update(p.strip(" :;,.()'") for p in re.split(r"\{[^{}]*\}", m.id))
    return {p for p in pieces if len(p) > 14 and " " in p}


def _german(argv: list[str], capsys) -> str:
    try:
        code = cli.main(["--lang", "de", *argv])
    finally:
        cli.set_language("en")
    captured = capsys.readouterr()
    return code, captured.out + captured.err


def test_commission_check_words_its_findings_in_german(tmp_path, capsys):
    from plants import device, modbus_line, plant_text

    path = tmp_path / "plant.toml"
    path.write_text(plant_text(modbus_line(locks=()) + device("door-1", "hdlock", "line1", address=1,
                                                               project={"LockReqDelay": 3, "LockRequestDelay": "x"}), name="p"))
    code, out = _german(["check", "--plant", str(path)], capsys)
    assert code == 1
    assert "Gerät 'door-1': unbekannter Parameter 'LockReqDelay'; war " in out
    assert "1 Geräte, 2 Projekteinträge, 2 ungültig oder unbekannt" in out
    english = _english_pieces(("app/project.py", "app/plant.py"))
    assert not [p for p in english if p in out], out
    path.write_text(plant_text(modbus_line(locks=()), name="p") + "\n[[devices]]\nname = \"x\"\n")
    code, out = _german(["check", "--plant", str(path)], capsys)
    assert code == 2 and "unbekannter Abschnitt [[devices]]; war [[device]] gemeint? bekannt: " in out, out
    assert not [p for p in english if p in out], out


def test_commission_check_words_the_parameter_models_refusals_in_german(tmp_path, capsys):
    from plants import device, modbus_line, plant_text

    from devices.hdlock.params import PARAMS

    delay = PARAMS.by_name["LockRequestDelay"]
    low, high = delay.limits()
    path = tmp_path / "plant.toml"
    path.write_text(plant_text(modbus_line(locks=()) + device("door-1", "hdlock", "line1", address=1,
                                                               project={"LockRequestDelay": 70000}), name="p"))
    code, out = _german(["check", "--plant", str(path)], capsys)
    assert code == 1
    assert f"Gerät 'door-1': LockRequestDelay: 70000 liegt außerhalb von {low} .. {high} {delay.unit}" in out, out
    assert "is outside" not in out, out


def test_commission_verify_words_its_checks_in_german(tmp_path, capsys):
    import sqlite3

    from app.record_store import RecordStore

    store = RecordStore(tmp_path / "record.sqlite")
    for title in ("one", "two", "three"):
        store.add(plant="p", device="door", kind="checkout", user="anna", role="engineer", title=title, data={})
    store.close()
    code, out = _german(["verify", "--record", "--data-dir", str(tmp_path)], capsys)
    assert code == 0 and "Protokoll " in out and ": unverändert (3 Protokollzeilen verkettet; letzte Zeile #3, Hash " in out, out
    db = sqlite3.connect(tmp_path / "record.sqlite")
    db.execute("DROP TRIGGER record_no_delete")
    db.execute("DELETE FROM record WHERE id = 2")
    db.commit()
    db.close()
    code, out = _german(["verify", "--record", "--data-dir", str(tmp_path)], capsys)
    assert code == 1, out
    assert "VERÄNDERT: Zeile #2 fehlt (außerhalb des Programms gelöscht): Zeile #3 folgt auf #1" in out
    assert "verändert: der Schutz record_no_delete des Protokolls wurde außerhalb des Programms entfernt" in out
    english = _english_pieces(("app/verify.py",))
    assert not [p for p in english if p in out], out
    code, out = _german(["verify", str(tmp_path / "record.sqlite")], capsys)
    assert code == 1 and "ist kein lesbares Archiv" in out and not [p for p in english if p in out], out


def test_the_commissioning_dates_are_written_the_languages_way():
    from app.report import commissioned_text

    d = {"commissioned_by": ["anna"], "commissioned": ["2026-11-28 14:05:09", "2026-11-29 08:00:00"], "signoff": {"id": 1}}
    assert commissioned_text(d) == "Commissioned by anna from 2026-11-28 14:05:09 to 2026-11-29 08:00:00."
    assert commissioned_text(d, lang=EN) == "Commissioned by anna from 2026-11-28 14:05:09 to 2026-11-29 08:00:00."
    german = commissioned_text(d, lang=DE)
    assert "28.11.2026, 14:05:09" in german and "29.11.2026, 08:00:00" in german, german


def test_the_login_and_the_records_refusals_keep_their_english_and_say_it_in_german():
    from app.message import said
    from app.record import RecordError

    refusal = RecordError(Message(N_("{device}: a checkout is running already"), device="door-1"))
    assert str(refusal) == "door-1: a checkout is running already"
    assert said(refusal, DE) == "door-1: eine Funktionsprüfung läuft bereits"
    assert said(refusal, None) == said(refusal, EN) == "door-1: a checkout is running already"


def test_the_texts_app_hands_the_pages_keep_their_english_and_come_in_german():
    from collections import deque

    from app import batch
    from app.backup import RestoreReport
    from app.message import said
    from app.project import allowed
    from app.replace import identity_text
    from app.worker.discovery import _Candidate
    from devices.hdlock.params import PARAMS

    report = RestoreReport(written=["LockRequestDelay"], unchanged=["LockDelay", "LockMode"], saved="Save-Settings")
    assert report.summary() == "1 written, 2 unchanged, 0 failed, 0 skipped; Save-Settings done"
    assert said(report.summary(), DE) == "1 geschrieben, 2 unverändert, 0 fehlgeschlagen, 0 übersprungen; Save-Settings ausgeführt"
    identity = identity_text({"serial": 660020, "FirmwareVersion": 57})
    assert identity == "serial 660020, firmware 57" and said(identity, DE) == "Seriennummer 660020, Firmware 57"
    whole = allowed(PARAMS.by_name["LockRequestDelay"])
    assert whole == "0 .. 65535 ms (whole numbers)" and said(whole, DE) == "0 .. 65535 ms (ganze Zahlen)"
    evidence = _Candidate(entry={}, heard=0.0, first_seen=0.0, frames=3, streak=3, intervals=deque([0.1, 0.1])).evidence_text()
    assert evidence == "3 frames in a row, 0.10, 0.10 s apart" and said(evidence, DE) == "3 Frames in Folge, 0,10, 0,10 s Abstand"
    assert batch.status_text(batch.WRITTEN, DE) == "geschrieben" and batch.status_text(batch.FAILED, EN) == "failed"



def test_commission_check_prints_a_device_types_own_check_in_german(tmp_path, capsys):
    """A device type's plant-file check (devices/hdlock check_config): German after --lang de, English without."""
    from plants import can_bus, device, plant_text

    plant = tmp_path / "plant.toml"
    plant.write_text(plant_text(can_bus(device("gate-1", "hdlock", "can1"), name="can1"), name=None))
    code, err = _german(["check", "--plant", str(plant)], capsys)
    assert code == 2
    assert "Gerät 'gate-1': 'device_id' (die CAN-Geräte-ID des Schlosses; Werkseinstellung: seine Seriennummer) ist " \
           "anzugeben" in err, err
    assert cli.main(["check", "--plant", str(plant)]) == 2
    assert "'device_id' (the lock's CAN device ID; factory default: its serial number) is required" in capsys.readouterr().err


def test_commission_backup_says_why_a_device_has_nothing_to_back_up_in_german(tmp_path, capsys):
    """An M3IO in simple mode: its own reason (devices/m3io/settings.py), in German."""
    from plants import can_bus, device, plant_text

    plant = tmp_path / "plant.toml"
    plant.write_text(plant_text(can_bus(device("heater", "m3io", "can3", variant="HM", sw1=0x1A), name="can3",
                                        bitrate=500000), name=None))
    code, out = _german(["backup", "--plant", str(plant), "--out", str(tmp_path / "out"), "--data-dir", str(tmp_path / "d")],
                        capsys)
    assert code == 0
    assert "nichts zu sichern: Kundendaten brauchen den adressierten Modus (SW1 Schalter 8 ein; SW1 ist 0x1A)" in out, out


def test_every_device_types_plant_file_checks_word_themselves_in_german():
    """What each device type's check_config says of an empty device and an unknown key: a Message with its German."""
    from app.message import said
    from devices.registry import DEVICE_TYPES

    for name, device_type in DEVICE_TYPES.items():
        for bus_type in device_type.bus_types:
            found = device_type.check_config({"bogus": 1}, bus_type)
            for key, message in found:
                assert isinstance(message, Message), (name, bus_type, key, message)
                assert said(message, DE) != message, (name, bus_type, key, message)
