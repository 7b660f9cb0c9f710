"""The as-left report's sentence on where the values come from (app/report.py ``values_text``, also in the PDF): its
time as the report writes times in the language (``29.11.2026, 07:30:43`` in German, ISO in English) and its counts as
phrases that name what they count (``95 Parameter nicht abgenommen``, ``95 parameters not approved``); the content
(frozen in a sign-off) keeps its English with the ISO time."""

from __future__ import annotations

from app import i18n
from app.report import measured_text, param_rows, sign_gaps, source_text, values_text

DE, EN = i18n.get("de"), i18n.get("en")
SOURCE = "as the device showed them at 2026-11-29 07:30:43 (else the last snapshot of 2026-11-28 14:05:09)"


def device(**counts) -> dict:
    return {
        "device": "m1",
        "parameters_source": SOURCE,
        "approved": None,
        "checkouts": [],
        "checkout_summary": [],
        "counts": {"equal": 0, "changed": 0, "not approved": 0, "updated by the device": 0, "live value": 0, **counts},
    }


def test_where_the_values_come_from_has_its_times_in_the_languages_form():
    assert source_text(SOURCE, DE) == (
        "wie das Gerät sie zeigte am 29.11.2026, 07:30:43 (sonst die letzte Momentaufnahme vom 28.11.2026, 14:05:09)"
    )
    assert source_text(SOURCE, EN) == SOURCE and source_text(SOURCE, None) == SOURCE


def test_the_counts_name_what_they_count_in_either_language():
    d = device(**{"not approved": 95})
    assert values_text(d, DE) == (
        "Werte wie das Gerät sie zeigte am 29.11.2026, 07:30:43 (sonst die letzte Momentaufnahme "
        "vom 28.11.2026, 14:05:09): 95 Parameter nicht abgenommen."
    )
    assert values_text(d, EN) == f"Values {SOURCE}: 95 parameters not approved."
    d = device(equal=1, changed=2, **{"updated by the device": 1, "live value": 3})
    assert values_text(d, EN).endswith(
        ": 1 parameter equal to the approved set, 2 parameters changed since approved, "
        "1 parameter updated by the device, 3 live values."
    )
    assert values_text(d, DE).endswith(
        ": 1 Parameter gleich dem abgenommenen Satz, 2 Parameter seit der Abnahme geändert, "
        "1 Parameter vom Gerät aktualisiert, 3 Live-Werte."
    )
    assert values_text(device(**{"live value": 1}), DE).endswith(": 1 Live-Wert.")


def test_a_sign_offs_gaps_count_parameters_too():
    d = {**device(**{"not approved": 95, "changed": 1}), "approved": {"id": 2}}
    assert sign_gaps(d) == ["m1: no checkout run, 95 parameters not approved, 1 parameter changed since approved"]
    assert sign_gaps(d, DE) == [
        "m1: keine Funktionsprüfung gelaufen, 95 Parameter nicht abgenommen, 1 Parameter seit der Abnahme geändert"
    ]


def test_a_units_words_are_the_reports_language_and_its_english_as_written():
    """The SCU's speeds and positions in the as-left report: its counts are the document's Flanken in German (data
    0x3011: Encoder Flanken/s), with the decimal comma; the English report as the snapshot wrote them."""
    de, en = i18n.get("de"), i18n.get("en")
    row = {"name": "Remote Speed F1", "value": "60 % or counts/s", "unit": "% or counts/s", "approved": "100 % or counts/s",
           "verdict": "differs"}
    assert param_rows([row], de)[0][1:3] == ["60 % oder Flanken/s", "100 % oder Flanken/s"]
    assert param_rows([row], en)[0][1:3] == ["60 % or counts/s", "100 % or counts/s"]
    assert param_rows([dict(row, approved="-")], de)[0][2] == "-"  # nothing approved: as it was
    travel = {"name": "A1 travel", "value": 12.5, "unit": "counts", "limit": "", "ok": True}
    assert measured_text(travel, de).startswith("A1 travel = 12,5 Flanken (")
    assert measured_text(travel, en).startswith("A1 travel = 12.5 counts (")
