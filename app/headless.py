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

from app import cli_lang
from app.cli_lang import _
from app.host import TerminalKeys
from app.i18n import N_
from app.message import said
from app.plant import DEMO_PLANT, PlantError, load_plant


def write_options(parser) -> None:
    """``--yes`` and ``--accept-risk`` of a command that writes devices (restore, apply): written without asking,
    and the risky values confirmed by name, as the GUI asks them."""
    parser.add_argument("--yes", action="store_true", help=_("write without asking (the diffs are printed anyway); "
                        "values that need a confirmation are still refused unless named with --accept-risk"))
    parser.add_argument("--accept-risk", action="append", default=[], metavar="NAME",
                        help=_("confirm a risky value of parameter NAME (repeatable), as the GUI's confirmation does"))


def load_plant_or_exit(path: Path | None):
    """The plant file at ``path`` (the demo plant without one); a file that cannot be used ends the command (exit 2)."""
    try:
        return load_plant(path or DEMO_PLANT)
    except PlantError as exc:
        print(f"commission: {said(exc, cli_lang.lang())}", file=sys.stderr)
        raise SystemExit(2) from None


def bindable(host: str, port: int) -> bool:
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


def refuse_taken_ports(plant, program: str = "commission", every: bool = False) -> bool:
    """Say which simulated ports are taken (another copy of the plant?); True when the start must stop.

    Polling whatever owns such a port as if it were this plant's twin would be worse than not starting.
    """
    taken = [(bus, host, port) for bus, host, port in _simulated_endpoints(plant, every) if not bindable(host, port)]
    for bus, host, port in taken:
        print(_("{program}: the simulated bus '{bus}' cannot listen on {host}:{port}: the port is taken "
                "(another copy of this plant or another program); stop it, or give the bus another port in the plant file").format(
                    program=program, bus=bus, host=host, port=port), file=sys.stderr)
    return bool(taken)


ONLINE_WAIT_S = 15.0  # how long a headless run waits for its devices to answer


async def run_headless(args, work, answers_needed=None) -> int:
    """Start the plant without GUI, wait until its devices answer, run ``work(runtime, names)``.

    ``answers_needed(runtime, name)`` says whether the work needs device ``name`` to answer (default: every one):
    a device the work will skip anyway is not waited for (an M3IO that nobody serves stays silent, and in simple
    mode it has nothing to back up)."""
    from app.runtime import Runtime
    from app.users import default_data_dir

    plant = load_plant_or_exit(args.plant)
    if not args.no_sim and refuse_taken_ports(plant):
        return 2
    names = args.device  # backup: a list (empty: every device); restore: one name; apply: its --devices
    names = [names] if isinstance(names, str) else (names or list(plant.devices))
    for name in names:
        if name not in plant.devices:
            print(_("commission: the plant has no device named {name} (devices: {devices})").format(
                name=repr(name), devices=", ".join(plant.devices)), file=sys.stderr)
            return 2
    runtime = Runtime(plant, simulate=not args.no_sim, data_dir=args.data_dir or default_data_dir())
    await runtime.start()
    try:
        awaited = [n for n in names if answers_needed is None or answers_needed(runtime, n)]
        if awaited:
            print(_("waiting up to {seconds:g} s for {n} device(s) to answer ...").format(seconds=ONLINE_WAIT_S, n=len(awaited)),
                  flush=True)
        loop = asyncio.get_running_loop()
        end = loop.time() + ONLINE_WAIT_S
        while loop.time() < end and any(runtime.store.devices[n].status != "online" for n in awaited):
            await asyncio.sleep(0.2)
        return await work(runtime, names)
    finally:
        await runtime.stop()


def cli_user() -> str:
    """Who ran a headless backup or restore, for the audit log."""
    import getpass

    try:
        return f"cli:{getpass.getuser()}"
    except (KeyError, OSError):
        return "cli"


# -- a person at a terminal: the questions of a checkout on real equipment, and a dead-man of its own --------
HELD_GAP_S = 0.7  # two presses of SPACE this close together: the key is held (the terminal's auto-repeat)
NO_KEYS = ("n", "N")
HOLD_WORDS = N_("hold SPACE to answer yes, and keep holding it while the step runs: releasing it stops what moves "
                "within 0.5 s (dead-man); n = no")


def simulated(runtime, device: str) -> bool:
    """Whether ``device`` is a twin of this run's simulated plant (nothing real moves when it does)."""
    return device in runtime.twins


def terminal_present(stream=None) -> bool:
    """Whether a person can answer on this process's terminal (standard input is one)."""
    stream = sys.stdin if stream is None else stream
    try:
        return stream is not None and stream.isatty()
    except (AttributeError, ValueError, OSError):
        return False


class TtyKeys(TerminalKeys):
    """Single key presses from the terminal on standard input, read in a thread of their own and handed to
    ``on_key`` in the event loop (POSIX: cbreak mode, restored at :meth:`stop`; Windows: the console's key
    buffer through msvcrt): :class:`app.host.TerminalKeys`."""


class TerminalPerson:
    """The person running a checkout of real equipment at a terminal.

    Every question is theirs (``--answer yes`` answers for simulated devices only): yes is SPACE held, no is
    ``n``. Each press of SPACE confirms to the worker's dead-man supervisor that the person is there
    (``worker.heartbeat(session)``), so motion and mains outputs of the run's session are kept only while the
    key is held and stop within the dead-man bound once it is released (the run itself does not beat).
    ``keys``: the source of key presses (:class:`TtyKeys`, or a test's)."""

    def __init__(self, worker, session: str, keys, out=print, clock=None):
        import time

        self.worker, self.session, self.keys, self.out = worker, session, keys, out
        self.clock = clock or time.monotonic
        self.presses: asyncio.Queue[str] = asyncio.Queue()
        self.beats = 0

    def start(self) -> None:
        self.keys.start(self._key)

    def stop(self) -> None:
        self.keys.stop()

    def _key(self, key: str) -> None:
        if key == " ":
            self.beats += 1
            self.worker.heartbeat(self.session)  # the person is there: the key is held
        self.presses.put_nowait(key)

    async def ask(self, question: str) -> bool:
        while not self.presses.empty():  # presses before the question answer nothing
            self.presses.get_nowait()
        self.out(f"    ? {said(question, cli_lang.lang())}\n      ({_(HOLD_WORDS)})")
        last: float | None = None
        while True:
            key = await self.presses.get()
            if key in NO_KEYS:
                self.out(_("      -> no"))
                return False
            if key != " ":
                continue
            now = self.clock()
            if last is not None and now - last <= HELD_GAP_S:
                self.out(_("      -> yes (SPACE held: keep holding it while the step runs)"))
                return True
            last = now
