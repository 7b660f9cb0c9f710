"""Helpers shared by the page tests (simulated user) and the browser tests."""

from __future__ import annotations

import asyncio
import contextlib
import importlib
import os
import re
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEMO_PLANT = ROOT / "plants" / "demo.toml"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def eventually(check: Callable[[], object], timeout: float = 5.0, interval: float = 0.05, what: str = "") -> None:
    """Retry ``check`` (which raises AssertionError, or returns falsy) until it passes or ``timeout`` ends."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout
    while True:
        try:
            result = check()
            if asyncio.iscoroutine(result):
                result = await result
            if result is None or result:
                return
            error: AssertionError | None = AssertionError(f"not true within {timeout} s: {what or check}")
        except AssertionError as exc:
            error = exc
        if loop.time() >= end:
            raise error
        await asyncio.sleep(interval)


async def stop_worker_tasks(runtime, timeout: float = 5.0) -> None:
    """End the worker's bus tasks before the app's shutdown, bounded, so a test's teardown cannot hang."""
    await asyncio.wait_for(runtime.worker.stop(), timeout + 1)


@contextlib.asynccontextmanager
async def simulated_user(runtime):
    """NiceGUI's simulated user on the app of ``runtime``, with NiceGUI's globals of its own.

    The app is registered (``server.register``: the simulated user's host name is "test"), its
    lifespan started, and on leaving the worker stopped (bounded) and the app shut down, also when
    the test failed inside, so that the next app can start.
    """
    import httpx
    from nicegui import core, ui
    from nicegui.functions.download import download
    from nicegui.functions.navigate import Navigate
    from nicegui.functions.notify import notify
    from nicegui.testing import User
    from nicegui.testing.general import nicegui_reset_globals, prepare_simulation

    from app import runtime as rt

    with nicegui_reset_globals():
        os.environ["NICEGUI_USER_SIMULATION"] = "true"
        try:
            prepare_simulation()
            # nicegui_reset_globals drops the module of every page function (server): import it afresh
            importlib.import_module("server").register(runtime, allowed_hosts=("test",))
            ui.run(storage_secret="test secret")
            failure: BaseException | None = None
            async with core.app.router.lifespan_context(core.app):
                async with httpx.AsyncClient(transport=httpx.ASGITransport(core.app), base_url="http://test") as client:
                    try:
                        yield User(client)
                    except BaseException as exc:  # noqa: BLE001 - re-raised below, after the app has shut down
                        failure = exc
                    finally:
                        await stop_worker_tasks(runtime)  # Worker.stop() can hang in the lifespan's shutdown
            if failure is not None:
                raise failure
        finally:
            os.environ.pop("NICEGUI_USER_SIMULATION", None)
            ui.navigate = Navigate()
            ui.notify = notify
            ui.download = download
            rt.set_current(None)


# -- the app as a separate process (browser tests) ---------------------------------------------


def demo_plant_text(bus_port: int) -> str:
    """The demo plant file with the simulated RS485 line moved to ``bus_port`` and every other
    simulated TCP endpoint (the SCU's serial line) to a free port of its own."""
    text = DEMO_PLANT.read_text()
    assert 'port = "socket://127.0.0.1:5020"' in text, "demo plant no longer names socket://127.0.0.1:5020"
    text = text.replace("socket://127.0.0.1:5020", f"socket://127.0.0.1:{bus_port}")
    text = re.sub(r"socket://127\.0\.0\.1:(?!%d\b)\d+" % bus_port, lambda m: f"socket://127.0.0.1:{free_port()}", text)
    # the simulated MO 64 on TCP: a host and a port of its own
    return re.sub(r'(type = "logited-tcp"\nhost = "127\.0\.0\.1"\nport = )\d+', lambda m: f"{m.group(1)}{free_port()}", text)


def private_endpoints(plant, tag: str):
    """A loaded plant with every simulated endpoint made private to one test: each
    ``socket://127.0.0.1:PORT`` on a free port, each CAN channel suffixed with ``tag``."""
    for bus in plant.buses.values():
        port = bus.options.get("port")
        if isinstance(port, str) and port.startswith("socket://127.0.0.1:"):
            bus.options["port"] = f"socket://127.0.0.1:{free_port()}"
        if bus.type == "logited-tcp" and bus.options.get("host") == "127.0.0.1":
            bus.options["port"] = free_port()
        if bus.type == "can":
            bus.options["channel"] = f"{bus.options['channel']}-{tag}"
    return plant


def wait_http(url: str, proc: subprocess.Popen | None = None, timeout: float = 20.0) -> None:
    """Wait until ``url`` answers 200 (raise if ``proc`` dies or ``timeout`` passes)."""
    end = time.monotonic() + timeout
    last: object = None
    while time.monotonic() < end:
        if proc is not None and proc.poll() is not None:
            raise RuntimeError(f"the app exited with {proc.returncode} before answering {url}")
        try:
            with urllib.request.urlopen(url, timeout=1) as response:
                if response.status == 200:
                    return
                last = response.status
        except (urllib.error.URLError, ConnectionError, OSError) as exc:
            last = exc
        time.sleep(0.1)
    raise TimeoutError(f"{url} did not answer within {timeout} s (last: {last})")


def start_app(plant_file: Path, port: int, log_file: Path) -> subprocess.Popen:
    """``python -m app.cli --plant plant_file --port port`` with its output in ``log_file``."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    env.pop("NICEGUI_USER_SIMULATION", None)
    env.pop("PYTEST_CURRENT_TEST", None)  # NiceGUI must not think it runs inside pytest
    with open(log_file, "wb") as log:
        return subprocess.Popen(
            [sys.executable, "-m", "app.cli", "--plant", str(plant_file), "--port", str(port)],
            cwd=ROOT,
            env=env,
            stdout=log,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )


def stop_app(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5)


@contextlib.contextmanager
def running_app(plant_text: str, folder: Path) -> Iterator[str]:
    """The GUI in its own process on ``plant_text``; yields its base URL once it answers."""
    plant = folder / "plant.toml"
    plant.write_text(plant_text)
    port = free_port()
    proc = start_app(plant, port, folder / "app.log")
    try:
        wait_http(f"http://127.0.0.1:{port}/", proc)
        yield f"http://127.0.0.1:{port}"
    finally:
        stop_app(proc)
