"""Frame to screen: from a CAN frame on the wire to the value on the screen, in chromium.

The app runs the demo plant in its own process, plus a ``udp_multicast`` CAN bus with one
HD-Lock (``bench-lock``, not simulated). A second process sends that lock's status frame
(section 6.5.1) ``--rate`` times a second, each with a new motorPos, and notes when it sent
which value. Chromium opens the lock's device page, the overview and the plant view, and
(``--pages``, 20 in all by default) the rest of ``bench/browser_load.py``'s mix of pages in a second
chromium whose threads run on idle CPU time only, as if those pages were on other devices: the app
serves them all, their drawing does not take the cores from the app. A
MutationObserver in each measured page notes (``Date.now()``) when the shown value changes: the device
page's "motorPos N Inc", the overview tile's "bolt N Inc", the plant view's "bolt N % out". Latency = shown time - send time of the
newest frame with that value (same machine, same clock). Printed per page: values shown,
p50/p95/max in ms.

Last line: ``frame_to_screen_p95_ms: X`` = the worst p95 of the three pages.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from browser_load import MIX, chromium_roots, run_when_idle  # noqa: E402
from liveapp import (  # noqa: E402  (standard library only: runs after `pip install -e .`, no pytest)
    CHROMIUM, CHROMIUM_ARGS, demo_plant_text, free_port, load, need_playwright, running_app, wait_devices_online,
)

GROUP = "239.74.163.11"
DEVICE_ID = 660100
LOCK = "bench-lock"

# the value a page shows, and when it changed; runs in each page
OBSERVE_JS = """([kind, name]) => {
  window.__shown = [];
  const re = kind === 'device' ? /motorPos (\\d+) Inc/ : kind === 'plant' ? /^bolt (\\d+) % out$/ : /^bolt (\\d+) Inc$/;
  const scope = kind === 'overview' ? `[data-device="${name}"]` : kind === 'plant' ? `[data-plant-tile="${name}"]` : null;
  let last = null;
  new MutationObserver(records => {
    const now = Date.now();
    for (const r of records) {
      const el = r.target.nodeType === 3 ? r.target.parentElement : r.target;
      if (!el || (scope && !el.closest(scope))) continue;
      const text = (el.textContent || '').trim();
      if (text.length > 200) continue;
      const m = text.match(re);
      if (m && m[1] !== last) { last = m[1]; window.__shown.push([now, +m[1]]); }
    }
  }).observe(document.body, {subtree: true, childList: true, characterData: true});
}"""

PAGES = {"device": f"/device/{LOCK}", "overview": "/", "plant": "/plant"}


def bench_plant(port: int) -> str:
    return demo_plant_text(free_port()) + f"""
# frame_to_screen: a lock whose status frames come from the benchmark's second process
[[bus]]
name = "bench-can"
type = "can"
interface = "udp_multicast"
channel = "{GROUP}"
port = {port}
bitrate = 250000
poll_period = 2.0

[[device]]
name = "{LOCK}"
type = "hdlock"
bus = "bench-can"
device_id = {DEVICE_ID}
"""


def sender(port: int, rate: float, seconds: float, start, sent) -> None:
    """Status frames with motorPos 1, 2, ... 110, 1, ...; (time, value) of each into ``sent``."""
    import can

    from devices.hdlock import codec

    with can.Bus(interface="udp_multicast", channel=GROUP, port=port) as bus:
        start.wait(120)
        t0 = time.time()
        n = 0
        while time.time() - t0 < seconds:
            value = 1 + n % 110
            data = codec.encode_status(codec.StatusFrame(0x0117, value, 20, 4))
            at = time.time()  # before the send: the app may show the value before this process gets to note it
            bus.send(can.Message(arbitration_id=DEVICE_ID, is_extended_id=True, data=data))
            sent.put((at, value))
            n += 1
            time.sleep(max(0.0, t0 + n / rate - time.time()))
    sent.put(None)


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(round(q / 100 * (len(ordered) - 1))))]


FULL_SCALE_INC = 115  # the HD-Lock tile's bar: the plant view shows the bolt's share of it ("bolt 43 % out")


def shown_as(kind: str, value: int) -> int:
    """What a page shows for motorPos ``value``: the value, or on the plant view its share of full travel."""
    return int(f"{value / FULL_SCALE_INC * 100:.0f}") if kind == "plant" else value


def latencies(shown: list[tuple[float, int]], sends: list[tuple[float, int]], kind: str = "device") -> list[float]:
    """For each shown value: ms since the newest send of a value shown that way before it was shown."""
    out = []
    for t_ms, value in shown:
        t = t_ms / 1000
        before = [s for s, v in sends if shown_as(kind, v) == value and s <= t + 0.002]
        if before:
            out.append((t - before[-1]) * 1000)
    return out


def main() -> None:
    sync_playwright = need_playwright()
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=30.0, help="how long frames are sent")
    parser.add_argument("--rate", type=float, default=10.0, help="status frames per second")
    parser.add_argument("--pages", type=int, default=20, help="pages open in all, the three measured ones included")
    parser.add_argument("--root", type=Path, help="run the app from another checkout (before and after, back to back)")
    args = parser.parse_args()

    import tempfile

    port = free_port()
    ctx = mp.get_context("spawn")
    start, sent = ctx.Event(), ctx.Queue()
    proc = ctx.Process(target=sender, args=(port, args.rate, args.seconds, start, sent), daemon=True)
    proc.start()
    with tempfile.TemporaryDirectory() as folder, running_app(bench_plant(port), Path(folder), root=args.root) as url:
        wait_devices_online(url, [n for n in ("door-1", "gate-1", "lift")], timeout=60)
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
            others = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)  # the other open pages
            for n in range(max(0, args.pages - len(PAGES))):
                other = others.new_page(viewport={"width": 1280, "height": 800})
                other.goto(url + MIX[n % len(MIX)], timeout=120_000)
            run_when_idle(chromium_roots()[-1])  # the newest: the one with the other pages
            pages = {}
            for kind, path in PAGES.items():
                page = browser.new_page(viewport={"width": 1440, "height": 900})
                page.goto(url + path)
                page.wait_for_load_state("networkidle")
                page.evaluate(OBSERVE_JS, [kind, LOCK])
                pages[kind] = page
            start.set()
            sends: list[tuple[float, int]] = []
            end = time.monotonic() + args.seconds + 30
            while time.monotonic() < end:
                for page in pages.values():
                    page.wait_for_timeout(200)  # lets playwright serve the pages' events meanwhile
                try:
                    while True:
                        item = sent.get_nowait()
                        if item is None:
                            end = 0
                            break
                        sends.append(item)
                except Exception:  # noqa: BLE001 - queue empty
                    pass
            for page in pages.values():
                page.wait_for_timeout(1000)  # the last frames reach the screen
            shown = {kind: page.evaluate("window.__shown") for kind, page in pages.items()}
            others.close()
            browser.close()
    proc.join(5)
    print(f"frames sent: {len(sends)} at {args.rate:g}/s for {args.seconds:g} s (a second process, udp_multicast); "
          f"{max(args.pages, len(PAGES))} pages open, {max(0, args.pages - len(PAGES))} of them on idle CPU time; {load()}")
    worst = 0.0
    for kind, values in shown.items():
        lat = latencies([tuple(v) for v in values], sends, kind)
        if not lat:
            print(f"{kind:9s}: no value change seen")
            worst = float("inf")
            continue
        p50, p95 = statistics.median(lat), percentile(lat, 95)
        worst = max(worst, p95)
        print(f"{kind:9s}: {len(lat)} values shown of {len(sends)} sent; p50 {p50:.0f} ms, p95 {p95:.0f} ms, max {max(lat):.0f} ms")
    print(f"frame_to_screen_p95_ms: {worst:.0f}")


if __name__ == "__main__":
    main()
