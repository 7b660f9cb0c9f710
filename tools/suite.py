"""The whole suite, as CI runs it: the linter, then the tests in three phases.

    python3 -m tools.suite [pytest options ...]

Most tests wait on devices, sockets and timers rather than compute (on two cores, six test processes
keep them about two-thirds busy), so every test without a browser runs six processes at a time; the tests
that drive chromium (marker ``browser``) each start the app and a browser, so they run afterwards two at
a time, where they cannot take the cores of a test that holds a device to a real-time bound; last, one at a
time, the tests marked ``alone``: the browser tests that are themselves held to one (the dead-man bound with a
real browser: a second chromium beside it delays its beats on their way) and the few whose subject is how the
program uses the cores (a line's thread that must keep up with its own period).
Every phase runs; the exit status is 0 only when the linter and every phase passed. Options
given here (``-x``, ``-k ...``, a path) go to every phase.
"""

from __future__ import annotations

import subprocess
import sys
import time

PHASES = (
    ("tests without a browser", ["-n", "6", "-m", "not browser and not alone"]),
    ("browser tests", ["-n", "2", "-m", "browser and not alone"]),
    ("tests that need the cores to themselves", ["-n", "0", "-m", "alone"]),
)


def main(argv: list[str] | None = None) -> int:
    extra = list(sys.argv[1:] if argv is None else argv)
    started = time.monotonic()
    lint = subprocess.run(["ruff", "check", "."], check=False)
    if lint.returncode != 0:
        print("suite: ruff found the problems above; fix them first", flush=True)
        return lint.returncode
    results: list[tuple[str, int, float]] = []
    for name, options in PHASES:
        begun = time.monotonic()
        print(f"suite: {name} ({' '.join(options)})", flush=True)
        run = subprocess.run([sys.executable, "-m", "pytest", "-q", *options, *extra], check=False)
        # 5: nothing was selected (a -k or a path outside this phase), not a failure
        results.append((name, 0 if run.returncode == 5 else run.returncode, time.monotonic() - begun))
    for name, code, seconds in results:
        print(f"suite: {name}: {'passed' if code == 0 else f'FAILED (exit {code})'} in {seconds / 60:.1f} min", flush=True)
    failed = [code for _name, code, _s in results if code != 0]
    print(f"suite: {'passed' if not failed else 'FAILED'} in {(time.monotonic() - started) / 60:.1f} min", flush=True)
    return failed[0] if failed else 0


if __name__ == "__main__":
    sys.exit(main())
