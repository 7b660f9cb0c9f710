"""The tool's cost per device: plants of 10, 30 and 100 devices, the twins in a process of their own.

Each plant (bench/scale_plants.py: the families in a site's mix, HD-Locks on RS485 lines of 16 at
19200 baud 8E1 whose twins answer after the wire time) runs split in two processes as in
``idle_cost.py``: ``commission sim`` (the twins) and ``commission --no-sim`` (the tool), its CAN buses
on ``udp_multicast``. The sizes run one after the other; for each, after every device is online and
``--settle`` seconds more, the tool's CPU (event-loop thread and the others) and its twins' over
``--seconds``, and the tool's RSS, with the machine's load beside them. A least-squares line through
the sizes gives the cost per device (its slope) and the tool's own (its intercept).

With the largest plant still running, chromium (Debian's, through playwright) opens the overview and
the plant view in a fresh context each time and times the request to the value of the plant's last
lock on screen (every tile drawn by then: a page is built with its values).

Then each family alone (as many devices as one bus of the hundred carries) and the tool with no device,
measured the same way: the cost per device of each family.

Then the RS485 lines alone: four lines of 16 HD-Locks, the twins in ``commission sim`` with the wire
time emulated, the tool's worker in this process. (a) A full register read of the 16 locks of every
line (12 transactions a lock), the four lines at once, against the wire time of the same telegrams
at 19200 8E1 (11 bits a character, 3.5 characters of silence after each telegram); (b) the worker's
own polling for ``--cycle-seconds``: the line's measured cycle and the wire time of the transactions
it made, from the line's log; both ratios have the goal 1.2.

Last line: ``tool_cpu_per_device_pct: X`` (the slope, % of one core per device; goal 0.1).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from liveapp import (  # noqa: E402
    CHROMIUM, CHROMIUM_ARGS, cpu_s, free_port, load, need_playwright, rss_mb, start_app, stop_app, thread_cpu_s,
    wait_devices_online, wait_http,
)
from scale_plants import BAUD, family_counts, scale_plant_text, tcp_ports, wait_listening  # noqa: E402

# each family alone, as many as a bus of the 100-device mix carries
FAMILIES = (("hdlock-modbus", 16), ("hdlock-can", 8), ("m3io", 8), ("electrak", 4), ("scu", 4), ("mo64", 6))
BITS_PER_CHAR = 11  # start + 8 data + even parity + stop
GAP_CHARS = 3.5  # the silence that ends an RTU telegram


def fit(xs: list[float], ys: list[float]) -> tuple[float, float]:
    """Least-squares slope and intercept of ``ys`` over ``xs``."""
    mx, my = statistics.fmean(xs), statistics.fmean(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys, strict=True)) / sxx if sxx else 0.0
    return slope, my - slope * mx


def last_lock(n: int) -> str:
    """The plant's last HD-Lock on RS485 (its values come last: the end of the longest line)."""
    from scale_plants import LOCKS_PER_LINE, MAX_MODBUS_LINES

    locks = family_counts(n)["hdlock-modbus"]
    lines = max(1, min(MAX_MODBUS_LINES, -(-locks // LOCKS_PER_LINE)))
    return f"door-{lines}-{locks // lines:02d}"


FIRST_VALUE = {"/": '[data-device="{name}"] >> text=/bolt (locked|unlocked|moving)/',
               "/plant": '[data-plant-tile="{name}"] >> text=/bolt (locked|unlocked|moving)/'}
LARGE_PLANT = 24  # pages/overview.py: from here on the overview opens with its table, its buses closed
# a large plant's overview opens with its table (its buses closed, their tiles drawn when opened): the lock's row
LARGE_FIRST_VALUE = '[data-glance="{name}"] >> text=online'

TEXT_FONT_LOADED = "document.fonts.load('1em Roboto', 'bolt locked').then(() => true)"


def first_values(url: str, name: str, tries: int, large: bool) -> dict[str, tuple[float, float]]:
    """path -> median seconds from the request to ``name``'s value on screen, and to the app's answer
    (``large``: a plant whose overview shows the table first, see pages/overview.py ``LARGE_PLANT``)."""
    sync_playwright = need_playwright()
    found: dict[str, tuple[float, float]] = {}
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        for path, selector in FIRST_VALUE.items():
            if large and path == "/":
                selector = LARGE_FIRST_VALUE
            totals, answers = [], []
            for _ in range(tries):
                page = browser.new_page(viewport={"width": 1600, "height": 1000})  # a new context: nothing cached
                start = time.monotonic()
                page.goto(url + path, wait_until="commit")
                answers.append(time.monotonic() - start)
                page.locator(selector.format(name=name)).wait_for(timeout=60_000)
                page.evaluate(TEXT_FONT_LOADED)
                totals.append(time.monotonic() - start)
                page.close()
            found[path] = (statistics.median(totals), statistics.median(answers))
        browser.close()
    return found


def measure_size(n: int, folder: Path, args: argparse.Namespace, browser: bool, counts: dict | None = None,
                 label: str = "") -> dict:
    """One plant of ``n`` devices split in two processes: CPU, RSS (and first values when ``browser``);
    ``counts``: devices per family instead of the mix (see scale_plants.scale_plant_text)."""
    label = label or f"{n:4d} devices"
    for attempt in range(3):  # a free port taken by another program meanwhile ends the twins: new ports
        plant = folder / f"scale{n}-{len(list(folder.glob('scale*.toml')))}.toml"
        text = scale_plant_text(n, split=True, counts=counts)
        plant.write_text(text)
        twins = start_app(plant, 0, folder / f"sim{plant.stem}.log", "sim") if n else None
        try:
            wait_listening(tcp_ports(text), twins)  # the twins listen before the tool connects (it would back off)
            break
        except RuntimeError:
            tail = (folder / f"sim{plant.stem}.log").read_text(errors="replace").splitlines()[-3:]
            print(f"{label}: the twins did not start ({' / '.join(tail)}), attempt {attempt + 1}", flush=True)
            if attempt == 2:
                raise
    tool = None
    try:
        port = free_port()
        tool = start_app(plant, port, folder / f"tool{plant.stem}.log", "--no-sim")
        url = f"http://127.0.0.1:{port}"
        wait_http(f"{url}/api/devices", tool, timeout=60)
        t_online = time.monotonic()
        if n:
            wait_devices_online(url, proc=tool, timeout=120)
        online_s = time.monotonic() - t_online
        time.sleep(args.settle)
        loads = [os.getloadavg()[0]]
        c0, l0, t0 = cpu_s(tool.pid), thread_cpu_s(tool.pid, tool.pid), time.monotonic()
        s0 = cpu_s(twins.pid) if twins else 0.0
        time.sleep(args.seconds)
        spent = time.monotonic() - t0
        loads.append(os.getloadavg()[0])
        result = {"n": n, "online_s": online_s, "cpu": 100 * (cpu_s(tool.pid) - c0) / spent,
                  "loop": 100 * (thread_cpu_s(tool.pid, tool.pid) - l0) / spent,
                  "twins": 100 * (cpu_s(twins.pid) - s0) / spent if twins else 0.0, "rss": rss_mb(tool.pid), "load": loads}
        print(f"{label}: tool {result['cpu']:5.1f} % of a core (event loop {result['loop']:4.1f}), "
              f"RSS {result['rss']:6.1f} MB; twins {result['twins']:5.1f} %; every device online {online_s:4.1f} s "
              f"after the API answered; load {loads[0]:.2f} -> {loads[1]:.2f}", flush=True)
        if browser:
            name = last_lock(n)
            result["first"] = first_values(url, name, args.tries, n > LARGE_PLANT)
            for path, (total, answered) in result["first"].items():
                print(f"     first value of {name} on a new {path} page: {total * 1000:.0f} ms "
                      f"(app's answer {answered * 1000:.0f} ms), {load()}", flush=True)
        return result
    finally:
        if tool is not None:
            stop_app(tool)
        if twins is not None:
            stop_app(twins)


# -- the RS485 lines against the wire -----------------------------------------------------------

def wire_s(request_hex: str, response_hex: str) -> float:
    """Seconds one transaction occupies a 19200 8E1 line: both telegrams and the silence after each."""
    chars = len(bytes.fromhex(request_hex.replace(" ", ""))) + len(bytes.fromhex(response_hex.replace(" ", "")))
    return (chars + 2 * GAP_CHARS) * BITS_PER_CHAR / BAUD


async def lines_against_wire(folder: Path, cycle_seconds: float) -> tuple[list[dict], list[dict]]:
    from app.plant import parse_plant
    from app.runtime import Runtime
    from app.worker import Worker

    text = scale_plant_text(64, name="lines", counts={"hdlock-modbus": 64})  # four lines of 16
    plant_file = folder / "lines.toml"
    plant_file.write_text(text)
    plant = parse_plant(text)
    lines = sorted(b.name for b in plant.buses.values())
    twins = start_app(plant_file, 0, folder / "lines-sim.log", "sim")
    full: list[dict] = []
    polled: list[dict] = []
    try:
        await asyncio.to_thread(wait_listening, tcp_ports(text), twins)
        # (a) a full register read of every lock of a line, the lines at once, driven here (no worker running)
        worker = Worker(parse_plant(text.replace("simulate = true", "simulate = false")))
        try:
            for line in lines:  # connected and warm
                for dev in plant.devices_on(line):
                    await worker.adapters[dev.name].poll()

            async def full_read(line: str) -> dict:
                store = worker.store.buses[line]
                t_begin = time.time()
                start = time.perf_counter()
                for dev in plant.devices_on(line):
                    adapter = worker.adapters[dev.name]
                    adapter.read_settings_next()
                    await adapter.poll()
                took = time.perf_counter() - start
                done = [t for t in list(store.transactions) if t.time >= t_begin]
                wire = sum(wire_s(t.request_hex, t.response_hex) for t in done)
                errors = sum(1 for t in done if t.error)
                return {"line": line, "locks": len(plant.devices_on(line)), "transactions": len(done), "took": took,
                        "wire": wire, "errors": errors}

            full = list(await asyncio.gather(*(full_read(line) for line in lines)))
        finally:
            for line in worker.lines.values():
                line.close()
        # (b) the worker's own polling: the line's cycle and what its transactions needed of the wire
        runtime = Runtime(parse_plant(text.replace("simulate = true", "simulate = false")), simulate=False,
                          data_dir=folder / "lines-data")
        await runtime.start()
        try:
            end = time.monotonic() + 60
            while time.monotonic() < end and not all(s.status == "online" for s in runtime.store.devices.values()):
                await asyncio.sleep(0.2)
            await asyncio.sleep(12)  # one settings read of every lock (every 10 s) falls inside the cycles measured
            t_begin = time.time()
            await asyncio.sleep(cycle_seconds)
            t_end = time.time()
            for line in lines:
                store = runtime.store.buses[line]
                done = [t for t in list(store.transactions) if t_begin <= t.time < t_end]
                wire = sum(wire_s(t.request_hex, t.response_hex) for t in done)
                polled.append({"line": line, "cycle": store.cycle_s or float("nan"), "busy": wire / (t_end - t_begin),
                               "transactions": len(done), "errors": sum(1 for t in done if t.error),
                               "per_transaction_ms": 1000 * (t_end - t_begin) / max(1, len(done))})
        finally:
            await runtime.stop()
    finally:
        stop_app(twins)
    return full, polled


async def keepalives_with_hundred(folder: Path, seconds: float) -> list[tuple[str, int, float, float]]:
    """The Electrak's control telegram and an M3IO's DigOut (both every 100 ms under control) while the other
    98 devices poll: the tool's worker in this process (at the GUI's priority, app/cli.py), the twins in
    ``commission sim``, the keep-alives heard on the ``udp_multicast`` buses from a third node (the kernel's
    receive time). Returns (name, telegrams, worst gap s, period s)."""
    import can

    from app.plant import parse_plant
    from app.runtime import Runtime, raise_priority
    from devices.electrak import codec as electrak
    from devices.m3io import codec as m3io

    text = scale_plant_text(100, name="keepalive", split=True)
    plant_file = folder / "keepalive.toml"
    plant_file.write_text(text)
    plant = parse_plant(text)
    twins = start_app(plant_file, 0, folder / "keepalive-sim.log", "sim")
    heard: dict[str, list[float]] = {"Electrak control 0x06": [], "M3IO DigOut": []}
    wanted = {"can-lift-1": ("Electrak control 0x06", electrak.CONTROL_ID),
              "can-io": ("M3IO DigOut", m3io.derive_ids(1).dig_out)}
    buses, run = [], [True]

    def listen(bus, name: str, can_id: int) -> None:
        while run[0]:
            msg = bus.recv(0.05)
            if msg is not None and msg.arbitration_id == can_id and not msg.is_extended_id:
                heard[name].append(msg.timestamp)

    import threading

    threads = []
    try:
        await asyncio.to_thread(wait_listening, tcp_ports(text), twins)
        raise_priority()
        for bus_name, (name, can_id) in wanted.items():
            options = plant.buses[bus_name].options
            bus = can.Bus(interface="udp_multicast", channel=options["channel"], port=options["port"])
            buses.append(bus)
            threads.append(threading.Thread(target=listen, args=(bus, name, can_id), daemon=True))
            threads[-1].start()
        runtime = Runtime(parse_plant(text.replace("simulate = true", "simulate = false")), simulate=False,
                          data_dir=folder / "keepalive-data")
        await runtime.start()

        async def beat() -> None:
            while True:
                runtime.worker.heartbeat("bench")
                await asyncio.sleep(0.1)

        beating = asyncio.create_task(beat())
        try:
            end = time.monotonic() + 90
            while time.monotonic() < end and not all(s.status == "online" for s in runtime.store.devices.values()):
                await asyncio.sleep(0.2)
            await runtime.worker.adapters["lift-01"].take_control("bench", "engineer")
            await runtime.worker.adapters["heater-01"].take_control("bench", "engineer")
            await asyncio.sleep(1.0)
            start = time.time()
            await asyncio.sleep(seconds)
            stop = time.time()
        finally:
            beating.cancel()
            await runtime.stop()
    finally:
        run[0] = False
        for thread in threads:
            thread.join(2)
        for bus in buses:
            bus.shutdown()
        stop_app(twins)
    found = []
    for name, times in heard.items():
        inside = [t for t in times if start <= t <= stop]
        gaps = [b - a for a, b in zip(inside, inside[1:], strict=False)]
        found.append((name, len(inside), max(gaps, default=float("inf")), 0.1))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="10,30,100", help="plant sizes, devices")
    parser.add_argument("--seconds", type=float, default=30.0, help="measuring time per size")
    parser.add_argument("--settle", type=float, default=10.0, help="seconds after every device is online")
    parser.add_argument("--tries", type=int, default=3, help="first-value timings per page")
    parser.add_argument("--cycle-seconds", type=float, default=20.0, help="the RS485 lines' own polling, measured")
    parser.add_argument("--no-browser", action="store_true", help="leave out the first values (no chromium)")
    parser.add_argument("--no-lines", action="store_true", help="leave out the RS485 lines against the wire")
    parser.add_argument("--no-families", action="store_true", help="leave out the cost of each family alone")
    parser.add_argument("--keepalive-seconds", type=float, default=20.0,
                        help="the keep-alives under control with 100 devices polling (0: left out)")
    args = parser.parse_args()
    sizes = [int(x) for x in args.sizes.split(",")]
    print(f"plants of {', '.join(map(str, sizes))} devices, {args.seconds:g} s each after {args.settle:g} s; {load()}", flush=True)
    results = []
    with tempfile.TemporaryDirectory(prefix="plant-scale-") as name:
        folder = Path(name)
        os.environ.setdefault("COMMISSION_DATA_DIR", str(folder / "data"))
        for n in sizes:
            results.append(measure_size(n, folder, args, browser=not args.no_browser and n == max(sizes)))
        families = []
        if not args.no_families:
            empty = measure_size(0, folder, args, False, counts={}, label="no device (the tool alone)")
            for family, k in FAMILIES:
                families.append((family, k, measure_size(k, folder, args, False, counts={family: k},
                                                         label=f"{k:2d} x {family}")))
        if not args.no_lines:
            full, polled = asyncio.run(lines_against_wire(folder, args.cycle_seconds))
            print(f"RS485 lines of HD-Locks at {BAUD} baud 8E1 ({load()}):")
            for r in full:
                print(f"  {r['line']}: full register read of {r['locks']} locks, {r['transactions']} transactions: "
                      f"{r['took'] * 1000:.0f} ms, wire time {r['wire'] * 1000:.0f} ms, ratio {r['took'] / r['wire'] if r['wire'] else float('inf'):.3f}"
                      f"{', ' + str(r['errors']) + ' errors' if r['errors'] else ''} (the four lines at once)")
            for r in polled:
                print(f"  {r['line']}: polled by the worker: cycle {r['cycle']:.2f} s, the line busy on the wire "
                      f"{100 * r['busy']:.1f} % of the time ({r['transactions']} transactions, "
                      f"{r['per_transaction_ms']:.1f} ms each), cycle / wire time {1 / r['busy'] if r['busy'] else float('inf'):.3f}"
                      f"{', ' + str(r['errors']) + ' errors' if r['errors'] else ''}")
            if full:
                print(f"full_read_wire_ratio_worst: {max(r['took'] / r['wire'] if r['wire'] else float('inf') for r in full):.3f}")
        if args.keepalive_seconds:
            found = asyncio.run(keepalives_with_hundred(folder, args.keepalive_seconds))
            print(f"keep-alives under control, 98 other devices polling ({load()}):")
            for name, count, worst, period in found:
                print(f"  {name}: {count} telegrams in {args.keepalive_seconds:g} s, worst gap {worst * 1000:.0f} ms "
                      f"= {worst / period:.2f} x its period")
            print(f"keepalive_worst_gap_ratio: {max(w / p for _, _, w, p in found):.2f}")
    xs = [float(r["n"]) for r in results]
    cpu_slope, cpu_base = fit(xs, [r["cpu"] for r in results]) if len(results) > 1 else (float("nan"), float("nan"))
    rss_slope, rss_base = fit(xs, [r["rss"] for r in results]) if len(results) > 1 else (float("nan"), float("nan"))
    loop_slope, _ = fit(xs, [r["loop"] for r in results]) if len(results) > 1 else (float("nan"), 0.0)
    print("devices  tool CPU %  event loop %  RSS MB  twins CPU %  load")
    for r in results:
        print(f"{r['n']:7d}  {r['cpu']:9.1f}  {r['loop']:12.1f}  {r['rss']:6.1f}  {r['twins']:11.1f}  "
              f"{r['load'][0]:.2f}-{r['load'][1]:.2f}")
    if families:
        print(f"by family (the tool with no device: {empty['cpu']:.1f} % of a core, {empty['rss']:.0f} MB):")
        print("family            devices  tool CPU %  per device %  RSS MB  per device MB")
        for family, k, r in families:
            print(f"{family:16s}  {k:7d}  {r['cpu']:10.1f}  {(r['cpu'] - empty['cpu']) / k:12.3f}  {r['rss']:6.1f}  "
                  f"{(r['rss'] - empty['rss']) / k:13.2f}")
    print(f"per device: {cpu_slope:.3f} % of a core (event loop {loop_slope:.3f}), {rss_slope:.2f} MB; "
          f"the tool with no device (intercept): {cpu_base:.1f} %, {rss_base:.0f} MB")
    print(f"tool_cpu_per_device_pct: {cpu_slope:.3f}")


if __name__ == "__main__":
    with contextlib.suppress(KeyboardInterrupt):
        main()
