"""OPC UA password guessing against the demo while an engineer holds a jog: does the flood stall the buses?

The demo plant runs as ``commission`` in a process of its own with ``[opcua] anonymous = false`` (sessions
must log in with an account) and the Electrak network on a ``udp_multicast`` CAN bus, so this process hears
its control telegrams. Chromium (Debian's, through playwright) opens the lift's page, takes control, arms
the jog and holds the jog button down for the whole run (hold-to-run, the mouse never released).

Then four OPC UA clients (in a process of their own) guess passwords for ``--seconds`` (30) as fast as the
server answers them, each a new connection with a user-name token. Meanwhile this process asks ``/api/devices`` every 50 ms (the GUI's
latency, p50/p95/max, before and during the flood) and listens to the lift's telegrams: a control telegram
with enable cleared, or a status telegram flagging a message timeout (no control telegram for 250 ms), while
the jog is held is a false stop.

The loop's worst stall during the flood: the app logs every stall of its 50 ms supervision tick over 100 ms
("event loop stalled for N ms"); the figure is the largest logged in the flood's window. When none was (every
lag under 100 ms), it is the longest ``/api/devices`` answer during the flood instead: a request is served
on the same loop, and one is always in flight or sent within 50 ms, so a stall shows in it. The page
header's loop p99 of the last minute is printed beside it. Last line: ``opcua_flood_loop_stall_ms: X``.

    python3 bench/opcua_login_flood.py [--seconds 30] [--clients 4] [--root OTHER_CHECKOUT]
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import json
import re
import secrets
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from datetime import datetime
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from liveapp import (  # noqa: E402 - after the path
    CHROMIUM,
    CHROMIUM_ARGS,
    demo_plant_text,
    die_with_parent,
    free_port,
    free_udp_port,
    load,
    need_playwright,
    start_app,
    stop_app,
    wait_devices_online,
    wait_http,
)

GROUP = "239.74.163.41"
CONTROL_ID = 0x006  # Electrak control telegram (byte 7 bit 0: enable)
STATUS_ID = 0x007  # Electrak status telegram (byte 7 bit 5: message timeout)
MESSAGE_TIMEOUT_S = 0.25  # the actuators flag a message timeout after this (the document's 250 ms)
STALL_LINE = re.compile(r"^(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d{3}) WARNING .*event loop stalled for (\d+) ms")


def bench_plant(udp_port: int, opcua_port: int) -> str:
    text = demo_plant_text()
    electrak_bus = 'interface = "virtual"\nchannel = "demo-can2"'
    if electrak_bus not in text:
        sys.exit("the demo plant's Electrak bus is not where this benchmark expects it (plants/demo.toml, bus can2)")
    text = text.replace(electrak_bus, f'interface = "udp_multicast"\nchannel = "{GROUP}"\nport = {udp_port}', 1)
    return text.replace('name = "demo"', f'name = "demo"\n\n[opcua]\nendpoint = "opc.tcp://127.0.0.1:{opcua_port}"\n'
                        'anonymous = false\n', 1)


def percentile(values: list[float], q: float) -> float:
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


class ApiProbe(threading.Thread):
    """``GET /api/devices`` every 50 ms: (time sent, seconds to the answer)."""

    def __init__(self, url: str):
        super().__init__(daemon=True)
        self.url, self.samples, self.errors, self.running = url, [], 0, True

    def run(self) -> None:
        while self.running:
            started = time.monotonic()
            try:
                with urllib.request.urlopen(self.url + "/api/devices", timeout=10) as response:
                    response.read()
                self.samples.append((started, time.monotonic() - started))
            except OSError:
                self.errors += 1
            time.sleep(max(0.0, 0.05 - (time.monotonic() - started)))

    def between(self, start: float, end: float) -> list[float]:
        return [d for t, d in self.samples if start <= t <= end]


class ControlListener(threading.Thread):
    """The lift's control telegrams on its udp_multicast bus: (arrival, enable bit)."""

    def __init__(self, port: int):
        import can

        super().__init__(daemon=True)
        self.bus = can.Bus(interface="udp_multicast", channel=GROUP, port=port, receive_own_messages=False)
        self.frames: list[tuple[float, bool]] = []
        self.timeouts: list[float] = []  # status telegrams flagging a message timeout (the actuator stops)
        self.running = True

    def run(self) -> None:
        while self.running:
            msg = self.bus.recv(0.05)
            if msg is not None and msg.arbitration_id == CONTROL_ID and len(msg.data) >= 8:
                self.frames.append((time.monotonic(), bool(msg.data[7] & 0x01)))
            elif msg is not None and msg.arbitration_id == STATUS_ID and len(msg.data) >= 8 and msg.data[7] & 0x20:
                self.timeouts.append(time.monotonic())

    def enabled_since(self, since: float, timeout: float) -> bool:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            if any(t >= since and on for t, on in list(self.frames)):
                return True
            time.sleep(0.02)
        return False

    def false_stops(self, start: float, end: float) -> tuple[int, int, float]:
        """Control telegrams with enable cleared, status telegrams flagging a message timeout, and the longest
        gap between control telegrams as heard here, from ``start`` to ``end``."""
        frames = [(t, on) for t, on in list(self.frames) if start <= t <= end]
        cleared = sum(1 for _t, on in frames if not on)
        timeouts = sum(1 for t in list(self.timeouts) if start <= t <= end)
        times = [start] + [t for t, _on in frames] + [end]
        return cleared, timeouts, max(b - a for a, b in itertools.pairwise(times))

    def close(self) -> None:
        self.running = False
        self.join(2)
        self.bus.shutdown()


def flood(url: str, clients: int, seconds: float, counts: dict) -> None:
    """``clients`` OPC UA clients guessing passwords for ``seconds`` (in this thread's own event loop)."""
    from asyncua import Client, ua

    async def guesser(n: int) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            client = Client(url, timeout=5)
            client.set_user("engineer" if n % 2 else f"guess-{secrets.token_hex(3)}")
            client.set_password(secrets.token_urlsafe(9))
            try:
                await client.connect()
                counts["accepted"] += 1
                await client.disconnect()
            except (ua.UaError, ua.UaStatusCodeError, asyncio.TimeoutError, OSError):
                counts["refused"] += 1
                with contextlib.suppress(Exception):  # half-open: nothing to close
                    await client.disconnect()
            counts["guesses"] += 1

    async def main() -> None:
        await asyncio.gather(*(guesser(n) for n in range(clients)))

    import logging

    logging.getLogger("asyncua").setLevel(logging.CRITICAL)  # the guessers' own complaints are not the figure
    asyncio.run(main())


def stalls_between(log_file: Path, start_wall: float, end_wall: float) -> list[int]:
    found = []
    for line in log_file.read_text(errors="replace").splitlines():
        match = STALL_LINE.match(line)
        if match:
            stamp = datetime.strptime(match.group(1), "%Y-%m-%d %H:%M:%S,%f").timestamp()
            if start_wall <= stamp <= end_wall + 1:
                found.append(int(match.group(2)))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--clients", type=int, default=4)
    parser.add_argument("--guess", metavar="URL", help=argparse.SUPPRESS)  # the guessers' own process
    parser.add_argument("--root", type=Path, default=ROOT, help="the checkout whose app runs (another version side by side)")
    args = parser.parse_args()
    if args.guess:
        counts = {"guesses": 0, "refused": 0, "accepted": 0}
        flood(args.guess, args.clients, args.seconds, counts)
        print(json.dumps(counts), flush=True)
        return
    sync_playwright = need_playwright()
    folder = Path(tempfile.mkdtemp(prefix="opcua-flood-"))
    udp_port, opcua_port, port = free_udp_port(), free_port(), free_port()
    (folder / "plant.toml").write_text(bench_plant(udp_port, opcua_port))
    listener = ControlListener(udp_port)
    listener.start()
    proc = start_app(folder / "plant.toml", port, folder / "app.log", root=args.root)
    url = f"http://127.0.0.1:{port}"
    try:
        wait_http(url + "/api/devices", proc, timeout=60)
        wait_devices_online(url, ["lift"], proc, timeout=60)
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
            page = browser.new_page(viewport={"width": 1440, "height": 900})
            page.goto(f"{url}/device/lift")
            page.get_by_test_id("take-control").click()
            page.get_by_text("you hold control").wait_for(timeout=15_000)
            page.get_by_test_id("jog-out").click()  # the first press asks that the area is clear and arms the jog
            clear = page.locator(".q-dialog").get_by_role("button", name=re.compile("area is clear"))
            with contextlib.suppress(Exception):  # versions of the page that ask it in a dialog (else playwright's timeout)
                clear.click(timeout=5_000)
            with contextlib.suppress(Exception):  # versions that arm the jog with the first press say so
                page.get_by_test_id("jog-armed").get_by_text("jog armed").wait_for(timeout=10_000)
            page.get_by_test_id("jog-out").scroll_into_view_if_needed()
            box = page.get_by_test_id("jog-out").bounding_box()
            page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
            held = time.monotonic()
            page.mouse.down()  # hold-to-run: held until the end of the run
            if not listener.enabled_since(held, 5):
                sys.exit("the jog did not start: no control telegram with enable")
            probe = ApiProbe(url)
            probe.start()
            quiet_start = time.monotonic()
            page.wait_for_timeout(5_000)  # the page stays live meanwhile (its beats, its updates)
            quiet_end = time.monotonic()
            # the guessers in a process of their own: their Python work must not hold up this process's probe
            flood_start, flood_wall = time.monotonic(), time.time()
            guessers = subprocess.Popen([sys.executable, __file__, "--guess", f"opc.tcp://127.0.0.1:{opcua_port}",
                                         "--seconds", str(args.seconds), "--clients", str(args.clients)],
                                        stdout=subprocess.PIPE, text=True, preexec_fn=die_with_parent)
            while guessers.poll() is None:
                page.wait_for_timeout(250)
            flood_end, flood_wall_end = time.monotonic(), time.time()
            counts = json.loads(guessers.stdout.read().strip().splitlines()[-1])
            probe.running = False
            header = page.get_by_test_id("loop-lag").inner_text()
            page.mouse.up()
            browser.close()
        cleared, timeouts, gap = listener.false_stops(held + 0.5, flood_end)
        quiet, during = probe.between(quiet_start, quiet_end), probe.between(flood_start, flood_end)
        stalls = stalls_between(folder / "app.log", flood_wall, flood_wall_end)
        p99_header = float(re.search(r"(\d+)", header).group(1)) if re.search(r"(\d+)", header) else float("nan")
        worst = max(stalls) if stalls else max(during, default=float("nan")) * 1000
        print(f"# {load()}; {args.clients} OPC UA clients guessing for {args.seconds:.0f} s, a jog held in chromium")
        print(f"guesses: {counts['guesses']} ({counts['refused']} refused, {counts['accepted']} accepted)")
        print(f"GUI /api/devices before the flood: p50 {percentile(quiet, 0.5) * 1000:.0f} ms, "
              f"p95 {percentile(quiet, 0.95) * 1000:.0f} ms ({len(quiet)} requests)")
        print(f"GUI /api/devices during the flood: p50 {percentile(during, 0.5) * 1000:.0f} ms, "
              f"p95 {percentile(during, 0.95) * 1000:.0f} ms, max {max(during, default=float('nan')) * 1000:.0f} ms "
              f"({len(during)} requests, {probe.errors} errors)")
        print(f"jog held: {cleared} control telegrams with enable cleared, {timeouts} status telegrams flagging a message "
              f"timeout: {'FALSE STOP' if cleared or timeouts else 'no false stop'} (longest gap between control "
              f"telegrams as heard by this process {gap * 1000:.0f} ms; the actuators' bound {MESSAGE_TIMEOUT_S * 1000:.0f} ms)")
        print(f"event-loop stalls over 100 ms logged during the flood: {len(stalls)}"
              + (f", worst {max(stalls)} ms" if stalls else " (the figure below is the longest API answer)")
              + f"; page header's loop p99 of the last minute: {p99_header:.0f} ms")
        print(f"opcua_flood_loop_stall_ms: {worst:.0f}")
    finally:
        stop_app(proc)
        listener.close()


if __name__ == "__main__":
    main()
