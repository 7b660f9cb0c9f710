"""App CPU of open HD-Lock and M3IO device pages: none open, then 5 HD-Lock and 5 M3IO pages in chromium.

The app runs the demo plant in its own process (``bench/liveapp.running_app``); the pages follow
the live store (pushed at most 10 times a second and once a second for ages), their charts append.
CPU is the app process's user+system time over ``--seconds`` (from /proc), in % of one core,
measured once with no page and once with the ten pages open.

Last line: ``device_page_cpu_pct_per_page: X`` = (CPU with 10 pages - CPU with none) / 10.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

HDLOCK = ["/device/door-1", "/device/door-2", "/device/gate-1", "/device/gate-2", "/device/door-1"]  # Modbus and CAN
M3IO = ["/device/heater-hm", "/device/heater-hmr", "/device/heater-hm", "/device/heater-hmr", "/device/heater-hm"]


def main() -> None:
    from browser_load import measure
    from liveapp import CHROMIUM_ARGS, app_pid, demo_plant_text, free_port, need_playwright, rss_mb, running_app, wait_devices_online
    sync_playwright = need_playwright()

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="measuring time per step")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder, running_app(demo_plant_text(free_port()), Path(folder)) as url:
        wait_devices_online(url, timeout=60)
        pid = app_pid(int(url.rsplit(":", 1)[1]))
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
            idle = browser.new_page()  # a blank page: the playwright loop's clock, not an app page
            idle.wait_for_timeout(3000)
            none_cpu, none_rss = measure(pid, args.seconds, idle), rss_mb(pid)
            print(f" 0 device pages: app CPU {none_cpu:5.1f} % of a core, RSS {none_rss:.0f} MB", flush=True)
            for path in HDLOCK + M3IO:
                page = browser.new_page(viewport={"width": 1440, "height": 900})
                page.goto(url + path)
                page.locator(".js-plotly-plot").first.wait_for(timeout=20_000)
            idle.wait_for_timeout(3000)  # settle
            open_cpu, open_rss = measure(pid, args.seconds, idle), rss_mb(pid)
            print(f"10 device pages (5 HD-Lock, 5 M3IO): app CPU {open_cpu:5.1f} % of a core, RSS {open_rss:.0f} MB", flush=True)
            browser.close()
    per_page = (open_cpu - none_cpu) / 10
    print(f"RSS growth 0 -> 10 pages: {open_rss - none_rss:.0f} MB")
    print(f"device_page_cpu_pct_per_page: {per_page:.2f}")


if __name__ == "__main__":
    main()
