"""The app in a process of its own for the benchmarks: the demo plant on free ports, started,
waited for and measured from /proc. Standard library only (no pytest, no test folder), so the
benchmarks run after ``pip install -e .``; the browser benchmarks need playwright besides
(Debian's chromium, never a downloaded one).
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Iterable, Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEMO_PLANT = ROOT / "plants" / "demo.toml"
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking"]
LOGS: list[Path] = []  # the log of every app this process started (a failing test's report quotes what they logged)


# Ports for the simulated endpoints are taken below the kernel's ephemeral range (Linux: 32768-60999), where
# no outgoing connection is given one meanwhile, and from a block of their own per process: the suite runs
# up to ten test processes side by side (pytest-xdist's gw0..gw9; up to sixteen have a block of their own), a
# benchmark or a single run uses one of blocks 16-19. A port asked of the kernel (bind to port 0) and let go could
# be handed to another process's connection before the simulation binds it ("address already in use"); two
# processes sharing a block did so too (gw8 took gw0's block while there were eight blocks, 2026-11-29).
PORT_BLOCKS_FROM, PORT_BLOCK = 12000, 1000  # twenty blocks: 12000-31999
WORKER_BLOCKS = 16
_next_port: dict[int, int] = {}


def _block() -> int:
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if worker.startswith("gw") and worker[2:].isdigit():
        return int(worker[2:]) % WORKER_BLOCKS
    return WORKER_BLOCKS + os.getpid() % 4


def _free(kind: int, host: str) -> int:
    start = PORT_BLOCKS_FROM + _block() * PORT_BLOCK
    offset = _next_port.get(kind, 0)
    for _ in range(PORT_BLOCK):
        port = start + offset
        offset = (offset + 1) % PORT_BLOCK
        with socket.socket(socket.AF_INET, kind) as s:
            try:
                s.bind((host, port))
            except OSError:
                continue  # in use (by a test of this process that still runs, or another program)
        _next_port[kind] = offset
        return port
    with socket.socket(socket.AF_INET, kind) as s:  # the whole block in use: the kernel's choice
        s.bind((host, 0))
        return s.getsockname()[1]


def free_port() -> int:
    """A TCP port free on 127.0.0.1 now, from this process's own block (see PORT_BLOCKS_FROM)."""
    return _free(socket.SOCK_STREAM, "127.0.0.1")


def free_udp_port() -> int:
    """A UDP port free now, from this process's own block (UDP and TCP ports are separate)."""
    return _free(socket.SOCK_DGRAM, "")


def demo_plant_text(bus_port: int | None = None) -> str:
    """The demo plant file with every simulated TCP endpoint on a free port of its own (the RS485
    line on ``bus_port`` when given), so a benchmark never meets another program's ports."""
    text = DEMO_PLANT.read_text()
    if bus_port is not None:
        text = text.replace("socket://127.0.0.1:5020", f"socket://127.0.0.1:{bus_port}")
    text = re.sub(r"socket://127\.0\.0\.1:(?!%d\b)\d+" % (bus_port or 0), lambda m: f"socket://127.0.0.1:{free_port()}", text)
    return re.sub(r'(type = "logited-tcp"\nhost = "127\.0\.0\.1"\nport = )\d+', lambda m: f"{m.group(1)}{free_port()}", text)


# -- plant files from parts (tests/plants.py builds the usual buses from these) ---------------------

ELECTRAK_ACTUATORS = ({"model": "HD24", "gearing": "B026", "stroke_mm": 300},) * 2


def toml_value(value) -> str:
    """``value`` as a TOML literal: text quoted, true/false, numbers, arrays and inline tables."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + " }"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return repr(value)


def table(kind: str, **fields) -> str:
    """One ``[[kind]]`` entry: ``[[bus]]`` or ``[[device]]``."""
    return "".join([f"[[{kind}]]\n", *(f"{k} = {toml_value(v)}\n" for k, v in fields.items() if v is not None)])


def device(name: str, type: str, bus: str, **options) -> str:  # noqa: A002 - the plant file's key
    return table("device", name=name, type=type, bus=bus, **options)


def bus(name: str, type: str, *devices: str, **options) -> str:  # noqa: A002 - the plant file's key
    """A bus and the devices on it (each from :func:`device`, with its ``bus`` set to ``name``)."""
    return table("bus", name=name, type=type, **options) + "".join(devices)


def plant_text(*buses: str, name: str | None = "t", head: str = "") -> str:
    """A plant file of ``buses`` (``head``: lines before them, such as a ``[broker]`` table)."""
    return (f"name = {toml_value(name)}\n" if name is not None else "") + head + "".join(buses)



def across_processes(plant_text: str) -> str:
    """The same plant with its ``virtual`` CAN buses (one process only) on ``udp_multicast`` groups of
    their own, so ``commission sim`` in one process and the GUI in another share them."""
    counter = iter(range(1, 250))

    def group(match: re.Match) -> str:
        return f'interface = "udp_multicast"\nchannel = "239.74.{os.getpid() % 250}.{next(counter)}"\nport = {free_udp_port()}'

    return re.sub(r'interface = "virtual"\nchannel = "[^"]*"', group, plant_text)


def wait_http(url: str, proc: subprocess.Popen | None = None, timeout: float = 30.0,
              accept: tuple[int, ...] = (200,)) -> None:
    """Wait until ``url`` answers with a status of ``accept`` (raise if ``proc`` dies or ``timeout`` passes)."""
    end = time.monotonic() + timeout
    last: object = None
    while time.monotonic() < end:
        if proc is not None and proc.poll() is not None:
            log = getattr(proc, "log_file", None)
            tail = "\n".join(Path(log).read_text(errors="replace").splitlines()[-15:]) if log else ""
            raise RuntimeError(f"the app exited with {proc.returncode} before answering {url}\n{tail}")
        try:
            with urllib.request.urlopen(url, timeout=1) as response:
                if response.status in accept:
                    return
                last = response.status
        except urllib.error.HTTPError as exc:
            if exc.code in accept:
                return
            last = exc
        except (urllib.error.URLError, ConnectionError, OSError) as exc:
            last = exc
        time.sleep(0.1)
    raise TimeoutError(f"{url} did not answer within {timeout} s (last: {last})")


def die_with_parent() -> None:
    """In the child before it runs the app: the kernel ends it (SIGTERM) when the process that started it ends,
    so an app started by a benchmark or a test that was killed does not run on and take the machine's CPU."""
    import ctypes
    import signal

    PR_SET_PDEATHSIG = 1
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the app is stopped by stop_app only
        pass


def start_app(plant_file: Path, port: int, log_file: Path, *args: str, root: Path = ROOT) -> subprocess.Popen:
    """``python -m app.cli ARGS --plant plant_file --port port`` with its output in ``log_file``; the
    data folder is the one of ``COMMISSION_DATA_DIR`` or a folder beside the log. ``root``: another
    checkout of the program (a benchmark comparing two versions side by side)."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    env.setdefault("COMMISSION_DATA_DIR", str(log_file.parent / "data"))
    env.pop("NICEGUI_USER_SIMULATION", None)
    env.pop("PYTEST_CURRENT_TEST", None)  # NiceGUI must not think it runs inside pytest
    with open(log_file, "wb") as log:
        proc = subprocess.Popen(
            [sys.executable, "-m", "app.cli", *args, "--plant", str(plant_file), *(("--port", str(port)) if port else ())],
            cwd=root, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=die_with_parent,
        )
    proc.log_file = log_file  # type: ignore[attr-defined]
    LOGS.append(log_file)
    return proc


def stop_app(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5)


@contextlib.contextmanager
def running_app(plant_text: str, folder: Path, *args: str, root: Path | None = None) -> Iterator[str]:
    """The GUI in its own process on ``plant_text`` (from the checkout ``root``, default this one);
    yields its base URL once it answers. It waits on ``/api/devices`` (or the login's refusal of it),
    not on a page: a page built for nobody would stay in the app for a minute and count in what a
    benchmark measures next."""
    plant = folder / "plant.toml"
    plant.write_text(plant_text)
    port = free_port()
    proc = start_app(plant, port, folder / "app.log", *args, root=root or ROOT)
    try:
        wait_http(f"http://127.0.0.1:{port}/api/devices", proc, accept=(200, 401))
        yield f"http://127.0.0.1:{port}"
    finally:
        stop_app(proc)


def wait_devices_online(url: str, names: Iterable[str] | None = None, proc: subprocess.Popen | None = None,
                        timeout: float = 30.0) -> dict[str, str]:
    """Wait until ``/api/devices`` of the app at ``url`` lists ``names`` (every device when None) online.

    Returns the status of every device; raises TimeoutError naming the devices that are not online,
    or RuntimeError when ``proc`` (the app) exits meanwhile.
    """
    wanted = None if names is None else set(names)
    end = time.monotonic() + timeout
    status: dict[str, str] = {}
    while True:
        if proc is not None and proc.poll() is not None:
            raise RuntimeError(f"the app exited with {proc.returncode} while waiting for its devices")
        try:
            with urllib.request.urlopen(url + "/api/devices", timeout=2) as response:
                status = {d["name"]: d["status"] for d in json.load(response)}
        except OSError as exc:
            status = {"(no answer)": str(exc)}
        names_now = set(status) if wanted is None else wanted
        if names_now and all(status.get(n) == "online" for n in names_now):
            return status
        if time.monotonic() >= end:
            raise TimeoutError(f"devices not online within {timeout} s: {status}")
        time.sleep(0.1)  # polling an HTTP endpoint from a synchronous caller: the condition is checked each round


# -- the cost of a process, from /proc ----------------------------------------------------------

def app_pid(port: int) -> int:
    """The process listening on ``port``."""
    out = subprocess.run(["ss", "-ltnpH", f"sport = :{port}"], capture_output=True, text=True).stdout
    return int(out.split("pid=")[1].split(",")[0])


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of ``pid`` so far."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def thread_cpu_s(pid: int, tid: int) -> float:
    """User + system CPU seconds of one thread of ``pid`` (the main thread, which runs the event loop: ``tid == pid``)."""
    try:
        fields = Path(f"/proc/{pid}/task/{tid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return 0.0


def load() -> str:
    """The machine's load averages (1, 5, 15 min) and cores, to print beside a figure."""
    one, five, fifteen = os.getloadavg()
    return f"load {one:.2f} {five:.2f} {fifteen:.2f} on {os.cpu_count()} cores"


def need_playwright():
    """playwright's sync API, or exit with how to get it (the browser is Debian's chromium)."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        sys.exit("this benchmark drives chromium through playwright: pip install playwright "
                 f"(no browser download: it uses {CHROMIUM})")
    return sync_playwright
