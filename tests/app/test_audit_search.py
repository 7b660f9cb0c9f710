"""The audit log's text search finds what a row names in its old and new values (issue 32 item 9):
a Save-Settings row lists the changes it made permanent in its new value."""

from __future__ import annotations

from pathlib import Path

from app.audit import AuditLog


def test_text_search_finds_the_changes_a_save_made_permanent(tmp_path: Path):
    log = AuditLog(tmp_path / "audit.sqlite")
    try:
        log.record(user="anna", role="engineer", device="door-1", action="Save-Settings", parameter="Save-Settings",
                   new="MaximumTimeUnlock (holding 1003) = 1234 ms; LockRequestDelay (holding 3000) = 250 ms", result="ok")
        log.record(user="anna", role="engineer", device="door-1", action="write", parameter="LockRequestDelay",
                   old="200 ms", new="250 ms", result="ok")
        found = log.query(text="MaximumTimeUnlock")
        assert [e.action for e in found] == ["Save-Settings"], found
        assert {e.action for e in log.query(text="250 ms")} == {"Save-Settings", "write"}
        assert [e.action for e in log.query(text="200 ms")] == ["write"]  # the old value too
    finally:
        log.close()
