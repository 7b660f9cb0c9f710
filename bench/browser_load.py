"""Cost per browser page: the app's CPU and RSS with 0, 5, 10 and 20 pages open, and how long a
new page takes to show its first value with none and with 20 open.

The app runs the demo plant in its own process; chromium opens a mix of the overview, the plant
view and device pages (HD-Lock on Modbus and CAN, Electrak, M3IO, SCU, MO 64). CPU is the app
process's user+system time over ``--seconds`` (from /proc), in % of one core.

The first value is timed in a second chromium, each time in a fresh context (a first visit:
nothing cached), from the request to the value on screen (in the page, and its text font loaded:
chromium does not draw text in a font that is still loading); the median of ``--tries``. With 20
pages open it is timed twice: with their browser at the same priority as everything else (all
20 pages drawn on this machine's cores beside the app), and with it on idle CPU time only
(SCHED_IDLE), which stands for the usual case of the pages being on other devices: the app still
serves all 20, but their drawing no longer takes the cores from the app and the new page.

An app's RSS grows by itself for its first ten minutes (each device's chart history fills up to
HISTORY_SECONDS), pages or not. So a second app on its own copy of the demo plant runs beside it with
no page open, started at the same time, and its growth over the same minutes is taken off: the RSS
per page is ((growth with 0 -> 20 pages) - (the page-less app's growth meanwhile)) / 20; and each
kind of page is opened and closed once before, so that what is loaded once for all pages (page
modules, assets) is not counted as the cost of each.

Last line: ``app_cpu_per_page_pct: X`` = (CPU with 20 pages - CPU with 0) / 20.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from liveapp import (  # noqa: E402  (standard library only: runs after `pip install -e .`, no pytest)
    CHROMIUM, CHROMIUM_ARGS, app_pid, cpu_s, demo_plant_text, free_port, load, need_playwright, rss_mb, running_app,
    wait_devices_online,
)

MIX = ["/", "/plant", "/device/door-1", "/device/gate-1", "/device/lift", "/device/heater-hm", "/device/lift-1",
       "/device/barrier-in", "/", "/plant"]
# the first value of a lock, whatever it is (waiting for one particular state would time the lock, not the page)
FIRST_VALUE = {"/plant": '[data-plant-tile="door-2"] >> text=/bolt (locked|unlocked|moving)/',
               "/": '[data-device="door-2"] >> text=/bolt (locked|unlocked|moving)/'}

TEXT_FONT_LOADED = "document.fonts.load('1em Roboto', 'bolt locked').then(() => true)"


def process_tree(root: int) -> list[int]:
    """``root`` and every process below it (from /proc)."""
    children: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(entry.name))
    found, todo = [], [root]
    while todo:
        pid = todo.pop()
        found.append(pid)
        todo.extend(children.get(pid, []))
    return found


def run_when_idle(root: int) -> None:
    """Every thread of ``root``'s processes to SCHED_IDLE: they run only on CPU time nothing else
    wants, and what they start inherits it (a nice value would not do: chromium sets its own)."""
    for pid in process_tree(root):
        try:
            threads = [int(t) for t in os.listdir(f"/proc/{pid}/task")]
        except OSError:
            continue
        for tid in threads:
            try:
                os.sched_setscheduler(tid, os.SCHED_IDLE, os.sched_param(0))
            except OSError:
                pass


def first_value(browser, url: str, path: str, tries: int) -> tuple[float, float]:
    """Median seconds from the request to the first value on screen, and to the app's answer."""
    import statistics

    totals, answers = [], []
    for _ in range(tries):
        page = browser.new_page(viewport={"width": 1280, "height": 800})  # a new context: nothing cached
        start = time.monotonic()
        page.goto(url + path, wait_until="commit")
        answers.append(time.monotonic() - start)  # the app's answer, before chromium's own work on the page
        page.locator(FIRST_VALUE[path]).wait_for(timeout=30_000)
        page.evaluate(TEXT_FONT_LOADED)  # chromium draws no text while its font is loading
        totals.append(time.monotonic() - start)
        page.close()
    return statistics.median(totals), statistics.median(answers)


def measure(pid: int, seconds: float, page) -> float:
    start_cpu, start = cpu_s(pid), time.monotonic()
    page.wait_for_timeout(seconds * 1000)
    return 100 * (cpu_s(pid) - start_cpu) / (time.monotonic() - start)


def main() -> None:
    sync_playwright = need_playwright()
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="measuring time per step")
    parser.add_argument("--tries", type=int, default=3, help="first-value timings per page type and case")
    parser.add_argument("--root", type=Path, help="run the app from another checkout (before and after, back to back)")
    args = parser.parse_args()
    firsts: list[tuple[str, str, float, float]] = []
    with contextlib.ExitStack() as stack:
        folder, alone = (Path(stack.enter_context(tempfile.TemporaryDirectory())) for _ in range(2))
        url = stack.enter_context(running_app(demo_plant_text(free_port()), folder, root=args.root))
        control = stack.enter_context(running_app(demo_plant_text(free_port()), alone, root=args.root))  # never a page
        wait_devices_online(url, timeout=60)
        wait_devices_online(control, timeout=60)
        pid = app_pid(int(url.rsplit(":", 1)[1]))
        control_pid = app_pid(int(control.rsplit(":", 1)[1]))
        control_rss = {}
        results = {}
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)  # the open pages
            newcomer = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)  # the new page

            def time_firsts(case: str) -> None:
                for path in ("/plant", "/"):
                    total, answered = first_value(newcomer, url, path, args.tries)
                    firsts.append((case, path, total, answered))
                    print(f"first value on a new {path} page, {case}: {total * 1000:.0f} ms "
                          f"(app answered after {answered * 1000:.0f} ms)", flush=True)

            idle = browser.new_page()  # a blank page: the playwright loop's clock, not an app page
            for path in dict.fromkeys(MIX):  # each kind of page once, so what is loaded once (modules, assets) is in
                page = browser.new_page(viewport={"width": 1280, "height": 800})
                page.goto(url + path, timeout=120_000)
                page.close()
            idle.wait_for_timeout(5000)  # the closed pages' clients are deleted (NiceGUI's reconnect timeout)
            pages = []
            for count in (0, 5, 10, 20):
                while len(pages) < count:
                    page = browser.new_page(viewport={"width": 1280, "height": 800})
                    page.goto(url + MIX[len(pages) % len(MIX)], timeout=120_000)  # a loaded machine: a page may take long
                    pages.append(page)
                idle.wait_for_timeout(3000)  # settle
                results[count] = (measure(pid, args.seconds, idle), rss_mb(pid))
                control_rss[count] = rss_mb(control_pid)
                print(f"{count:2d} pages: app CPU {results[count][0]:5.1f} % of a core, RSS {results[count][1]:.0f} MB ({load()})", flush=True)
                if count == 0:
                    time_firsts("no other page open")
            time_firsts("20 open, drawn on this machine at the same priority")
            run_when_idle(chromium_root())
            idle.wait_for_timeout(2000)
            time_firsts("20 open, their browser on idle CPU time only (as if on other devices)")
            newcomer.close()
            browser.close()
    per_page = (results[20][0] - results[0][0]) / 20
    growth, by_itself = results[20][1] - results[0][1], control_rss[20] - control_rss[0]
    print(f"RSS growth 0 -> 20 pages: {growth:.0f} MB; the same app with no page open grew {by_itself:.0f} MB "
          f"over the same minutes; per page: {(growth - by_itself) / 20:.2f} MB")
    print(f"app_cpu_per_page_pct: {per_page:.2f}")


def chromium_roots() -> list[int]:
    """The chromium browsers this process started through playwright (their main processes), oldest first."""
    roots = []
    for pid in process_tree(os.getpid()):
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
        except OSError:
            continue
        if b"chromium" in cmd.split(b"\0", 1)[0] and b"--type=" not in cmd:  # the browser, not a helper process
            roots.append(pid)
    return sorted(roots)


def chromium_root() -> int:
    """The first chromium this process started through playwright: the one with the open pages."""
    return chromium_roots()[0]


if __name__ == "__main__":
    main()
