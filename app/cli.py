"""``commission``: the GUI on a plant file, or the simulated devices of a plant alone."""

from __future__ import annotations

import argparse
import asyncio
import logging
import signal
import sys
from pathlib import Path

from app.plant import DEMO_PLANT, PlantError, load_plant

EPILOG = """\
examples:
  commission                          GUI on the built-in simulated demo plant
  commission --plant site.toml        GUI on the real buses of site.toml (buses with
                                      simulate = true get their simulated devices in-process)
  commission sim --plant site.toml    only the simulated devices of site.toml, on the
                                      endpoints the file names (e.g. socket://127.0.0.1:5020),
                                      for a GUI or another Modbus master in another process
  commission --plant site.toml --no-sim
                                      GUI only, talking to devices simulated elsewhere

The plant file (TOML) lists [[bus]] and [[device]] tables; see README.md.
"""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="commission",
        description="Browser-based commissioning tool for field devices on CAN, Modbus RTU and serial lines.",
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--plant", type=Path, default=None, help="plant file (default: the built-in demo plant)")
    parser.add_argument("--host", default="127.0.0.1", help="address to serve the GUI on (default: 127.0.0.1, loopback only)")
    parser.add_argument("--port", type=int, default=8080, help="HTTP port of the GUI (default: 8080)")
    parser.add_argument("--no-sim", action="store_true", help="do not start simulated devices, even for buses with simulate = true")
    parser.add_argument("--show", action="store_true", help="open a browser window")
    parser.add_argument("-v", "--verbose", action="store_true", help="log more")
    sub = parser.add_subparsers(dest="command")
    sim = sub.add_parser("sim", help="run only the simulated devices of a plant file")
    sim.add_argument("--plant", type=Path, default=None, help="plant file (default: the built-in demo plant)")
    sim.add_argument("--all", action="store_true", help="simulate every bus, not only those with simulate = true")
    return parser


def _load(path: Path | None):
    try:
        return load_plant(path or DEMO_PLANT)
    except PlantError as exc:
        print(f"commission: {exc}", file=sys.stderr)
        raise SystemExit(2) from None


def _quiet_libraries(verbose: bool) -> None:
    logging.basicConfig(level=logging.DEBUG if verbose else logging.INFO, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    logging.getLogger("pymodbus").setLevel(logging.DEBUG if verbose else logging.CRITICAL)
    logging.getLogger("can").setLevel(logging.INFO if verbose else logging.WARNING)


def run_sim(args) -> int:
    from app.runtime import SimulatedPlant

    plant = _load(args.plant)
    sim = SimulatedPlant(plant, only_flagged=not args.all)
    if not sim.servers:
        print("commission sim: the plant file has no bus with simulate = true (use --all to simulate every bus)", file=sys.stderr)
        return 2

    async def main() -> None:
        errors = await sim.start()
        if errors:
            for error in errors:
                print(f"commission sim: {error}", file=sys.stderr)
            await sim.stop()
            raise SystemExit(1)
        for bus in plant.buses.values():
            if bus.simulated or args.all:
                devices = plant.devices_on(bus.name) + [d for d in plant.sim_devices.values() if d.bus == bus.name]
                names = ", ".join(d.name for d in devices)
                print(f"simulating {bus.name} ({bus.type}) on {bus.endpoint}: {names}", flush=True)
                if bus.options.get("interface") == "virtual":
                    print(
                        f"  note: {bus.name} uses the virtual CAN interface, which other processes cannot reach; "
                        'use interface = "udp_multicast" (channel "239.74.163.2") to share it across processes',
                        file=sys.stderr, flush=True,
                    )
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, stop.set)
        await stop.wait()
        await sim.stop()

    asyncio.run(main())
    return 0


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    _quiet_libraries(args.verbose)
    if args.command == "sim":
        return run_sim(args)

    from nicegui import ui

    from app import web
    from app.runtime import Runtime

    plant = _load(args.plant)
    runtime = Runtime(plant, simulate=not args.no_sim)
    web.register(runtime)
    print(f"commission: plant '{plant.name}' ({len(plant.devices)} devices) at http://{args.host}:{args.port}/", flush=True)
    ui.run(
        host=args.host,
        port=args.port,
        title="commission",
        show=args.show,
        reload=False,
        show_welcome_message=False,
        favicon="🔧",
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
