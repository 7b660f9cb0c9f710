"""CSV exports in the language of the page (issue 47): German spreadsheets read a semicolon between cells and a
decimal comma; English ones a comma and a point. Headings in the language; records and times as written."""

from __future__ import annotations

import csv
import io

from app import i18n
from app.audit import AuditEntry, to_csv
from app.csvfile import csv_text

DE, EN = i18n.get("de"), i18n.get("en")


def test_numbers_and_separators_per_language():
    head, rows = ["time", "Position"], [["2026-11-28T14:05:09.120", 12.5], ["2026-11-28T14:05:09.220", None], ["x", 3]]
    english = csv_text(head, rows, EN)
    german = csv_text(head, rows, DE)
    assert list(csv.reader(io.StringIO(english))) == [["time", "Position"], ["2026-11-28T14:05:09.120", "12.5"],
                                                      ["2026-11-28T14:05:09.220", ""], ["x", "3"]]
    assert list(csv.reader(io.StringIO(german), delimiter=";")) == [["Zeit", "Position"], ["2026-11-28T14:05:09.120", "12,5"],
                                                                    ["2026-11-28T14:05:09.220", ""], ["x", "3"]]
    assert csv_text(head, [[0.125]], DE).splitlines()[1] == "0,125"  # every decimal kept


def test_the_audit_csv_in_german_keeps_its_records_as_written():
    entry = AuditEntry(id=1, time=0.0, user="=HYPERLINK(1)", role="engineer", device="door-1", action="write",
                       parameter="LockRequestDelay", old="200", new="350", result="ok")
    german = list(csv.reader(io.StringIO(to_csv([entry], DE)), delimiter=";"))
    assert german[0] == ["Zeit", "Benutzer", "Rolle", "Gerät", "Aktion", "Parameter", "alt", "neu", "Ergebnis"]
    assert german[1][1:] == ["'=HYPERLINK(1)", "engineer", "door-1", "write", "LockRequestDelay", "200", "350", "ok"]
    assert to_csv([entry]).splitlines()[0] == "time,user,role,device,action,parameter,old,new,result"  # English as before
