"""Soak: the app's RSS and CPU over ``--minutes`` with ``--browsers`` pages open on the demo plant.

Pages: the overview, the plant view and device pages with charts (HD-Lock, Electrak, M3IO).
Every 30 s: RSS (MB) and CPU (% of a core over the interval). The bounded buffers fill within
about 21 minutes (device history: 600 s of samples; events 200 per device; the CAN monitor rings
of 20,000 frames, the slowest of the demo's buses at 16 frames/s taking 21 min), so growth is
fitted over the samples after ``--warmup`` minutes (25 for an hour).

Last line: ``rss_growth_mb_per_h_after_warmup: X`` (least-squares slope, MB per hour).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from liveapp import (  # noqa: E402
    CHROMIUM_ARGS, app_pid, cpu_s, demo_plant_text, free_port, need_playwright, rss_mb, running_app, wait_devices_online,
)

PAGES = ["/", "/plant", "/device/door-1", "/device/lift", "/device/heater-hm", "/device/gate-1", "/device/lift-1"]


def slope_per_h(samples: list[tuple[float, float]]) -> float:
    if len(samples) < 2:
        return 0.0
    n = len(samples)
    mt = sum(t for t, _ in samples) / n
    mr = sum(r for _, r in samples) / n
    den = sum((t - mt) ** 2 for t, _ in samples)
    return 0.0 if den == 0 else 3600 * sum((t - mt) * (r - mr) for t, r in samples) / den


def main() -> None:
    sync_playwright = need_playwright()

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=60.0)
    parser.add_argument("--browsers", type=int, default=5)
    parser.add_argument("--warmup", type=float, default=None, help="minutes before the fit (default: 5/12 of the run, at most 25)")
    args = parser.parse_args()
    warmup = args.warmup if args.warmup is not None else min(25.0, args.minutes * 5 / 12)
    with tempfile.TemporaryDirectory() as folder, running_app(demo_plant_text(free_port()), Path(folder)) as url:
        wait_devices_online(url, timeout=60)
        pid = app_pid(int(url.rsplit(":", 1)[1]))
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
            clock = browser.new_page()
            for n in range(args.browsers):
                context = browser.new_context(viewport={"width": 1280, "height": 800})  # one browser session each
                context.new_page().goto(url + PAGES[n % len(PAGES)])
            start = time.monotonic()
            samples = []
            last_cpu, last_t = cpu_s(pid), start
            print(f"{args.browsers} browsers for {args.minutes:g} min; fit after {warmup:g} min", flush=True)
            while time.monotonic() - start < args.minutes * 60:
                clock.wait_for_timeout(30_000)
                now, cpu = time.monotonic(), cpu_s(pid)
                rss = rss_mb(pid)
                minutes = (now - start) / 60
                samples.append((now - start, rss))
                print(f"{minutes:6.1f} min  RSS {rss:6.1f} MB  CPU {100 * (cpu - last_cpu) / (now - last_t):5.1f} %", flush=True)
                last_cpu, last_t = cpu, now
            browser.close()
    after = [(t, r) for t, r in samples if t >= warmup * 60]
    print(f"RSS {samples[0][1]:.1f} -> {samples[-1][1]:.1f} MB; after warm-up {after[0][1] if after else 0:.1f} -> {after[-1][1] if after else 0:.1f} MB")
    print(f"rss_growth_mb_per_h_after_warmup: {slope_per_h(after):.1f}")


if __name__ == "__main__":
    main()
