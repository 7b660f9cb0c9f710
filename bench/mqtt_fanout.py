"""N instances publish the demo plant's devices through one Mosquitto to one plant-wide view.

The instances are in-process publishers (app.mqtt.MqttPublisher, the code a ``commission``
process runs) on copies of the demo plant's live stores, filled once from the real demo plant
(simulated devices, real adapters) and then kept changing (every device's values move every
100 ms, so every sampling period has something to send). Separate processes would need N full
plants with their twins on a 2-core machine; the broker and the view are the parts measured.
The view is a ``commission view`` in its own process (its CPU share is read from /proc).

Prints per N: messages/s the view received, publish-to-view latency p50/p95 (the state payload's
``time`` against the view's receive time, one clock) and the view's CPU share; last line
``view_latency_p95_ms: X`` (of the largest N).
"""

from __future__ import annotations

import argparse
import asyncio
import copy
import json
import os
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from app.mqtt import MqttPublisher  # noqa: E402
from app.plant import load_plant, parse_plant  # noqa: E402
from app.runtime import Runtime  # noqa: E402
from app.state import StateStore  # noqa: E402
from webutil import demo_plant_text, free_port  # noqa: E402

CLK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK


def get(url: str) -> dict:
    with urllib.request.urlopen(url, timeout=5) as response:
        return json.load(response)


async def filled_store(folder: Path) -> StateStore:
    """The demo plant run for a few seconds: a store with every device type's real values."""
    (folder / "demo.toml").write_text(demo_plant_text(free_port()))
    runtime = Runtime(load_plant(folder / "demo.toml"), simulate=True, data_dir=folder / "data")
    await runtime.start()
    await asyncio.sleep(6)
    await runtime.stop()
    for state in runtime.store.devices.values():
        state.online, state.last_seen = True, time.time()
    return runtime.store


async def wiggle(stores: list[StateStore]) -> None:
    """Every device's live values move every 100 ms (a busy plant), fresh times included."""
    tick = 0
    while True:
        tick += 1
        now = time.time()
        for store in stores:
            for state in store.devices.values():
                state.last_seen = now
                state.publish("bench tick", tick, time=now)
        await asyncio.sleep(0.1)


async def phase(n: int, base: StateStore, broker_url: str, view: str, view_pid: int, seconds: float) -> dict:
    publishers, stores = [], []
    for i in range(n):
        store = StateStore()
        store.devices = {name: copy.deepcopy(state) for name, state in base.devices.items()}
        cfg = parse_plant(f'name = "inst-{i}"\n[mqtt]\nurl = "{broker_url}"\nsite = "bench-{n}"\n').mqtt
        publishers.append(MqttPublisher(cfg, store, f"inst-{i}"))
        stores.append(store)
    for pub in publishers:
        await pub.start()
    mover = asyncio.create_task(wiggle(stores))
    try:
        end = time.monotonic() + 20
        while time.monotonic() < end and not all(p.connected for p in publishers):
            await asyncio.sleep(0.1)
        await asyncio.sleep(2)  # the retained burst of the first connection passes
        before = await asyncio.to_thread(get, f"{view}/api/bench")
        cpu0, t0 = cpu_seconds(view_pid), time.monotonic()
        await asyncio.sleep(seconds)
        after = await asyncio.to_thread(get, f"{view}/api/bench")
        cpu1, t1 = cpu_seconds(view_pid), time.monotonic()
    finally:
        mover.cancel()
        for pub in publishers:
            await pub.stop()
    lat = sorted(after["latency"][-after["received"] + before["received"]:]) if after["received"] > before["received"] else [0.0]
    return {"n": n, "devices": n * len(base.devices), "msgs_s": (after["received"] - before["received"]) / (t1 - t0),
            "p50_ms": 1000 * lat[len(lat) // 2], "p95_ms": 1000 * lat[int(len(lat) * 0.95)],
            "view_cpu": (cpu1 - cpu0) / (t1 - t0)}


VIEW_SCRIPT = """
import sys, time
sys.path.insert(0, {root!r})
from app.site_view import SiteStore
from nicegui import app, ui
store = SiteStore({url!r})
app.on_startup(store.start)
app.on_shutdown(store.stop)

@app.get("/api/bench")
def bench():
    return {{"received": store.received, "latency": store.latency[-20000:]}}

@app.get("/api/site")
def site():
    return store.snapshot()

ui.run(port={port}, reload=False, show=False, show_welcome_message=False)
"""


async def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--instances", default="1,4,16")
    parser.add_argument("--seconds", type=float, default=8.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="mqtt-bench-") as tmp:
        folder = Path(tmp)
        port = free_port()
        (folder / "mosquitto.conf").write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
        broker = subprocess.Popen(["/usr/sbin/mosquitto", "-c", str(folder / "mosquitto.conf")],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        url = f"mqtt://127.0.0.1:{port}"
        view_port = free_port()
        env = {**os.environ, "NICEGUI_STORAGE_PATH": str(folder / "ng")}
        env.pop("PYTEST_CURRENT_TEST", None)
        # the view's subscriber (app.site_view.SiteStore, as `commission view` runs it) with one more
        # route that hands out its receive latencies
        view = subprocess.Popen([sys.executable, "-c", VIEW_SCRIPT.format(root=str(ROOT), url=url, port=view_port)],
                                env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            base_url = f"http://127.0.0.1:{view_port}"
            end = time.monotonic() + 30
            while True:
                try:
                    get(f"{base_url}/api/bench")
                    break
                except OSError:
                    if time.monotonic() > end:
                        raise
                    time.sleep(0.2)
            base = await filled_store(folder)
            print(f"demo plant: {len(base.devices)} devices per instance; in-process publishers (one Python process), "
                  f"one Mosquitto, one view process; {args.seconds:g} s per phase", flush=True)
            results = []
            for n in (int(x) for x in args.instances.split(",")):
                r = await phase(n, base, url, base_url, view.pid, args.seconds)
                results.append(r)
                print(f"N={r['n']:>2}  devices={r['devices']:>3}  messages/s={r['msgs_s']:7.0f}  latency p50={r['p50_ms']:6.1f} ms  "
                      f"p95={r['p95_ms']:6.1f} ms  view CPU={100 * r['view_cpu']:5.1f} %", flush=True)
        finally:
            view.terminate()
            broker.terminate()
            view.wait(timeout=10)
            broker.wait(timeout=10)
    print(f"view_latency_p95_ms: {results[-1]['p95_ms']:.1f}")


if __name__ == "__main__":
    asyncio.run(main())
