"""The whole suite, as CI runs it: the linter, then the tests in four phases.

    python3 -m tools.suite [pytest options ...]

1. The tests without a browser and held to no real-time bound, ten processes that steal work from each other:
   they wait on devices, sockets and timers far more than they compute (measured on 2026-11-29: 307 s of CPU in
   202 s on two cores, the cores 75 % busy; 175 s in ten processes against 198 s in eight).
2. The tests that hold a device, a bus or a page to a real-time bound (marker ``realtime``: a keep-alive period,
   the dead-man bound, a poll cycle against the wire time), eight processes, with nothing else beside them. They
   compute little (13 s of CPU in 45 s), but run beside the browser tests five of them missed their bounds
   (2026-11-29: a keep-alive gap of 0.46 s, an SCU's RC 0.76 s apart).
3. The tests that drive chromium (marker ``browser``), two at a time, each test file whole in one process: each
   starts the app and a browser and waits on what its page shows. Three at a time took 152 s against 172 s, with
   the cores 92 % busy, but two runs in a row then failed a browser test on a starved page (2026-11-29: a drive's
   beats 409 ms apart stopped it under the dead-man rule; a number typed into the Modbus poll was put back by
   its page), so the phase keeps the slack two processes leave.
4. One at a time, the tests marked ``alone``: the browser tests that are themselves held to a real-time bound (a
   second chromium beside one delays its beats on their way) and the few whose subject is how the program uses
   the cores (a line's thread that must keep up with its own period, a stalled loop's stop).

Each phase's processes collect only the files that hold a test of that phase: the collection before the first
phase (below) notes each test's markers (``tools/phase_files.py``).

Every phase runs; the exit status is 0 only when the linter and every phase passed. Options given here (``-x``,
``-k ...``, a path) go to every phase. At the end, after the phases' times, every failed test is named again with
the lines of its error (``E ...``) and what its browser pages did: the last screen of a long run says what failed
and why, not only that a phase failed. The phases' JUnit reports (each test's time) are kept in the folder that
``COMMISSION_SUITE_REPORTS`` names, when it is set.

Python's compiled modules are kept (``__pycache__``, ignored by git) even where ``PYTHONDONTWRITEBYTECODE`` is set:
every test process would otherwise compile the package and rewrite the asserts of every test module it collects
again (measured: 14 s of CPU to collect the suite in one process, 4.4 s with the compiled files there), and every
app, simulator and command-line process a test starts would compile the package again. Before the first phase two
processes collect the suite's halves once, so the processes of every phase find them compiled.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

PHASES = (
    ("tests without a browser or a real-time bound", ["-n", "10", "--dist", "worksteal", "-m", "not browser and not realtime and not alone"]),
    ("tests held to a real-time bound", ["-n", "8", "--dist", "worksteal", "-m", "realtime and not browser and not alone"]),
    ("browser tests", ["-n", "2", "-m", "browser and not alone"]),
    ("tests that need the cores to themselves", ["-n", "0", "-m", "alone"]),
)


#: the halves of the suite that two processes collect side by side before the first phase (about equal in size)
HALVES = (["tests/app", "tests/safety"], ["tests/devices", "tests/pages", "tests/browser"])


def compiled_environment(scratch: Path) -> tuple[dict[str, str], list[list]]:
    """This environment with compiled modules kept, and the suite collected once so that they are there; with each
    collected test's file and markers (none when a half did not collect: then every phase collects the whole suite)."""
    env = {key: value for key, value in os.environ.items() if key != "PYTHONDONTWRITEBYTECODE"}
    collecting = []
    for n, half in enumerate(HALVES):
        marks = scratch / f"marks-{n}.json"
        collecting.append((marks, subprocess.Popen(
            [sys.executable, "-m", "pytest", "-q", "--collect-only", "-p", "no:xdist", "-p", "tools.phase_files",
             "-o", "addopts=-p nicegui.testing.user_plugin -p no:benchmark", *half], env={**env, "COMMISSION_SUITE_MARKS": str(marks)},
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)))
    tests: list[list] = []
    for marks, process in collecting:
        # a module that does not import fails in its phase, with its error shown there
        if process.wait() != 0 or not marks.exists():
            return env, []
        tests += json.loads(marks.read_text(encoding="utf-8"))
    return env, tests


def phase_files(tests: list[list], options: list[str]) -> list[str]:
    """The files that hold a test the phase's ``-m`` expression selects (a phase's processes collect only those), the
    expression read as pytest reads ``-m`` (its own parser, no ``eval``)."""
    from _pytest.mark.expression import Expression

    expression = Expression.compile(options[options.index("-m") + 1])
    return sorted({file for file, marks in tests if expression.evaluate(lambda name, *_, marks=frozenset(marks), **__: name in marks)})


RECAP_LINES = 12  # of each failed test's error lines


def _sections(text: str) -> dict[str, list[str]]:
    """The sections a test's report adds after its error (``---- title ----`` and their lines that are not empty)."""
    sections: dict[str, list[str]] = {}
    current = None
    for line in text.splitlines():
        heading = re.fullmatch(r"-{3,} (.+?) -{3,}", line.strip())
        if heading:
            current = sections.setdefault(heading.group(1), [])
        elif current is not None and line.strip():
            current.append(line.strip())
    return sections


def failures(report: Path) -> list[str]:
    """The failed and erring tests of a phase's JUnit report: the test, then its error's ``E`` lines, its pages'
    events and what its apps logged (at most :data:`RECAP_LINES` each, the last ones), indented."""
    try:
        root = ET.parse(report).getroot()
    except (OSError, ET.ParseError):
        return []
    lines = []
    for case in root.iter("testcase"):
        for bad in [*case.findall("failure"), *case.findall("error")]:
            test = f"{case.get('classname', '').replace('.', '/')}.py::{case.get('name')}"
            text = bad.text or ""
            said = [line for line in text.splitlines() if line.lstrip().startswith("E ")][:RECAP_LINES]
            if not said:  # no assertion lines: the report's message, else the end of its text
                said = (bad.get("message") or "").splitlines()[:1] or [
                    line for line in text.splitlines() if line.strip()][-5:]
            sections = _sections(text)
            lines.append(f"suite: {bad.tag}: {test}")
            lines += [f"    {line}" for line in said]
            for title in ("what the test's pages did", "what its apps logged"):
                if sections.get(title):
                    lines.append(f"    {title}:")
                    lines += [f"      {line}" for line in sections[title][-RECAP_LINES:]]
    return lines


def main(argv: list[str] | None = None) -> int:
    extra = list(sys.argv[1:] if argv is None else argv)
    started = time.monotonic()
    lint = subprocess.run(["ruff", "check", "."], check=False)
    if lint.returncode != 0:
        print("suite: ruff found the problems above; fix them first", flush=True)
        return lint.returncode
    results: list[tuple[str, int, float]] = []
    recap: list[str] = []
    with tempfile.TemporaryDirectory(prefix="suite-") as scratch:
        env, tests = compiled_environment(Path(scratch))
        print(f"suite: the suite collected and compiled in {time.monotonic() - started:.0f} s", flush=True)
        reports = os.environ.get("COMMISSION_SUITE_REPORTS") or scratch  # kept there when named, for study
        Path(reports).mkdir(parents=True, exist_ok=True)
        for n, (name, options) in enumerate(PHASES):
            begun = time.monotonic()
            print(f"suite: {name} ({' '.join(options)})", flush=True)
            report = Path(reports) / f"phase-{n}.xml"
            files: list[str] = []
            if tests and not extra:  # the phase's own files, unless a path or an option given here chooses
                files = phase_files(tests, options)
                if not files:
                    results.append((name, 0, 0.0))  # no test of this phase
                    continue
            run = subprocess.run([sys.executable, "-m", "pytest", "-q", *options, f"--junitxml={report}", *extra, *files],
                                 check=False, env=env)
            # 5: nothing was selected (a -k or a path outside this phase), not a failure
            results.append((name, 0 if run.returncode == 5 else run.returncode, time.monotonic() - begun))
            recap += failures(report)
    for name, code, seconds in results:
        print(f"suite: {name}: {'passed' if code == 0 else f'FAILED (exit {code})'} in {seconds / 60:.1f} min", flush=True)
    for line in recap:
        print(line, flush=True)
    failed = [code for _name, code, _s in results if code != 0]
    print(f"suite: {'passed' if not failed else 'FAILED'} in {(time.monotonic() - started) / 60:.1f} min", flush=True)
    return failed[0] if failed else 0


if __name__ == "__main__":
    sys.exit(main())
