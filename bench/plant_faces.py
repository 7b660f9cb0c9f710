"""The demo plant at 10x its real publishing rate through its standard faces: Sparkplug B on a Mosquitto of
its own and OPC UA subscriptions; prints messages/s, publish-to-subscriber latency p95 and the instance's CPU.

The instance runs as ``commission`` in a process of its own (its CPU is read from /proc), with
``[mqtt] sparkplug = true, rate = 20`` (the default rate is 2 a second per device) and ``[opcua] rate = 100``
(the default 10), and this process is the subscriber: a Sparkplug host on ``spBv1.0/#`` and an asyncua
client subscribed to every live value of every device at a 10 ms publishing interval.

Latency: Sparkplug, from the payload's timestamp (set by the node as it publishes, in ms) to its arrival
here; OPC UA, from the value's server timestamp (set as it is written into the address space) to the
notification's arrival. Both clocks are this machine's. Last line: ``sparkplug_latency_p95_ms: X``.

    python3 bench/plant_faces.py [--seconds 20]
"""

from __future__ import annotations

import argparse
import asyncio
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from app.sparkplug import Payload  # noqa: E402 - after the path

MOSQUITTO = "/usr/sbin/mosquitto"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def demo_plant(broker_port: int, opcua_port: int) -> str:
    text = (ROOT / "plants" / "demo.toml").read_text()
    text = re.sub(r"socket://127\.0\.0\.1:\d+", lambda m: f"socket://127.0.0.1:{free_port()}", text)
    text = re.sub(r'(type = "logited-tcp"\nhost = "127\.0\.0\.1"\nport = )\d+', lambda m: f"{m.group(1)}{free_port()}", text)
    text = re.sub(r'channel = "(demo-can\d)"', lambda m: f'channel = "{m.group(1)}-bench{os.getpid()}"', text)
    return text.replace('name = "demo"', f'name = "demo"\n\n[mqtt]\nurl = "mqtt://127.0.0.1:{broker_port}"\nsite = "bench"\n'
                        f'sparkplug = true\nrate = 20\n\n[opcua]\nendpoint = "opc.tcp://127.0.0.1:{opcua_port}"\nrate = 100\n', 1)


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def p95(values: list[float]) -> float:
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(0.95 * len(ordered)))]


async def wait_port(port: int, timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            _r, w = await asyncio.open_connection("127.0.0.1", port)
            w.close()
            return
        except OSError:
            await asyncio.sleep(0.1)
    raise TimeoutError(f"nothing listens on {port}")


async def bench(seconds: float) -> None:
    import aiomqtt
    from asyncua import Client

    folder = Path(tempfile.mkdtemp(prefix="plant-faces-"))
    broker_port, opcua_port = free_port(), free_port()
    (folder / "mosquitto.conf").write_text(f"listener {broker_port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
    broker = subprocess.Popen([MOSQUITTO, "-c", str(folder / "mosquitto.conf")], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    (folder / "plant.toml").write_text(demo_plant(broker_port, opcua_port))
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "NICEGUI_STORAGE_PATH": str(folder / "storage")}
    with open(folder / "instance.log", "wb") as log:
        instance = subprocess.Popen([sys.executable, "-m", "app.cli", "--plant", str(folder / "plant.toml"), "--port", str(free_port()),
                                     "--data-dir", str(folder / "data")], cwd=ROOT, env=env, stdout=log, stderr=subprocess.STDOUT)
    spb_latency: list[float] = []
    ua_latency: list[float] = []
    counts = {"sparkplug": 0, "opcua": 0}
    measuring = False
    try:
        await wait_port(broker_port, 10)
        await wait_port(opcua_port, 60)

        class Changes:
            def datachange_notification(self, node, value, data):
                if measuring:
                    counts["opcua"] += 1
                    stamp = data.monitored_item.Value.ServerTimestamp
                    if stamp is not None:
                        ua_latency.append((datetime.now(timezone.utc) - stamp.replace(tzinfo=timezone.utc)).total_seconds() * 1000)

        async with aiomqtt.Client("127.0.0.1", broker_port) as host:
            await host.subscribe("spBv1.0/#")

            async def read_sparkplug():
                async for message in host.messages:
                    if not measuring or "/STATE/" in str(message.topic):
                        continue
                    arrived = time.time() * 1000
                    payload = Payload()
                    payload.ParseFromString(bytes(message.payload))
                    counts["sparkplug"] += 1
                    if payload.timestamp:
                        spb_latency.append(arrived - payload.timestamp)

            reader = asyncio.create_task(read_sparkplug())
            client = Client(f"opc.tcp://127.0.0.1:{opcua_port}", timeout=10)
            await client.connect()
            try:
                di = await client.get_namespace_index("http://opcfoundation.org/UA/DI/")
                await asyncio.sleep(5)  # every device answers and its values are in the address space
                device_set = await client.nodes.objects.get_child(f"{di}:DeviceSet")
                variables = []
                for device in await device_set.get_children():
                    variables += await (await device.get_child(f"{di}:ParameterSet")).get_children()
                subscription = await client.create_subscription(10, Changes())
                await subscription.subscribe_data_change(variables, sampling_interval=0)
                await asyncio.sleep(1)
                cpu0, t0 = cpu_seconds(instance.pid), time.monotonic()
                measuring = True
                await asyncio.sleep(seconds)
                measuring = False
                cpu1, t1 = cpu_seconds(instance.pid), time.monotonic()
            finally:
                reader.cancel()
                await client.disconnect()
        elapsed = t1 - t0
        print(f"demo plant, {seconds:g} s, Sparkplug rate 20/s per device (10x), OPC UA rate 100/s (10x), "
              f"{len(variables)} OPC UA values subscribed")
        print(f"sparkplug_messages_per_s: {counts['sparkplug'] / elapsed:.1f}")
        print(f"opcua_notifications_per_s: {counts['opcua'] / elapsed:.1f}")
        print(f"opcua_latency_p95_ms: {p95(ua_latency):.1f}")
        print(f"instance_cpu_percent: {100 * (cpu1 - cpu0) / elapsed:.1f} (one core = 100)")
        print(f"sparkplug_latency_p95_ms: {p95(spb_latency):.1f}")
    finally:
        instance.send_signal(signal.SIGTERM)
        try:
            instance.wait(timeout=10)
        except subprocess.TimeoutExpired:
            instance.kill()
        broker.terminate()
        broker.wait(timeout=5)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    asyncio.run(bench(parser.parse_args().seconds))


if __name__ == "__main__":
    main()
