"""What the headless commands share: loading a plant file, starting its runtime without the GUI,
checking the simulated devices' ports, and the name a command-line user is audited under.

Kept apart from :mod:`app.cli` so the commands' own modules (backup, restore, report, checkout,
apply, export) import it without importing the command line.
"""

from __future__ import annotations

import asyncio
import socket
import sys
from pathlib import Path
from urllib.parse import urlparse

from app.plant import DEMO_PLANT, PlantError, load_plant


def _load(path: Path | None):
    try:
        return load_plant(path or DEMO_PLANT)
    except PlantError as exc:
        print(f"commission: {exc}", file=sys.stderr)
        raise SystemExit(2) from None


def _bindable(host: str, port: int) -> bool:
    """Whether a TCP server could listen on ``host:port`` now (SO_REUSEADDR, as asyncio and uvicorn bind)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError:
            return False
    return True


def _simulated_endpoints(plant, every: bool = False) -> list[tuple[str, str, int]]:
    """``(bus, host, port)`` of each TCP port the simulated devices of ``plant`` listen on."""
    endpoints = []
    for bus in plant.buses.values():
        if not (bus.simulated or every):
            continue
        if bus.type == "logited-tcp":
            endpoints.append((bus.name, bus.options["host"], bus.options["port"]))
        elif isinstance(bus.options.get("port"), str) and bus.options["port"].startswith("socket://"):
            url = urlparse(bus.options["port"])
            if url.port:
                endpoints.append((bus.name, url.hostname or "127.0.0.1", url.port))
    return endpoints


def _refuse_taken_ports(plant, program: str = "commission", every: bool = False) -> bool:
    """Say which simulated ports are taken (another copy of the plant?); True when the start must stop.

    Polling whatever owns such a port as if it were this plant's twin would be worse than not starting.
    """
    taken = [(bus, host, port) for bus, host, port in _simulated_endpoints(plant, every) if not _bindable(host, port)]
    for bus, host, port in taken:
        print(f"{program}: the simulated bus '{bus}' cannot listen on {host}:{port}: the port is taken "
              "(another copy of this plant or another program); stop it, or give the bus another port in the plant file",
              file=sys.stderr)
    return bool(taken)


async def _headless(args, work) -> int:
    """Start the plant without GUI, wait until its devices answer, run ``work(runtime)``."""
    from app.runtime import Runtime
    from app.users import default_data_dir

    plant = _load(args.plant)
    if not args.no_sim and _refuse_taken_ports(plant):
        return 2
    names = getattr(args, "device", None)
    names = [names] if isinstance(names, str) else (names or list(plant.devices))
    for name in names:
        if name not in plant.devices:
            print(f"commission: the plant has no device named {name!r} (devices: {', '.join(plant.devices)})", file=sys.stderr)
            return 2
    runtime = Runtime(plant, simulate=not args.no_sim, data_dir=args.data_dir or default_data_dir())
    await runtime.start()
    try:
        print(f"waiting up to 15 s for {len(names)} device(s) to answer ...", flush=True)
        loop = asyncio.get_running_loop()
        end = loop.time() + 15
        while loop.time() < end and any(runtime.store.devices[n].status != "online" for n in names):
            await asyncio.sleep(0.2)
        return await work(runtime, names)
    finally:
        await runtime.stop()


def _cli_user() -> str:
    """Who ran a headless backup or restore, for the audit log."""
    import getpass

    try:
        return f"cli:{getpass.getuser()}"
    except (KeyError, OSError):
        return "cli"
