"""The idle plant's CPU with no page open: the tool's own cost apart from its twins'.

A real plant has no twins, so the demo plant runs split in two processes: ``commission sim`` (the
twins alone) and ``commission --no-sim`` (the tool: worker, state store, web server), their CAN
buses on ``udp_multicast`` instead of ``virtual`` so that the two processes share them. Then the
demo as a user starts it, twins and tool in one process. CPU is each process's user+system time
over ``--seconds`` (from /proc), in % of one core, after ``--settle`` seconds; all three are
measured over the same interval, so a busy machine weighs on them alike. Each figure is split into the
event loop's thread (the main thread) and the others (CAN readers, keep-alive senders, the SCU line).
The app is waited for through its API, so no page is built (and none open) while it is measured.

``--baseline DIR`` runs the same three from another checkout (e.g. ``git worktree add DIR HEAD``)
at the same time, on buses of their own: the two versions measured over the same interval.

Last line: ``idle_tool_cpu_pct: X`` (the ``--no-sim`` process).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from liveapp import (  # noqa: E402
    across_processes, cpu_s, demo_plant_text, free_port, load, start_app, stop_app, thread_cpu_s, wait_devices_online,
    wait_http,
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="measuring time")
    parser.add_argument("--settle", type=float, default=10.0, help="seconds after every device is online")
    parser.add_argument("--baseline", type=Path, help="another checkout, measured side by side")
    args = parser.parse_args()
    trees = {"": Path(__file__).resolve().parent.parent}
    if args.baseline is not None:
        trees["baseline "] = args.baseline.resolve()
    procs: dict = {}
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        try:
            guis = []
            for tag, root in trees.items():
                split = folder / f"split{len(guis)}.toml"
                split.write_text(across_processes(demo_plant_text(free_port())))
                demo = folder / f"demo{len(guis)}.toml"
                demo.write_text(demo_plant_text(free_port()))
                gui_port, demo_port = free_port(), free_port()
                twins = start_app(split, 0, folder / f"sim{len(guis)}.log", "sim", root=root)
                time.sleep(2)  # the twins' endpoints listen before the tool connects
                tool = start_app(split, gui_port, folder / f"tool{len(guis)}.log", "--no-sim", root=root)
                whole = start_app(demo, demo_port, folder / f"demo{len(guis)}.log", root=root)
                procs.update({f"{tag}twins (commission sim)": twins, f"{tag}tool (commission --no-sim)": tool,
                              f"{tag}demo (tool and twins)": whole})
                guis += [(gui_port, tool), (demo_port, whole)]
            for port, proc in guis:
                # the API, not a page: a page built here (never connected) would live for a minute, its watchers
                # running through the measurement, and "no page open" would not hold
                wait_http(f"http://127.0.0.1:{port}/api/devices", proc)
                wait_devices_online(f"http://127.0.0.1:{port}", timeout=60)
            time.sleep(args.settle)
            start = {name: cpu_s(p.pid) for name, p in procs.items()}
            loop_start = {name: thread_cpu_s(p.pid, p.pid) for name, p in procs.items()}
            t0 = time.monotonic()
            print(f"measuring {args.seconds:g} s, {load()}", flush=True)
            time.sleep(args.seconds)
            spent = time.monotonic() - t0
            cost = {name: 100 * (cpu_s(p.pid) - start[name]) / spent for name, p in procs.items()}
            loop = {name: 100 * (thread_cpu_s(p.pid, p.pid) - loop_start[name]) / spent for name, p in procs.items()}
            print(f"after: {load()}")
        finally:
            for proc in procs.values():
                stop_app(proc)
    for name, pct in cost.items():
        print(f"{name:37s} {pct:5.1f} % of a core (event loop thread {loop[name]:4.1f}, other threads {pct - loop[name]:4.1f})")
    print(f"idle_tool_cpu_pct: {cost['tool (commission --no-sim)']:.1f}")


if __name__ == "__main__":
    main()
