"""The last screen of a failed suite says why (tools/suite.py): each failed test with its error's lines, what its
pages did and what its apps logged meanwhile (tests/page_events.py)."""

from __future__ import annotations

import liveapp
import page_events

from tools.suite import PHASES, failures, phase_files

REPORT = """<?xml version="1.0" encoding="utf-8"?>
<testsuites><testsuite name="pytest" errors="0" failures="1" tests="2">
<testcase classname="tests.browser.test_m3io" name="test_fuse" time="23.0"><failure message="TimeoutError">
self = ...
E           playwright._impl._errors.TimeoutError: Locator.wait_for: Timeout 15000ms exceeded.

------------------------- what the test's pages did -------------------------
   50.63 s navigated to http://127.0.0.1:1/device/heater-hm
---------------------------- what its apps logged ----------------------------
m3io0: 2026-11-29 03:40:01,000 WARNING app.worker.deadman: session s: dead-man: the controlling browser has not confirmed
</failure></testcase>
<testcase classname="tests.app.test_ok" name="test_ok" time="0.1"/>
</testsuite></testsuites>"""


def test_the_recap_names_the_failed_test_its_error_its_pages_and_its_apps(tmp_path):
    report = tmp_path / "phase.xml"
    report.write_text(REPORT)
    recap = failures(report)
    assert recap[0] == "suite: failure: tests/browser/test_m3io.py::test_fuse"
    assert any("Timeout 15000ms exceeded" in line for line in recap)
    pages = recap.index("    what the test's pages did:")
    assert "navigated to http://127.0.0.1:1/device/heater-hm" in recap[pages + 1]
    logged = recap.index("    what its apps logged:")
    assert "dead-man: the controlling browser has not confirmed" in recap[logged + 1]
    assert not any("test_ok" in line for line in recap)


def test_a_report_quotes_what_its_apps_logged_while_it_ran(tmp_path, monkeypatch):
    log = tmp_path / "app" / "app.log"
    log.parent.mkdir()
    log.write_text("2026-11-29 03:39:00,000 WARNING app.worker.loophealth: before the test\n")
    monkeypatch.setattr(liveapp, "LOGS", [log])
    page_events.app_logs_began()
    with log.open("a") as out:
        out.write("2026-11-29 03:40:00,000 INFO app.web: a page opened\n"
                  "2026-11-29 03:40:01,000 INFO app.worker.deadman: session s: a beat came 1170 ms after the one before\n"
                  "2026-11-29 03:40:02,000 WARNING app.worker.loophealth: event loop stalled for 244 ms\n")
    assert page_events.app_log_lines() == [
        "app: 2026-11-29 03:40:01,000 INFO app.worker.deadman: session s: a beat came 1170 ms after the one before",
        "app: 2026-11-29 03:40:02,000 WARNING app.worker.loophealth: event loop stalled for 244 ms"]


def test_each_phase_takes_the_files_of_its_marks_as_pytest_reads_its_expression():
    """Every test falls into exactly one phase: the phases' ``-m`` expressions read by pytest's own parser."""
    tests = [["plain.py", []], ["page.py", ["browser"]], ["bound.py", ["realtime"]], ["both.py", ["browser", "realtime"]],
             ["alone.py", ["alone", "browser"]], ["slow.py", ["slow"]]]
    taken = {name: phase_files(tests, options) for name, options in PHASES}
    assert list(taken.values()) == [["plain.py", "slow.py"], ["bound.py"], ["both.py", "page.py"], ["alone.py"]]
    assert sorted(f for files in taken.values() for f in files) == sorted(file for file, _marks in tests)
