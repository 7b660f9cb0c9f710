"""App CPU with 5 lift (Electrak) pages open in chromium against none.

Starts the app on a simulated Electrak network (two actuators, 100 ms status telegrams), measures the
app process's CPU (user + system from /proc) over a window with no browser, then with 5 pages of the
lift open in Debian's chromium, and prints the cost per page. Last line: ``app_cpu_per_lift_page_pct: X``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "bench"))

from liveapp import (  # noqa: E402
    CHROMIUM_ARGS,
    ELECTRAK_ACTUATORS,
    app_pid,
    bus,
    cpu_s,
    device,
    free_port,
    plant_text,
    running_app,
)


def lift_plant() -> str:
    """An Electrak network of two HD24 actuators alone, on a virtual CAN channel of its own."""
    return plant_text(bus("can2", "can", device("lift", "electrak", "can2", actuators=list(ELECTRAK_ACTUATORS)),
                          interface="virtual", channel=f"page-cost-{free_port()}", bitrate=500000, simulate=True),
                      name="page-cost")


def measure(pid: int, seconds: float) -> float:
    """Percent of one core the app used over ``seconds``."""
    c0, t0 = cpu_s(pid), time.monotonic()
    time.sleep(seconds)  # a measuring window, not a wait for a condition
    return 100 * (cpu_s(pid) - c0) / (time.monotonic() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--pages", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=30.0, help="length of each measuring window")
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as folder, running_app(lift_plant(), Path(folder)) as url:
        pid = app_pid(int(url.rsplit(":", 1)[1]))
        time.sleep(3)  # let the start-up settle (imports, first connections) before the idle window
        idle = measure(pid, args.seconds)
        print(f"app CPU, no page open: {idle:.1f} % of a core over {args.seconds:g} s")
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
            pages = []
            for _ in range(args.pages):
                page = browser.new_page(viewport={"width": 1440, "height": 900})
                page.goto(f"{url}/device/lift")
                page.get_by_text("actuators heard per 100 ms: 2 of 2 configured").wait_for(timeout=20_000)
                pages.append(page)
            time.sleep(3)  # the pages' first drawing is not part of the steady cost
            loaded = measure(pid, args.seconds)
            browser.close()
        per_page = (loaded - idle) / args.pages
        print(f"app CPU, {args.pages} lift pages open: {loaded:.1f} % of a core over {args.seconds:g} s")
        print(f"cost per open lift page: {per_page:.2f} % of a core (goal of issue 16: at most 0.5 %)")
        print(f"app_cpu_per_lift_page_pct: {per_page:.2f}")


if __name__ == "__main__":
    main()
