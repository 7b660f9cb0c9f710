"""A site of many instances on one broker: real ``commission`` processes, ``commission view`` and a Sparkplug host.

Every instance is a ``commission`` process of its own (a cabinet of ``--devices`` simulated devices in the
mix of bench/scale_plants.py, its twins in the same process, as a cabinet's laptop would run them), with
``[mqtt]`` on one Mosquitto (Debian's ``/usr/sbin/mosquitto``, a free loopback port, no persistence) and
Sparkplug B on. The view is ``commission view``'s subscriber and page (``server.register_view``, as
``commission view`` runs it) in a process of its own with one more route that hands out its receive
latencies; a Sparkplug host (a paho client in this process) subscribes to ``spBv1.0/#`` and decodes
every payload's timestamp.

``--instances 5,10`` are phases: the instances of a phase keep running into the next one, which adds
the rest. Per phase, after every device of every instance is in the view and ``--settle`` seconds:
messages/s into the view and into the Sparkplug host, publish-to-view latency p50/p95 (the state
payload's ``time`` against the view's receive time, one clock), publish-to-host p95, the CPU and RSS of
the view, of the broker and of the instances (mean per instance), and the machine's load.
``--full`` runs 5, 10, 25 and 50 (a thousand devices at 20 a cabinet): on two cores the instances' own
buses and twins take the CPU long before the broker or the view do, and the figures say so.

Then the bridge (``--bridge``, on by default): a hall broker, a second Mosquitto bridged to the site
broker (``topic commission/# out 1`` and ``topic spBv1.0/# out 1``, as a hall's broker forwards to the
site's), with ``--bridge-instances`` more instances on it; the view on the site broker must list their
devices, and the latency through the bridge is measured on the site broker. Last, a view started on
the warm broker (retained messages only), and a cold broker: the site broker restarted without its
retained messages, the time until the instances have sent everything again and a new view lists every
device.

Last line: ``site_view_latency_p95_ms: X`` (of the largest phase).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from liveapp import ROOT, cpu_s, die_with_parent, free_port, load, rss_mb, start_app, stop_app, wait_http  # noqa: E402
from scale_plants import scale_plant_text  # noqa: E402

MOSQUITTO = "/usr/sbin/mosquitto"

VIEW_SCRIPT = """
import os, sys, tempfile
sys.path.insert(0, {root!r})
os.environ.setdefault("NICEGUI_STORAGE_PATH", tempfile.mkdtemp(prefix="site-view-"))
from app.site_view import SiteStore
from nicegui import app, ui
import server
store = SiteStore({url!r})
server.register_view(store, host="127.0.0.1")

@app.get("/api/bench")
def bench():
    latency = list(store.latency)
    store.latency.clear()
    return {{"received": store.received, "latency": latency, "devices": len(store.devices),
             "instances": len(store.instances)}}

ui.run(host="127.0.0.1", port={port}, title="commission view", reload=False, show=False, show_welcome_message=False,
       tailwind=False)
"""


def get(url: str) -> dict:
    with urllib.request.urlopen(url, timeout=10) as response:
        return json.load(response)


def pct(values: list[float], q: float) -> float:
    return sorted(values)[min(len(values) - 1, int(q * len(values)))] if values else float("nan")


class Broker:
    """One Mosquitto on a free loopback port (``bridge_to``: the port of a broker it forwards our topics to)."""

    def __init__(self, folder: Path, name: str, bridge_to: int | None = None, port: int | None = None):
        self.port = port or free_port()
        self.conf = folder / f"{name}.conf"
        lines = [f"listener {self.port} 127.0.0.1", "allow_anonymous true", "persistence false", "max_queued_messages 100000"]
        if bridge_to is not None:
            lines += [f"connection {name}-to-site", f"address 127.0.0.1:{bridge_to}", "topic commission/# out 1",
                      "topic spBv1.0/# out 1", "cleansession true", "restart_timeout 1 5"]
        self.conf.write_text("\n".join(lines) + "\n")
        self.log = folder / f"{name}.log"
        self.proc = subprocess.Popen([MOSQUITTO, "-c", str(self.conf)], stdout=open(self.log, "wb"), stderr=subprocess.STDOUT,
                                     preexec_fn=die_with_parent)
        self.url = f"mqtt://127.0.0.1:{self.port}"
        end = time.monotonic() + 10
        import socket

        while True:
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=1):
                    return
            except OSError:
                if time.monotonic() > end or self.proc.poll() is not None:
                    raise RuntimeError(f"mosquitto did not start: {self.log.read_text(errors='replace')[-500:]}") from None
                time.sleep(0.05)  # a synchronous start waiting on a port

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            self.proc.wait(timeout=10)


class View:
    """``commission view`` (its subscriber and page) in a process of its own, on ``broker_url``."""

    def __init__(self, folder: Path, broker_url: str, name: str = "view"):
        self.port = free_port()
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        env.pop("PYTEST_CURRENT_TEST", None)
        self.log = folder / f"{name}.log"
        self.proc = subprocess.Popen([sys.executable, "-c", VIEW_SCRIPT.format(root=str(ROOT), url=broker_url, port=self.port)],
                                     env=env, cwd=ROOT, stdout=open(self.log, "wb"), stderr=subprocess.STDOUT,
                                     preexec_fn=die_with_parent)
        self.url = f"http://127.0.0.1:{self.port}"
        wait_http(f"{self.url}/api/bench", self.proc, timeout=60)

    def bench(self) -> dict:
        return get(f"{self.url}/api/bench")

    def wait_devices(self, count: int, timeout: float) -> float:
        """Seconds until the view lists ``count`` devices (raises on timeout)."""
        start = time.monotonic()
        seen = 0
        while time.monotonic() - start < timeout:
            seen = self.bench()["devices"]
            if seen >= count:
                return time.monotonic() - start
            time.sleep(0.2)  # a synchronous caller polling the view's API
        raise TimeoutError(f"the view lists {seen} of {count} devices after {timeout} s")

    def stop(self) -> None:
        stop_app(self.proc)


class SparkplugHost:
    """A Sparkplug host application: subscribes to ``spBv1.0/#`` and decodes every payload's timestamp."""

    def __init__(self, port: int):
        import paho.mqtt.client as mqtt

        from app.sparkplug import Payload

        self._payload = Payload
        self.received = 0
        self.births = 0
        self.latency: list[float] = []
        self.lock = threading.Lock()
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=f"bench-host-{os.getpid()}")
        self.client.on_connect = lambda c, *_: c.subscribe("spBv1.0/#", qos=0)
        self.client.on_message = self._on_message
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()

    def _on_message(self, _client, _userdata, message) -> None:
        now = time.time()
        kind = message.topic.split("/")[2] if message.topic.count("/") >= 3 else ""
        with self.lock:
            self.received += 1
            if kind in ("NBIRTH", "DBIRTH"):
                self.births += 1
            if kind == "DDATA":
                payload = self._payload()
                try:
                    payload.ParseFromString(message.payload)
                except Exception:  # noqa: BLE001 - a foreign payload on the broker: not ours to measure
                    return
                if payload.timestamp:
                    self.latency.append(now - payload.timestamp / 1000)

    def take(self) -> tuple[int, list[float]]:
        with self.lock:
            latency, self.latency = self.latency, []
            return self.received, latency

    def stop(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


class Probe:
    """A subscriber on one broker for the state messages of one site: their publish-to-here latency."""

    def __init__(self, port: int, site: str):
        import paho.mqtt.client as mqtt

        self.latency: list[float] = []
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=f"bench-probe-{site}-{os.getpid()}")
        self.client.on_connect = lambda c, *_: c.subscribe(f"commission/{site}/+/state", qos=0)
        self.client.on_message = self._on_message
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()

    def _on_message(self, _client, _userdata, message) -> None:
        if message.retain:
            return
        try:
            sent = json.loads(message.payload).get("time")
        except ValueError:
            return
        if isinstance(sent, int | float):
            self.latency.append(time.time() - sent)

    def stop(self) -> None:
        self.client.loop_stop()
        self.client.disconnect()


def start_instances(folder: Path, broker: Broker, site: str, first: int, count: int, devices: int) -> list:
    procs = []
    for i in range(first, first + count):
        head = f'[mqtt]\nurl = "{broker.url}"\nsite = "{site}"\nsparkplug = true\n'
        plant = folder / f"cabinet-{i}.toml"
        plant.write_text(scale_plant_text(devices, name=f"cabinet-{i}", head=head, prefix=f"c{i}-"))
        port = free_port()
        env_dir = folder / f"cabinet-{i}"
        env_dir.mkdir(exist_ok=True)
        os.environ["COMMISSION_DATA_DIR"] = str(env_dir / "data")
        proc = start_app(plant, port, env_dir / "app.log")
        proc.api = f"http://127.0.0.1:{port}"  # type: ignore[attr-defined]
        procs.append(proc)
    for proc in procs:
        wait_http(f"{proc.api}/api/devices", proc, timeout=180)
    return procs


def phase(n: int, instances: list, view: View, host: SparkplugHost, broker: Broker, seconds: float) -> dict:
    view.bench()  # the latencies so far (the retained burst of the start) are dropped
    host.take()
    pids = [p.pid for p in instances]
    before = {"view": cpu_s(view.proc.pid), "broker": cpu_s(broker.proc.pid), "inst": sum(cpu_s(p) for p in pids)}
    received0, host0 = view.bench()["received"], host.take()[0]
    loads = [os.getloadavg()[0]]
    t0 = time.monotonic()
    latencies: list[float] = []
    host_latencies: list[float] = []
    while time.monotonic() - t0 < seconds:
        time.sleep(min(2.0, max(0.0, seconds - (time.monotonic() - t0))))  # the view's list is bounded: taken every 2 s
        latencies += view.bench()["latency"]
        host_latencies += host.take()[1]
    spent = time.monotonic() - t0
    after = view.bench()
    latencies += after["latency"]
    host_received, more = host.take()
    host_latencies += more
    loads.append(os.getloadavg()[0])
    return {"n": n, "devices": after["devices"], "msgs_s": (after["received"] - received0) / spent,
            "host_msgs_s": (host_received - host0) / spent,
            "p50_ms": 1000 * pct(latencies, 0.5), "p95_ms": 1000 * pct(latencies, 0.95),
            "host_p95_ms": 1000 * pct(host_latencies, 0.95),
            "view_cpu": 100 * (cpu_s(view.proc.pid) - before["view"]) / spent, "view_rss": rss_mb(view.proc.pid),
            "broker_cpu": 100 * (cpu_s(broker.proc.pid) - before["broker"]) / spent, "broker_rss": rss_mb(broker.proc.pid),
            "inst_cpu": 100 * (sum(cpu_s(p) for p in pids) - before["inst"]) / spent / len(pids),
            "inst_rss": statistics.fmean(rss_mb(p) for p in pids), "load": loads}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--instances", default="5,10", help="instances per phase (each phase adds to the last)")
    parser.add_argument("--full", action="store_true", help="5, 10, 25 and 50 instances (a thousand devices)")
    parser.add_argument("--devices", type=int, default=20, help="simulated devices per instance")
    parser.add_argument("--seconds", type=float, default=20.0, help="measuring time per phase")
    parser.add_argument("--settle", type=float, default=10.0, help="seconds after every device is in the view")
    parser.add_argument("--no-bridge", action="store_true", help="leave out the bridged broker and the cold start")
    parser.add_argument("--bridge-instances", type=int, default=2, help="instances on the bridged hall broker")
    args = parser.parse_args()
    steps = [5, 10, 25, 50] if args.full else [int(x) for x in args.instances.split(",")]
    print(f"instances {', '.join(map(str, steps))} of {args.devices} simulated devices each (one process each, "
          f"Sparkplug B on), one Mosquitto, one view, one Sparkplug host; {args.seconds:g} s a phase; {load()}", flush=True)
    results: list[dict] = []
    instances: list = []
    extra: list = []
    brokers: list[Broker] = []
    views: list[View] = []
    host = None
    with tempfile.TemporaryDirectory(prefix="site-scale-") as name:
        folder = Path(name)
        try:
            site = Broker(folder, "site")
            brokers.append(site)
            view = View(folder, site.url)
            views.append(view)
            host = SparkplugHost(site.port)
            for n in steps:
                t_start = time.monotonic()
                instances += start_instances(folder, site, "hall-1", len(instances), n - len(instances), args.devices)
                try:
                    took = view.wait_devices(n * args.devices, timeout=300)
                except TimeoutError as exc:
                    print(f"N={n}: {exc}; the machine holds no more instances", flush=True)
                    break
                print(f"N={n}: every device in the view {time.monotonic() - t_start:.0f} s after the new instances were "
                      f"started ({took:.1f} s after they answered); {load()}", flush=True)
                time.sleep(args.settle)
                r = phase(n, instances, view, host, site, args.seconds)
                results.append(r)
                print(f"N={n:>2}  devices={r['devices']:>4}  view: {r['msgs_s']:6.0f} msg/s, latency p50 {r['p50_ms']:6.1f} ms, "
                      f"p95 {r['p95_ms']:6.1f} ms, CPU {r['view_cpu']:5.1f} %, RSS {r['view_rss']:5.0f} MB; "
                      f"Sparkplug host {r['host_msgs_s']:5.0f} msg/s, p95 {r['host_p95_ms']:6.1f} ms; "
                      f"broker CPU {r['broker_cpu']:4.1f} %, RSS {r['broker_rss']:4.1f} MB; per instance CPU "
                      f"{r['inst_cpu']:4.1f} %, RSS {r['inst_rss']:4.0f} MB; load {r['load'][0]:.2f} -> {r['load'][1]:.2f}",
                      flush=True)
            if not args.no_bridge and results:
                bridge(folder, args, site, brokers, views, extra, len(instances))
        finally:
            if host is not None:
                host.stop()
            for proc in instances + extra:
                stop_app(proc)
            for v in views:
                v.stop()
            for b in brokers:
                b.stop()
    print("instances  devices  view msg/s  p50 ms  p95 ms  view CPU %  view RSS MB  broker CPU %  instance CPU %  load")
    for r in results:
        print(f"{r['n']:9d}  {r['devices']:7d}  {r['msgs_s']:10.0f}  {r['p50_ms']:6.1f}  {r['p95_ms']:6.1f}  {r['view_cpu']:10.1f}  "
              f"{r['view_rss']:11.0f}  {r['broker_cpu']:12.1f}  {r['inst_cpu']:14.1f}  {r['load'][0]:.2f}-{r['load'][1]:.2f}")
    print(f"site_view_latency_p95_ms: {results[-1]['p95_ms'] if results else float('nan'):.1f}")


def bridge(folder: Path, args, site: Broker, brokers: list, views: list, extra: list, running: int) -> None:
    """The hall broker bridged to the site broker, a view on a warm broker, and a cold site broker."""
    hall = Broker(folder, "hall", bridge_to=site.port)
    brokers.append(hall)
    total = (running + args.bridge_instances) * args.devices
    probe = Probe(site.port, "hall-2")
    try:
        t0 = time.monotonic()
        extra += start_instances(folder, hall, "hall-2", running, args.bridge_instances, args.devices)
        views[0].wait_devices(total, timeout=180)
        print(f"bridge: {args.bridge_instances} instances on the hall broker (bridged to the site broker): every one of "
              f"their {args.bridge_instances * args.devices} devices in the site's view {time.monotonic() - t0:.0f} s "
              f"after they were started; {load()}", flush=True)
        probe.latency.clear()
        time.sleep(args.seconds)
        lat = list(probe.latency)
        print(f"bridge: {len(lat) / args.seconds:.0f} state messages/s of the hall's devices on the site broker, "
              f"publish-to-site-broker latency p50 {1000 * pct(lat, 0.5):.1f} ms, p95 {1000 * pct(lat, 0.95):.1f} ms", flush=True)
    finally:
        probe.stop()
    t0 = time.monotonic()
    late = View(folder, site.url, "late-view")
    views.append(late)
    took = late.wait_devices(total, timeout=120)
    print(f"warm broker: a view started now lists all {total} devices {time.monotonic() - t0:.1f} s after its start "
          f"({took:.1f} s after it answered; from the retained messages)", flush=True)
    late.stop()
    views.remove(late)
    site.stop()
    brokers.remove(site)
    t0 = time.monotonic()
    cold = Broker(folder, "site-cold", port=site.port)
    brokers.append(cold)
    fresh = View(folder, cold.url, "cold-view")
    views.append(fresh)
    try:
        took = fresh.wait_devices(total, timeout=180)
        print(f"cold broker: the site broker restarted empty (no persistence); a new view lists all {total} devices "
              f"{time.monotonic() - t0:.1f} s after the restart: the instances and the bridge reconnected and sent "
              f"every retained state again; {load()}", flush=True)
    except TimeoutError as exc:
        print(f"cold broker: {exc}", flush=True)


if __name__ == "__main__":
    main()
