"""Plants of any size for the scale benchmarks and tests: the demo's families in the mix of a real site.

A site of a hundred devices, as ``scale_plant_text(100)`` builds it:

- 64 HD-Locks on four Modbus RTU lines of 16 at 19200 baud 8E1 (RS485, the twins answer after the
  wire time of each telegram: ``wire_delay``);
- 8 HD-Locks in CAN mode on one CAN bus (250 kbit/s, extended device IDs);
- 8 CAN-M3IO I/O modules on one CAN bus (500 kbit/s, SW1 0x01.., served idle: DigOut every 500 ms);
- 4 Electrak HD networks of two actuators, each on its CAN bus of its own (its IDs are fixed);
- 4 Ewellix SCUs, each on its point-to-point RS232 line (38400 baud);
- 12 Bauer MO 64 barriers on two shared RS485 lines of six (LogiTed, token passing).

Smaller and larger plants keep the same shares (largest remainder, at least one device of each family
from six devices on). Every simulated endpoint is on a free port; ``split=True`` puts the CAN buses on
``udp_multicast`` so that ``commission sim`` and ``commission --no-sim`` share them from two processes.

    python bench/scale_plants.py 100 > plant.toml      # the file, to run by hand
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from liveapp import ELECTRAK_ACTUATORS, across_processes, bus, device, free_port, plant_text  # noqa: E402

# the share of each family in a site of 100 devices
MIX = (("hdlock-modbus", 64), ("hdlock-can", 8), ("m3io", 8), ("electrak", 4), ("scu", 4), ("mo64", 12))
LOCKS_PER_LINE = 16  # an RS485 line of HD-Locks, as a site wires them
MAX_MODBUS_LINES = 4
GATES_PER_LINE = 6
BAUD = 19200


def family_counts(n: int) -> dict[str, int]:
    """How many devices of each family a plant of ``n`` devices has (sums to ``n``)."""
    total = sum(share for _, share in MIX)
    floor = 1 if n >= len(MIX) else 0
    exact = {name: n * share / total for name, share in MIX}
    counts = {name: max(floor, int(value)) for name, value in exact.items()}
    while sum(counts.values()) > n:  # the floor of one each took more than the small families' share
        counts[max(counts, key=lambda k: counts[k])] -= 1
    rest = n - sum(counts.values())
    for name in sorted(exact, key=lambda k: exact[k] - int(exact[k]), reverse=True)[:rest]:
        counts[name] += 1
    return counts


def _spread(count: int, groups: int) -> list[int]:
    """``count`` items in ``groups`` groups as even as can be."""
    return [count // groups + (1 if i < count % groups else 0) for i in range(groups)] if groups else []


def scale_plant_text(n: int, name: str | None = None, split: bool = False, wire_delay: bool = True,
                     modbus_poll_period: float = 0.5, head: str = "", counts: dict[str, int] | None = None, prefix: str = "") -> str:
    """The plant file of ``n`` devices (see the module text); ``head``: lines before the buses (a ``[mqtt]``
    table); ``counts``: devices per family instead of the mix (the families left out have none); ``prefix``:
    before every device name (device names are unique within a site, docs/mqtt.md). Channel
    names carry a free port, so two plants made here never share a CAN bus."""
    counts = {name: 0 for name, _ in MIX} | counts if counts is not None else family_counts(n)
    tag = free_port()
    buses: list[str] = []
    locks = counts["hdlock-modbus"]
    lines = max(1, min(MAX_MODBUS_LINES, math.ceil(locks / LOCKS_PER_LINE))) if locks else 0
    for line, on_line in enumerate(_spread(locks, lines), start=1):
        bus_name = f"rs485-{line}"
        buses.append(bus(bus_name, "modbus-rtu",
                         *(device(f"{prefix}door-{line}-{a:02d}", "hdlock", bus_name, address=a, serial=660000 + 100 * line + a)
                           for a in range(1, on_line + 1)),
                         port=f"socket://127.0.0.1:{free_port()}", baudrate=BAUD, parity="E", timeout=0.5, retries=1,
                         poll_period=modbus_poll_period, wire_delay=wire_delay or None, simulate=True))
    if counts["hdlock-can"]:
        buses.append(bus("can-locks", "can",
                         *(device(f"{prefix}gate-{i:02d}", "hdlock", "can-locks", device_id=661000 + i)
                           for i in range(1, counts["hdlock-can"] + 1)),
                         interface="virtual", channel=f"scale-{tag}-locks", bitrate=250000, poll_period=2.0, simulate=True))
    if counts["m3io"]:
        buses.append(bus("can-io", "can",
                         *(device(f"{prefix}heater-{i:02d}", "m3io", "can-io", variant="HM", sw1=i, master="always")
                           for i in range(1, counts["m3io"] + 1)),
                         interface="virtual", channel=f"scale-{tag}-io", bitrate=500000, simulate=True))
    for i in range(1, counts["electrak"] + 1):
        buses.append(bus(f"can-lift-{i}", "can", device(f"{prefix}lift-{i:02d}", "electrak", f"can-lift-{i}",
                                                        actuators=list(ELECTRAK_ACTUATORS)),
                         interface="virtual", channel=f"scale-{tag}-lift{i}", bitrate=500000, simulate=True))
    for i in range(1, counts["scu"] + 1):
        buses.append(bus(f"rs232-{i}", "serial",
                         device(f"{prefix}table-{i:02d}", "scu", f"rs232-{i}", actuators=[{"counts_per_mm": 10}, {"stroke_mm": 300}]),
                         port=f"socket://127.0.0.1:{free_port()}", baudrate=38400, timeout=0.3, poll_period=0.2, simulate=True))
    gates = counts["mo64"]
    gate_lines = math.ceil(gates / GATES_PER_LINE) if gates else 0
    for line, on_line in enumerate(_spread(gates, gate_lines), start=1):
        bus_name = f"gates-{line}"
        buses.append(bus(bus_name, "logited-rs485",
                         *(device(f"{prefix}barrier-{line}-{a:02d}", "mo64", bus_name, address=16 + a) for a in range(on_line)),
                         port=f"socket://127.0.0.1:{free_port()}", master_address=0, shared=True, next_master=1,
                         poll_period=1.0, simulate=True))
    text = plant_text(*buses, name=name or f"scale-{n}", head=head)
    return across_processes(text) if split else text


def tcp_ports(text: str) -> list[int]:
    """The localhost TCP ports of a plant file's simulated endpoints (``socket://127.0.0.1:PORT``)."""
    import re

    return [int(p) for p in re.findall(r"socket://127\.0\.0\.1:(\d+)", text)]


def wait_listening(ports: list[int], proc=None, timeout: float = 60.0) -> None:
    """Wait until every port of ``ports`` takes a connection (the twins of ``commission sim`` listen)."""
    import socket
    import time

    end = time.monotonic() + timeout
    for port in ports:
        while True:
            if proc is not None and proc.poll() is not None:
                raise RuntimeError(f"the twins' process exited with {proc.returncode}")
            try:
                with socket.create_connection(("127.0.0.1", port), timeout=1):
                    break
            except OSError:
                if time.monotonic() > end:
                    raise TimeoutError(f"nothing listens on port {port} within {timeout} s") from None
                time.sleep(0.1)  # a synchronous caller polling a port: checked again each round


def bus_of_devices(text: str) -> dict[str, str]:
    """device name -> its bus, read back from a plant file's text (for the reports)."""
    import tomllib

    return {d["name"]: d["bus"] for d in tomllib.loads(text).get("device", [])}


if __name__ == "__main__":
    print(scale_plant_text(int(sys.argv[1]) if len(sys.argv) > 1 else 100), end="")
