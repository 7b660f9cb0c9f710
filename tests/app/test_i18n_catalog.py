"""The catalogs (issue 47): every text of the translated modules is in the German and the English catalog, the
compiled catalogs are those of the .po files, placeholders survive translation, and every text of the device
tiles and every word of their points is translated in German."""

from __future__ import annotations

import configparser
import re
from io import BytesIO
from pathlib import Path

import pytest
from babel.messages.extract import extract_from_file
from babel.messages.mofile import read_mo, write_mo
from babel.messages.pofile import read_po

from app import i18n
from devices.registry import DEVICE_TYPES

ROOT = Path(__file__).resolve().parents[2]
LOCALE = ROOT / "locale"
KEYWORDS = {"_": None, "gettext": None, "ngettext": (1, 2), "pgettext": ((1, "c"), 2), "N_": None, "NP_": ((1, "c"), 2)}
FIELD = re.compile(r"\{[^{}]*\}")


def translated_modules() -> list[str]:
    """The modules babel.cfg names: the ones whose texts are in the catalogs."""
    config = configparser.ConfigParser()
    config.read(LOCALE / "babel.cfg")
    return [section.split(":", 1)[1].strip() for section in config.sections() if section.startswith("python:")]


def extracted() -> set[tuple[str | None, str]]:
    """``(context, message)`` of every text the translated modules mark, as ``pybabel extract`` finds them."""
    found = set()
    for module in translated_modules():
        for _line, message, _comments, context in extract_from_file("python", str(ROOT / module), keywords=KEYWORDS):
            found.add((context, message if isinstance(message, str) else message[0]))
    return found


def catalog(code: str):
    with open(LOCALE / code / "LC_MESSAGES" / "messages.po", "rb") as f:
        return read_po(f, locale=code)


@pytest.mark.parametrize("code", sorted(i18n.LANGUAGES))
def test_every_text_of_the_translated_modules_is_translated(code):
    texts = extracted()
    assert len(texts) > 200, "the translated modules mark their texts"
    po = catalog(code)
    missing = [text for text in sorted(texts, key=str) if po.get(text[1], text[0]) is None]
    assert not missing, f"{code}: not in locale/{code}: {missing} (pybabel extract and update, docs/i18n.md)"
    untranslated = [m.id for m in po if m.id and (not m.string or m.fuzzy)]
    assert not untranslated, f"{code}: untranslated or fuzzy: {untranslated}"


def test_the_template_is_current():
    with open(LOCALE / "messages.pot", "rb") as f:
        template = {(m.context, m.id[0] if isinstance(m.id, tuple) else m.id) for m in read_po(f) if m.id}
    assert template == extracted(), "locale/messages.pot is stale: run pybabel extract (docs/i18n.md)"


@pytest.mark.parametrize("code", sorted(i18n.LANGUAGES))
def test_the_compiled_catalog_is_the_po_file(code):
    """The .mo files are committed: each holds exactly what its .po file says (pybabel compile after each change)."""
    po = catalog(code)
    with open(LOCALE / code / "LC_MESSAGES" / "messages.mo", "rb") as f:
        mo = read_mo(f)
    def entries(messages) -> set:  # a plural's forms as a tuple in both (read_mo gives lists)
        return {(m.context, tuple(m.id) if isinstance(m.id, list | tuple) else m.id,
                 tuple(m.string) if isinstance(m.string, list | tuple) else m.string) for m in messages if m.id}

    assert entries(mo) == entries(po), \
        f"locale/{code}/LC_MESSAGES/messages.mo is stale: run pybabel compile -d locale (docs/i18n.md)"
    buffer = BytesIO()
    write_mo(buffer, po)  # and it compiles
    assert buffer.getvalue()


@pytest.mark.parametrize("code", sorted(i18n.LANGUAGES))
def test_placeholders_survive_translation(code):
    po = catalog(code)
    errors = [(m.id, list(e)) for m in po if m.id for e in [m.check(po)] if e]
    assert not errors, errors
    for message in po:
        if message.id and message.string:
            ids = message.id if isinstance(message.id, tuple) else (message.id,)
            strings = message.string if isinstance(message.string, tuple) else (message.string,)
            for string in strings:  # a plural's every form keeps the fields of its English forms
                assert sorted(FIELD.findall(string)) in [sorted(FIELD.findall(i)) for i in ids], message.id


def test_every_tile_text_of_every_device_type_is_in_german():
    from pages.plant_view import tile_texts

    german = i18n.Lang("de")
    gaps = []
    for name, device_type in DEVICE_TYPES.items():
        for text in [*tile_texts(device_type.tile), device_type.title]:
            german.phrase(text)  # the catalog's entry, or the one with its numbers as {0} (SSR3 -> SSR{0})
            if text in german.missing:
                gaps.append((name, text))
    assert not gaps, f"tile texts not in the catalog (mark them in app/device_words.py): {gaps}"


def test_the_words_of_the_points_on_the_tiles_are_the_documents():
    """The enum words a tile shows: HD-Lock DoorState and StateMachineState (000, 3.1), the MO 64's gate state
    (003, 5.1.12), the Electrak's error flags (004, Fehler-Flags)."""
    from devices.electrak.codec import ERROR_FLAGS
    from devices.hdlock.params import DOOR_STATE, STATE_MACHINE_STATE
    from devices.mo64.codec import GATE_STATE_NAMES

    german = i18n.Lang("de")
    words = [("DoorState", w) for w in DOOR_STATE.values()] + [("StateMachineState", w) for w in STATE_MACHINE_STATE.values()]
    words += [("Gate state", w) for w in GATE_STATE_NAMES.values()] + [(None, name) for name, *_ in ERROR_FLAGS.values()]
    missing = [(point, word) for point, word in words if not german.has(word, point)]
    assert not missing, missing
    assert german.phrase("Door closed", "DoorState") == "Tür geschlossen"
    assert german.phrase("closed", "Gate state") == "Schranke ist geschlossen"
    assert german.phrase("Backdrive") == "Rücklauf erkannt"


def test_the_catalogs_count_their_texts():
    """The closing figure of the issue: how many texts each catalog holds (printed with -s)."""
    counts = {code: sum(1 for m in catalog(code) if m.id) for code in i18n.LANGUAGES}
    print("catalog texts:", counts)
    assert counts["de"] == counts["en"] > 200


def test_every_scu_error_bit_is_in_the_documents_german():
    """Table 10 (002, section 4.5) as the SCU's tile shows an Error_Code: each bit, and several at once."""
    from devices.scu import codec

    german = i18n.Lang("de")
    for bit in codec.ERROR_BITS.values():
        german.phrase(codec.error_text(bit.mask), "Error code")
    german.phrase(codec.error_text(1 << 8), "Error code")  # bit 9: not in table 10
    assert not german.missing, german.missing
    both = codec.ERROR_BITS[14].mask | codec.ERROR_BITS[22].mask
    assert german.phrase(codec.error_text(both), "Error code") == \
        "Bit 14: Summenstrom wurde überschritten; Bit 22: Remote Kommunikation Timeout"
    assert german.phrase(codec.error_text(codec.ERROR_BITS[17].mask), "Error code") == "Bit 17: Fehler des Antriebs 3"
